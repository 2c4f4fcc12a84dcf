// The vehicle's calibration routine (`CalibrationSession` around the stepwise `CalibrationRun`)
// against the simulated vehicle, cycle by cycle as agvnav-vehicle steps it: the whole routine
// writes a calibration within the Monte-Carlo tolerance of the simulated routine and keeps the old
// file as .bak; a PLC Stop, a drive fault and a heartbeat loss quick-stop and abort with the file
// untouched; a plan that does not fit is refused before any set-point; the atomic file write.
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "agv/calib/calibration_file.hpp"
#include "agv/calibration/calibration_session.hpp"
#include "agv/calibration/sim_calibration_vehicle.hpp"
#include "agv/sim/ray_caster.hpp"
#include "agv/sim/world.hpp"
#include "agv_test.hpp"
#include "calibration_check.hpp"

using agv::deg2rad;
using agv::Duration;
using agv::Pose2d;
using agv::Status;
using agv::Timestamp;
namespace cal = agv::calibration;

namespace {

std::string work(const char* name) {
  return std::string(AGV_TEST_WORK_DIR) + "/" + name;
}

void writeText(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f << text;
}

/// The simulated drive with a switchable fault, counting what the routine sends.
class TestDrive final : public agv::hal::DriveControl {
 public:
  explicit TestDrive(agv::hal::DriveControl& inner) : inner_(inner) {}
  Status command(const agv::hal::DriveCommand& cmd) noexcept override {
    ++commands;
    lastSpeed = cmd.speed;
    if (faulted) {
      static_cast<void>(inner_.stop());  // the drive stops by itself on its fault reaction
      return Status::DeviceFault;
    }
    return inner_.command(cmd);
  }
  Status stop() noexcept override {
    ++stops;
    lastSpeed = 0.0;
    return inner_.stop();
  }
  bool isStandstill() const noexcept override { return inner_.isStandstill(); }

  int commands = 0;
  int stops = 0;
  int quickStops = 0;
  double lastSpeed = 0.0;
  bool faulted = false;
  std::uint32_t faultCode = 0;

 private:
  agv::hal::DriveControl& inner_;
};

const Pose2d kStart{10.0, 12.5, 0.0};

/// The simulated vehicle of agvnav-calibrate (built-in warehouse, encoders over CANopen) and a
/// session on it writing `file`.
struct Bench {
  explicit Bench(const std::string& file, int segmentsPerPhase = 2,
                 cal::FreeArea area = cal::FreeArea{2.5, 0.5, 24.0, 23.0}) {
    agv::sim::WorldParseError perr;
    REQUIRE(agv::sim::parseWorld(agv::sim::defaultWorldText(), world, perr) == Status::Ok);
    caster = std::make_unique<agv::sim::RayCaster>(world, 1.0);
    vehicle = std::make_unique<cal::SimCalibrationVehicle>(*caster, truth, agv::sim::SimLaserParams{}, 1, kStart, &can);
    REQUIRE(vehicle->status() == Status::Ok);
    drive = std::make_unique<TestDrive>(vehicle->drive());
    cal::SessionConfig config;
    config.plan.segmentsPerPhase = segmentsPerPhase;
    config.plan.area = area;
    config.routine.deceleration = truth.acceleration;
    config.calibrationFile = file;
    cal::DriveHooks hooks;
    hooks.quickStop = [this] {
      ++drive->quickStops;
      static_cast<void>(drive->stop());
    };
    hooks.faultCode = [this] { return drive->faultCode; };
    session = std::make_unique<cal::CalibrationSession>(*drive, hooks, config,
                                                        [this](const std::string& line) { log.push_back(line); });
  }

  /// One control cycle of 20 ms as the vehicle runs it: samples, sweeps, one step.
  bool cycle() {
    vehicle->wait(Duration::fromMilliseconds(20));
    agv::hal::EncoderSample s;
    while (vehicle->encoders().read(s) == Status::Ok) {
      session->onEncoderSample(s);
    }
    while (vehicle->laser().read(*scan) == Status::Ok) {
      session->onSweep(*scan);
    }
    const bool written = session->step(vehicle->now());
    states.insert(session->progress().state);
    if (session->progress().segment > maxSegment) {
      maxSegment = session->progress().segment;
    }
    return written;
  }

