// The drive controller's safety triggers on the real Linux CAN stack with both sides as processes
// of their own (docs/vcan-testing.md, docs/drives.md): the drives are the `agvnav-sim-drives`
// program, the controller is `vcan-drive-controller` (tests/vcan/vcan_drive_controller.cpp: the
// `SocketCanDriveControl` agvnav-vehicle runs, in a small loop). This test starts them on vcan0,
// records the bus with its own socket (kernel receive stamps on CLOCK_MONOTONIC, the clock the
// controller prints its events on) and checks the frames: a stale set-point, the controller's exit
// (normal and on SIGTERM), the controller killed (SIGKILL) or stopped (SIGSTOP) so that the drives
// stop by their heartbeat consumer, the steering node's heartbeat loss and fault, and a bus-off
// reported by an error frame. The programs are looked up in $AGV_VCAN_PROGRAM_DIR (default /test,
// where run-vcan-vm.sh puts them).
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "agv/drivers/linux/monotonic_clock.hpp"
#include "agv/drivers/linux/socketcan_bus.hpp"
#include "agv/drivers/protocol/canopen/cia402.hpp"
#include "agv_test.hpp"
#include "cia402_frames.hpp"
#include "vcan_peer.hpp"
#include "vcan_programs.hpp"

extern char** environ;

using agv::Duration;
using agv::Status;
using agv::Timestamp;
using agv::drivers::CanFrame;
using agv::drivers::monotonicNow;
using agv::drivers::canopen::decodeStatusword;
using agv::drivers::canopen::PowerState;
using agv::test::Child;
using agv::test::i32;
using agv::test::isQuickStop;
using agv::test::kTractionRpdo;
using agv::test::programPath;
using agv::test::u16;

namespace {

constexpr std::uint32_t kTractionEmcy = 0x081;
constexpr std::uint32_t kSteeringEmcy = 0x083;
constexpr std::uint32_t kTractionTpdo1 = 0x181;
constexpr std::uint32_t kTractionTpdo2 = 0x281;
constexpr std::uint32_t kSteeringSdoRequest = 0x603;
constexpr std::uint32_t kTractionHeartbeat = 0x701;
constexpr std::uint32_t kSteeringHeartbeat = 0x703;
constexpr std::uint32_t kControllerHeartbeat = 0x77F;
constexpr std::uint16_t kControllerLostCode = 0x8130;  // the drives' heartbeat consumer fault

/// A frame the controller transmits: NMT, RPDOs, SDO requests, its heartbeat.
bool fromController(const CanFrame& f) {
  return !f.error && (f.id == 0x000 || f.id == kTractionRpdo || f.id == 0x203 || f.id == 0x601 ||
                      f.id == kSteeringSdoRequest || f.id == kControllerHeartbeat);
}
/// A frame node `node` transmits (EMCY, TPDO1/2, SDO response, heartbeat).
bool fromNode(const CanFrame& f, std::uint32_t node) {
  if (f.error || (f.id & 0x7FU) != node) {
    return false;
  }
  const std::uint32_t base = f.id - node;
  return base == 0x080 || base == 0x180 || base == 0x280 || base == 0x580 || base == 0x700;
}
bool isEmcy(const CanFrame& f, std::uint32_t id, std::uint16_t code) {
  return !f.error && f.id == id && f.dlc == 8 && u16(f, 0) == code;
}
PowerState tractionState(const CanFrame& f) {
  return decodeStatusword(u16(f, 0));
}
double ms(Duration d) {
  return 1e3 * d.seconds();
}

/// The bus monitor, the drives' process and the controller's process.
class Bench {
 public:
  /// Opens the monitor and starts `agvnav-sim-drives` with `driveArgs`, then the controller with
  /// `controllerArgs` once the drives' boot-up messages are on the bus.
  Bench(const std::vector<std::string>& driveArgs, const std::vector<std::string>& controllerArgs) {
    agv::drivers::SocketCanConfig config;
    config.interfaceName = interface_.c_str();
    config.receiveErrorFrames = true;  // the bus-off case's error frame, with its stamp
    REQUIRE(monitor_.open(config) == Status::Ok);
    std::vector<std::string> args = {"--interface", interface_, "--step-ms", "2"};
    args.insert(args.end(), driveArgs.begin(), driveArgs.end());
    drives = std::make_unique<Child>(programPath("agvnav-sim-drives"), args);
    REQUIRE(drives->started());
    // The nodes' boot-up (heartbeat with state 0) says the program listens: the controller's first
    // frames (NMT pre-operational, SDO) would be lost before.
    REQUIRE(runUntil(
        [&] {
          return firstAfter(Timestamp{}, [](const CanFrame& f) { return f.id == kTractionHeartbeat; }) != nullptr &&
                 firstAfter(Timestamp{}, [](const CanFrame& f) { return f.id == kSteeringHeartbeat; }) != nullptr;
        },
        Duration::fromSeconds(5.0)));
    std::vector<std::string> c = {"--interface", interface_};
    c.insert(c.end(), controllerArgs.begin(), controllerArgs.end());
    controller = std::make_unique<Child>(programPath("vcan-drive-controller"), c);
    REQUIRE(controller->started());
  }
  ~Bench() {
    // Reap the programs before the monitor closes (a SIGTERM lets the drives print their counts).
    controller.reset();
    if (drives && drives->running()) {
      drives->signal(SIGTERM);
      runUntil([&] { return !drives->running(); }, Duration::fromSeconds(2.0));
    }
  }
  Bench(const Bench&) = delete;
  Bench& operator=(const Bench&) = delete;

