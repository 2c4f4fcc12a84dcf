#pragma once
// The vcan VM's in-process calibration bench (docs/vcan-testing.md) of test_calibration_vm.cpp,
// built when there is no libmodbus (and so no agvnav-vehicle program): the refusal, Stop,
// heartbeat, fault and whole-routine cases with a scripted PLC. The vehicle side is the program's
// code (`VehicleCalibrationRoutine`, the SocketCAN CiA 402 drive controller, the real
// `CanopenEncoderSource` reading the drive encoder from the traction drive's TPDO1 at
// {0x181, 2, 4}, the navigation pipeline); the other side of vcan0 plays the two CiA 402 drives
// (`SimDrives` of agvnav-sim-drives, on their own socket), the steering encoder (node 2) and the
// simulated tricycle and laser, all in real time. A peer socket on vcan0 records what the vehicle
// sends to the drives, with kernel timestamps.
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

namespace agv::test::vmcal {

using agv::Duration;
using agv::Pose2d;
using agv::Status;
using agv::Timestamp;
using agv::drivers::CanFrame;
using agv::drivers::monotonicNow;
namespace cal = agv::calibration;

inline const Pose2d kStart{10.0, 12.5, 0.0};
inline const char* const kOld = "the calibration file before the routine\n";

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

inline std::uint16_t controlword(const CanFrame& f) {
  return static_cast<std::uint16_t>(f.data[0] | (f.data[1] << 8U));
}

inline std::int32_t rpdoTarget(const CanFrame& f) {
  std::uint32_t t = 0;
  for (unsigned i = 0; i < 4U; ++i) {
    t |= static_cast<std::uint32_t>(f.data[2 + i]) << (8U * i);
  }
  return static_cast<std::int32_t>(t);
}

inline bool isQuickStop(const CanFrame& f) {
  return f.id == kTractionRpdo && f.dlc == 6 && controlword(f) == kQuickStopControlword;
}

class MonoClock final : public hal::Clock {
 public:
  Timestamp now() const noexcept override { return monotonicNow(); }
};

/// The calibration file `file` written by the whole routine: parsed, printed (after `label`) against
/// the simulator's `truth`, and within twice the `calibrate.app` tolerance (docs/calibration.md): 8 segments of
/// 90 deg at 40..50 deg steering and 1 deg laser beams instead of its half circles at 18..50 deg
/// and 0.25 deg. The old file (`old`) kept as `.bak`.
inline void checkCalibrationFile(const std::string& file, const agv::sim::SimVehicleParams& truth, const char* label,
                                 const std::string& old = kOld) {
  static_cast<void>(agv::test::checkCalibrationFile(file, truth, label, 2.0));
  CHECK(readFile(file + ".bak") == old);
}

/// The vehicle's calibration routine and the simulated drives, encoder, vehicle and laser on vcan0,
/// and the peer socket; see the file comment. `area` is the configured free area (none: the
/// default, the open floor of the built-in warehouse). The PLC is the scripted `plc`.
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

  /// One loop, real time: the vehicle's pipeline (it reads the PLC's commands, the encoders and
  /// the laser), the drives' side, the vehicle's routine (which cycles the drive controller every
  /// 10 ms), the peer socket drained, 2 ms of sleep. True when the routine wrote its file in this
  /// cycle. The drives' side runs right before the controller reads the bus: the drives are not
  /// independent devices here, and a stall of this one process between their step and the
  /// controller's poll (a long pipeline cycle, or the VM's CPU not scheduled on a loaded host)
  /// would look to the controller like a silent drive (heartbeat timeout 150 ms).
  bool cycle() {
    static_cast<void>(pipeline->cycle());
    stepWorld(monotonicNow());
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

  /// The calibration file written by the whole routine (`checkCalibrationFile`).
  void checkWrittenCalibration() const { checkCalibrationFile(file, truth, "vcan routine"); }

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

}  // namespace agv::test::vmcal
