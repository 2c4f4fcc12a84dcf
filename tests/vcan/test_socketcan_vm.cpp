// SocketCAN transport against the real Linux CAN stack (vcan), run inside the test VM by
// run-vcan-vm.sh. The peer is can-utils: `cansend` (spawned here) plays the devices on the bus,
// `candump -L` (started by the VM's init) records what this program transmits, and the init
// script checks that record after the run.
//
// Environment: AGV_VCAN_IF (default vcan0), AGV_VCAN_IF2 (default vcan1, taken down and up by
// the link-loss test so that candump on vcan0 keeps recording), AGV_CANSEND (default cansend).
#include <linux/can.h>
#include <linux/can/error.h>

#include <cerrno>
#include <string>
#include <vector>

#include "agv/drivers/linux/socketcan_bus.hpp"
#include "agv_test.hpp"
#include "vcan_peer.hpp"
#include "vm_alloc_count.hpp"

using agv::Duration;
using agv::Status;
using agv::Timestamp;
using agv::drivers::CanControllerState;
using agv::drivers::CanFrame;
using agv::drivers::CanLinkState;
using agv::drivers::SocketCanBus;
using agv::drivers::SocketCanConfig;
using agv::test::cansend;
using agv::test::realtimeNow;
using agv::test::setLinkUp;

namespace {

std::string busName() {
  return agv::test::vcanInterface();
}
std::string flapBusName() {
  return agv::test::vcanSpareInterface();
}

SocketCanConfig config(const std::string& name) {
  SocketCanConfig c;
  c.interfaceName = name.c_str();
  return c;
}

const Duration kWait = Duration::fromSeconds(2.0);          // a frame on vcan arrives within microseconds
const Duration kSilence = Duration::fromMilliseconds(200);  // "nothing more comes"

CanFrame frame(std::uint32_t id, std::initializer_list<std::uint8_t> bytes, bool extended = false) {
  CanFrame f;
  f.id = id;
  f.extended = extended;
  f.dlc = static_cast<std::uint8_t>(bytes.size());
  std::uint8_t i = 0;
  for (std::uint8_t b : bytes)
    f.data[i++] = b;
  return f;
}

bool sameBytes(const CanFrame& f, std::initializer_list<std::uint8_t> bytes) {
  if (f.dlc != bytes.size())
    return false;
  std::uint8_t i = 0;
  for (std::uint8_t b : bytes) {
    if (f.data[i++] != b)
      return false;
  }
  return true;
}

}  // namespace

TEST_CASE("frames sent by a peer are received with monotonic kernel timestamps", "[vcan]") {
  const std::string name = busName();
  SocketCanBus bus;
  REQUIRE(bus.open(config(name)) == Status::Ok);
  REQUIRE(bus.isUp());

  const Timestamp before = agv::drivers::monotonicNow();
  Timestamp previous = before;
  CanFrame f;

  REQUIRE(cansend(name, "181#0102030405060708") == 0);
  REQUIRE(bus.receive(f, kWait) == Status::Ok);
  CHECK(f.id == 0x181U);
  CHECK_FALSE(f.extended);
  CHECK_FALSE(f.rtr);
  CHECK_FALSE(f.error);
  CHECK(sameBytes(f, {1, 2, 3, 4, 5, 6, 7, 8}));
  CHECK(f.stamp.ns != 0);
  CHECK(f.stamp > previous);
  CHECK(f.stamp <= agv::drivers::monotonicNow());
  previous = f.stamp;

  REQUIRE(cansend(name, "12345678#AABB") == 0);
  REQUIRE(bus.receive(f, kWait) == Status::Ok);
  CHECK(f.id == 0x12345678U);
  CHECK(f.extended);
  CHECK(sameBytes(f, {0xAA, 0xBB}));
  CHECK(f.stamp > previous);
  CHECK(f.stamp <= agv::drivers::monotonicNow());
  previous = f.stamp;

  REQUIRE(cansend(name, "701#R") == 0);
  REQUIRE(bus.receive(f, kWait) == Status::Ok);
  CHECK(f.id == 0x701U);
  CHECK(f.rtr);
  CHECK_FALSE(f.extended);
  CHECK(f.stamp > previous);
  previous = f.stamp;

  REQUIRE(cansend(name, "7FF#") == 0);
  REQUIRE(bus.receive(f, kWait) == Status::Ok);
  CHECK(f.id == 0x7FFU);
  CHECK(f.dlc == 0);
  CHECK(f.stamp > previous);

  // Nothing else is on the bus: a bounded wait returns Timeout and leaves the frame alone.
  CanFrame untouched = frame(0x55, {9});
  CHECK(bus.receive(untouched, kSilence) == Status::Timeout);
  CHECK(untouched.id == 0x55U);
  CHECK(bus.health().counters.framesReceived == 4U);
  CHECK(bus.health().counters.rxDroppedByKernel == 0U);
  CHECK(bus.health().counters.errorFramesReceived == 0U);
}