  /// Records frames for `d`, polling both programs.
  void pump(Duration d) {
    runUntil([] { return false; }, d);
  }
  bool runUntil(const std::function<bool()>& done, Duration max) {
    const Timestamp end = monotonicNow() + max;
    for (;;) {
      if (controller) {
        controller->poll();
      }
      drives->poll();
      if (done()) {
        return true;
      }
      const Timestamp now = monotonicNow();
      if (now >= end) {
        return false;
      }
      const Duration wait = end - now < Duration::fromMilliseconds(5) ? end - now : Duration::fromMilliseconds(5);
      CanFrame f;
      while (monitor_.receive(f, wait) == Status::Ok) {
        seen.push_back(f);
        if (monotonicNow() >= end) {
          break;
        }
      }
    }
  }
  /// Waits for the controller's line `WORD` (after `after`).
  bool waitFor(const std::string& word, Duration max, Timestamp& t, Timestamp after = Timestamp{}) {
    return runUntil([&] { return controller->find(word, t, nullptr, after); }, max);
  }
  const CanFrame* firstAfter(Timestamp t, const std::function<bool(const CanFrame&)>& match) const {
    for (const CanFrame& f : seen) {
      if (f.stamp > t && match(f)) {
        return &f;
      }
    }
    return nullptr;
  }
  const CanFrame* lastBefore(Timestamp t, const std::function<bool(const CanFrame&)>& match) const {
    const CanFrame* last = nullptr;
    for (const CanFrame& f : seen) {
      if (f.stamp < t && match(f)) {
        last = &f;
      }
    }
    return last;
  }
  int count(Timestamp from, Timestamp to, const std::function<bool(const CanFrame&)>& match) const {
    int n = 0;
    for (const CanFrame& f : seen) {
      n += (f.stamp > from && f.stamp < to && match(f)) ? 1 : 0;
    }
    return n;
  }
  /// Waits for the enable and the traction drive at the commanded 0.3 m/s (3000 units/s, reached
  /// 0.6 s after the enable at 0.5 m/s^2); returns the enable time.
  Timestamp enabledAndMoving() {
    Timestamp enabled{};
    REQUIRE(waitFor("STATE Enabled", Duration::fromSeconds(6.0), enabled));
    REQUIRE(runUntil(
        [&] {
          return firstAfter(enabled, [](const CanFrame& f) { return f.id == kTractionTpdo2 && i32(f, 0) == 3000; }) !=
                 nullptr;
        },
        Duration::fromSeconds(3.0)));
    return enabled;
  }

  std::vector<CanFrame> seen;
  std::unique_ptr<Child> drives;
  std::unique_ptr<Child> controller;

