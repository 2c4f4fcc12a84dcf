// agvnav-vehicle's calibration routine in-process: the navigation pipeline on the simulated
// vehicle (encoders over CANopen, laser with reflectors, a reflector map of the world), the
// `VehicleCalibrationRoutine` taps between them, a scripted PLC link and simulated drives. The
// PLC's Calibrate runs the routine through all its states with the progress in the published
// reports, writes the file (old one as .bak) and reloads it; a Stop mid-segment quick-stops in the
// cycle that reads it; a drive fault and a heartbeat loss abort with the reason on the registers;
// a plan that does not fit and a Calibrate without a pose are refused before the drives move.
#include <cmath>
#include <fstream>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "agv/calib/calibration_file.hpp"
#include "agv/calibration/sim_calibration_vehicle.hpp"
#include "agv/nav/pipeline.hpp"
#include "agv/sim/ray_caster.hpp"
#include "agv/sim/sim_clock.hpp"
#include "agv/sim/world.hpp"
#include "agv_test.hpp"
#include "calibration_check.hpp"
#include "scripted_plc.hpp"
#include "sim_drives.hpp"
#include "simulated_drive_side.hpp"
#include "vehicle_calibration.hpp"

using agv::Duration;
using agv::Pose2d;
using agv::Status;
using agv::Timestamp;
namespace cal = agv::calibration;
namespace hal = agv::hal;
using agv::test::ScriptedPlc;

namespace {

std::string work(const char* name) {
  return std::string(AGV_TEST_WORK_DIR) + "/" + name;
}

/// The simulated vehicle's drive as the vehicle's drives, with a switchable fault.
class SimDrives final : public agv::vehicle::VehicleDrives, public hal::DriveControl {
 public:
  explicit SimDrives(hal::DriveControl& inner) : inner_(inner) {}
  hal::DriveControl& control() noexcept override { return *this; }
  void bringUp(Timestamp) noexcept override { ++bringUps; }
  Status health(const char*& why) const noexcept override {
    why = health_ == Status::Ok ? "enabled" : reason;
    return health_;
  }
  void quickStop() noexcept override {
    ++quickStops;
    static_cast<void>(inner_.stop());
  }
  void release() noexcept override { ++releases; }
  std::uint32_t faultCode() const noexcept override { return code; }
  void cycle(Timestamp) noexcept override {}
  Status command(const hal::DriveCommand& cmd) noexcept override {
    ++commands;
    return health_ == Status::Ok ? inner_.command(cmd) : Status::DeviceFault;
  }
  Status stop() noexcept override { return inner_.stop(); }
  bool isStandstill() const noexcept override { return inner_.isStandstill(); }

  /// The drive stops by itself (fault reaction / heartbeat consumer).
  void fail(Status h, const char* why, std::uint32_t faultCode) {
    health_ = h;
    reason = why;
    code = faultCode;
    static_cast<void>(inner_.stop());
  }

  int bringUps = 0;
  int quickStops = 0;
  int releases = 0;
  int commands = 0;
  const char* reason = "";
  std::uint32_t code = 0;

