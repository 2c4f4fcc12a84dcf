// CanopenEncoderSource (CANopen encoders on SocketCAN) against the real Linux CAN stack, run inside
// the test VM by run-vcan-vm.sh. `cansend` plays the two encoder nodes (drive 0x11, steering 0x12):
// boot-up and heartbeats (0x700 + node), TPDOs, EMCY, error frames. A second socket on the bus
// watches what the source transmits (NMT Start, SYNC); the VM's init also looks for those frames
// in the candump log (000#0111, 000#0112, 080#).
#include <cmath>
#include <ctime>
#include <string>
#include <vector>

#include "agv/drivers/linux/canopen_encoder_source.hpp"
#include "agv/drivers/linux/socketcan_bus.hpp"
#include "agv_test.hpp"
#include "vcan_peer.hpp"
#include "vm_alloc_count.hpp"

using agv::Duration;
using agv::Status;
using agv::Timestamp;
using agv::drivers::CanFrame;
using agv::drivers::CanopenEncoderSource;
using agv::drivers::CanopenEncoderSourceConfig;
using agv::drivers::monotonicNow;
using agv::drivers::SocketCanBus;
using agv::drivers::SocketCanConfig;
using agv::hal::EncoderSample;
using agv::test::cansend;

namespace {

constexpr std::uint8_t kDriveNode = 0x11;
constexpr std::uint8_t kSteerNode = 0x12;
constexpr double kPi = 3.14159265358979323846;
constexpr double kRadPerCount = 2.0 * kPi / 8192.0;

CanopenEncoderSourceConfig sourceConfig(const std::string& name) {
  CanopenEncoderSourceConfig c;
  c.interfaceName = name.c_str();
  c.canopen.drive.nodeId = kDriveNode;
  c.canopen.drive.pdo = {0x191, 0, 4};
  c.canopen.steering.nodeId = kSteerNode;
  c.canopen.steering.pdo = {0x192, 2, 2};  // position in bytes 2..3 of the TPDO
  c.canopen.steering.radiansPerCount = kRadPerCount;
  c.canopen.steering.zeroCount = 100;
  c.canopen.steering.countsPerRevolution = 8192;
  c.canopen.heartbeatTimeout = Duration::fromMilliseconds(1000);
  // The two TPDOs of a cycle come from two cansend processes here, tens of milliseconds apart
  // under TCG (devices send them back to back): a wide pairing window, and no SYNC (a SYNC between
  // them would end the cycle); SYNC production has its own test case.
  c.canopen.pairingWindow = Duration::fromMilliseconds(500);
  c.canopen.syncPeriod = Duration{};
  c.openRetryInterval = Duration::fromMilliseconds(100);
  return c;
}

/// A socket that sees the NMT (0x000) and SYNC (0x080) frames other sockets send on `name`.
bool openMonitor(SocketCanBus& bus, const std::string& name) {
  SocketCanConfig c;
  c.interfaceName = name.c_str();
  c.receiveErrorFrames = false;
  (void)c.filters.push_back({0x000, 0x7FF, false});
  (void)c.filters.push_back({0x080, 0x7FF, false});
  return bus.open(c) == Status::Ok;
}

struct Seen {
  int nmtStart[2] = {0, 0};  // drive, steering
  int syncs = 0;
  int other = 0;
};

void drainMonitor(SocketCanBus& monitor, Seen& seen) {
  CanFrame f;
  for (int i = 0; i < 10000 && monitor.receive(f, Duration::fromMilliseconds(20)) == Status::Ok; ++i) {
    if (f.id == 0x000 && f.dlc == 2 && f.data[0] == 0x01 && f.data[1] == kDriveNode) {
      ++seen.nmtStart[0];
    } else if (f.id == 0x000 && f.dlc == 2 && f.data[0] == 0x01 && f.data[1] == kSteerNode) {
      ++seen.nmtStart[1];
    } else if (f.id == 0x080 && f.dlc == 0 && !f.rtr) {
      ++seen.syncs;
    } else {
      ++seen.other;
    }
  }
}

void sleepMs(int ms) {
  timespec t{0, static_cast<long>(ms) * 1000000L};
  (void)nanosleep(&t, nullptr);
}

/// Polls `read()` (1 ms apart, at most `ms`) until it returns `want`; the allocations made inside
/// the read() calls are added to `allocs`.
Status pollUntil(CanopenEncoderSource& src, EncoderSample& out, Status want, int ms, std::uint64_t& allocs) {
  Status s = Status::NotFound;
  for (int i = 0; i < ms; ++i) {
    const std::uint64_t before = agv::test::vmAllocationCalls();
    s = src.read(out);
    allocs += agv::test::vmAllocationCalls() - before;
    if (s == want) {
      return s;
    }
    sleepMs(1);
  }
  return s;
}

bool heartbeats(const std::string& name, const char* state = "05") {
  return cansend(name, std::string("711#") + state) == 0 && cansend(name, std::string("712#") + state) == 0;
}

}  // namespace