 private:
  std::string interface_ = agv::test::vcanInterface();
  agv::drivers::SocketCanBus monitor_;
};

/// After the traction quick stop `qs`: the drive reports Quick stop active and its velocity reaches
/// 0 on the 2 m/s^2 ramp (0.15 s from 0.3 m/s) within 0.3 s (the ramp, a 10 ms TPDO period, and
/// scheduling of three processes on the VM's one emulated CPU).
void checkDriveQuickStopped(const Bench& b, const CanFrame& qs) {
  const CanFrame* state = b.firstAfter(qs.stamp, [](const CanFrame& f) {
    return f.id == kTractionTpdo1 && tractionState(f) == PowerState::QuickStopActive;
  });
  CHECK(state != nullptr);
  const CanFrame* still =
      b.firstAfter(qs.stamp, [](const CanFrame& f) { return f.id == kTractionTpdo2 && i32(f, 0) == 0; });
  REQUIRE(still != nullptr);
  std::printf("  traction at velocity 0 %.1f ms after the quick stop\n", ms(still->stamp - qs.stamp));
  CHECK(still->stamp - qs.stamp < Duration::fromMilliseconds(300));
}

/// The controller fell silent at `silentFrom` (killed or stopped): nothing from it after that
/// moment, no quick stop from it, and both drives fault by their heartbeat consumer (EMCY 0x8130)
/// 200 ms after its last heartbeat, the traction one then at velocity 0.
void checkDrivesStopByThemselves(const Bench& b, Timestamp silentFrom, Timestamp until) {
  CHECK(b.count(silentFrom, until, fromController) == 0);
  CHECK(b.count(silentFrom, until, isQuickStop) == 0);
  const CanFrame* hb = b.lastBefore(silentFrom, [](const CanFrame& f) { return f.id == kControllerHeartbeat; });
  REQUIRE(hb != nullptr);
  for (const std::uint32_t emcyId : {kTractionEmcy, kSteeringEmcy}) {
    const CanFrame* emcy =
        b.firstAfter(hb->stamp, [&](const CanFrame& f) { return isEmcy(f, emcyId, kControllerLostCode); });
    REQUIRE(emcy != nullptr);
    CHECK(emcy->stamp < until);
    const Duration latency = emcy->stamp - hb->stamp;
    std::printf("  EMCY 0x%03X 0x8130 %.1f ms after the controller's last heartbeat\n", static_cast<unsigned>(emcyId),
                ms(latency));
    // Consumer time 200 ms, measured by the node from the heartbeat's reception (not earlier than
    // its kernel stamp), checked every 2 ms step; up to 100 ms late for the emulated CPU's
    // scheduling.
    CHECK(latency > Duration::fromMilliseconds(200));
    CHECK(latency < Duration::fromMilliseconds(300));
  }
  const CanFrame* emcy =
      b.firstAfter(hb->stamp, [](const CanFrame& f) { return isEmcy(f, kTractionEmcy, kControllerLostCode); });
  REQUIRE(emcy != nullptr);
  const CanFrame* fault = b.firstAfter(emcy->stamp, [](const CanFrame& f) {
    return f.id == kTractionTpdo1 &&
           (tractionState(f) == PowerState::FaultReactionActive || tractionState(f) == PowerState::Fault);
  });
  CHECK(fault != nullptr);
  const CanFrame* still =
      b.firstAfter(emcy->stamp, [](const CanFrame& f) { return f.id == kTractionTpdo2 && i32(f, 0) == 0; });
  REQUIRE(still != nullptr);
  std::printf("  traction at velocity 0 %.1f ms after its EMCY\n", ms(still->stamp - emcy->stamp));
  CHECK(still->stamp - emcy->stamp < Duration::fromMilliseconds(300));
}

}  // namespace

