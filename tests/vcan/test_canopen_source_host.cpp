// Host-side checks of CanopenEncoderSource that need no CAN stack: configuration refusal and the
// behaviour when the bus cannot be opened (this host's kernel has no CAN at all, a vehicle may
// miss its interface): a device fault, retried at the configured interval, never an allocation.
// The source on a real CAN stack is tested in the VM (test_canopen_source_vm.cpp).
#include "agv/drivers/linux/canopen_encoder_source.hpp"
#include "agv_test.hpp"

using agv::Duration;
using agv::Status;
using agv::drivers::CanopenEncoderSource;
using agv::drivers::CanopenEncoderSourceConfig;

namespace {
CanopenEncoderSourceConfig goodConfig() {
  CanopenEncoderSourceConfig c;
  c.interfaceName = "agvcan-missing";
  c.canopen.steering.radiansPerCount = 1e-4;
  c.openRetryInterval = Duration::fromMilliseconds(1);
  return c;
}

void sleepMs(int ms) {
  timespec t{0, static_cast<long>(ms) * 1000000L};
  (void)nanosleep(&t, nullptr);
}
}  // namespace

TEST_CASE("a bad configuration is refused by open() and read()", "[socketcan][canopen]") {
  CanopenEncoderSourceConfig sameNodes = goodConfig();
  sameNodes.canopen.steering.nodeId = sameNodes.canopen.drive.nodeId;
  CanopenEncoderSourceConfig noScale = goodConfig();
  noScale.canopen.steering.radiansPerCount = 0.0;
  CanopenEncoderSourceConfig longName = goodConfig();
  longName.interfaceName = "a-name-longer-than-15";
  CanopenEncoderSourceConfig noName = goodConfig();
  noName.interfaceName = nullptr;
  CanopenEncoderSourceConfig noFrames = goodConfig();
  noFrames.maxFramesPerRead = 0;
  CanopenEncoderSourceConfig noRetry = goodConfig();
  noRetry.openRetryInterval = Duration{};
  for (const CanopenEncoderSourceConfig* c : {&sameNodes, &noScale, &longName, &noName, &noFrames, &noRetry}) {
    CanopenEncoderSource src(*c);
    CHECK(src.open() == Status::InvalidArgument);
    agv::hal::EncoderSample s;
    CHECK(src.read(s) == Status::InvalidArgument);
    CHECK(src.health() == Status::InvalidArgument);
    CHECK(src.counters().openAttempts == 0U);
  }
}

TEST_CASE("a bus that cannot be opened is a device fault, retried without allocating", "[socketcan][canopen]") {
  CanopenEncoderSource src(goodConfig());
  agv::hal::EncoderSample s;
  s.driveTicks = 42;
  CHECK(src.read(s) == Status::NotInitialized);  // open() not called
  const Status opened = src.open();
  // No CAN in this kernel (Unsupported) or no such interface (NotFound).
  CHECK((opened == Status::Unsupported || opened == Status::NotFound));
  CHECK(src.openStatus() == opened);
  CHECK(src.health() == Status::DeviceFault);
  Status r = Status::Ok;
  for (int i = 0; i < 5; ++i) {
    sleepMs(2);  // past the 1 ms retry interval
    AGV_CHECK_NO_ALLOCATIONS(r = src.read(s));
    CHECK(r == Status::DeviceFault);
  }
  CHECK(s.driveTicks == 42);  // untouched
  CHECK(src.counters().openAttempts == 6U);
  CHECK(src.counters().nmtStartsSent == 0U);
  src.close();
  CHECK(src.read(s) == Status::NotInitialized);
}