 private:
  hal::DriveControl& inner_;
  Status health_ = Status::Ok;
};

/// The drives as on the vehicle: the CiA 402 drive controller and the two simulated CiA 402 nodes
/// of agvnav-sim-drives exchanging frames in-process; the nodes' actual velocity and position drive
/// the simulated tricycle. With `wheel` (the simulated vehicle's own encoder measurements) the loop
/// is closed through the traction drive: the node reports the wheel's counts as its position
/// actual value, and the vehicle's encoder decoder reads them from its TPDO1 at {0x181, 2, 4}
/// (statusword first), with the steering encoder (node 2) on the same frames' path.
class Cia402Drives final : public agv::vehicle::VehicleDrives, public hal::EncoderSource {
 public:
  Cia402Drives(hal::DriveControl& physics, hal::EncoderSource* wheel, double trueDriveScale)
      : physics_(physics),
        wheel_(wheel),
        trueDriveScale_(trueDriveScale),
        nodes_(agv::simdrives::SimDrivesOptions{}, nullptr),
        ctl_(config_),
        decoder_(decoderConfig()) {}
  hal::DriveControl& control() noexcept override { return ctl_; }
  void bringUp(Timestamp now) noexcept override {
    if (ctl_.state() != agv::drivers::canopen::DriveControllerState::Enabled) {
      static_cast<void>(ctl_.start(now));
    }
    ++bringUps;
  }
  Status health(const char*& why) const noexcept override { return agv::vehicle::drivesHealth(ctl_, why); }
  void quickStop() noexcept override {
    ++quickStops;
    ctl_.quickStop(agv::drivers::canopen::SafeStopReason::PlcStop);
  }
  void release() noexcept override { static_cast<void>(ctl_.release()); }
  std::uint32_t faultCode() const noexcept override { return agv::vehicle::drivesFaultCode(ctl_); }
  void cycle(Timestamp now) noexcept override {
    using agv::drivers::CanFrame;
    if (wheel_ != nullptr) {  // the wheel's measured counts and steering angle
      agv::test::feedWheel(*wheel_, nodes_.node(1), wheelTicks_, wheelSteer_);
    }
    CanFrame buf[agv::simdrives::SimDrives::kMaxFrames];
    const std::size_t n = nodes_.step(now, agv::Span<CanFrame>(buf));
    for (std::size_t k = 0; k < n; ++k) {
      ctl_.onFrame(buf[k]);
      buf[k].stamp = now;
      static_cast<void>(decoder_.onFrame(buf[k]));  // the encoder decoder on the same bus
    }
    if (wheel_ != nullptr) {  // the CiA 406 steering encoder, node 2: heartbeat and TPDO1
      CanFrame enc[2];
      agv::test::steeringEncoderFrames(wheelSteer_, now, enc);
      for (const CanFrame& f : enc) {
        static_cast<void>(decoder_.onFrame(f));
      }
    }
    ctl_.poll(now);
    const std::size_t m = ctl_.takeFrames(agv::Span<CanFrame>(buf));
    for (std::size_t k = 0; k < m; ++k) {
      nodes_.receive(buf[k], now);
    }
    // The motors move the vehicle. Without the wheel's feedback the traction node's own position is
    // the wheel: its counts are metres at the configured scale.
    const double scale = wheel_ != nullptr ? trueDriveScale_ : 1.0 / config_.traction.velocityUnitsPerMps;
    static_cast<void>(
        physics_.command(agv::test::motorsToVehicle(nodes_.traction(), nodes_.steering(), config_, scale, now)));
  }
  // hal::EncoderSource: the samples the vehicle's decoder made from the frames.
  Status read(hal::EncoderSample& out) noexcept override {
    if (!decoder_.takeSample(out)) {
      return Status::NotFound;
    }
    ++samplesDecoded;
    return Status::Ok;
  }
  Status health() const noexcept override { return decoder_.health(); }

  agv::simdrives::SimDrives& nodes() noexcept { return nodes_; }
  const agv::drivers::canopen::Cia402DriveController& controller() const noexcept { return ctl_; }
  const agv::drivers::canopen::CanopenEncoders& decoder() const noexcept { return decoder_; }
  int bringUps = 0;
  int quickStops = 0;
  std::uint64_t samplesDecoded = 0;  ///< samples the vehicle got from the decoder