TEST_CASE("drive processes on vcan: a stale set-point quick-stops the traction by the watchdog", "[drives-process]") {
  Bench b({}, {"--stale-after", "1.0"});
  const Timestamp enabled = b.enabledAndMoving();
  Timestamp noted{};
  std::string rest;
  REQUIRE(b.waitFor("LAST-SETPOINT", Duration::fromSeconds(3.0), noted));
  REQUIRE(b.controller->find("LAST-SETPOINT", noted, &rest));
  const Timestamp lastSetpoint = Timestamp::fromNanoseconds(std::strtoll(rest.c_str(), nullptr, 10));
  Timestamp safeStop{};
  REQUIRE(b.waitFor("SAFE-STOP SetpointTimeout", Duration::fromSeconds(1.0), safeStop));
  b.pump(Duration::fromSeconds(0.5));
  // Until the last set-point the RPDOs carried enable operation with 0.3 m/s (3000).
  CHECK(b.count(enabled, lastSetpoint, isQuickStop) == 0);
  const int moving = b.count(enabled, lastSetpoint, [](const CanFrame& f) {
    return f.id == kTractionRpdo && u16(f, 0) == 0x000F && i32(f, 2) == 3000;
  });
  CHECK(moving > 40);  // ~100 cycles in the second before
  // The watchdog: the first poll more than 200 ms after the cycle that took the last set-point,
  // i.e. the 21st 10 ms cycle, or later by as much as the emulated CPU delays the controller
  // process (50 ms allowed).
  const CanFrame* qs = b.firstAfter(lastSetpoint, isQuickStop);
  REQUIRE(qs != nullptr);
  const Duration latency = qs->stamp - lastSetpoint;
  std::printf("stale set-point: quick stop %.1f ms after the last set-point (%d moving RPDOs before)\n", ms(latency),
              moving);
  CHECK(latency > Duration::fromMilliseconds(200));
  CHECK(latency < Duration::fromMilliseconds(260));
  CHECK(b.count(lastSetpoint, qs->stamp, [](const CanFrame& f) { return f.id == kTractionRpdo; }) >= 15);
  checkDriveQuickStopped(b, *qs);
  // The quick stop is repeated, target 0, until the end.
  CHECK(b.count(qs->stamp, monotonicNow(),
                [](const CanFrame& f) { return f.id == kTractionRpdo && !isQuickStop(f); }) == 0);
}

TEST_CASE("drive processes on vcan: the controller exiting normally quick-stops the traction before it goes",
          "[drives-process]") {
  Bench b({}, {"--exit-after", "1.0"});
  (void)b.enabledAndMoving();
  REQUIRE(b.runUntil([&] { return !b.controller->running(); }, Duration::fromSeconds(3.0)));
  CHECK(b.controller->exitCode() == 0);
  Timestamp exitLine{};
  REQUIRE(b.controller->find("EXIT", exitLine));
  b.pump(Duration::fromSeconds(0.5));
  // The destructor's quick stop: after the loop ended, before the process was gone, and the last
  // frame the controller sent.
  const CanFrame* qs = b.firstAfter(Timestamp{}, isQuickStop);
  REQUIRE(qs != nullptr);
  std::printf("normal exit: quick stop %.2f ms after the loop ended, %.2f ms before the process was reaped\n",
              ms(qs->stamp - exitLine), ms(b.controller->reapedAt() - qs->stamp));
  CHECK(qs->stamp > exitLine);
  CHECK(qs->stamp < b.controller->reapedAt());
  CHECK(i32(*qs, 2) == 0);
  CHECK(b.firstAfter(qs->stamp, fromController) == nullptr);
  checkDriveQuickStopped(b, *qs);
  // Then the drives lose the controller's heartbeat as well (EMCY 0x8130), the traction already at rest.
  CHECK(b.firstAfter(qs->stamp, [](const CanFrame& f) { return isEmcy(f, kTractionEmcy, kControllerLostCode); }) !=
        nullptr);
}

TEST_CASE("drive processes on vcan: SIGTERM to the controller quick-stops the traction before it goes",
          "[drives-process]") {
  Bench b({}, {});
  (void)b.enabledAndMoving();
  b.pump(Duration::fromSeconds(0.3));
  const Timestamp tTerm = monotonicNow();
  b.controller->signal(SIGTERM);
  REQUIRE(b.runUntil([&] { return !b.controller->running(); }, Duration::fromSeconds(3.0)));
  CHECK(b.controller->exitCode() == 0);
  b.pump(Duration::fromSeconds(0.3));
  Timestamp shutdown{};
  CHECK(b.controller->find("SAFE-STOP Shutdown", shutdown));
  const CanFrame* qs = b.firstAfter(tTerm, isQuickStop);
  REQUIRE(qs != nullptr);
  std::printf("SIGTERM: quick stop %.2f ms after the signal, %.2f ms before the process was reaped\n",
              ms(qs->stamp - tTerm), ms(b.controller->reapedAt() - qs->stamp));
  CHECK(b.count(Timestamp{}, tTerm, isQuickStop) == 0);
  CHECK(qs->stamp < b.controller->reapedAt());
  // Sent at once by quickStop() in the handling of the signal, not by a later cycle: the signal
  // interrupts the 10 ms sleep; 50 ms for the emulated CPU.
  CHECK(qs->stamp - tTerm < Duration::fromMilliseconds(50));
  // Nothing but the quick stop from the controller after it (the destructor repeats it).
  CHECK(b.count(qs->stamp, monotonicNow(), [](const CanFrame& f) { return fromController(f) && !isQuickStop(f); }) ==
        0);
  checkDriveQuickStopped(b, *qs);
}