TEST_CASE("stamps are the kernel's receive times, not the read times", "[vcan]") {
  const std::string name = busName();
  SocketCanBus bus;
  REQUIRE(bus.open(config(name)) == Status::Ok);
  // A periodic peer: 20 frames, at least 5 ms apart (cangen sleeps between them), with an
  // incrementing payload. They are all read after cangen has finished, within a short time.
  REQUIRE(agv::test::runPeer({"cangen", name, "-I", "181", "-L", "8", "-D", "i", "-g", "5", "-n", "20"}) == 0);
  CanFrame f;
  CanFrame previous;
  for (int i = 0; i < 20; ++i) {
    REQUIRE(bus.receive(f, kWait) == Status::Ok);
    CHECK(f.id == 0x181U);
    if (i > 0) {
      CHECK(f.data[0] == static_cast<std::uint8_t>(previous.data[0] + 1U));
      // Send times are >= 5 ms apart; allow 1 ms for the path from the send call to the stamp.
      CHECK(f.stamp - previous.stamp >= Duration::fromMilliseconds(4));
    }
    previous = f;
  }
  CHECK(bus.receive(f, kSilence) == Status::Timeout);
}

TEST_CASE("receive timestamps on the wall clock when asked", "[vcan]") {
  const std::string name = busName();
  SocketCanConfig cfg = config(name);
  cfg.stampClock = agv::drivers::CanStampClock::Realtime;
  SocketCanBus bus;
  REQUIRE(bus.open(cfg) == Status::Ok);
  const Timestamp before = realtimeNow();
  REQUIRE(cansend(name, "182#01") == 0);
  CanFrame f;
  REQUIRE(bus.receive(f, kWait) == Status::Ok);
  const Timestamp after = realtimeNow();
  CHECK(f.stamp >= before);
  CHECK(f.stamp <= after);
}

TEST_CASE("transmitted frames reach other sockets and the bus monitor", "[vcan]") {
  const std::string name = busName();
  SocketCanBus tx;
  SocketCanBus rx;
  REQUIRE(tx.open(config(name)) == Status::Ok);
  REQUIRE(rx.open(config(name)) == Status::Ok);

  // The VM's init script looks for exactly these three frames in candump's log.
  CanFrame a = frame(0x201, {0x11, 0x22, 0x33, 0x44});
  CanFrame b = frame(0x1ABCDE01, {0x01}, true);
  CanFrame c = frame(0x202, {});
  c.rtr = true;
  REQUIRE(tx.send(a) == Status::Ok);
  REQUIRE(tx.send(b) == Status::Ok);
  REQUIRE(tx.send(c) == Status::Ok);

  CanFrame f;
  REQUIRE(rx.receive(f, kWait) == Status::Ok);
  CHECK(f.id == 0x201U);
  CHECK(sameBytes(f, {0x11, 0x22, 0x33, 0x44}));
  REQUIRE(rx.receive(f, kWait) == Status::Ok);
  CHECK(f.id == 0x1ABCDE01U);
  CHECK(f.extended);
  CHECK(sameBytes(f, {0x01}));
  REQUIRE(rx.receive(f, kWait) == Status::Ok);
  CHECK(f.id == 0x202U);
  CHECK(f.rtr);

  // The sender does not hear itself by default.
  CHECK(tx.receive(f, kSilence) == Status::Timeout);
  CHECK(tx.health().counters.framesSent == 3U);
  CHECK(tx.health().counters.txRefused == 0U);

  // Impossible frames are refused before they reach the kernel, and counted.
  CHECK(tx.send(frame(0x800, {1})) == Status::InvalidArgument);
  CanFrame longFrame = frame(0x100, {1});
  longFrame.dlc = 9;
  CHECK(tx.send(longFrame) == Status::InvalidArgument);
  CanFrame err = frame(CAN_ERR_BUSOFF, {});
  err.error = true;
  CHECK(tx.send(err) == Status::InvalidArgument);
  CHECK(tx.health().counters.txRefused == 3U);
  CHECK(rx.receive(f, kSilence) == Status::Timeout);
}