 private:
  static agv::drivers::canopen::CanopenEncodersConfig decoderConfig() {
    agv::drivers::canopen::CanopenEncodersConfig c;
    c.drive.nodeId = 1;
    c.drive.pdo = agv::drivers::canopen::PdoMapping{0x181, 2, 4};  // statusword + position actual value
    c.steering.nodeId = 2;
    c.steering.radiansPerCount = agv::test::kSteerEncoderRadPerCount;
    c.trigger = agv::drivers::canopen::SampleTrigger::DriveUpdated;
    return c;
  }
  hal::DriveControl& physics_;
  hal::EncoderSource* wheel_;
  double trueDriveScale_;
  agv::drivers::canopen::Cia402DriveConfig config_{};
  agv::simdrives::SimDrives nodes_;
  agv::drivers::canopen::Cia402DriveController ctl_;
  agv::drivers::canopen::CanopenEncoders decoder_;
  std::int64_t wheelTicks_ = 0;
  double wheelSteer_ = 0.0;
};

const Pose2d kStart{10.0, 12.5, 0.0};
const char* kOld = "the calibration file before the routine\n";

struct VehicleBench {
  /// `cia402`: the drives through the CiA 402 controller and simulated nodes; `closed`: and the
  /// vehicle's encoders from the traction drive's TPDO1 (see `Cia402Drives`).
  explicit VehicleBench(const std::string& file, cal::FreeArea area = cal::FreeArea{2.5, 0.5, 24.0, 23.0},
                        bool cia402 = false, bool closed = false) {
    {
      std::ofstream f(file, std::ios::trunc);
      f << kOld;
    }
    agv::sim::WorldParseError perr;
    REQUIRE(agv::sim::parseWorld(agv::sim::defaultWorldText(), world, perr) == Status::Ok);
    caster = std::make_unique<agv::sim::RayCaster>(world, 1.0);
    sim = std::make_unique<cal::SimCalibrationVehicle>(*caster, truth, laserParams, 1, kStart, closed ? nullptr : &can);
    REQUIRE(sim->status() == Status::Ok);
    drives = std::make_unique<SimDrives>(sim->drive());
    if (cia402) {
      cia = std::make_unique<Cia402Drives>(sim->drive(), closed ? &sim->encoders() : nullptr, truth.truth.driveScale);
    }
    map = std::make_unique<agv::LandmarkMap>();
    std::uint32_t id = 1;
    for (const agv::sim::Circle& c : world.circles) {
      if (c.kind == agv::sim::ObstacleKind::Reflector) {
        REQUIRE(map->addSurveyed(agv::LandmarkKind::Reflector, c.centre.x, c.centre.y, 0.005, id++).ok());
      }
    }
    map->setMode(agv::MapMode::Static);
    current.params = agv::TricycleParams{1.5, 1.0e-4, 0.0, 0.0};  // the drawing's values
    current.laserPose = Pose2d{1.6, 0.0, 0.0};
    config.drivesEnabled = true;
    config.calibrationAreaSet = true;
    config.calibrationPlan.area = area;
    config.calibrationPlan.segmentsPerPhase = 2;
    config.drives.traction.acceleration = truth.acceleration;
    config.calibrationFile = file;
    routine = std::make_unique<agv::vehicle::VehicleCalibrationRoutine>(
        config, current, closed ? static_cast<hal::EncoderSource&>(*cia) : sim->encoders(), sim->laser(), plc,
        cia ? static_cast<agv::vehicle::VehicleDrives*>(cia.get()) : drives.get(),
        [this](const std::string& line) { log.push_back(line); });
    agv::nav::PipelineParams p;
    p.kinematics = current.params;
    p.localizer.laser.mounting = current.laserPose;
    p.localizer.laser.rangeMax = 30.0;
    pipeline = std::make_unique<agv::nav::Pipeline>(
        p, *map, agv::nav::PipelineDevices{routine->encoders(), routine->laser(), routine->plc(), clock});
    REQUIRE(pipeline->configure() == Status::Ok);
    REQUIRE(pipeline->activate() == Status::Ok);
    routine->attach(*pipeline);
  }

  /// One vehicle cycle of 10 ms: the pipeline (devices through the taps), then the routine. The
  /// allocations of the vehicle's part (not the simulation's) are counted while the routine
  /// collects data (states settling .. observing).
  bool cycle() {
    sim->wait(Duration::fromMilliseconds(10));
    clock.set(sim->now());
    const bool collecting = routine->progress().state != cal::RoutineState::Idle && routine->running() &&
                            routine->progress().state != cal::RoutineState::Solving;
    bool w = false;
    const std::uint64_t n = agv::test::countAllocations([&] {
      static_cast<void>(pipeline->cycle());
      w = routine->step(sim->now());
    });
    if (collecting && routine->progress().state != cal::RoutineState::Solving) {
      collectingCycles += 1;
      collectingAllocations += n;
    }
    states.insert(routine->progress().state);
    if (routine->progress().segment > maxSegment) {
      maxSegment = routine->progress().segment;
    }
    wrote = wrote || w;
    return w;
  }