TEST_CASE("drive processes on vcan: a controller killed with SIGKILL is stopped by the drives' heartbeat consumers",
          "[drives-process]") {
  Bench b({}, {});
  (void)b.enabledAndMoving();
  b.pump(Duration::fromSeconds(0.2));
  const Timestamp tKill = monotonicNow();
  b.controller->signal(SIGKILL);
  REQUIRE(b.runUntil([&] { return !b.controller->running(); }, Duration::fromSeconds(2.0)));
  b.pump(Duration::fromSeconds(0.8));
  std::printf("SIGKILL:\n");
  checkDrivesStopByThemselves(b, tKill, monotonicNow());
}

TEST_CASE("drive processes on vcan: a controller stopped with SIGSTOP is stopped by the drives, which stay in Fault",
          "[drives-process]") {
  Bench b({}, {});
  (void)b.enabledAndMoving();
  b.pump(Duration::fromSeconds(0.2));
  const Timestamp tStop = monotonicNow();
  b.controller->signal(SIGSTOP);
  b.pump(Duration::fromSeconds(0.8));
  const Timestamp tCont = monotonicNow();
  std::printf("SIGSTOP:\n");
  checkDrivesStopByThemselves(b, tStop, tCont);
  b.controller->signal(SIGCONT);
  b.pump(Duration::fromSeconds(0.6));
  // Resumed, the controller finds the drives faulted (or their heartbeats old) and safe-stops;
  // it does not reset them: the traction drive stays in Fault at velocity 0.
  Timestamp safeStop{};
  std::string reason;
  REQUIRE(b.controller->find("SAFE-STOP", safeStop, &reason, tCont));
  reason = reason.substr(0, reason.find(' '));
  std::printf("  resumed: SAFE-STOP %s\n", reason.c_str());
  CHECK((reason == "DriveFault" || reason == "DriveHeartbeatLost"));
  CHECK(b.count(tCont, monotonicNow(),
                [](const CanFrame& f) { return f.id == kTractionRpdo && (u16(f, 0) & 0x0080U) != 0; }) == 0);
  CHECK(b.count(tCont, monotonicNow(), [](const CanFrame& f) {
    return f.id == kTractionTpdo1 && tractionState(f) != PowerState::Fault;
  }) == 0);
  CHECK(b.count(tCont, monotonicNow(), [](const CanFrame& f) { return f.id == kTractionTpdo2 && i32(f, 0) != 0; }) ==
        0);
  CHECK(b.count(tCont, monotonicNow(), [](const CanFrame& f) { return f.id == kTractionTpdo1; }) > 20);
}

TEST_CASE("drive processes on vcan: the steering node's heartbeat loss quick-stops the traction", "[drives-process]") {
  Bench b({"--silence", "3@3"}, {});
  const Timestamp enabled = b.enabledAndMoving();
  Timestamp safeStop{};
  REQUIRE(b.waitFor("SAFE-STOP DriveHeartbeatLost", Duration::fromSeconds(5.0), safeStop));
  b.pump(Duration::fromSeconds(0.5));
  // The node fell silent after the enable: its last heartbeat, then nothing from it at all.
  const CanFrame* hb = b.lastBefore(monotonicNow(), [](const CanFrame& f) { return f.id == kSteeringHeartbeat; });
  REQUIRE(hb != nullptr);
  CHECK(hb->stamp > enabled);
  const CanFrame* lastOf3 = b.lastBefore(monotonicNow(), [](const CanFrame& f) { return fromNode(f, 3); });
  REQUIRE(lastOf3 != nullptr);
  CHECK(b.count(lastOf3->stamp + Duration::fromMilliseconds(1), monotonicNow(),
                [](const CanFrame& f) { return fromNode(f, 3); }) == 0);
  // The controller's consumer time: 150 ms after the heartbeat, seen by the first 10 ms cycle
  // after it; 100 ms allowed for the emulated CPU's scheduling of three processes. The axis stamps a
  // heartbeat with the time of the poll before the cycle that reads it (Cia402Axis::onFrame), up to
  // one cycle (10 ms, more when that cycle ran late) before its kernel stamp: the quick stop can
  // come that much before 150 ms (147.2 ms measured once), so the lower bound is 130 ms.
  const CanFrame* qs = b.firstAfter(hb->stamp, isQuickStop);
  REQUIRE(qs != nullptr);
  const Duration latency = qs->stamp - hb->stamp;
  std::printf("steering heartbeat loss: quick stop %.1f ms after the node's last heartbeat\n", ms(latency));
  CHECK(b.count(enabled, hb->stamp, isQuickStop) == 0);
  CHECK(latency > Duration::fromMilliseconds(130));
  CHECK(latency < Duration::fromMilliseconds(250));
  checkDriveQuickStopped(b, *qs);
}