TEST_CASE("steady-state send and receive do not allocate", "[vcan]") {
  const std::string name = busName();
  SocketCanBus tx;
  SocketCanBus rx;
  REQUIRE(tx.open(config(name)) == Status::Ok);
  REQUIRE(rx.open(config(name)) == Status::Ok);
  // The counter must see an allocation, or a zero below would prove nothing.
  const std::uint64_t probe = agv::test::vmAllocationCalls();
  {
    std::vector<int> v(16, 1);
    CHECK(v.size() == 16U);
  }
  REQUIRE(agv::test::vmAllocationCalls() > probe);

  int received = 0;
  int sentOk = 0;
  const std::uint64_t before = agv::test::vmAllocationCalls();
  for (int i = 0; i < 50; ++i) {
    CanFrame out;
    out.id = 0x300;
    out.dlc = 1;
    out.data[0] = static_cast<std::uint8_t>(i);
    sentOk += tx.send(out) == Status::Ok ? 1 : 0;
    CanFrame in;
    received += (rx.receive(in, kWait) == Status::Ok && in.data[0] == out.data[0]) ? 1 : 0;
  }
  CanFrame none;
  const Status quietStatus = rx.receive(none, Duration::fromMilliseconds(20));
  const std::uint64_t calls = agv::test::vmAllocationCalls() - before;
  CHECK(calls == 0U);
  CHECK(sentOk == 50);
  CHECK(received == 50);
  CHECK(quietStatus == Status::Timeout);
}

TEST_CASE("error frames: subscription, decoding, bus-off refusal and restart", "[vcan]") {
  const std::string name = busName();
  SocketCanBus bus;
  SocketCanBus quiet;
  REQUIRE(bus.open(config(name)) == Status::Ok);
  SocketCanConfig quietCfg = config(name);
  quietCfg.receiveErrorFrames = false;
  REQUIRE(quiet.open(quietCfg) == Status::Ok);
  CanFrame f;

  // A controller reaching the warning level, then error-passive (the controller status byte).
  REQUIRE(cansend(name, "20000004#0008000000000000") == 0);
  REQUIRE(bus.receive(f, kWait) == Status::Ok);
  CHECK(f.error);
  CHECK(f.id == CAN_ERR_CRTL);
  CHECK(bus.health().controller == CanControllerState::ErrorWarning);
  REQUIRE(cansend(name, "20000004#0020000000000000") == 0);
  REQUIRE(bus.receive(f, kWait) == Status::Ok);
  CHECK(bus.health().controller == CanControllerState::ErrorPassive);
  CHECK(bus.health().counters.controllerProblems == 2U);

  // A receive overflow in the controller and a missing acknowledge.
  REQUIRE(cansend(name, "20000004#0001000000000000") == 0);
  REQUIRE(bus.receive(f, kWait) == Status::Ok);
  CHECK(bus.health().lastError.rxOverflow);
  CHECK(bus.health().counters.controllerOverflows == 1U);
  REQUIRE(cansend(name, "20000020#0000000000000000") == 0);
  REQUIRE(bus.receive(f, kWait) == Status::Ok);
  CHECK(bus.health().lastError.noAck);
  CHECK(bus.health().counters.noAckEvents == 1U);

  // Bus-off: transmission is refused until the controller reports its restart.
  REQUIRE(cansend(name, "20000040#0000000000000000") == 0);
  REQUIRE(bus.receive(f, kWait) == Status::Ok);
  CHECK(f.error);
  CHECK(bus.health().lastError.busOff);
  CHECK(bus.health().controller == CanControllerState::BusOff);
  CHECK(bus.health().counters.busOffEvents == 1U);
  CHECK(bus.health().lastErrorStamp == f.stamp);
  CHECK(bus.send(frame(0x210, {1})) == Status::DeviceFault);
  CHECK(bus.health().counters.txRefused == 1U);

  REQUIRE(cansend(name, "20000100#0000000000000000") == 0);
  REQUIRE(bus.receive(f, kWait) == Status::Ok);
  CHECK(bus.health().lastError.restarted);
  CHECK(bus.health().controller == CanControllerState::ErrorActive);
  CHECK(bus.send(frame(0x210, {2})) == Status::Ok);

  CHECK(bus.health().counters.errorFramesReceived == 6U);
  CHECK(bus.health().counters.framesReceived == 0U);

  // The socket that did not subscribe saw none of the six error frames, only the data frame.
  REQUIRE(quiet.receive(f, kWait) == Status::Ok);
  CHECK_FALSE(f.error);
  CHECK(f.id == 0x210U);
  CHECK(quiet.receive(f, kSilence) == Status::Timeout);
  CHECK(quiet.health().counters.errorFramesReceived == 0U);
  CHECK(quiet.health().controller == CanControllerState::ErrorActive);
}