  template <typename F>
  bool cycleUntil(F done, int limit = 300000) {
    for (int i = 0; i < limit; ++i) {
      if (done()) {
        return true;
      }
      cycle();
    }
    return done();
  }

  /// Localize at the true start, then a few cycles.
  void localize() {
    plc.send(hal::PlcCommandKind::Localize, kStart);
    for (int i = 0; i < 20; ++i) {
      cycle();
    }
    REQUIRE(pipeline->localizing());
  }

  agv::sim::World world;
  std::unique_ptr<agv::sim::RayCaster> caster;
  agv::sim::SimVehicleParams truth;
  agv::sim::SimLaserParams laserParams;
  agv::sim::SimCanEncodersParams can = agv::sim::defaultSimCanEncoders(1U << 14U);
  std::unique_ptr<cal::SimCalibrationVehicle> sim;
  std::unique_ptr<SimDrives> drives;
  std::unique_ptr<Cia402Drives> cia;
  std::unique_ptr<agv::LandmarkMap> map;
  agv::VehicleCalibration current;
  agv::vehicle::VehicleConfig config;
  ScriptedPlc plc;
  agv::sim::SimClock clock;
  std::unique_ptr<agv::vehicle::VehicleCalibrationRoutine> routine;
  std::unique_ptr<agv::nav::Pipeline> pipeline;
  std::vector<std::string> log;
  std::set<cal::RoutineState> states;
  int maxSegment = 0;
  bool wrote = false;
  std::uint64_t collectingCycles = 0;
  std::uint64_t collectingAllocations = 0;
};

}  // namespace

TEST_CASE("vehicle.calibration: the PLC's Calibrate runs the routine, writes and reloads the file",
          "[vehicle][calibrate]") {
  const std::string file = work("vehicle_cal.txt");
  VehicleBench b(file);
  b.localize();
  b.plc.send(hal::PlcCommandKind::Calibrate);
  REQUIRE(b.cycleUntil([&] { return b.routine->running(); }, 10));
  CHECK(b.drives->bringUps == 1);
  REQUIRE(b.cycleUntil([&] { return !b.routine->running(); }));
  INFO(b.routine->session()->lastMessage());
  CHECK(b.routine->progress().state == cal::RoutineState::Done);
  REQUIRE(b.wrote);
  CHECK(b.maxSegment == 8);
  CHECK(b.drives->releases == 1);  // handed back at the end
  CHECK(b.drives->quickStops == 0);
  // The cycles while collecting (taps, set-points, observations) allocate nothing.
  CHECK(b.collectingCycles > 10000);
  CHECK(b.collectingAllocations == 0U);
  // Published: mode Calibrating during the run, the states on register 44 in the reports.
  CHECK(b.plc.calibratingReports > 100);
  for (int i = 0; i < 5; ++i) {
    b.cycle();
  }
  for (cal::RoutineState s : {cal::RoutineState::Settling, cal::RoutineState::Steering, cal::RoutineState::Driving,
                              cal::RoutineState::Stopping, cal::RoutineState::Observing, cal::RoutineState::Done}) {
    CHECK(b.plc.seen[static_cast<std::uint8_t>(s)]);
  }
  CHECK(b.plc.last.health.calibration.state == static_cast<std::uint8_t>(cal::RoutineState::Done));
  CHECK(b.plc.last.health.calibration.total == 8);
  CHECK(b.plc.last.health.calibration.lastRefusal == Status::Ok);
  CHECK(b.plc.last.health.mode != hal::NavMode::Calibrating);
  // The file: parsed back, within the calibrate.app tolerance of the truth; the old one as .bak.
  CHECK(agv::test::readFile(file + ".bak") == kOld);
  const agv::VehicleCalibration got = agv::test::checkCalibrationFile(file, b.truth, "vehicle routine");
  // Reloaded: the vehicle's calibration is the file's, and the pipeline goes on localizing with it.
  CHECK(b.routine->calibration().params.driveScale == Approx(got.params.driveScale).epsilon(1e-6));
  CHECK(b.pipeline->localizing());
  const Pose2d truePose = b.sim->vehicle().truePose();
  const Pose2d est = b.pipeline->localizer().pose();
  CHECK(std::hypot(est.x - truePose.x, est.y - truePose.y) < 0.1);
}