TEST_CASE("drive processes on vcan: a steering fault quick-stops the traction and its code is read back",
          "[drives-process]") {
  Bench b({"--fault", "3:7305@3"}, {});
  const Timestamp enabled = b.enabledAndMoving();
  Timestamp code{};
  REQUIRE(b.waitFor("ERROR-CODE steering 0x7305", Duration::fromSeconds(5.0), code));
  b.pump(Duration::fromSeconds(0.5));
  Timestamp safeStop{};
  CHECK(b.controller->find("SAFE-STOP DriveFault", safeStop));
  const CanFrame* emcy = b.firstAfter(enabled, [](const CanFrame& f) { return isEmcy(f, kSteeringEmcy, 0x7305); });
  REQUIRE(emcy != nullptr);
  CHECK(b.count(enabled, emcy->stamp, isQuickStop) == 0);
  // Read in the controller's next 10 ms cycle and sent in it; 20 ms for the emulated CPU.
  const CanFrame* qs = b.firstAfter(emcy->stamp, isQuickStop);
  REQUIRE(qs != nullptr);
  std::printf("steering fault: quick stop %.2f ms after the EMCY\n", ms(qs->stamp - emcy->stamp));
  CHECK(qs->stamp - emcy->stamp < Duration::fromMilliseconds(30));
  // The error code read back by SDO upload of 0x603F from node 3.
  CHECK(b.firstAfter(emcy->stamp, [](const CanFrame& f) {
    return f.id == kSteeringSdoRequest && f.data[0] == 0x40 && u16(f, 1) == 0x603F && f.data[3] == 0;
  }) != nullptr);
  checkDriveQuickStopped(b, *qs);
}

TEST_CASE("drive processes on vcan: a bus-off error frame quick-stops the traction", "[drives-process]") {
  Bench b({}, {});
  const Timestamp enabled = b.enabledAndMoving();
  b.pump(Duration::fromSeconds(0.2));
  // The kernel hands an error frame written to a CAN_RAW socket of a virtual CAN interface to the
  // other sockets subscribed to error frames, as it would a CAN controller driver's report: here
  // the controller's socket (agvnav-sim-drives does not subscribe: its nodes' own controllers are
  // not the one that went off the bus). CAN_ERR_BUSOFF, as a controller in bus-off reports it.
  REQUIRE(agv::test::cansend(agv::test::vcanInterface(), "20000040#0000000000000000") == 0);
  Timestamp safeStop{};
  REQUIRE(b.waitFor("SAFE-STOP BusOff", Duration::fromSeconds(1.0), safeStop));
  b.pump(Duration::fromSeconds(0.5));
  const CanFrame* off = b.firstAfter(enabled, [](const CanFrame& f) { return f.error && (f.id & 0x40U) != 0; });
  REQUIRE(off != nullptr);
  CHECK(b.count(enabled, off->stamp, isQuickStop) == 0);
  // The drives kept talking, so the controller's socket reads TPDOs right after the error frame,
  // which the transport takes as the controller's return: the bus-off lasts less than a cycle
  // and the quick stop goes out in the cycle that read it (10 ms, 20 ms for the emulated CPU).
  const CanFrame* qs = b.firstAfter(off->stamp, isQuickStop);
  REQUIRE(qs != nullptr);
  std::printf("bus-off: quick stop %.2f ms after the error frame\n", ms(qs->stamp - off->stamp));
  CHECK(qs->stamp - off->stamp < Duration::fromMilliseconds(30));
  checkDriveQuickStopped(b, *qs);
  // The drives did not lose the controller (it kept its heartbeat): no EMCY 0x8130.
  CHECK(b.firstAfter(enabled, [](const CanFrame& f) { return isEmcy(f, kTractionEmcy, kControllerLostCode); }) ==
        nullptr);
}