TEST_CASE("CANopen encoder source: NMT start, TPDOs across the 32-bit wrap, boot-up, EMCY, heartbeat timeout",
          "[vcan][canopen]") {
  const std::string name = agv::test::vcanInterface();
  SocketCanBus monitor;
  REQUIRE(openMonitor(monitor, name));
  CanopenEncoderSource src(sourceConfig(name));

  // The allocation counter must see an allocation, or the zero below would prove nothing.
  const std::uint64_t probe = agv::test::vmAllocationCalls();
  {
    std::vector<int> v(16, 1);
    CHECK(v.size() == 16U);
  }
  REQUIRE(agv::test::vmAllocationCalls() > probe);
  std::uint64_t allocs = 0;

  REQUIRE(src.open() == Status::Ok);
  CHECK(src.counters().nmtStartsSent == 2U);
  EncoderSample s;
  // Nodes silent, no position yet: nothing to report.
  CHECK(pollUntil(src, s, Status::Ok, 20, allocs) == Status::NotFound);
  CHECK(src.health() == Status::NotInitialized);

  // Heartbeats (operational), then the first pair of positions: drive raw 0xFFFFFFF0 = -16 ticks,
  // steering raw 1124 = zero + 1024 counts = +pi/4.
  REQUIRE(heartbeats(name));
  REQUIRE(cansend(name, "191#F0FFFFFF") == 0);
  const Timestamp sentFrom = monotonicNow();
  REQUIRE(cansend(name, "192#AAAA6404") == 0);
  const Timestamp sentTo = monotonicNow();
  sleepMs(50);  // the sample is read well after its frame arrived
  REQUIRE(pollUntil(src, s, Status::Ok, 2000, allocs) == Status::Ok);
  const Timestamp readAt = monotonicNow();
  CHECK(s.driveTicks == -16);
  CHECK(s.steeringAngle == Approx(1024 * kRadPerCount).margin(1e-12));
  // Kernel receive time of the steering TPDO (the second frame), not the read time.
  CHECK(s.stamp >= sentFrom);
  CHECK(s.stamp <= sentTo);
  CHECK(readAt - s.stamp >= Duration::fromMilliseconds(50));
  const Timestamp firstStamp = s.stamp;

  // Across the unsigned wrap: 0xFFFFFFF0 -> 0x00000010 is +32 ticks. Steering raw 8092: the
  // difference to the zero (100) wraps into half a revolution, -200 counts.
  REQUIRE(heartbeats(name));
  REQUIRE(cansend(name, "191#10000000") == 0);
  REQUIRE(cansend(name, "192#AAAA9C1F") == 0);
  REQUIRE(pollUntil(src, s, Status::Ok, 2000, allocs) == Status::Ok);
  CHECK(s.driveTicks == -16 + 32);
  CHECK(s.steeringAngle == Approx(-200 * kRadPerCount).margin(1e-12));
  CHECK(s.stamp > firstStamp);
  const Timestamp secondStamp = s.stamp;

  // Two pairs queued before one read: both samples come out, in order, none overwritten. The
  // signed wrap is crossed: 0x7FFFFFF8 then 0x80000008 (+16) beyond the int32 range.
  REQUIRE(heartbeats(name));
  REQUIRE(cansend(name, "191#F8FFFF7F") == 0);
  REQUIRE(cansend(name, "192#AAAA6404") == 0);
  REQUIRE(cansend(name, "191#08000080") == 0);
  REQUIRE(cansend(name, "192#AAAA6500") == 0);  // raw 101: one count left of the zero
  const std::int64_t ticksA = 16 + (0x7FFFFFF8LL - 0x10LL);
  REQUIRE(pollUntil(src, s, Status::Ok, 2000, allocs) == Status::Ok);
  CHECK(s.driveTicks == ticksA);
  CHECK(s.steeringAngle == Approx(1024 * kRadPerCount).margin(1e-12));
  CHECK(s.stamp > secondStamp);
  const Timestamp thirdStamp = s.stamp;
  REQUIRE(pollUntil(src, s, Status::Ok, 2000, allocs) == Status::Ok);
  CHECK(s.driveTicks == ticksA + 16);
  CHECK(s.driveTicks > 2147483647LL);
  CHECK(s.steeringAngle == Approx(kRadPerCount).margin(1e-12));
  CHECK(s.stamp > thirdStamp);
  CHECK(src.counters().samples == 4U);
  CHECK(src.health() == Status::Ok);

  // The drive reboots: its boot-up message makes the source send NMT Start to it again; until it
  // reports operational the source reports a device fault.
  REQUIRE(cansend(name, "711#00") == 0);
  CHECK(pollUntil(src, s, Status::DeviceFault, 2000, allocs) == Status::DeviceFault);
  CHECK(src.decoder().driveHealth().bootUps == 1U);
  CHECK(src.counters().nmtStartsSent == 3U);
  REQUIRE(heartbeats(name));
  CHECK(pollUntil(src, s, Status::NotFound, 2000, allocs) == Status::NotFound);
  CHECK(src.health() == Status::Ok);

  // EMCY 0x2310 (current, device output side) with error register 0x03 from the drive: a fault
  // until the error-reset EMCY (code 0).
  REQUIRE(cansend(name, "091#1023030102030405") == 0);
  CHECK(pollUntil(src, s, Status::DeviceFault, 2000, allocs) == Status::DeviceFault);
  agv::drivers::canopen::EmcyRecord emcy;
  REQUIRE(src.takeEmcy(emcy));
  CHECK(emcy.nodeId == kDriveNode);
  CHECK(emcy.errorCode == 0x2310U);
  CHECK(emcy.errorRegister == 0x03U);
  CHECK(emcy.vendor[0] == 0x01U);
  CHECK(emcy.vendor[4] == 0x05U);
  CHECK(emcy.stamp > thirdStamp);
  REQUIRE(heartbeats(name));
  REQUIRE(cansend(name, "091#0000000000000000") == 0);
  CHECK(pollUntil(src, s, Status::NotFound, 2000, allocs) == Status::NotFound);
  REQUIRE(src.takeEmcy(emcy));
  CHECK(emcy.errorCode == 0U);
  CHECK_FALSE(src.takeEmcy(emcy));
  CHECK(src.health() == Status::Ok);

  // The nodes fall silent: after the heartbeat timeout (1 s) read() reports Timeout.
  CHECK(pollUntil(src, s, Status::Timeout, 3000, allocs) == Status::Timeout);
  CHECK(src.health() == Status::Timeout);
  CHECK((src.decoder().driveHealth().heartbeatTimedOut || src.decoder().steeringHealth().heartbeatTimedOut));
  REQUIRE(heartbeats(name));
  CHECK(pollUntil(src, s, Status::NotFound, 2000, allocs) == Status::NotFound);
  CHECK(src.health() == Status::Ok);

  // Every read() above, in every state, allocated nothing.
  CHECK(allocs == 0U);
  CHECK(src.counters().sendFailures == 0U);
  CHECK(src.decoder().malformedFrames() == 0U);

  CHECK(src.decoder().incompleteCycles() == 0U);

  // What went out on the bus: NMT Start to both nodes at open, again to the drive after its
  // boot-up; no SYNC (not configured).
  src.close();
  Seen seen;
  drainMonitor(monitor, seen);
  CHECK(seen.nmtStart[0] == 2);
  CHECK(seen.nmtStart[1] == 1);
  CHECK(seen.syncs == 0);
  CHECK(src.counters().syncsSent == 0U);
  CHECK(seen.other == 0);
}