TEST_CASE("a bus-off without restart report reopens the socket after the configured time", "[vcan]") {
  const std::string name = busName();
  SocketCanConfig cfg = config(name);
  cfg.busOffReopenAfter = Duration::fromMilliseconds(300);
  SocketCanBus bus;
  REQUIRE(bus.open(cfg) == Status::Ok);
  REQUIRE(cansend(name, "20000040#0000000000000000") == 0);
  CanFrame f;
  REQUIRE(bus.receive(f, kWait) == Status::Ok);
  REQUIRE(bus.health().controller == CanControllerState::BusOff);
  CHECK(bus.send(frame(0x211, {1})) == Status::DeviceFault);
  // Nothing arrives; the bounded wait passes the reopen time.
  CHECK(bus.receive(f, Duration::fromMilliseconds(500)) == Status::Timeout);
  CHECK(bus.health().counters.reopens == 1U);
  CHECK(bus.health().controller == CanControllerState::ErrorActive);
  CHECK(bus.send(frame(0x211, {2})) == Status::Ok);
}

TEST_CASE("filters pass only the matching identifiers", "[vcan]") {
  const std::string name = busName();
  SocketCanConfig stdCfg = config(name);
  REQUIRE(stdCfg.filters.push_back({0x181, 0x7FF, false}) == Status::Ok);
  SocketCanConfig extCfg = config(name);
  REQUIRE(extCfg.filters.push_back({0x181, 0x1FFFFFFF, true}) == Status::Ok);
  SocketCanConfig rangeCfg = config(name);
  REQUIRE(rangeCfg.filters.push_back({0x180, 0x780, false}) == Status::Ok);  // 0x180..0x1FF (TPDO1)
  SocketCanBus stdBus;
  SocketCanBus extBus;
  SocketCanBus rangeBus;
  REQUIRE(stdBus.open(stdCfg) == Status::Ok);
  REQUIRE(extBus.open(extCfg) == Status::Ok);
  REQUIRE(rangeBus.open(rangeCfg) == Status::Ok);

  REQUIRE(cansend(name, "182#01") == 0);
  REQUIRE(cansend(name, "00000181#02") == 0);  // extended id 0x181
  REQUIRE(cansend(name, "281#04") == 0);
  REQUIRE(cansend(name, "181#03") == 0);

  CanFrame f;
  REQUIRE(stdBus.receive(f, kWait) == Status::Ok);
  CHECK(f.id == 0x181U);
  CHECK_FALSE(f.extended);
  CHECK(sameBytes(f, {3}));
  CHECK(stdBus.receive(f, kSilence) == Status::Timeout);

  REQUIRE(extBus.receive(f, kWait) == Status::Ok);
  CHECK(f.id == 0x181U);
  CHECK(f.extended);
  CHECK(sameBytes(f, {2}));
  CHECK(extBus.receive(f, kSilence) == Status::Timeout);

  REQUIRE(rangeBus.receive(f, kWait) == Status::Ok);
  CHECK(f.id == 0x182U);
  REQUIRE(rangeBus.receive(f, kWait) == Status::Ok);
  CHECK(f.id == 0x181U);
  CHECK_FALSE(f.extended);
  CHECK(rangeBus.receive(f, kSilence) == Status::Timeout);

  // Error frames pass their own subscription, not the id filters.
  REQUIRE(cansend(name, "20000020#0000000000000000") == 0);
  REQUIRE(stdBus.receive(f, kWait) == Status::Ok);
  CHECK(f.error);
  CHECK(stdBus.health().counters.noAckEvents == 1U);
}