TEST_CASE("vehicle.calibration: a PLC Stop mid-segment quick-stops in the cycle that reads it",
          "[vehicle][calibrate]") {
  const std::string file = work("vehicle_cal_stop.txt");
  VehicleBench b(file);
  b.localize();
  b.plc.send(hal::PlcCommandKind::Calibrate);
  REQUIRE(b.cycleUntil([&] {
    return b.routine->progress().segment == 2 && b.routine->progress().state == cal::RoutineState::Driving &&
           !b.sim->drive().isStandstill();
  }));
  b.plc.send(hal::PlcCommandKind::Stop);
  b.sim->wait(Duration::fromMilliseconds(10));
  b.clock.set(b.sim->now());
  static_cast<void>(b.pipeline->cycle());  // reads the Stop: the quick stop happens here
  CHECK(b.drives->quickStops == 1);
  CHECK(b.routine->progress().state == cal::RoutineState::Aborted);
  CHECK(b.drives->releases == 0);  // an abort quick-stops; it does not hand back
  const int commands = b.drives->commands;
  REQUIRE(b.cycleUntil([&] { return b.sim->drive().isStandstill(); }, 500));
  for (int i = 0; i < 100; ++i) {
    b.cycle();
  }
  CHECK(b.drives->commands == commands);
  CHECK(b.plc.last.health.calibration.state == static_cast<std::uint8_t>(cal::RoutineState::Aborted));
  CHECK(b.plc.last.health.calibration.lastRefusal == Status::Ok);
  CHECK(b.plc.last.health.mode == hal::NavMode::Idle);  // the Stop reached the pipeline too
  CHECK(agv::test::readFile(file) == kOld);
}

TEST_CASE("vehicle.calibration: a drive fault and a heartbeat loss abort with the reason on the registers",
          "[vehicle][calibrate]") {
  struct Case {
    Status health;
    const char* why;
    std::uint32_t code;
    const char* expect;
  };
  for (const Case& k : {Case{Status::DeviceFault, "drive fault", 0x2310, "0x2310"},
                        Case{Status::Timeout, "drive heartbeat lost", 0, "heartbeat"}}) {
    const std::string file = work("vehicle_cal_fault.txt");
    VehicleBench b(file);
    b.localize();
    b.plc.send(hal::PlcCommandKind::Calibrate);
    REQUIRE(b.cycleUntil([&] {
      return b.routine->progress().segment == 3 && b.routine->progress().state == cal::RoutineState::Driving;
    }));
    b.drives->fail(k.health, k.why, k.code);
    for (int i = 0; i < 5; ++i) {  // the abort in the first, then at least one publication (20 ms)
      b.cycle();
    }
    CHECK(b.routine->progress().state == cal::RoutineState::Aborted);
    CHECK(b.plc.last.health.calibration.lastRefusal == k.health);
    CHECK(b.plc.last.health.calibration.driveFault == k.code);  // register 49
    CHECK(b.drives->quickStops >= 1);
    REQUIRE_FALSE(b.log.empty());
    CHECK(b.log.back().find(k.expect) != std::string::npos);
    CHECK(agv::test::readFile(file) == kOld);
  }
  {
    // A drive that shows Fault before its code is known (the controller reads 0x603F by SDO after
    // the abort): register 49 gets the code in a later cycle.
    const std::string file = work("vehicle_cal_late_code.txt");
    VehicleBench b(file);
    b.localize();
    b.plc.send(hal::PlcCommandKind::Calibrate);
    REQUIRE(b.cycleUntil([&] { return b.routine->progress().state == cal::RoutineState::Driving; }));
    b.drives->fail(Status::DeviceFault, "drive fault", 0);
    for (int i = 0; i < 5; ++i) {
      b.cycle();
    }
    CHECK(b.routine->progress().state == cal::RoutineState::Aborted);
    CHECK(b.plc.last.health.calibration.lastRefusal == Status::DeviceFault);
    CHECK(b.plc.last.health.calibration.driveFault == 0U);
    b.drives->code = 0x7121;  // the SDO answer
    for (int i = 0; i < 5; ++i) {
      b.cycle();
    }
    CHECK(b.plc.last.health.calibration.driveFault == 0x7121U);
    CHECK(agv::test::readFile(file) == kOld);
  }
}

