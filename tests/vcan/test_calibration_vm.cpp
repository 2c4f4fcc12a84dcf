// agvnav-vehicle's calibration routine on the real Linux CAN stack, in the vcan VM
// (docs/vcan-testing.md): the vehicle side is the program's code (`VehicleCalibrationRoutine`,
// the SocketCAN CiA 402 drive controller, the real `CanopenEncoderSource` reading the drive
// encoder from the traction drive's TPDO1 at {0x181, 2, 4}, the navigation pipeline); the other
// side of vcan0 plays the two CiA 402 drives (`SimDrives` of agvnav-sim-drives, on their own
// socket), the steering encoder (node 2) and the simulated tricycle and laser, all in real time.
// A scripted PLC (this statically linked binary has no libmodbus) localizes and writes Calibrate.
// A peer socket on vcan0 records what the vehicle sends to the drives, with kernel timestamps.
// Cases: a plan that does not fit is refused before any frame to the drives; a PLC Stop
// mid-segment, a heartbeat loss of the traction node and a traction drive fault each quick-stop
// the traction and abort the routine, the calibration file untouched; the whole routine runs
// through every state and writes a calibration file. The init script checks candump's log for
// the bring-up and enable sequence of the traction drive and its quick stop.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "agv/calib/calibration_file.hpp"
#include "agv/calibration/sim_calibration_vehicle.hpp"
#include "agv/drivers/linux/canopen_encoder_source.hpp"
#include "agv/drivers/linux/monotonic_clock.hpp"
#include "agv/drivers/linux/socketcan_bus.hpp"
#include "agv/nav/pipeline.hpp"
#include "agv/sim/ray_caster.hpp"
#include "agv/sim/world.hpp"
#include "agv_test.hpp"
#include "calibration_check.hpp"
#include "scripted_plc.hpp"
#include "sim_drives.hpp"
#include "simulated_drive_side.hpp"
#include "vcan_peer.hpp"
#include "vehicle_calibration.hpp"

using agv::Duration;
using agv::Pose2d;
using agv::Status;
using agv::Timestamp;
using agv::drivers::CanFrame;
using agv::drivers::monotonicNow;
using agv::drivers::canopen::PowerState;
namespace cal = agv::calibration;
namespace hal = agv::hal;