TEST_CASE("frames the kernel dropped from a full socket queue are counted", "[vcan]") {
  const std::string name = busName();
  SocketCanConfig small = config(name);
  small.receiveBufferBytes = 1;  // the kernel's minimum: a handful of frames
  SocketCanBus rx;
  SocketCanBus tx;
  REQUIRE(rx.open(small) == Status::Ok);
  REQUIRE(tx.open(config(name)) == Status::Ok);

  constexpr int kBurst = 300;
  int sent = 0;
  for (int i = 0; i < kBurst; ++i) {
    if (tx.send(frame(0x3A0, {static_cast<std::uint8_t>(i & 0xFF), static_cast<std::uint8_t>(i >> 8)})) == Status::Ok) {
      ++sent;
    }
  }
  REQUIRE(sent > 100);
  // Drain what the queue kept, in order.
  int received = 0;
  int lastIndex = -1;
  CanFrame f;
  while (received <= kBurst && rx.receive(f, kSilence) == Status::Ok) {
    const int index = f.data[0] | (f.data[1] << 8);
    CHECK(index > lastIndex);
    lastIndex = index;
    ++received;
  }
  CHECK(received < sent);
  // The kernel reports drops with the next frame it queues: a marker after the burst.
  REQUIRE(tx.send(frame(0x3A1, {0xEE})) == Status::Ok);
  REQUIRE(rx.receive(f, kWait) == Status::Ok);
  CHECK(f.id == 0x3A1U);
  ++received;
  const std::uint64_t dropped = rx.health().counters.rxDroppedByKernel;
  CHECK(dropped > 0U);
  CHECK(static_cast<std::uint64_t>(received) + dropped == static_cast<std::uint64_t>(sent) + 1U);
  CHECK(rx.health().counters.framesReceived == static_cast<std::uint64_t>(received));
}

TEST_CASE("a lost interface is reported and the socket reopened with back-off", "[vcan]") {
  const std::string name = flapBusName();
  SocketCanConfig cfg = config(name);
  cfg.reopenBackoffInitial = Duration::fromMilliseconds(50);
  cfg.reopenBackoffMax = Duration::fromMilliseconds(400);
  SocketCanBus bus;
  REQUIRE(bus.open(cfg) == Status::Ok);

  REQUIRE(setLinkUp(name, false));
  CanFrame f;
  CHECK(bus.receive(f, Duration::fromMilliseconds(300)) == Status::DeviceFault);
  CHECK(bus.health().link == CanLinkState::Down);
  CHECK(bus.health().counters.linkLosses == 1U);
  CHECK(bus.health().lastErrno == ENETDOWN);
  CHECK(bus.send(frame(0x220, {1})) == Status::DeviceFault);
  // While the interface stays down the reopen attempts fail and back off (50, 100, 200 ms ...).
  const std::uint64_t attemptsWhileDown = bus.health().counters.reopenAttempts;
  CHECK(attemptsWhileDown >= 1U);
  CHECK(attemptsWhileDown <= 4U);
  CHECK(bus.health().counters.reopens == 0U);

  REQUIRE(setLinkUp(name, true));
  // The next receive reopens once the back-off allows and then gets the peer's frame.
  Status s = Status::DeviceFault;
  for (int i = 0; i < 40 && s != Status::Timeout; ++i) {
    s = bus.receive(f, Duration::fromMilliseconds(100));
  }
  REQUIRE(s == Status::Timeout);
  CHECK(bus.isUp());
  CHECK(bus.health().counters.reopens == 1U);
  REQUIRE(cansend(name, "185#55") == 0);
  REQUIRE(bus.receive(f, kWait) == Status::Ok);
  CHECK(f.id == 0x185U);
  CHECK(sameBytes(f, {0x55}));
  CHECK(bus.send(frame(0x220, {2})) == Status::Ok);
}

TEST_CASE("an interface that does not exist is NotFound", "[vcan]") {
  SocketCanBus bus;
  SocketCanConfig cfg;
  cfg.interfaceName = "vcan9";
  CHECK(bus.open(cfg) == Status::NotFound);
  CHECK(bus.health().lastErrno == ENODEV);
  CHECK_FALSE(bus.isUp());
}