TEST_CASE("CANopen encoder source: SYNC production while polled", "[vcan][canopen]") {
  const std::string name = agv::test::vcanInterface();
  SocketCanBus monitor;
  REQUIRE(openMonitor(monitor, name));
  CanopenEncoderSourceConfig cfg = sourceConfig(name);
  cfg.canopen.syncPeriod = Duration::fromMilliseconds(20);
  CanopenEncoderSource src(cfg);
  REQUIRE(src.open() == Status::Ok);
  std::uint64_t allocs = 0;
  EncoderSample s;
  // Polled about every millisecond, 300 times: a SYNC about every 20 ms, none in a burst.
  const Timestamp from = monotonicNow();
  CHECK(pollUntil(src, s, Status::Ok, 300, allocs) == Status::NotFound);
  const Duration polled = monotonicNow() - from;
  CHECK(allocs == 0U);
  src.close();
  Seen seen;
  drainMonitor(monitor, seen);
  CHECK(seen.nmtStart[0] == 1);
  CHECK(seen.nmtStart[1] == 1);
  // At most one per period (no bursts), the first at the first poll; at least 5 in >= 300 ms.
  const auto maxSyncs = static_cast<int>(polled.ns / Duration::fromMilliseconds(20).ns) + 1;
  CHECK(seen.syncs >= 5);
  CHECK(seen.syncs <= maxSyncs);
  CHECK(static_cast<std::uint64_t>(seen.syncs) == src.counters().syncsSent);
  CHECK(seen.other == 0);
}

