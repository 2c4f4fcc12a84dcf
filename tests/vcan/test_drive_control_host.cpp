// Host-side checks of SocketCanDriveControl that need no CAN stack (this host's kernel has none):
// configuration refusal, and a bus that cannot be opened: the drives cannot be started, set-points
// are refused as a device fault, cycles report it without allocating, the open is retried, and
// destruction is harmless; which bus-state reports a cycle gives the drive controller. The drives
// on a real CAN stack: the vcan VM test (test_drive_processes_vm.cpp, test_calibration_vm.cpp).
#include <ctime>

#include "agv/drivers/linux/socketcan_drive_control.hpp"
#include "agv_test.hpp"

using agv::Duration;
using agv::Status;
using agv::Timestamp;
using agv::drivers::SocketCanDriveControl;
using agv::drivers::SocketCanDriveControlConfig;

namespace {
SocketCanDriveControlConfig goodConfig() {
  SocketCanDriveControlConfig c;
  c.interfaceName = "agvcan-missing";
  c.openRetryInterval = Duration::fromMilliseconds(100);
  return c;
}
}  // namespace

TEST_CASE("a bad drive configuration is refused by open()", "[socketcan][drives]") {
  SocketCanDriveControlConfig longName = goodConfig();
  longName.interfaceName = "a-name-longer-than-15";
  SocketCanDriveControlConfig noName = goodConfig();
  noName.interfaceName = nullptr;
  SocketCanDriveControlConfig sameNodes = goodConfig();
  sameNodes.drives.steering.nodeId = sameNodes.drives.traction.nodeId;
  SocketCanDriveControlConfig noSpeed = goodConfig();
  noSpeed.drives.traction.maxSpeed = 0.0;
  SocketCanDriveControlConfig noFrames = goodConfig();
  noFrames.maxFramesPerCycle = 0;
  for (const SocketCanDriveControlConfig* c : {&longName, &noName, &sameNodes, &noSpeed, &noFrames}) {
    SocketCanDriveControl d(*c);
    CHECK(d.open(Timestamp{1}) == Status::InvalidArgument);
  }
}

TEST_CASE("without a CAN interface the drives are a device fault, retried, never started", "[socketcan][drives]") {
  SocketCanDriveControl d(goodConfig());
  Timestamp now = Timestamp::fromSeconds(10.0);
  const Status opened = d.open(now);
  CHECK((opened == Status::NotFound || opened == Status::Unsupported));
  CHECK(d.start(now) == Status::NotInitialized);
  agv::hal::DriveCommand c;
  c.speed = 0.1;
  CHECK(d.command(c) == Status::DeviceFault);
  Status cycled = Status::Ok;
  AGV_CHECK_NO_ALLOCATIONS(cycled = d.cycle(now));
  CHECK(cycled == Status::DeviceFault);
  CHECK(d.stop() == Status::DeviceFault);  // the drive controller was told the bus is unusable
  CHECK_FALSE(d.isStandstill());
  CHECK(d.counters().openAttempts == 1);
  now = now + Duration::fromMilliseconds(50);
  (void)d.cycle(now);
  CHECK(d.counters().openAttempts == 1);  // not before the retry interval
  now = now + Duration::fromMilliseconds(60);
  (void)d.cycle(now);
  CHECK(d.counters().openAttempts == 2);
  d.quickStop(agv::drivers::canopen::SafeStopReason::PlcStop);  // nothing to send: no crash
  CHECK(d.counters().framesSent == 0);
}

TEST_CASE("a bus-off seen during a cycle's read is reported even when frames after it ended it",
          "[socketcan][drives]") {
  using agv::drivers::busStateReports;
  using agv::drivers::BusStateReports;
  // Nothing happened: no report.
  BusStateReports r = busStateReports(false, false, true);
  CHECK_FALSE(r.off);
  CHECK_FALSE(r.back);
  // A bus-off report, then data frames in the same read (the transport's sign that the CAN
  // controller is back): off and back in this cycle, so the traction is quick-stopped. Before, the
  // usable bus at the end of the read hid the bus-off (seen in the vcan VM with the drives talking).
  r = busStateReports(false, true, true);
  CHECK(r.off);
  CHECK(r.back);
  // Still off after the read: off only; in a later cycle, usable again: back only.
  r = busStateReports(false, true, false);
  CHECK(r.off);
  CHECK_FALSE(r.back);
  r = busStateReports(true, false, true);
  CHECK_FALSE(r.off);
  CHECK(r.back);
  // Still off, already reported: nothing more; a further bus-off report while off: nothing more.
  r = busStateReports(true, false, false);
  CHECK_FALSE(r.off);
  CHECK_FALSE(r.back);
  r = busStateReports(true, true, false);
  CHECK_FALSE(r.off);
  CHECK_FALSE(r.back);
  // A link lost (not usable, no bus-off report): off, as before.
  r = busStateReports(false, false, false);
  CHECK(r.off);
  CHECK_FALSE(r.back);
}