TEST_CASE("vehicle.calibration: refused before the drives move", "[vehicle][calibrate]") {
  const std::string file = work("vehicle_cal_refused.txt");
  {
    VehicleBench b(file, cal::FreeArea{4.0, 6.0, 16.0, 19.0});
    b.localize();
    b.plc.send(hal::PlcCommandKind::Calibrate);
    for (int i = 0; i < 50; ++i) {
      b.cycle();
    }
    CHECK(b.drives->bringUps == 0);
    CHECK(b.drives->commands == 0);
    CHECK(b.plc.last.health.calibration.lastRefusal == Status::OutOfRange);
    CHECK(hal::hasBit(b.plc.last.health.bits, hal::HealthBit::CommandRejected));
    CHECK(b.plc.last.health.mode == hal::NavMode::Localizing);
    REQUIRE_FALSE(b.log.empty());
    CHECK(b.log.back().find("leaves the free area") != std::string::npos);
    CHECK(agv::test::readFile(file) == kOld);
  }
  {
    VehicleBench b(file);  // not localizing: no start pose
    b.plc.send(hal::PlcCommandKind::Calibrate);
    for (int i = 0; i < 50; ++i) {
      b.cycle();
    }
    CHECK(b.drives->bringUps == 0);
    CHECK(b.drives->commands == 0);
    CHECK(b.plc.last.health.calibration.lastRefusal == Status::NotInitialized);
  }
}