  /// Cycles until `done` or `limit` cycles; true when `done` held.
  template <typename F>
  bool cycleUntil(F done, int limit = 200000) {
    for (int i = 0; i < limit; ++i) {
      if (done()) {
        return true;
      }
      wrote = cycle() || wrote;
    }
    return done();
  }

  agv::sim::World world;
  std::unique_ptr<agv::sim::RayCaster> caster;
  agv::sim::SimVehicleParams truth;
  agv::sim::SimCanEncodersParams can = agv::sim::defaultSimCanEncoders(1U << 14U);
  std::unique_ptr<cal::SimCalibrationVehicle> vehicle;
  std::unique_ptr<TestDrive> drive;
  std::unique_ptr<cal::CalibrationSession> session;
  std::unique_ptr<agv::hal::LaserMeasurement> scan = std::make_unique<agv::hal::LaserMeasurement>();
  std::vector<std::string> log;
  std::set<cal::RoutineState> states;
  int maxSegment = 0;
  bool wrote = false;
};

const char* kOldFile = "old calibration file: must survive an aborted routine\n";

}  // namespace

TEST_CASE("calibrate.session: the whole routine writes a calibration within the Monte-Carlo tolerance", "[calibrate]") {
  const std::string file = work("session_whole.txt");
  writeText(file, kOldFile);
  Bench b(file);
  REQUIRE(b.session->requestCalibrate(kStart, b.vehicle->now()) == Status::Ok);
  CHECK(b.session->progress().total == 8);
  REQUIRE(b.cycleUntil([&] { return !b.session->running(); }));
  INFO(b.session->lastMessage());
  CHECK(b.session->progress().state == cal::RoutineState::Done);
  CHECK(b.session->progress().lastRefusal == Status::Ok);
  REQUIRE(b.wrote);
  CHECK(b.maxSegment == 8);
  for (cal::RoutineState s : {cal::RoutineState::Settling, cal::RoutineState::Steering, cal::RoutineState::Driving,
                              cal::RoutineState::Stopping, cal::RoutineState::Observing, cal::RoutineState::Done}) {
    CHECK(b.states.count(s) == 1);
  }
  // The old file is the backup; the new one parses and agrees with the simulator's truth within the
  // tolerance of calibrate.app (5 standard deviations of the Monte-Carlo figures scaled to 8
  // segments, docs/calibration.md: s_w 2000 ppm, offsets 0.1 deg, lx/ly 8 mm, ltheta 0.3 deg).
  CHECK(agv::test::readFile(file + ".bak") == kOldFile);
  CHECK_FALSE(agv::test::fileExists(file + ".tmp"));
  const agv::VehicleCalibration got = agv::test::checkCalibrationFile(file, b.truth, "session routine");
  // The values the vehicle reloads are the ones written.
  CHECK(b.session->lastCalibration().params.driveScale == Approx(got.params.driveScale).epsilon(1e-6));
  // The vehicle is back near its start (each backward segment retraces its forward one).
  const Pose2d end = b.vehicle->vehicle().truePose();
  CHECK(std::hypot(end.x - kStart.x, end.y - kStart.y) < 0.5);
}

TEST_CASE("calibrate.session: a PLC Stop mid-segment quick-stops in the same cycle and leaves the file",
          "[calibrate]") {
  const std::string file = work("session_stop.txt");
  writeText(file, kOldFile);
  std::remove((file + ".bak").c_str());
  Bench b(file);
  REQUIRE(b.session->requestCalibrate(kStart, b.vehicle->now()) == Status::Ok);
  // Mid-segment: driving segment 3 at speed.
  REQUIRE(b.cycleUntil([&] {
    return b.session->progress().segment == 3 && b.session->progress().state == cal::RoutineState::Driving &&
           !b.drive->isStandstill() && std::fabs(b.drive->lastSpeed) > 0.4;
  }));
  const int commandsBefore = b.drive->commands;
  b.session->requestStop(b.vehicle->now());
  CHECK(b.drive->quickStops == 1);  // in the call itself, not a later cycle
  CHECK(b.drive->lastSpeed == 0.0);
  CHECK(b.session->progress().state == cal::RoutineState::Aborted);
  CHECK(b.session->progress().lastRefusal == Status::Ok);  // stopped on request, no fault
  CHECK_FALSE(b.session->running());
  for (int i = 0; i < 200; ++i) {
    CHECK_FALSE(b.cycle());
  }
  CHECK(b.drive->commands == commandsBefore);  // no set-point after the stop
  CHECK(b.drive->isStandstill());
  CHECK(agv::test::readFile(file) == kOldFile);
  CHECK_FALSE(agv::test::fileExists(file + ".bak"));
  CHECK_FALSE(agv::test::fileExists(file + ".tmp"));
}

