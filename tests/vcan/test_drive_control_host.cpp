// Host-side checks of SocketCanDriveControl that need no CAN stack (this host's kernel has none):
// configuration refusal, and a bus that cannot be opened: the drives cannot be started, set-points
// are refused as a device fault, cycles report it without allocating, the open is retried, and
// destruction is harmless. The drives on a real CAN stack are for the VM test (not written yet).
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