TEST_CASE("vehicle.calibration: through the CiA 402 controller and simulated drive nodes", "[vehicle][calibrate]") {
  SECTION("the whole routine") {
    const std::string file = work("vehicle_cal_cia402.txt");
    VehicleBench b(file, cal::FreeArea{2.5, 0.5, 24.0, 23.0}, true);
    b.localize();
    b.plc.send(hal::PlcCommandKind::Calibrate);
    // The drives come up first (SDO configuration, NMT start, power state machine).
    REQUIRE(b.cycleUntil([&] { return b.routine->progress().state == cal::RoutineState::Settling; }, 500));
    CHECK(b.cia->controller().state() == agv::drivers::canopen::DriveControllerState::Enabled);
    REQUIRE(b.cycleUntil([&] { return !b.routine->running(); }));
    INFO(b.routine->session()->lastMessage());
    CHECK(b.routine->progress().state == cal::RoutineState::Done);
    REQUIRE(b.wrote);
    static_cast<void>(agv::test::checkCalibrationFile(file, b.truth, "vehicle routine through CiA 402"));
    // The drives handed back at the end (disable operation), not quick-stopped by the set-point
    // watchdog 200 ms later: one second on, both still in Switched on, no safe stop.
    using agv::drivers::canopen::DriveControllerState;
    using agv::drivers::canopen::PowerState;
    CHECK(b.cia->controller().state() == DriveControllerState::Released);
    for (int i = 0; i < 100; ++i) {
      b.cycle();
    }
    CHECK(b.cia->controller().state() == DriveControllerState::Released);
    CHECK(b.cia->quickStops == 0);
    CHECK(b.cia->nodes().traction().state() == PowerState::SwitchedOn);
    CHECK(b.cia->nodes().steering().state() == PowerState::SwitchedOn);
    // A second Calibrate brings them up again; the PLC's Stop then ends it.
    b.plc.send(hal::PlcCommandKind::Calibrate);
    REQUIRE(b.cycleUntil([&] { return b.routine->progress().state == cal::RoutineState::Settling; }, 500));
    CHECK(b.cia->controller().state() == DriveControllerState::Enabled);
    b.plc.send(hal::PlcCommandKind::Stop);
    REQUIRE(b.cycleUntil([&] { return !b.routine->running(); }, 100));
    CHECK(b.routine->progress().state == cal::RoutineState::Aborted);
    CHECK(b.cia->controller().state() == DriveControllerState::SafeStop);
  }
  SECTION("heartbeat loss of the traction node, and a traction fault") {
    for (int k = 0; k < 2; ++k) {
      const std::string file = work("vehicle_cal_cia402_fault.txt");
      VehicleBench b(file, cal::FreeArea{2.5, 0.5, 24.0, 23.0}, true);
      b.localize();
      b.plc.send(hal::PlcCommandKind::Calibrate);
      REQUIRE(b.cycleUntil([&] {
        return b.routine->progress().segment == 2 && b.routine->progress().state == cal::RoutineState::Driving &&
               !b.sim->drive().isStandstill();
      }));
      if (k == 0) {
        b.cia->nodes().node(1).setSilent(true);
      } else {
        b.cia->nodes().node(1).injectFault(0x2310);
      }
      REQUIRE(b.cycleUntil([&] { return !b.routine->running(); }, 100));  // 150 ms heartbeat timeout, 1 s bound
      CHECK(b.routine->progress().state == cal::RoutineState::Aborted);
      CHECK(b.routine->progress().lastRefusal == (k == 0 ? Status::Timeout : Status::DeviceFault));
      REQUIRE_FALSE(b.log.empty());
      CHECK(b.log.back().find(k == 0 ? "heartbeat" : "0x2310") != std::string::npos);
      CHECK(b.cia->quickStops >= 1);
      REQUIRE(b.cycleUntil([&] { return b.sim->drive().isStandstill(); }, 1000));
      // Register 49: the traction drive's error code (its EMCY, and 0x603F read back by SDO);
      // none for a lost heartbeat.
      CHECK(b.plc.last.health.calibration.driveFault == (k == 0 ? 0U : 0x2310U));
      CHECK(b.cia->controller().traction().errorCode() == (k == 0 ? 0U : 0x2310U));
      CHECK(agv::test::readFile(file) == kOld);
    }
  }
}

TEST_CASE("vehicle.calibration: the loop closed through the traction drive's TPDO1 at {0x181, 2, 4}",
          "[vehicle][calibrate]") {
  const std::string file = work("vehicle_cal_closed.txt");
  VehicleBench b(file, cal::FreeArea{2.5, 0.5, 24.0, 23.0}, true, true);
  b.localize();
  b.plc.send(hal::PlcCommandKind::Calibrate);
  REQUIRE(b.cycleUntil([&] { return b.routine->progress().state == cal::RoutineState::Settling; }, 500));
  REQUIRE(b.cycleUntil([&] { return !b.routine->running(); }));
  INFO(b.routine->session()->lastMessage());
  CHECK(b.routine->progress().state == cal::RoutineState::Done);
  REQUIRE(b.wrote);
  // The vehicle's only encoder input was the decoder of the traction node's TPDO1 (offset 2): a
  // sample per TPDO (10 ms) over the run, no malformed frame.
  CHECK(b.cia->samplesDecoded > 10000U);
  CHECK(b.cia->decoder().malformedFrames() == 0U);
  static_cast<void>(agv::test::checkCalibrationFile(file, b.truth, "vehicle routine, encoders from the drive's TPDO1"));
}