namespace {

const Pose2d kStart{10.0, 12.5, 0.0};
const char* const kOld = "the calibration file before the routine\n";

/// The identifiers the peer socket records: NMT, the traction drive's EMCY, the drives' RPDO1
/// (controlword + target), the SDO requests to them, the drive controller's heartbeat, and the
/// steering encoder's heartbeat (sent all along by the drives' side: the peer socket receives).
constexpr std::uint32_t kNmt = 0x000;
constexpr std::uint32_t kTractionEmcy = 0x081;
constexpr std::uint32_t kTractionRpdo = 0x201;
constexpr std::uint32_t kSteeringRpdo = 0x203;
constexpr std::uint32_t kTractionSdo = 0x601;
constexpr std::uint32_t kSteeringSdo = 0x603;
constexpr std::uint32_t kEncoderHeartbeat = 0x702;
constexpr std::uint32_t kControllerHeartbeat = 0x77F;
constexpr std::uint16_t kQuickStopControlword = 0x0002;

std::uint16_t controlword(const CanFrame& f) {
  return static_cast<std::uint16_t>(f.data[0] | (f.data[1] << 8U));
}

std::int32_t rpdoTarget(const CanFrame& f) {
  std::uint32_t t = 0;
  for (unsigned i = 0; i < 4U; ++i) {
    t |= static_cast<std::uint32_t>(f.data[2 + i]) << (8U * i);
  }
  return static_cast<std::int32_t>(t);
}

bool isQuickStop(const CanFrame& f) {
  return f.id == kTractionRpdo && f.dlc == 6 && controlword(f) == kQuickStopControlword;
}

class MonoClock final : public hal::Clock {
 public:
  Timestamp now() const noexcept override { return monotonicNow(); }
};

/// The vehicle's calibration routine and the simulated drives, encoder, vehicle and laser on vcan0,
/// and the peer socket; see the file comment. `area` is the configured free area.
struct VmCalibrationBench {
  explicit VmCalibrationBench(const std::string& calibrationFile, const cal::FreeArea& area = cal::FreeArea{}) {
    file = calibrationFile;
    {
      std::ofstream old(file, std::ios::trunc | std::ios::binary);
      old << kOld;
    }
    std::remove((file + ".bak").c_str());
    // The world, the simulated vehicle (its own encoder measurements feed the simulated drives)
    // and its laser (1 deg beams: the routine uses the reflectors), at the VM's monotonic time.
    agv::sim::WorldParseError perr;
    REQUIRE(agv::sim::parseWorld(agv::sim::defaultWorldText(), world, perr) == Status::Ok);
    caster = std::make_unique<agv::sim::RayCaster>(world, 1.0);
    laserParams.angularResolution = agv::deg2rad(1.0);
    sim = std::make_unique<cal::SimCalibrationVehicle>(*caster, truth, laserParams, 1, kStart, nullptr);
    REQUIRE(sim->status() == Status::Ok);
    sim->wait(monotonicNow() - sim->now());

    // The drives' side of the bus, and the peer socket.
    agv::drivers::SocketCanConfig busConfig;
    busConfig.interfaceName = ifname.c_str();
    busConfig.receiveErrorFrames = false;
    REQUIRE(nodesBus.open(busConfig) == Status::Ok);
    nodes = std::make_unique<agv::simdrives::SimDrives>(agv::simdrives::SimDrivesOptions{}, nullptr);
    agv::drivers::SocketCanConfig peerConfig = busConfig;
    for (std::uint32_t id : {kNmt, kTractionEmcy, kTractionRpdo, kSteeringRpdo, kTractionSdo, kSteeringSdo,
                             kEncoderHeartbeat, kControllerHeartbeat}) {
      REQUIRE(peerConfig.filters.push_back(agv::drivers::CanFilter{id, 0x7FFU, false}) == Status::Ok);
    }
    peerConfig.receiveBufferBytes = 1 << 20;
    REQUIRE(peer.open(peerConfig) == Status::Ok);

    // The vehicle's side: configuration as agvnav-vehicle would parse it.
    config.canInterface = ifname;
    config.drivesEnabled = true;
    config.calibrationAreaSet = true;
    if (area.xMax > area.xMin) {
      config.calibrationPlan.area = area;
    }
    config.calibrationPlan.segmentsPerPhase = 2;  // 8 short segments: the VM's time budget
    config.calibrationPlan.minSteering = agv::deg2rad(40.0);
    config.calibrationPlan.maxSteering = agv::deg2rad(50.0);
    config.calibrationPlan.rotation = agv::deg2rad(90.0);
    config.calibrationSpeed = 0.8;
    config.calibrationFile = file;
    agv::drivers::CanopenEncoderSourceConfig enc;
    enc.interfaceName = ifname.c_str();
    enc.canopen.drive.nodeId = 1;
    enc.canopen.drive.pdo = agv::drivers::canopen::PdoMapping{0x181, 2, 4};  // statusword + position
    enc.canopen.steering.nodeId = 2;
    enc.canopen.steering.radiansPerCount = agv::test::kSteerEncoderRadPerCount;
    enc.canopen.trigger = agv::drivers::canopen::SampleTrigger::DriveUpdated;
    enc.canopen.heartbeatTimeout = Duration::fromMilliseconds(500);
    encoders = std::make_unique<agv::drivers::CanopenEncoderSource>(enc);
    REQUIRE(encoders->open() == Status::Ok);
    drives = agv::vehicle::makeSocketCanDrives(config);
    current.params = agv::TricycleParams{1.5, 1.0e-4, 0.0, 0.0};
    current.laserPose = Pose2d{1.6, 0.0, 0.0};
    const auto logLine = [this](const std::string& line) {
      std::printf("vehicle: %s\n", line.c_str());
      log.push_back(line);
    };
    routine = std::make_unique<agv::vehicle::VehicleCalibrationRoutine>(config, current, *encoders, sim->laser(), plc,
                                                                        drives.get(), logLine);
    std::uint32_t id = 1;
    for (const agv::sim::Circle& c : world.circles) {
      if (c.kind == agv::sim::ObstacleKind::Reflector) {
        REQUIRE(map.addSurveyed(agv::LandmarkKind::Reflector, c.centre.x, c.centre.y, 0.005, id++).ok());
      }
    }
    map.setMode(agv::MapMode::Static);
    agv::nav::PipelineParams p;
    p.kinematics = current.params;
    p.localizer.laser.mounting = current.laserPose;
    p.localizer.laser.rangeMax = 30.0;
    p.relocalization.enabled = false;  // the PLC's Localize gives the pose (a global search is slow under TCG)
    pipeline = std::make_unique<agv::nav::Pipeline>(
        p, map, agv::nav::PipelineDevices{routine->encoders(), routine->laser(), routine->plc(), clock});
    REQUIRE(pipeline->configure() == Status::Ok);
    REQUIRE(pipeline->activate() == Status::Ok);
    routine->attach(*pipeline);
    nextNodes = monotonicNow();
  }

