// agvnav-vehicle's calibration routine on the real Linux CAN stack, in the vcan VM
// (docs/vcan-testing.md), with the bench of calibration_vm_bench.hpp (the vehicle's code in this
// process, agvnav-sim-drives' nodes on a second socket) and a scripted PLC. Built only without
// libmodbus, where there is no agvnav-vehicle program: with it, test_calibration_modbus_vm.cpp runs
// the same cases with agvnav-vehicle and agvnav-sim-drives --vehicle as programs instead. Cases: a
// plan that does not fit is refused before any frame to the drives; a PLC Stop mid-segment, a
// heartbeat loss of the traction node and a traction drive fault each quick-stop the traction
// (timed on the bus by the peer socket) and abort the routine, the calibration file untouched; the
// whole routine (every state, a file). The init script checks candump's log for the bring-up and
// enable sequence of the traction drive and its quick stop.
#include <cmath>
#include <cstdio>
#include <string>

#include "calibration_vm_bench.hpp"

using agv::Duration;
using agv::Pose2d;
using agv::Status;
using agv::Timestamp;
using agv::drivers::CanFrame;
using agv::drivers::monotonicNow;
using agv::drivers::canopen::PowerState;
using agv::test::vmcal::isQuickStop;
using agv::test::vmcal::kEncoderHeartbeat;
using agv::test::vmcal::kNmt;
using agv::test::vmcal::kOld;
using agv::test::vmcal::kStart;
using agv::test::vmcal::kTractionEmcy;
using agv::test::vmcal::kTractionRpdo;
using agv::test::vmcal::kTractionSdo;
using agv::test::vmcal::rpdoTarget;
using agv::test::vmcal::VmCalibrationBench;
namespace cal = agv::calibration;
namespace hal = agv::hal;

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
  // Not Calibrating. (Nor localizing for long: the drive encoder is the traction node's TPDO1,
  // which only the drive controller's bring-up maps with the position and gives an event timer and
  // a heartbeat; unconfigured, the node leaves the encoder source silent and the navigation Lost.)
  CHECK(b.plc.last.health.mode != hal::NavMode::Calibrating);
  std::printf("refused plan: mode %u, health bits 0x%04X\n", static_cast<unsigned>(b.plc.last.health.mode),
              static_cast<unsigned>(b.plc.last.health.bits));
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
  // The Stop arrives just before a cycle of the vehicle, whose pipeline reads it first: the quick
  // stop goes out in this cycle.
  const Timestamp tStop = monotonicNow();
  b.plc.send(hal::PlcCommandKind::Stop);
  b.cycle();
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
  // EMCY 0x2310, 0x603F = 0x2310, Fault reaction active -> Fault.
  b.nodes->node(1).injectFault(0x2310);
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
  CHECK(b.plc.last.health.calibration.driveFault == 0x2310U);  // register 49
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
  b.checkWrittenCalibration();
}