TEST_CASE("calibrate.session: a drive fault aborts with its code, file untouched", "[calibrate]") {
  const std::string file = work("session_fault.txt");
  writeText(file, kOldFile);
  Bench b(file);
  REQUIRE(b.session->requestCalibrate(kStart, b.vehicle->now()) == Status::Ok);
  REQUIRE(b.cycleUntil(
      [&] { return b.session->progress().segment == 2 && b.session->progress().state == cal::RoutineState::Driving; }));
  b.drive->faulted = true;
  b.drive->faultCode = 0x2310;
  b.cycle();  // the next set-point is refused: aborted in that cycle
  CHECK(b.session->progress().state == cal::RoutineState::Aborted);
  CHECK(b.session->progress().lastRefusal == Status::DeviceFault);
  CHECK(b.drive->quickStops == 1);
  CHECK(b.session->lastMessage().find("0x2310") != std::string::npos);
  CHECK(b.session->lastMessage().find("segment 2 of 8") != std::string::npos);
  // The code for the PLC (register 49); a code known already is not replaced.
  CHECK(b.session->progress().driveFault == 0x2310U);
  b.session->noteDriveFault(0x7305);
  CHECK(b.session->progress().driveFault == 0x2310U);
  REQUIRE_FALSE(b.log.empty());
  CHECK(b.log.back() == b.session->lastMessage());
  CHECK(agv::test::readFile(file) == kOldFile);
  CHECK_FALSE(b.wrote);
  // The next Calibrate (from the start again) clears the code with the refusal.
  b.drive->faulted = false;
  REQUIRE(b.session->requestCalibrate(kStart, b.vehicle->now()) == Status::Ok);
  CHECK(b.session->progress().lastRefusal == Status::Ok);
  CHECK(b.session->progress().driveFault == 0U);
}

TEST_CASE("calibrate.session: a drive fault whose code comes after the abort gets it once known", "[calibrate]") {
  const std::string file = work("session_late_code.txt");
  writeText(file, kOldFile);
  Bench b(file);
  b.session->noteDriveFault(0x2310);  // no run: ignored
  CHECK(b.session->progress().driveFault == 0U);
  REQUIRE(b.session->requestCalibrate(kStart, b.vehicle->now()) == Status::Ok);
  REQUIRE(b.cycleUntil([&] { return b.session->progress().state == cal::RoutineState::Driving; }));
  b.session->noteDriveFault(0x2310);  // running: ignored
  CHECK(b.session->progress().driveFault == 0U);
  // The statusword showed Fault; the error code (0x603F) is read by SDO afterwards.
  b.session->abortOnFault(Status::DeviceFault, "drive fault", b.vehicle->now());
  CHECK(b.session->progress().lastRefusal == Status::DeviceFault);
  CHECK(b.session->progress().driveFault == 0U);
  b.session->noteDriveFault(0);
  CHECK(b.session->progress().driveFault == 0U);
  b.session->noteDriveFault(0x2310);
  CHECK(b.session->progress().driveFault == 0x2310U);
  b.session->noteDriveFault(0x7305);  // the first code stays
  CHECK(b.session->progress().driveFault == 0x2310U);
  CHECK(agv::test::readFile(file) == kOldFile);
}