  ~VmCalibrationBench() { encoders->close(); }

  /// The drives' side every 10 ms: frames in, nodes stepped, the wheel's counts as the traction
  /// position, the steering encoder's heartbeat and TPDO, the motors moving the vehicle.
  void stepWorld(Timestamp now) {
    sim->wait(now - sim->now());
    CanFrame f;
    while (nodesBus.receive(f, Duration{}) == Status::Ok) {
      if (!f.error) {
        nodes->receive(f, now);
      }
    }
    if (now < nextNodes) {
      return;
    }
    nextNodes = now + Duration::fromMilliseconds(10);
    agv::test::feedWheel(sim->encoders(), nodes->node(1), wheelTicks, wheelSteer);
    CanFrame out[agv::simdrives::SimDrives::kMaxFrames];
    const std::size_t n = nodes->step(now, agv::Span<CanFrame>(out));
    for (std::size_t k = 0; k < n; ++k) {
      static_cast<void>(nodesBus.send(out[k]));
    }
    CanFrame encoderFrames[2];
    agv::test::steeringEncoderFrames(wheelSteer, now, encoderFrames);
    for (const CanFrame& e : encoderFrames) {
      static_cast<void>(nodesBus.send(e));
    }
    static_cast<void>(sim->drive().command(
        agv::test::motorsToVehicle(nodes->traction(), nodes->steering(), config.drives, truth.truth.driveScale, now)));
  }

  /// Everything the peer socket has received so far, kept in `seen`.
  void drainPeer() {
    CanFrame f;
    while (peer.receive(f, Duration{}) == Status::Ok) {
      if (!f.error) {
        seen.push_back(f);
      }
    }
  }

  /// One loop, real time: the drives' side, the vehicle's pipeline and routine (every 2 ms), the
  /// peer socket. True when the routine wrote its file in this cycle.
  bool cycle() {
    stepWorld(monotonicNow());
    static_cast<void>(pipeline->cycle());
    const bool w = routine->step(monotonicNow());
    drainPeer();
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
    wrote = wrote || w;
    return w;
  }

  void runCycles(int n) {
    for (int i = 0; i < n; ++i) {
      cycle();
    }
  }

  void runFor(Duration d) {
    const Timestamp end = monotonicNow() + d;
    while (monotonicNow() < end) {
      cycle();
    }
  }

  template <typename F>
  bool runUntil(F done, Duration limit) {
    const Timestamp end = monotonicNow() + limit;
    while (!done() && monotonicNow() < end) {
      cycle();
    }
    return done();
  }

  /// Localizes at the start (the encoder decoder needs its first samples first).
  void localize() {
    runCycles(100);
    plc.send(hal::PlcCommandKind::Localize, kStart);
    runCycles(100);
    REQUIRE(pipeline->localizing());
  }