TEST_CASE("CANopen encoder source: error frames, bus-off and recovery", "[vcan][canopen]") {
  const std::string name = agv::test::vcanInterface();
  SocketCanBus monitor;
  REQUIRE(openMonitor(monitor, name));
  CanopenEncoderSourceConfig cfg = sourceConfig(name);
  cfg.canopen.syncPeriod = Duration::fromMilliseconds(20);
  CanopenEncoderSource src(cfg);
  REQUIRE(src.open() == Status::Ok);
  std::uint64_t allocs = 0;
  EncoderSample s;
  REQUIRE(heartbeats(name));
  CHECK(pollUntil(src, s, Status::Ok, 100, allocs) == Status::NotFound);
  CHECK(src.health() == Status::NotInitialized);  // operational nodes, no position yet: no fault

  // An error-warning report is counted but is no fault.
  REQUIRE(cansend(name, "20000004#0008000000000000") == 0);
  CHECK(pollUntil(src, s, Status::Ok, 100, allocs) == Status::NotFound);
  CHECK(src.counters().errorFrames == 1U);
  CHECK(src.health() == Status::NotInitialized);

  // Bus-off: a device fault, SYNC refused, until the controller reports its restart; then NMT
  // Start goes out again to both nodes.
  REQUIRE(cansend(name, "20000040#0000000000000000") == 0);
  CHECK(pollUntil(src, s, Status::DeviceFault, 2000, allocs) == Status::DeviceFault);
  CHECK(src.busHealth().controller == agv::drivers::CanControllerState::BusOff);
  CHECK(pollUntil(src, s, Status::Ok, 60, allocs) == Status::DeviceFault);  // > 2 SYNC periods
  CHECK(src.counters().sendFailures >= 1U);
  REQUIRE(heartbeats(name));
  REQUIRE(cansend(name, "20000100#0000000000000000") == 0);
  CHECK(pollUntil(src, s, Status::NotFound, 2000, allocs) == Status::NotFound);
  CHECK(src.counters().recoveries == 1U);
  CHECK(src.counters().nmtStartsSent == 4U);
  CHECK(src.health() == Status::NotInitialized);
  CHECK(allocs == 0U);

  Seen seen;
  drainMonitor(monitor, seen);
  CHECK(seen.nmtStart[0] == 2);
  CHECK(seen.nmtStart[1] == 2);
  CHECK(seen.syncs >= 1);
}

TEST_CASE("CANopen encoder source: a lost interface is a device fault, then the nodes are started again",
          "[vcan][canopen]") {
  const std::string name = agv::test::vcanSpareInterface();
  CanopenEncoderSource src(sourceConfig(name));
  REQUIRE(src.open() == Status::Ok);
  CHECK(src.counters().nmtStartsSent == 2U);
  REQUIRE(agv::test::setLinkUp(name, false));
  std::uint64_t allocs = 0;
  EncoderSample s;
  CHECK(pollUntil(src, s, Status::DeviceFault, 500, allocs) == Status::DeviceFault);
  CHECK(src.health() == Status::DeviceFault);
  REQUIRE(agv::test::setLinkUp(name, true));
  // Reopened once the back-off allows (100 ms, 200 ms ...): NMT Start is sent again.
  for (int i = 0; i < 3000 && src.counters().recoveries == 0U; ++i) {
    (void)src.read(s);
    sleepMs(1);
  }
  CHECK(src.counters().recoveries == 1U);
  CHECK(src.counters().nmtStartsSent == 4U);
  CHECK(src.busHealth().counters.reopens >= 1U);
}

TEST_CASE("CANopen encoder source: an interface that does not exist is retried, not fatal", "[vcan][canopen]") {
  CanopenEncoderSourceConfig cfg = sourceConfig("vcan9");
  CanopenEncoderSource src(cfg);
  const Timestamp from = monotonicNow();
  CHECK(src.open() == Status::NotFound);
  EncoderSample s;
  std::uint64_t allocs = 0;
  CHECK(pollUntil(src, s, Status::Ok, 250, allocs) == Status::DeviceFault);
  const Duration polled = monotonicNow() - from;
  // Retried every 100 ms, never faster: the explicit open(), then at most one attempt per
  // interval of the time the 250 polls really took (1 ms sleeps last longer under TCG).
  const auto maxAttempts = static_cast<std::uint64_t>(polled.ns / cfg.openRetryInterval.ns) + 1U;
  CHECK(src.counters().openAttempts >= 2U);
  CHECK(src.counters().openAttempts <= maxAttempts);
  CHECK(src.health() == Status::DeviceFault);
  CHECK(src.openStatus() == Status::NotFound);
}