TEST_CASE("calibrate.session: a heartbeat loss seen by the owner aborts the routine", "[calibrate]") {
  const std::string file = work("session_heartbeat.txt");
  writeText(file, kOldFile);
  Bench b(file);
  REQUIRE(b.session->requestCalibrate(kStart, b.vehicle->now()) == Status::Ok);
  REQUIRE(b.cycleUntil([&] { return b.session->progress().state == cal::RoutineState::Driving; }));
  b.session->abortOnFault(Status::Timeout, "heartbeat of the traction drive lost", b.vehicle->now());
  CHECK(b.drive->quickStops == 1);
  CHECK(b.session->progress().state == cal::RoutineState::Aborted);
  CHECK(b.session->progress().lastRefusal == Status::Timeout);
  CHECK(b.session->lastMessage().find("heartbeat") != std::string::npos);
  // No drive fault code for a lost heartbeat, and none taken later.
  CHECK(b.session->progress().driveFault == 0U);
  b.session->noteDriveFault(0x8130);
  CHECK(b.session->progress().driveFault == 0U);
  const int commands = b.drive->commands;
  for (int i = 0; i < 50; ++i) {
    b.cycle();
  }
  CHECK(b.drive->commands == commands);
  CHECK(agv::test::readFile(file) == kOldFile);
}

TEST_CASE("calibrate.session: a plan that does not fit is refused before any motion", "[calibrate]") {
  const std::string file = work("session_nofit.txt");
  writeText(file, kOldFile);
  Bench b(file, 2, cal::FreeArea{4.0, 6.0, 16.0, 19.0});
  const Status s = b.session->requestCalibrate(kStart, b.vehicle->now());
  CHECK(s == Status::OutOfRange);
  CHECK(b.session->progress().lastRefusal == Status::OutOfRange);
  CHECK(b.session->progress().state == cal::RoutineState::Idle);
  CHECK(b.session->lastMessage().find("leaves the free area") != std::string::npos);
  CHECK_FALSE(b.session->running());
  for (int i = 0; i < 100; ++i) {
    b.cycle();
  }
  CHECK(b.drive->commands == 0);
  CHECK(b.drive->stops == 0);
  const Pose2d p = b.vehicle->vehicle().truePose();
  CHECK(p.x == kStart.x);
  CHECK(p.y == kStart.y);
  CHECK(agv::test::readFile(file) == kOldFile);
  // No pose known: refused as well.
  CHECK(b.session->requestCalibrate(Pose2d{NAN, 0.0, 0.0}, b.vehicle->now()) == Status::NotInitialized);
  CHECK(b.drive->commands == 0);
}

TEST_CASE("calibrate.session: the atomic write keeps the old file on a failure before the rename", "[calibrate]") {
  const std::string file = work("atomic.txt");
  std::remove((file + ".bak").c_str());
  writeText(file, "A\n");
  std::string error;
  // A crash between the temporary's write and the rename: the file is the old one.
  const Status s = cal::writeFileAtomically(file, "B\n", error, [] { return Status::DeviceFault; });
  CHECK(s == Status::DeviceFault);
  CHECK_FALSE(error.empty());
  CHECK(agv::test::readFile(file) == "A\n");
  CHECK_FALSE(agv::test::fileExists(file + ".tmp"));
  // A successful write: the new content, the old one as the backup.
  REQUIRE(cal::writeFileAtomically(file, "C\n", error) == Status::Ok);
  CHECK(agv::test::readFile(file) == "C\n");
  CHECK(agv::test::readFile(file + ".bak") == "A\n");
  // The temporary cannot be created (a folder in its place): refused, file intact.
  const std::string blocked = work("atomic_blocked.txt");
  writeText(blocked, "D\n");
  std::remove((blocked + ".tmp").c_str());
  REQUIRE(std::system(("mkdir -p '" + blocked + ".tmp'").c_str()) == 0);
  CHECK(cal::writeFileAtomically(blocked, "E\n", error) == Status::DeviceFault);
  CHECK(error.find(".tmp") != std::string::npos);
  CHECK(agv::test::readFile(blocked) == "D\n");
  // A first file has no backup.
  const std::string fresh = work("atomic_fresh.txt");
  std::remove(fresh.c_str());
  std::remove((fresh + ".bak").c_str());
  REQUIRE(cal::writeFileAtomically(fresh, "F\n", error) == Status::Ok);
  CHECK(agv::test::readFile(fresh) == "F\n");
  CHECK_FALSE(agv::test::fileExists(fresh + ".bak"));
}