  /// Calibrate, then cycles until the first segment is driven at half the routine's speed.
  void calibrateUntilMidSegment() {
    plc.send(hal::PlcCommandKind::Calibrate);
    const bool driving = runUntil(
        [&] {
          return routine->progress().segment == 1 && routine->progress().state == cal::RoutineState::Driving &&
                 std::fabs(nodes->traction().velocity() * truth.truth.driveScale) > 0.5 * config.calibrationSpeed;
        },
        Duration::fromSeconds(20.0));
    INFO(routine->session()->lastMessage());
    REQUIRE(driving);
  }

  /// The first frame the peer saw stamped at or after `t` that satisfies `match` (null: none).
  template <typename F>
  const CanFrame* firstAfter(Timestamp t, F match) const {
    for (const CanFrame& f : seen) {
      if (f.stamp >= t && match(f)) {
        return &f;
      }
    }
    return nullptr;
  }

  /// The published calibration registers and the file are those of an aborted run.
  void checkAbortedAndFileUntouched(Status reason) {
    CHECK(routine->progress().state == cal::RoutineState::Aborted);
    CHECK(!routine->running());
    CHECK(plc.last.health.calibration.state == static_cast<std::uint8_t>(cal::RoutineState::Aborted));
    CHECK(plc.last.health.calibration.lastRefusal == reason);
    CHECK(plc.last.health.mode != hal::NavMode::Calibrating);
    CHECK_FALSE(wrote);
    CHECK(agv::test::readFile(file) == kOld);
    CHECK_FALSE(agv::test::fileExists(file + ".tmp"));
    CHECK_FALSE(agv::test::fileExists(file + ".bak"));
  }

  std::string ifname = agv::test::vcanInterface();
  std::string file;
  agv::sim::World world;
  std::unique_ptr<agv::sim::RayCaster> caster;
  agv::sim::SimVehicleParams truth;
  agv::sim::SimLaserParams laserParams;
  std::unique_ptr<cal::SimCalibrationVehicle> sim;
  agv::drivers::SocketCanBus nodesBus;
  std::unique_ptr<agv::simdrives::SimDrives> nodes;
  agv::drivers::SocketCanBus peer;
  std::vector<CanFrame> seen;
  agv::vehicle::VehicleConfig config;
  std::unique_ptr<agv::drivers::CanopenEncoderSource> encoders;
  std::unique_ptr<agv::vehicle::VehicleDrives> drives;
  agv::VehicleCalibration current;
  agv::test::ScriptedPlc plc;
  std::vector<std::string> log;
  std::unique_ptr<agv::vehicle::VehicleCalibrationRoutine> routine;
  agv::LandmarkMap map;
  MonoClock clock;
  std::unique_ptr<agv::nav::Pipeline> pipeline;
  std::int64_t wheelTicks = 0;
  double wheelSteer = 0.0;
  Timestamp nextNodes{};
  bool wrote = false;
};

}  // namespace

TEST_CASE("calibration on vcan: a plan that does not fit the free area is refused before any frame to the drives",
          "[calibration]") {
  // The start (10, 12.5) fits with its 0.8 m clearance; the left circles (radius 1.8 m at 40 deg)
  // reach y = 14.3.
  VmCalibrationBench b("/tmp/agv_vm_cal_refused.txt", cal::FreeArea{8.0, 11.0, 13.0, 14.0});
  b.localize();
  b.plc.send(hal::PlcCommandKind::Calibrate);
  b.runFor(Duration::fromSeconds(1.0));
  // The refusal on the registers (48: OutOfRange, status bit 8) and in the log.
  CHECK(b.routine->progress().lastRefusal == Status::OutOfRange);
  CHECK(b.plc.last.health.calibration.lastRefusal == Status::OutOfRange);
  CHECK(b.plc.last.health.calibration.state == static_cast<std::uint8_t>(cal::RoutineState::Idle));
  CHECK(hal::hasBit(b.plc.last.health.bits, hal::HealthBit::CommandRejected));
  // Not Calibrating. (Nor localizing for long: the drive encoder is the traction node's TPDO1, which
  // only the drive controller's bring-up maps with the position and gives an event timer and a
  // heartbeat; unconfigured, the node leaves the encoder source silent and the navigation Lost.)
  CHECK(b.plc.last.health.mode != hal::NavMode::Calibrating);
  REQUIRE_FALSE(b.log.empty());
  CHECK(b.log.back().find("leaves the free area") != std::string::npos);
  // The drive controller sent nothing: no NMT pre-operational, no SDO, no RPDO (so no target
  // velocity at all), no heartbeat. (The encoder source's NMT Start of nodes 1 and 2 at its open()
  // is the encoders' own.) The peer socket did receive: the steering encoder's heartbeats.
  int toDrives = 0;
  int movingTargets = 0;
  int encoderHeartbeats = 0;
  for (const CanFrame& f : b.seen) {
    if (f.id == kEncoderHeartbeat) {
      ++encoderHeartbeats;
    } else if (f.id != kTractionEmcy && !(f.id == kNmt && f.data[0] == 0x01)) {
      ++toDrives;
    }
    if (f.id == kTractionRpdo && rpdoTarget(f) != 0) {
      ++movingTargets;
    }
  }
  CHECK(encoderHeartbeats > 50);
  CHECK(toDrives == 0);
  CHECK(movingTargets == 0);
  CHECK(b.nodes->traction().state() != PowerState::OperationEnabled);
  const Pose2d truePose = b.sim->vehicle().truePose();
  CHECK(std::hypot(truePose.x - kStart.x, truePose.y - kStart.y) < 1e-9);
  CHECK_FALSE(b.wrote);
  CHECK(agv::test::readFile(b.file) == kOld);
}

TEST_CASE("calibration on vcan: a PLC Stop mid-segment quick-stops the traction in the cycle that reads it",
          "[calibration]") {
  VmCalibrationBench b("/tmp/agv_vm_cal_stop.txt");
  b.localize();
  b.calibrateUntilMidSegment();
  const Timestamp tStop = monotonicNow();
  b.plc.send(hal::PlcCommandKind::Stop);
  b.cycle();  // the pipeline reads the Stop: the quick stop goes out in this cycle
  const Timestamp tCycleEnd = monotonicNow();
  CHECK(b.routine->progress().state == cal::RoutineState::Aborted);
  // The quick-stop ramp (2 m/s^2 from 0.4..0.8 m/s): at most 0.4 s, then Switch on disabled.
  b.runFor(Duration::fromSeconds(1.0));
  // The first traction RPDO on the bus after the Stop is the quick stop, sent while the vehicle's
  // cycle that read the Stop ran, within one control cycle (10 ms) of the Stop.
  const CanFrame* first = b.firstAfter(tStop, [](const CanFrame& f) { return f.id == kTractionRpdo; });
  REQUIRE(first != nullptr);
  CHECK(isQuickStop(*first));
  CHECK(rpdoTarget(*first) == 0);
  const Duration latency = first->stamp - tStop;
  std::printf("PLC Stop -> quick stop on the bus: %.2f ms (the vehicle's cycle took %.2f ms)\n",
              1e3 * latency.seconds(), 1e3 * (tCycleEnd - tStop).seconds());
  CHECK(first->stamp <= tCycleEnd);
  CHECK(latency < Duration::fromMilliseconds(10));
  // Every later traction RPDO repeats the quick stop with target 0: no set-point after the Stop.
  int rpdos = 0;
  int others = 0;
  for (const CanFrame& f : b.seen) {
    if (f.stamp >= tStop && f.id == kTractionRpdo) {
      ++rpdos;
      others += (isQuickStop(f) && rpdoTarget(f) == 0) ? 0 : 1;
    }
  }
  CHECK(rpdos > 20);
  CHECK(others == 0);
  // The drive stopped on its quick-stop ramp and is in Switch on disabled; the vehicle stands.
  CHECK(b.nodes->traction().velocity() == 0.0);
  CHECK(b.nodes->traction().state() == PowerState::SwitchOnDisabled);
  CHECK(b.sim->drive().isStandstill());
  // Aborted on request: no fault reason; the Stop reached the pipeline too.
  b.checkAbortedAndFileUntouched(Status::Ok);
  CHECK(b.plc.last.health.mode == hal::NavMode::Idle);
}

TEST_CASE("calibration on vcan: a heartbeat loss of the traction node aborts the routine and stops the vehicle",
          "[calibration]") {
  VmCalibrationBench b("/tmp/agv_vm_cal_heartbeat.txt");
  b.localize();
  b.calibrateUntilMidSegment();
  const Timestamp tSilent = monotonicNow();
  b.nodes->node(1).setSilent(true);  // transmits nothing from now on (still listens)
  REQUIRE(b.runUntil([&] { return !b.routine->running(); }, Duration::fromSeconds(2.0)));
  // The quick stop after the drive's heartbeat timeout: 150 ms from the last heartbeat, which came
  // at most one 50 ms producer period (plus a 10 ms step of the nodes) before the silence.
  const CanFrame* qs = b.firstAfter(tSilent, [](const CanFrame& f) { return isQuickStop(f); });
  REQUIRE(qs != nullptr);
  const Duration latency = qs->stamp - tSilent;
  std::printf("traction node silent -> quick stop on the bus: %.1f ms\n", 1e3 * latency.seconds());
  CHECK(latency > Duration::fromMilliseconds(80));
  CHECK(latency < Duration::fromMilliseconds(250));
  // Longer than the encoder source's heartbeat timeout (0.5 s): the drive encoder (node 1) too.
  b.runFor(Duration::fromSeconds(1.0));
  CHECK(b.nodes->traction().velocity() == 0.0);
  CHECK(b.sim->drive().isStandstill());
  b.checkAbortedAndFileUntouched(Status::Timeout);
  CHECK(hal::hasBit(b.plc.last.health.bits, hal::HealthBit::EncoderTimeout));
  CHECK(b.routine->session()->lastMessage().find("heartbeat") != std::string::npos);
}

TEST_CASE("calibration on vcan: a traction drive fault is reported with its code and aborts the routine",
          "[calibration]") {
  VmCalibrationBench b("/tmp/agv_vm_cal_fault.txt");
  b.localize();
  b.calibrateUntilMidSegment();
  const Timestamp tFault = monotonicNow();
  b.nodes->node(1).injectFault(0x2310);  // EMCY 0x2310, 0x603F = 0x2310, Fault reaction active -> Fault
  REQUIRE(b.runUntil([&] { return !b.routine->running(); }, Duration::fromSeconds(2.0)));
  b.runFor(Duration::fromSeconds(1.0));
  // The EMCY crossed the bus; the controller quick-stopped the traction in its next control cycle
  // and read the error code (SDO upload of 0x603F).
  const CanFrame* emcy = b.firstAfter(tFault, [](const CanFrame& f) { return f.id == kTractionEmcy; });
  REQUIRE(emcy != nullptr);
  CHECK(emcy->data[0] == 0x10);
  CHECK(emcy->data[1] == 0x23);
  const CanFrame* qs = b.firstAfter(emcy->stamp, [](const CanFrame& f) { return isQuickStop(f); });
  REQUIRE(qs != nullptr);
  const Duration latency = qs->stamp - emcy->stamp;
  std::printf("traction EMCY -> quick stop on the bus: %.2f ms\n", 1e3 * latency.seconds());
  CHECK(latency < Duration::fromMilliseconds(30));
  CHECK(b.firstAfter(tFault, [](const CanFrame& f) {
    return f.id == kTractionSdo && f.data[0] == 0x40 && f.data[1] == 0x3F && f.data[2] == 0x60;
  }) != nullptr);
  // The fault code in the routine's reason and log; DeviceFault on register 48 and status bit 6
  // (the encoder source saw the same EMCY of node 1); the drive stopped by its fault reaction.
  CHECK(b.drives->faultCode() == 0x2310U);
  CHECK(b.routine->session()->lastMessage().find("0x2310") != std::string::npos);
  b.checkAbortedAndFileUntouched(Status::DeviceFault);
  CHECK(hal::hasBit(b.plc.last.health.bits, hal::HealthBit::DeviceFault));
  CHECK(b.nodes->traction().state() == PowerState::Fault);
  CHECK(b.nodes->traction().velocity() == 0.0);
  CHECK(b.sim->drive().isStandstill());
}

TEST_CASE("calibration routine on vcan: CiA 402 drives, encoders from the traction TPDO1, all phases, a file",
          "[calibration]") {
  VmCalibrationBench b("/tmp/agv_vm_calibration.txt");
  b.localize();
  b.plc.send(hal::PlcCommandKind::Calibrate);
  const Timestamp t0 = monotonicNow();
  int lastSegment = -1;
  int lastState = -1;
  while (monotonicNow() - t0 < Duration::fromSeconds(100.0)) {
    b.cycle();
    const cal::SessionProgress& pr = b.routine->progress();
    if (static_cast<int>(pr.state) != lastState || pr.segment != lastSegment) {
      lastState = static_cast<int>(pr.state);
      lastSegment = pr.segment;
      std::printf("%.2f s: %s, segment %u of %u\n", (monotonicNow() - t0).seconds(), cal::routineStateName(pr.state),
                  pr.segment, pr.total);
    }
    if (!b.routine->running() && monotonicNow() - t0 > Duration::fromSeconds(1.0)) {
      break;
    }
  }
  INFO(b.routine->session()->lastMessage());
  std::printf("routine %s after %.1f s; %s\n", cal::routineStateName(b.routine->progress().state),
              (monotonicNow() - t0).seconds(), b.routine->session()->lastMessage().c_str());
  CHECK(b.routine->progress().state == cal::RoutineState::Done);
  CHECK(b.routine->progress().total == 8);
  REQUIRE(b.wrote);
  for (cal::RoutineState s : {cal::RoutineState::Settling, cal::RoutineState::Steering, cal::RoutineState::Driving,
                              cal::RoutineState::Stopping, cal::RoutineState::Observing}) {
    CHECK(b.plc.seen[static_cast<int>(s)]);
  }
  const std::string t = agv::test::readFile(b.file);
  agv::VehicleCalibration got;
  REQUIRE(agv::parseCalibrationFile(agv::Span<const char>(t.data(), t.size()), got) == Status::Ok);
  const agv::TricycleParams& tr = b.truth.truth;
  const Pose2d& mount = b.truth.laserMount;
  std::printf(
      "vcan routine: s_w %+.0f ppm, alpha_F %+.4f deg, alpha_B %+.4f deg, lx %+.2f mm, ly %+.2f mm, "
      "ltheta %+.4f deg (refined - truth)\n",
      1e6 * (got.params.driveScale / tr.driveScale - 1.0),
      agv::rad2deg(got.params.steerOffsetForward - tr.steerOffsetForward),
      agv::rad2deg(got.params.steerOffsetBackward - tr.steerOffsetBackward), 1e3 * (got.laserPose.x - mount.x),
      1e3 * (got.laserPose.y - mount.y), agv::rad2deg(got.laserPose.theta - mount.theta));
  // 8 segments of 90 deg at 40..50 deg steering and 1 deg laser beams instead of calibrate.app's
  // half circles at 18..50 deg and 0.25 deg: its tolerance doubled (docs/calibration.md).
  CHECK(std::fabs(got.params.driveScale / tr.driveScale - 1.0) < 4000e-6);
  CHECK(std::fabs(got.params.steerOffsetForward - tr.steerOffsetForward) < agv::deg2rad(0.2));
  CHECK(std::fabs(got.params.steerOffsetBackward - tr.steerOffsetBackward) < agv::deg2rad(0.2));
  CHECK(std::fabs(got.laserPose.x - mount.x) < 0.016);
  CHECK(std::fabs(got.laserPose.y - mount.y) < 0.016);
  CHECK(std::fabs(got.laserPose.theta - mount.theta) < agv::deg2rad(0.6));
  CHECK(agv::test::readFile(b.file + ".bak") == kOld);
}
