// The CiA 402 drive controller (drivers/protocol) driving two simulated CiA 402 nodes
// (drivers/sim) in-process: frames are passed between them as on one CAN bus, no kernel.
// Bring-up, velocity and position set-points with the handshake, scaling and limits, each safe-state
// trigger ending in a traction quick stop within one cycle, fault read-back and reset, the drives'
// own stop when the controller falls silent, SDO aborts and timeouts in the bring-up, and garbage.
// Expected values are computed here from the configuration and CiA 402 / CiA 301, not read back
// from the controller.
#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "agv/drivers/protocol/canopen/cia402_drive.hpp"
#include "agv/sim/sim_cia402_node.hpp"
#include "agv_test.hpp"

using namespace agv;
using namespace agv::drivers;
using namespace agv::drivers::canopen;
using agv::sim::SimCia402Node;
using agv::sim::SimCia402NodeParams;

namespace {

constexpr Duration kCycle = Duration::fromMilliseconds(10);

struct BusFrame {
  CanFrame frame;
  int sender;  // 0 controller, 1 traction, 2 steering
  Timestamp at;
};

/// The controller and the two drives on one simulated bus, stepped in 10 ms cycles.
struct Bench {
  Cia402DriveConfig cfg;
  std::unique_ptr<Cia402DriveController> ctl;
  SimCia402Node traction;
  SimCia402Node steering;
  Timestamp now{Timestamp::fromSeconds(1.0)};
  std::vector<BusFrame> log;
  bool controllerAlive = true;
  /// Frames from a drive pass through this filter before the controller sees them (false = dropped).
  std::function<bool(CanFrame&)> toController;

  static SimCia402NodeParams node(std::uint8_t id, std::int32_t pos) {
    SimCia402NodeParams p;
    p.nodeId = id;
    p.initialPosition = pos;
    return p;
  }

  explicit Bench(const Cia402DriveConfig& c = Cia402DriveConfig{})
      : cfg(c),
        ctl(new Cia402DriveController(c)),
        traction(node(c.traction.nodeId, 0)),
        steering(node(c.steering.nodeId, c.steering.zeroCount)) {}

  void deliverFromController(const CanFrame* frames, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) {
      log.push_back({frames[i], 0, now});
      traction.receive(frames[i], now);
      steering.receive(frames[i], now);
    }
  }

  void fromNode(SimCia402Node& sender, SimCia402Node& other, int id) {
    CanFrame buf[32];
    const std::size_t n = sender.step(now, Span<CanFrame>(buf));
    for (std::size_t i = 0; i < n; ++i) {
      log.push_back({buf[i], id, now});
      other.receive(buf[i], now);
      CanFrame f = buf[i];
      if (controllerAlive && (!toController || toController(f))) {
        ctl->onFrame(f);
      }
    }
  }

  /// Sends what the controller queued (the outbox after a call outside poll()).
  void flush() {
    CanFrame buf[CanOutbox::kCapacity];
    const std::size_t n = ctl->takeFrames(Span<CanFrame>(buf));
    deliverFromController(buf, n);
  }

  void cycle() {
    now = now + kCycle;
    fromNode(traction, steering, 1);
    fromNode(steering, traction, 2);
    if (controllerAlive) {
      ctl->poll(now);
      flush();
    }
  }

  void run(Duration d) {
    const Timestamp end = now + d;
    while (now < end) {
      cycle();
    }
  }

  /// Cycles until the controller is enabled (at most `limit`); the number of cycles taken.
  int bringUp(Duration limit = Duration::fromMilliseconds(2000)) {
    REQUIRE(ctl->start(now) == Status::Ok);
    int cycles = 0;
    const Timestamp end = now + limit;
    while (now < end && ctl->state() != DriveControllerState::Enabled) {
      cycle();
      ++cycles;
    }
    REQUIRE(ctl->state() == DriveControllerState::Enabled);
    return cycles;
  }

  /// Runs `d` while commanding `cmd` every cycle (the watchdog is fed).
  void drive(double speed, double angle, Duration d) {
    const Timestamp end = now + d;
    while (now < end) {
      hal::DriveCommand c;
      c.speed = speed;
      c.steeringAngle = angle;
      REQUIRE(ctl->command(c) == Status::Ok);
      cycle();
    }
  }

  /// Controlwords of the RPDOs the controller sent to `node` since log index `from`.
  std::vector<std::uint16_t> controlwords(std::uint8_t node, std::size_t from = 0) const {
    std::vector<std::uint16_t> out;
    for (std::size_t i = from; i < log.size(); ++i) {
      const BusFrame& b = log[i];
      if (b.sender == 0 && b.frame.id == 0x200U + node && b.frame.dlc >= 2) {
        out.push_back(static_cast<std::uint16_t>(b.frame.data[0] | (b.frame.data[1] << 8)));
      }
    }
    return out;
  }

  static std::int32_t rpdoTarget(const CanFrame& f) {
    return static_cast<std::int32_t>(
        static_cast<std::uint32_t>(f.data[2]) | (static_cast<std::uint32_t>(f.data[3]) << 8) |
        (static_cast<std::uint32_t>(f.data[4]) << 16) | (static_cast<std::uint32_t>(f.data[5]) << 24));
  }
};

bool contains(const std::vector<std::uint16_t>& v, std::uint16_t x) {
  for (std::uint16_t y : v) {
    if (y == x) {
      return true;
    }
  }
  return false;
}

// CiA 402 controlwords (bits 0-3, 7).
constexpr std::uint16_t kShutdown = 0x0006;
constexpr std::uint16_t kSwitchOn = 0x0007;
constexpr std::uint16_t kEnableOperation = 0x000F;
constexpr std::uint16_t kQuickStop = 0x0002;

/// After a trigger in the cycle just run: the traction drive got the quick-stop controlword in that
/// cycle and is in Quick stop active (or already past it, stopped, in Switch on disabled).
void requireTractionQuickStopped(const Bench& b, std::size_t logBefore) {
  const std::vector<std::uint16_t> cws = b.controlwords(b.cfg.traction.nodeId, logBefore);
  REQUIRE_FALSE(cws.empty());
  CHECK((cws.back() & 0x008F) == kQuickStop);
  const PowerState s = b.traction.state();
  CHECK((s == PowerState::QuickStopActive || s == PowerState::SwitchOnDisabled || s == PowerState::Fault ||
         s == PowerState::FaultReactionActive));
}

}  // namespace

TEST_CASE("bring-up: NMT, SDO configuration, mode confirmed, then shutdown, switch on, enable operation", "[drives]") {
  Bench b;
  REQUIRE(b.ctl->validate() == Status::Ok);
  const int cycles = b.bringUp();
  INFO("bring-up cycles " << cycles);
  CHECK(cycles < 100);  // about 30 SDOs per drive at one per cycle, then 3 state steps
  CHECK(b.traction.state() == PowerState::OperationEnabled);
  CHECK(b.steering.state() == PowerState::OperationEnabled);
  CHECK(b.traction.modeDisplay() == 3);  // profile velocity
  CHECK(b.steering.modeDisplay() == 1);  // profile position
  CHECK(b.traction.nmtState() == NmtState::Operational);

  // What the drives hold now, from the configuration's SI values:
  const Cia402DriveConfig& c = b.cfg;
  CHECK(b.traction.read(0x1017, 0) == 50);                     // producer heartbeat [ms]
  CHECK(b.traction.read(0x1016, 1) == ((127U << 16) | 200U));  // consume node 127, 200 ms
  CHECK(b.steering.read(0x1016, 1) == ((127U << 16) | 200U));
  CHECK(b.traction.read(0x6083, 0) == std::lround(c.traction.acceleration * c.traction.velocityUnitsPerMps));
  CHECK(b.traction.read(0x6085, 0) == std::lround(c.traction.quickStopDeceleration * c.traction.velocityUnitsPerMps));
  CHECK(b.steering.read(0x6081, 0) == std::lround(c.steering.maxRate * c.steering.countsPerRadian));
  // RPDO1 = controlword + target, TPDO1 = statusword + position, TPDO2 = velocity.
  CHECK(b.traction.read(0x1600, 0) == 2);
  CHECK(b.traction.read(0x1600, 1) == 0x60400010U);
  CHECK(b.traction.read(0x1600, 2) == 0x60FF0020U);
  CHECK(b.steering.read(0x1600, 2) == 0x607A0020U);
  CHECK(b.traction.read(0x1A00, 1) == 0x60410010U);
  CHECK(b.traction.read(0x1A00, 2) == 0x60640020U);
  CHECK(b.traction.read(0x1A01, 1) == 0x606C0020U);
  CHECK(b.traction.read(0x1800, 5) == 10);
  // The drives' own reactions (CiA 402): a lost controller = fault signal (the simulated drive
  // leaves the factory with 0, no reaction), quick stop and fault reaction on the quick-stop ramp.
  for (const SimCia402Node* d : {&b.traction, &b.steering}) {
    CHECK(d->read(0x6007, 0) == 1);
    CHECK(d->read(0x605A, 0) == 2);
    CHECK(d->read(0x605E, 0) == 2);
  }
  CHECK(b.traction.counters().sdoAborts == 0);

  // The order on the bus for the traction node: NMT pre-operational, SDOs (0x6060 before the
  // 0x6061 read), NMT start after the 0x6061 answer, then shutdown, switch on, enable operation.
  const std::uint8_t n = c.traction.nodeId;
  std::size_t preop = SIZE_MAX, firstSdo = SIZE_MAX, modeWrite = SIZE_MAX, modeRead = SIZE_MAX, start = SIZE_MAX;
  for (std::size_t i = 0; i < b.log.size(); ++i) {
    const CanFrame& f = b.log[i].frame;
    if (b.log[i].sender == 0 && f.id == 0 && f.data[1] == n) {
      if (f.data[0] == 0x80 && preop == SIZE_MAX)
        preop = i;
      if (f.data[0] == 0x01 && start == SIZE_MAX)
        start = i;
    }
    if (b.log[i].sender == 0 && f.id == 0x600U + n) {
      if (firstSdo == SIZE_MAX)
        firstSdo = i;
      const std::uint16_t idx = static_cast<std::uint16_t>(f.data[1] | (f.data[2] << 8));
      if (idx == 0x6060 && f.data[0] == 0x2F && modeWrite == SIZE_MAX)
        modeWrite = i;
      if (idx == 0x6061 && f.data[0] == 0x40 && modeRead == SIZE_MAX)
        modeRead = i;
    }
  }
  REQUIRE(preop != SIZE_MAX);
  REQUIRE(start != SIZE_MAX);
  CHECK(preop < firstSdo);
  CHECK(modeWrite < modeRead);
  CHECK(modeRead < start);
  const std::vector<std::uint16_t> cws = b.controlwords(n);
  std::vector<std::uint16_t> steps;
  for (std::uint16_t w : cws) {
    const std::uint16_t s = w & 0x008F;
    if (steps.empty() || steps.back() != s)
      steps.push_back(s);
  }
  REQUIRE(steps.size() >= 3);
  // Shutdown, switch on, enable operation in this order (perhaps after a hold word at start).
  const std::size_t k = steps.size() - 3;
  CHECK(steps[k] == kShutdown);
  CHECK(steps[k + 1] == kSwitchOn);
  CHECK(steps[k + 2] == kEnableOperation);
  // The controller produces its heartbeat (0x77F) every 50 ms.
  int heartbeats = 0;
  for (const BusFrame& f : b.log) {
    if (f.sender == 0 && f.frame.id == 0x77F)
      ++heartbeats;
  }
  CHECK(heartbeats >= cycles / 5 - 1);
  CHECK(b.ctl->traction().counters().malformed == 0);
  CHECK(b.ctl->ignoredFrames() == 0);  // both nodes' frames were all understood
}

TEST_CASE("velocity set-point scaled from m/s, steering by the set-point handshake, standstill", "[drives]") {
  Bench b;
  b.bringUp();
  CHECK(b.ctl->isStandstill());
  // 0.5 m/s -> 0.5 * 10000 velocity units; 0.2 rad -> 0.2 * 10000 counts from zero.
  const std::size_t mark = b.log.size();
  b.drive(0.5, 0.2, Duration::fromMilliseconds(1500));  // 0.5 m/s at 0.5 m/s^2 takes 1 s
  CHECK(b.traction.targetVelocity() == 5000);
  AGV_CHECK_NEAR(b.traction.velocity(), 5000.0, 1e-6);
  AGV_CHECK_NEAR(b.ctl->speedActual(), 0.5, 1e-4);
  CHECK_FALSE(b.ctl->isStandstill());
  CHECK(b.steering.activeTargetPosition() == 2000);
  AGV_CHECK_NEAR(b.steering.position(), 2000.0, 0.5);
  AGV_CHECK_NEAR(b.ctl->steeringAngleActual(), 0.2, 1e-4);
  CHECK(b.steering.counters().setPointsAccepted == 1);  // one target, one handshake
  // Handshake on the bus: the RPDO with bit 4 carries the target; bit 4 drops after the drive's bit 12.
  bool sawNew = false, sawAck = false, sawDrop = false;
  for (std::size_t i = mark; i < b.log.size(); ++i) {
    const BusFrame& f = b.log[i];
    if (f.sender == 0 && f.frame.id == 0x203) {
      const std::uint16_t cw = static_cast<std::uint16_t>(f.frame.data[0] | (f.frame.data[1] << 8));
      if ((cw & 0x10) && !sawNew) {
        sawNew = true;
        CHECK(Bench::rpdoTarget(f.frame) == 2000);
        CHECK((cw & 0x20) != 0);  // change set immediately
      }
      if (sawAck && !(cw & 0x10))
        sawDrop = true;
    }
    if (f.sender == 2 && f.frame.id == 0x183 && sawNew) {
      const std::uint16_t sw = static_cast<std::uint16_t>(f.frame.data[0] | (f.frame.data[1] << 8));
      if (sw & 0x1000)
        sawAck = true;
    }
  }
  CHECK(sawNew);
  CHECK(sawAck);
  CHECK(sawDrop);

  // A second target, backwards and to the right.
  b.drive(-0.3, -0.1, Duration::fromMilliseconds(2500));
  CHECK(b.steering.counters().setPointsAccepted == 2);
  AGV_CHECK_NEAR(b.steering.position(), -1000.0, 0.5);
  AGV_CHECK_NEAR(b.traction.velocity(), -3000.0, 1e-6);
  // The steering rate limit: at most maxRate (0.8 rad/s = 8000 counts/s) between two cycles.
  // stop(): ramps to zero with the profile deceleration (0.3 m/s at 0.5 m/s^2: 0.6 s), steering kept.
  for (int i = 0; i < 100; ++i) {
    REQUIRE(b.ctl->stop() == Status::Ok);
    b.cycle();
  }
  CHECK(b.ctl->state() == DriveControllerState::Enabled);
  CHECK(b.traction.state() == PowerState::OperationEnabled);
  CHECK(b.traction.velocity() == 0.0);
  CHECK(b.ctl->isStandstill());
  AGV_CHECK_NEAR(b.steering.position(), -1000.0, 0.5);
}

TEST_CASE("steering moves no faster than the configured rate", "[drives]") {
  Bench b;
  b.bringUp();
  double last = b.steering.position();
  double fastest = 0.0;
  const Timestamp end = b.now + Duration::fromMilliseconds(3000);
  while (b.now < end) {
    hal::DriveCommand c;
    c.steeringAngle = 1.2;
    REQUIRE(b.ctl->command(c) == Status::Ok);
    b.cycle();
    fastest = std::fmax(fastest, std::fabs(b.steering.position() - last) / kCycle.seconds());
    last = b.steering.position();
  }
  AGV_CHECK_NEAR(b.steering.position(), 12000.0, 0.5);
  CHECK(fastest <= 0.8 * 10000.0 + 1e-6);
  CHECK(fastest > 0.7 * 10000.0);  // it did reach the rate
}

TEST_CASE("set-points are refused outside the limits, NaN, or before the drives are enabled", "[drives]") {
  Bench b;
  hal::DriveCommand c;
  c.speed = 0.1;
  CHECK(b.ctl->command(c) == Status::DeviceFault);  // not started
  b.bringUp();
  c.speed = 1.01;  // maxSpeed 1.0
  CHECK(b.ctl->command(c) == Status::InvalidArgument);
  c.speed = 0.2;
  c.steeringAngle = -1.41;  // maxAngle 1.4
  CHECK(b.ctl->command(c) == Status::InvalidArgument);
  c.steeringAngle = std::nan("");
  CHECK(b.ctl->command(c) == Status::NonFiniteInput);
  c.steeringAngle = 0.0;
  c.speed = INFINITY;
  CHECK(b.ctl->command(c) == Status::NonFiniteInput);
  b.cycle();
  CHECK(b.traction.targetVelocity() == 0);  // nothing refused reached the drive

  // Direction and zero offset: a drive counting backwards, steering zero at 500 counts.
  Cia402DriveConfig cfg;
  cfg.traction.direction = -1;
  cfg.steering.direction = -1;
  cfg.steering.zeroCount = 500;
  cfg.steering.countsPerRadian = 4000.0;
  Bench r(cfg);
  r.bringUp();
  r.drive(0.25, 0.1, Duration::fromMilliseconds(1500));
  CHECK(r.traction.targetVelocity() == -2500);
  CHECK(r.steering.activeTargetPosition() == 500 - 400);
  AGV_CHECK_NEAR(r.ctl->speedActual(), 0.25, 1e-4);
  AGV_CHECK_NEAR(r.ctl->steeringAngleActual(), 0.1, 1e-3);
}

TEST_CASE("each safe-state trigger quick-stops the traction axis within one cycle", "[drives]") {
  auto moving = [](Bench& b) {
    b.bringUp();
    b.drive(0.6, 0.1, Duration::fromMilliseconds(1500));
    REQUIRE(b.traction.velocity() > 5000.0);
  };

  SECTION("PLC stop") {
    Bench b;
    moving(b);
    const std::size_t mark = b.log.size();
    b.ctl->quickStop(SafeStopReason::PlcStop);
    b.cycle();
    CHECK(b.ctl->state() == DriveControllerState::SafeStop);
    CHECK(b.ctl->safeStopReason() == SafeStopReason::PlcStop);
    requireTractionQuickStopped(b, mark);
    // The drive decelerates at the quick-stop deceleration (2 m/s^2 = 20000 units/s^2): 6000 units/s
    // stop in 0.3 s, and it then goes to Switch on disabled (quick-stop option code 2).
    b.run(Duration::fromMilliseconds(400));
    CHECK(b.traction.velocity() == 0.0);
    CHECK(b.traction.state() == PowerState::SwitchOnDisabled);
    hal::DriveCommand c;
    CHECK(b.ctl->command(c) == Status::DeviceFault);  // no set-points until started again
    // The steering drive is not stopped: it holds its position, enabled.
    CHECK(b.steering.state() == PowerState::OperationEnabled);
    // Resume: start() brings both up again.
    b.bringUp();
    CHECK(b.traction.state() == PowerState::OperationEnabled);
  }
  SECTION("stale set-point (watchdog)") {
    Bench b;
    moving(b);
    int cycles = 0;
    std::size_t mark = b.log.size();
    while (b.ctl->state() == DriveControllerState::Enabled && cycles < 100) {
      mark = b.log.size();
      b.cycle();  // no command() any more
      ++cycles;
    }
    CHECK(b.ctl->safeStopReason() == SafeStopReason::SetpointTimeout);
    // 200 ms without a set-point: the 21st cycle after the last one.
    CHECK(cycles >= 20);
    CHECK(cycles <= 22);
    requireTractionQuickStopped(b, mark);
  }
  SECTION("EMCY from the traction drive, fault code read back, fault reset") {
    Bench b;
    moving(b);
    const std::size_t mark = b.log.size();
    b.traction.injectFault(0x2310);  // over-current
    b.cycle();                       // the EMCY reaches the controller
    CHECK(b.ctl->state() == DriveControllerState::SafeStop);
    CHECK(b.ctl->safeStopReason() == SafeStopReason::DriveFault);
    CHECK(b.ctl->traction().emcyActive());
    CHECK(b.ctl->traction().lastEmcy().errorCode == 0x2310);
    requireTractionQuickStopped(b, mark);
    b.run(Duration::fromMilliseconds(500));
    CHECK(b.traction.state() == PowerState::Fault);
    CHECK(b.ctl->traction().errorCode() == 0x2310);
    // 0x603F was read back by SDO.
    bool readBack = false;
    for (const BusFrame& f : b.log) {
      if (f.sender == 1 && f.frame.id == 0x581 && f.frame.data[0] == 0x4B && f.frame.data[1] == 0x3F &&
          f.frame.data[2] == 0x60) {
        readBack = f.frame.data[4] == 0x10 && f.frame.data[5] == 0x23;
      }
    }
    CHECK(readBack);
    // Fault reset: bit 7 low, then high (the edge), Switch on disabled, then enabled again.
    const std::size_t before = b.log.size();
    REQUIRE(b.ctl->faultReset(b.now) == Status::Ok);
    for (int i = 0; i < 100 && b.ctl->state() != DriveControllerState::Enabled; ++i) {
      b.cycle();
    }
    CHECK(b.ctl->state() == DriveControllerState::Enabled);
    CHECK(b.traction.state() == PowerState::OperationEnabled);
    const std::vector<std::uint16_t> cws = b.controlwords(1, before);
    std::size_t low = SIZE_MAX, high = SIZE_MAX;
    for (std::size_t i = 0; i < cws.size(); ++i) {
      if (cws[i] == 0x0000 && low == SIZE_MAX)
        low = i;
      if (cws[i] == 0x0080 && high == SIZE_MAX)
        high = i;
    }
    REQUIRE(low != SIZE_MAX);
    REQUIRE(high != SIZE_MAX);
    CHECK(low < high);
    CHECK(contains(cws, kEnableOperation));
    CHECK_FALSE(b.ctl->traction().emcyActive());  // the drive's error-reset EMCY (code 0)
  }
  SECTION("a fault reset is refused when no drive is in Fault") {
    Bench b;
    moving(b);
    CHECK(b.ctl->faultReset(b.now) == Status::Rejected);
  }
  SECTION("EMCY from the steering drive stops the traction") {
    Bench b;
    moving(b);
    const std::size_t mark = b.log.size();
    b.steering.injectFault(0x7305);  // incremental sensor 1 fault
    b.cycle();
    CHECK(b.ctl->safeStopReason() == SafeStopReason::DriveFault);
    requireTractionQuickStopped(b, mark);
    b.run(Duration::fromMilliseconds(300));
    CHECK(b.ctl->steering().errorCode() == 0x7305);
  }
  SECTION("heartbeat loss of the steering drive") {
    Bench b;
    moving(b);
    b.steering.setSilent(true);
    int cycles = 0;
    std::size_t mark = b.log.size();
    while (b.ctl->state() == DriveControllerState::Enabled && cycles < 100) {
      hal::DriveCommand c;
      c.speed = 0.6;
      REQUIRE(b.ctl->command(c) == Status::Ok);
      mark = b.log.size();
      b.cycle();
      ++cycles;
    }
    CHECK(b.ctl->safeStopReason() == SafeStopReason::DriveHeartbeatLost);
    CHECK(b.ctl->steering().heartbeatLost());
    // Lost after the 150 ms consumer time (+ up to one 50 ms producer period since the last one).
    CHECK(cycles >= 10);
    CHECK(cycles <= 21);
    requireTractionQuickStopped(b, mark);
  }
  SECTION("heartbeat loss of the traction drive (it still listens)") {
    Bench b;
    moving(b);
    b.traction.setSilent(true);
    std::size_t mark = b.log.size();
    for (int i = 0; i < 100 && b.ctl->state() == DriveControllerState::Enabled; ++i) {
      hal::DriveCommand c;
      c.speed = 0.6;
      REQUIRE(b.ctl->command(c) == Status::Ok);
      mark = b.log.size();
      b.cycle();
    }
    CHECK(b.ctl->safeStopReason() == SafeStopReason::DriveHeartbeatLost);
    requireTractionQuickStopped(b, mark);
  }
  SECTION("a drive that boots again (power cycle) counts as a lost heartbeat") {
    Bench b;
    moving(b);
    b.traction.powerCycle();
    const std::size_t mark = b.log.size();
    b.cycle();  // the boot-up message reaches the controller
    CHECK(b.ctl->state() == DriveControllerState::SafeStop);
    CHECK(b.ctl->safeStopReason() == SafeStopReason::DriveHeartbeatLost);
    CHECK(b.ctl->traction().heartbeatLost());
    requireTractionQuickStopped(b, mark);
    CHECK(b.traction.velocity() == 0.0);  // the rebooted drive is not enabled
    // start() configures it again from scratch.
    b.bringUp();
    CHECK(b.traction.read(0x1600, 2) == 0x60FF0020U);
  }
  SECTION("CAN bus-off reported by the transport") {
    Bench b;
    moving(b);
    b.ctl->onBusState(true, b.now);
    CHECK(b.ctl->state() == DriveControllerState::SafeStop);
    CHECK(b.ctl->safeStopReason() == SafeStopReason::BusOff);
    CHECK(b.ctl->stop() == Status::DeviceFault);
    hal::DriveCommand c;
    CHECK(b.ctl->command(c) == Status::DeviceFault);
    CHECK(b.ctl->start(b.now) == Status::DeviceFault);
    // The quick stop is queued at once and repeated in every cycle's RPDO, so it reaches the
    // drive with the first frames after the bus is back.
    CanFrame buf[CanOutbox::kCapacity];
    const std::size_t n = b.ctl->takeFrames(Span<CanFrame>(buf));
    bool queued = false;
    for (std::size_t i = 0; i < n; ++i) {
      if (buf[i].id == 0x201 && (buf[i].data[0] & 0x8F) == kQuickStop)
        queued = true;
    }
    CHECK(queued);
    b.ctl->onBusState(false, b.now);
    const std::size_t mark = b.log.size();
    b.cycle();
    requireTractionQuickStopped(b, mark);
  }
  SECTION("shutdown (process exiting)") {
    Bench b;
    moving(b);
    const std::size_t mark = b.log.size();
    b.ctl->shutdown();
    b.flush();  // the frame is queued by the call itself
    CHECK(b.ctl->safeStopReason() == SafeStopReason::Shutdown);
    requireTractionQuickStopped(b, mark);
  }
  SECTION("destruction sends the quick stop through the emergency sink") {
    Bench b;
    moving(b);
    struct Sink final : CanFrameSink {
      Bench* bench = nullptr;
      int sent = 0;
      bool send(const CanFrame& f) noexcept override {
        bench->deliverFromController(&f, 1);
        ++sent;
        return true;
      }
    } sink;
    sink.bench = &b;
    b.ctl->setEmergencySink(&sink);
    const std::size_t mark = b.log.size();
    b.ctl.reset();
    b.controllerAlive = false;
    CHECK(sink.sent >= 1);
    requireTractionQuickStopped(b, mark);
  }
  SECTION("a trigger keeps its first reason") {
    Bench b;
    moving(b);
    b.ctl->quickStop(SafeStopReason::PlcStop);
    b.ctl->onBusState(true, b.now);
    CHECK(b.ctl->safeStopReason() == SafeStopReason::PlcStop);
  }
}

TEST_CASE("release: the drives handed back by disable operation, not by the set-point watchdog", "[drives]") {
  Bench b;
  b.bringUp();
  b.drive(0.6, 0.1, Duration::fromMilliseconds(1500));
  REQUIRE(b.traction.velocity() > 5000.0);
  // Not while moving: nothing changes, the set-points go on.
  CHECK(b.ctl->release() == Status::Rejected);
  CHECK(b.ctl->state() == DriveControllerState::Enabled);
  b.drive(0.6, 0.1, Duration::fromMilliseconds(100));
  CHECK(b.traction.velocity() > 5000.0);
  // Stopped by set-point (the profile deceleration), as a routine ends a segment.
  for (int i = 0; i < 200 && !b.ctl->isStandstill(); ++i) {
    REQUIRE(b.ctl->stop() == Status::Ok);
    b.cycle();
  }
  REQUIRE(b.ctl->isStandstill());
  const std::size_t mark = b.log.size();
  REQUIRE(b.ctl->release() == Status::Ok);
  // Five watchdog periods without a set-point: no quick stop, both drives in Switched on.
  b.run(Duration::fromMilliseconds(1000));
  CHECK(b.ctl->state() == DriveControllerState::Released);
  CHECK(b.ctl->safeStopReason() == SafeStopReason::None);
  for (std::uint8_t node : {b.cfg.traction.nodeId, b.cfg.steering.nodeId}) {
    const std::vector<std::uint16_t> cws = b.controlwords(node, mark);
    REQUIRE(cws.size() >= 50);  // an RPDO per 10 ms cycle
    for (std::uint16_t cw : cws) {
      CHECK((cw & 0x008F) == kSwitchOn);  // "disable operation" has the bits of switch on
    }
  }
  for (std::size_t i = mark; i < b.log.size(); ++i) {
    if (b.log[i].sender == 0 && b.log[i].frame.id == 0x200U + b.cfg.traction.nodeId) {
      CHECK(Bench::rpdoTarget(b.log[i].frame) == 0);
    }
  }
  CHECK(b.traction.state() == PowerState::SwitchedOn);
  CHECK(b.steering.state() == PowerState::SwitchedOn);
  CHECK(b.traction.velocity() == 0.0);
  hal::DriveCommand c;
  c.speed = 0.2;
  CHECK(b.ctl->command(c) == Status::DeviceFault);  // no set-points until started again
  CHECK(b.ctl->release() == Status::Rejected);

  SECTION("the heartbeats stay supervised") {
    b.traction.setSilent(true);
    std::size_t before = b.log.size();
    for (int i = 0; i < 100 && b.ctl->state() == DriveControllerState::Released; ++i) {
      before = b.log.size();
      b.cycle();
    }
    CHECK(b.ctl->state() == DriveControllerState::SafeStop);
    CHECK(b.ctl->safeStopReason() == SafeStopReason::DriveHeartbeatLost);
    const std::vector<std::uint16_t> cws = b.controlwords(b.cfg.traction.nodeId, before);
    REQUIRE_FALSE(cws.empty());
    CHECK((cws.back() & 0x008F) == kQuickStop);
  }
  SECTION("a drive fault stops as in any state") {
    b.steering.injectFault(0x7305);
    for (int i = 0; i < 20 && b.ctl->state() == DriveControllerState::Released; ++i) {
      b.cycle();
    }
    CHECK(b.ctl->state() == DriveControllerState::SafeStop);
    CHECK(b.ctl->safeStopReason() == SafeStopReason::DriveFault);
  }
  SECTION("start() enables the drives again") {
    b.bringUp();
    b.drive(0.3, 0.0, Duration::fromMilliseconds(1000));
    CHECK(b.traction.velocity() > 2000.0);
  }
}

TEST_CASE("release is refused unless the drives are enabled; a safe stop stays one", "[drives]") {
  Bench b;
  CHECK(b.ctl->release() == Status::Rejected);  // idle
  CHECK(b.ctl->state() == DriveControllerState::Idle);
  b.bringUp();
  b.ctl->quickStop(SafeStopReason::PlcStop);
  b.cycle();
  CHECK(b.ctl->release() == Status::Rejected);
  CHECK(b.ctl->state() == DriveControllerState::SafeStop);
  CHECK(b.ctl->safeStopReason() == SafeStopReason::PlcStop);
}

TEST_CASE("heartbeats queued while the controller was held up count at their receive stamps", "[drives]") {
  // The controller's process is held up 170 ms (beyond its 150 ms consumer time for the drives'
  // heartbeats, within the drives' 200 ms for its own) while the drives keep sending; then it reads
  // what queued. With the transport's receive stamps the heartbeats are on time; without stamps
  // (in-process buses) they count at the previous poll, which reports the loss: the false alarm a
  // loaded vehicle computer would raise without the stamps.
  for (const bool stamped : {true, false}) {
    Bench b;
    b.bringUp();
    b.drive(0.4, 0.0, Duration::fromMilliseconds(300));
    // Start the hold-up right after the controller's own heartbeat (0x77F).
    for (int i = 0; i < 10 && !(b.log.back().sender == 0 && b.log.back().frame.id == 0x77FU); ++i) {
      b.drive(0.4, 0.0, kCycle);
    }
    REQUIRE(b.log.back().frame.id == 0x77FU);
    std::vector<CanFrame> queued;
    b.toController = [&](CanFrame& f) {
      f.stamp = stamped ? b.now : Timestamp{};
      queued.push_back(f);
      return false;  // held in the queue
    };
    const Timestamp end = b.now + Duration::fromMilliseconds(170);
    while (b.now < end) {
      b.now = b.now + kCycle;
      b.fromNode(b.traction, b.steering, 1);
      b.fromNode(b.steering, b.traction, 2);
    }
    b.toController = nullptr;
    int heartbeats = 0;
    for (const CanFrame& f : queued) {
      heartbeats += f.id == 0x701U ? 1 : 0;
      b.ctl->onFrame(f);
    }
    CHECK(heartbeats >= 3);
    b.ctl->poll(b.now);
    b.flush();
    INFO((stamped ? "receive stamps" : "no stamps"));
    CHECK(b.ctl->traction().heartbeatLost() == !stamped);
    CHECK((b.ctl->state() == DriveControllerState::Enabled) == stamped);
    if (stamped) {
      b.drive(0.4, 0.0, Duration::fromMilliseconds(500));  // and on it goes
      CHECK(b.ctl->state() == DriveControllerState::Enabled);
      CHECK_FALSE(b.traction.controllerLost());
    }
  }
}

TEST_CASE("a receive stamp ahead of the controller's clock counts as now, and a silent drive is still lost",
          "[drives]") {
  Bench b;
  b.bringUp();
  b.drive(0.4, 0.0, Duration::fromMilliseconds(200));
  // One heartbeat stamped 10 s ahead (a wrong clock), then the traction drive falls silent.
  b.toController = [&](CanFrame& f) {
    if (f.id == 0x701U) {
      f.stamp = b.now + Duration::fromSeconds(10.0);
      b.toController = nullptr;
    }
    return true;
  };
  b.drive(0.4, 0.0, Duration::fromMilliseconds(60));
  REQUIRE_FALSE(b.toController);
  b.traction.setSilent(true);
  int cycles = 0;
  while (b.ctl->state() == DriveControllerState::Enabled && cycles < 100) {
    b.drive(0.4, 0.0, kCycle);
    ++cycles;
  }
  CHECK(b.ctl->safeStopReason() == SafeStopReason::DriveHeartbeatLost);
  // As in "heartbeat loss of the traction drive": the 150 ms consumer time and up to one period.
  CHECK(cycles <= 21);
}

TEST_CASE("a silent controller faults both drives through their heartbeat consumers", "[drives]") {
  Bench b;
  b.bringUp();
  b.drive(0.4, 0.0, Duration::fromMilliseconds(1000));
  REQUIRE(b.traction.velocity() > 3000.0);
  // The controller dies without a word (no destructor, no sink).
  b.controllerAlive = false;
  Timestamp faultedAt{};
  for (int i = 0; i < 100; ++i) {
    b.cycle();
    if (b.traction.state() == PowerState::FaultReactionActive || b.traction.state() == PowerState::Fault) {
      if (faultedAt == Timestamp{})
        faultedAt = b.now;
    }
  }
  CHECK(b.traction.controllerLost());
  CHECK(b.steering.controllerLost());
  CHECK(b.traction.state() == PowerState::Fault);
  CHECK(b.steering.state() == PowerState::Fault);
  CHECK(b.traction.errorCode() == 0x8130);  // CiA 301: heartbeat error
  CHECK(b.traction.velocity() == 0.0);
  // The last controller heartbeat was at most 50 ms before it died; consumer time 200 ms.
  REQUIRE(faultedAt != Timestamp{});
  CHECK((faultedAt - (b.now - Duration::fromMilliseconds(1000))).ns <= Duration::fromMilliseconds(260).ns);
  // EMCYs with the code were sent.
  bool emcy = false;
  for (const BusFrame& f : b.log) {
    if (f.sender == 1 && f.frame.id == 0x081 && f.frame.data[0] == 0x30 && f.frame.data[1] == 0x81)
      emcy = true;
  }
  CHECK(emcy);
}

namespace {

/// A filter for `Bench::toController`: the traction drive's (node 1) confirmation of a download to
/// `index` becomes an SDO abort with `code`.
std::function<bool(CanFrame&)> abortTractionDownload(std::uint16_t index, std::uint32_t code) {
  return [index, code](CanFrame& f) {
    if (f.id == 0x581 && f.data[0] == 0x60 && f.data[1] == (index & 0xFF) && f.data[2] == (index >> 8)) {
      f.data[0] = 0x80;
      for (int i = 0; i < 4; ++i)
        f.data[4 + i] = static_cast<std::uint8_t>(code >> (8 * i));
    }
    return true;
  };
}

}  // namespace

TEST_CASE("bring-up failures: SDO abort named, SDO timeout, a mode not confirmed, a drive in Fault", "[drives]") {
  SECTION("abort on the mode write") {
    Bench b;
    b.toController = abortTractionDownload(0x6060, 0x06090030U);  // invalid value
    REQUIRE(b.ctl->start(b.now) == Status::Ok);
    b.run(Duration::fromMilliseconds(1000));
    CHECK(b.ctl->state() == DriveControllerState::Failed);
    CHECK(b.ctl->traction().phase() == AxisPhase::Failed);
    CHECK(b.ctl->traction().lastError() == Status::DeviceFault);
    CHECK(b.ctl->traction().lastAbortCode() == 0x06090030U);
    CHECK(std::string(sdoAbortName(b.ctl->traction().lastAbortCode())) == "invalid value");
    CHECK(b.ctl->traction().lastErrorIndex() == 0x6060);
    CHECK(b.traction.state() != PowerState::OperationEnabled);
  }
  SECTION("a drive without the abort connection option code (0x6007) is not driven") {
    Bench b;
    b.toController = abortTractionDownload(0x6007, 0x06020000U);  // object does not exist
    REQUIRE(b.ctl->start(b.now) == Status::Ok);
    b.run(Duration::fromMilliseconds(1000));
    CHECK(b.ctl->state() == DriveControllerState::Failed);
    CHECK(b.ctl->traction().lastAbortCode() == 0x06020000U);
    CHECK(b.ctl->traction().lastErrorIndex() == 0x6007);
    CHECK(b.traction.state() != PowerState::OperationEnabled);
  }
  SECTION("no SDO answer") {
    Bench b;
    b.toController = [](CanFrame& f) { return f.id != 0x583; };
    REQUIRE(b.ctl->start(b.now) == Status::Ok);
    b.run(Duration::fromMilliseconds(500));
    CHECK(b.ctl->state() == DriveControllerState::Failed);
    CHECK(b.ctl->steering().lastError() == Status::Timeout);
  }
  SECTION("0x6061 reports another mode") {
    Bench b;
    b.toController = [](CanFrame& f) {
      if (f.id == 0x581 && f.data[0] == 0x4F && f.data[1] == 0x61 && f.data[2] == 0x60) {
        f.data[4] = 0x01;  // profile position instead of profile velocity
      }
      return true;
    };
    REQUIRE(b.ctl->start(b.now) == Status::Ok);
    b.run(Duration::fromMilliseconds(1000));
    CHECK(b.ctl->state() == DriveControllerState::Failed);
    CHECK(b.ctl->traction().lastError() == Status::Rejected);
    CHECK(b.traction.nmtState() != NmtState::Operational);  // never started
  }
  SECTION("a drive in Fault at bring-up: error code read, reset on request") {
    Bench b;
    b.cycle();
    b.traction.injectFault(0x5530);
    REQUIRE(b.ctl->start(b.now) == Status::Ok);
    b.run(Duration::fromMilliseconds(1000));
    CHECK(b.ctl->state() == DriveControllerState::SafeStop);
    CHECK(b.ctl->safeStopReason() == SafeStopReason::DriveFault);
    CHECK(b.ctl->traction().errorCode() == 0x5530);
    CHECK(b.traction.state() == PowerState::Fault);  // no reset unless asked
    INFO("traction phase " << toString(b.ctl->traction().phase()) << ", power state "
                           << toString(b.ctl->traction().powerState()));
    REQUIRE(b.ctl->faultReset(b.now) == Status::Ok);
    for (int i = 0; i < 100 && b.ctl->state() != DriveControllerState::Enabled; ++i) {
      b.cycle();
    }
    CHECK(b.ctl->state() == DriveControllerState::Enabled);
  }
}

TEST_CASE("garbage and truncated frames are counted and ignored", "[drives]") {
  Bench b;
  b.bringUp();
  b.drive(0.2, 0.05, Duration::fromMilliseconds(300));
  const AxisCounters before = b.ctl->traction().counters();
  const std::uint16_t sw = b.ctl->traction().statusword();
  auto frame = [](std::uint32_t id, std::uint8_t dlc, std::uint8_t fill) {
    CanFrame f;
    f.id = id;
    f.dlc = dlc;
    for (auto& d : f.data)
      d = fill;
    return f;
  };
  b.ctl->onFrame(frame(0x181, 3, 0xFF));  // TPDO1 too short
  b.ctl->onFrame(frame(0x281, 2, 0xFF));  // TPDO2 too short
  b.ctl->onFrame(frame(0x581, 5, 0x00));  // SDO response too short
  b.ctl->onFrame(frame(0x701, 0, 0x00));  // heartbeat without state
  b.ctl->onFrame(frame(0x701, 1, 0x33));  // not an NMT state
  b.ctl->onFrame(frame(0x081, 2, 0x10));  // EMCY without error register
  b.ctl->onFrame(frame(0x581, 8, 0xE0));  // reserved command specifier
  CHECK(b.ctl->traction().counters().malformed == before.malformed + 7);
  CHECK(b.ctl->traction().statusword() == sw);
  CHECK_FALSE(b.ctl->traction().emcyActive());
  const std::uint32_t ignored = b.ctl->ignoredFrames();
  b.ctl->onFrame(frame(0x123, 8, 0x55));
  CanFrame ext = frame(0x181, 8, 0x00);
  ext.extended = true;
  b.ctl->onFrame(ext);
  CanFrame err = frame(0x181, 8, 0x00);
  err.error = true;
  b.ctl->onFrame(err);
  CHECK(b.ctl->ignoredFrames() == ignored + 3);
  // The simulated drive discards an RPDO shorter than its mapping.
  const std::uint32_t simMalformed = b.traction.counters().malformed;
  b.traction.receive(frame(0x201, 3, 0x00), b.now);
  CHECK(b.traction.counters().malformed == simMalformed + 1);
  b.drive(0.2, 0.05, Duration::fromMilliseconds(100));
  CHECK(b.ctl->state() == DriveControllerState::Enabled);
  CHECK(b.traction.state() == PowerState::OperationEnabled);
}

namespace {

/// An SDO request to `node` written byte by byte from CiA 301 (not with the encoder under test):
/// command specifier `cmd`, object `index`/`sub`, `value` little-endian in bytes 4..7.
CanFrame sdoRequest(std::uint8_t node, std::uint8_t cmd, std::uint16_t index, std::uint8_t sub, std::uint32_t value) {
  CanFrame f;
  f.id = 0x600U + node;
  f.dlc = 8;
  f.data[0] = cmd;
  f.data[1] = static_cast<std::uint8_t>(index & 0xFF);
  f.data[2] = static_cast<std::uint8_t>(index >> 8);
  f.data[3] = sub;
  for (int i = 0; i < 4; ++i)
    f.data[4 + i] = static_cast<std::uint8_t>(value >> (8 * i));
  return f;
}

}  // namespace

TEST_CASE("the simulated drive's SDO server aborts with the CiA 301 codes", "[drives]") {
  SimCia402NodeParams p;
  p.nodeId = 4;
  SimCia402Node node(p);
  Timestamp t{1000};
  CanFrame buf[8];
  (void)node.step(t, Span<CanFrame>(buf));  // boot-up: pre-operational
  auto ask = [&](std::uint8_t cmd, std::uint16_t index, std::uint8_t sub, std::uint32_t value) {
    node.receive(sdoRequest(4, cmd, index, sub, value), t);
    t = t + kCycle;
    const std::size_t n = node.step(t, Span<CanFrame>(buf));
    for (std::size_t i = 0; i < n; ++i) {
      if (buf[i].id == 0x584) {
        if (buf[i].data[0] != 0x80)
          return std::uint32_t{0};
        return static_cast<std::uint32_t>(buf[i].data[4] | (buf[i].data[5] << 8) | (buf[i].data[6] << 16) |
                                          (static_cast<std::uint32_t>(buf[i].data[7]) << 24));
      }
    }
    return std::uint32_t{0xFFFFFFFF};  // no answer
  };
  CHECK(ask(0x40, 0x2000, 0, 0) == 0x06020000U);  // object does not exist
  CHECK(ask(0x40, 0x6041, 1, 0) == 0x06090011U);  // sub-index does not exist
  CHECK(ask(0x2B, 0x6041, 0, 0) == 0x06010002U);  // statusword is read-only
  CHECK(ask(0x2B, 0x6060, 0, 3) == 0x06070012U);  // 2 bytes into a 1-byte object
  CHECK(ask(0x2F, 0x6060, 0, 7) == 0x06090030U);  // mode 7 not supported
  CHECK(ask(0x2F, 0x1600, 0, 0) == 0x08000022U);  // mapping while RPDO1 is valid
  CHECK(ask(0x23, 0x1400, 1, 0x80000204U) == 0);  // disable RPDO1
  CHECK(ask(0x2F, 0x1600, 0, 0) == 0);
  CHECK(ask(0x23, 0x1600, 1, 0x10000020U) == 0);  // device type: an entry can be written ...
  CHECK(ask(0x2F, 0x1600, 0, 1) == 0x06040041U);  // ... but not enabled: not mappable
  CHECK(ask(0x23, 0x1600, 1, 0x60400020U) == 0);  // controlword with 32 bits
  CHECK(ask(0x2F, 0x1600, 0, 1) == 0x06040043U);  // length does not match the object
  CHECK(ask(0x2F, 0x1600, 0, 5) == 0x06040042U);  // more entries than fit
  CHECK(ask(0xE0, 0x6040, 0, 0) == 0x05040001U);  // reserved command specifier
  CHECK(ask(0x2F, 0x6060, 0, 1) == 0);
  CHECK(ask(0x40, 0x6061, 0, 0) == 0);
  CHECK(node.modeDisplay() == 1);
  CHECK(node.counters().sdoAborts == 10);
  // A stopped node does not answer SDOs.
  CanFrame nmt;
  nmt.id = 0;
  nmt.dlc = 2;
  nmt.data[0] = 0x02;
  nmt.data[1] = 4;
  node.receive(nmt, t);
  CHECK(ask(0x40, 0x6061, 0, 0) == 0xFFFFFFFFU);
}

TEST_CASE("the simulated drive follows the controlword through the CiA 402 states", "[drives]") {
  SimCia402NodeParams p;
  p.nodeId = 3;
  SimCia402Node node(p);
  Timestamp t{1000};
  CanFrame buf[8];
  (void)node.step(t, Span<CanFrame>(buf));
  auto cw = [&](std::uint16_t w) {
    CanFrame f;
    f.id = 0x603;
    f.dlc = 8;
    f.data[0] = 0x2B;
    f.data[1] = 0x40;
    f.data[2] = 0x60;
    f.data[4] = static_cast<std::uint8_t>(w & 0xFF);
    f.data[5] = static_cast<std::uint8_t>(w >> 8);
    node.receive(f, t);
    t = t + kCycle;
    (void)node.step(t, Span<CanFrame>(buf));
    return node.state();
  };
  CHECK(node.state() == PowerState::SwitchOnDisabled);
  CHECK(cw(0x0007) == PowerState::SwitchOnDisabled);  // switch on from SOD: refused
  CHECK(node.counters().rejectedCommands == 1);
  CHECK(cw(0x0006) == PowerState::ReadyToSwitchOn);
  CHECK(cw(0x000F) == PowerState::OperationEnabled);  // 3 + 4
  CHECK(cw(0x0007) == PowerState::SwitchedOn);        // 5
  CHECK(cw(0x000F) == PowerState::OperationEnabled);  // 4
  CHECK(cw(0x0002) == PowerState::SwitchOnDisabled);  // 11, and stopped at once: 12 automatic
  CHECK(cw(0x0006) == PowerState::ReadyToSwitchOn);
  CHECK(cw(0x0000) == PowerState::SwitchOnDisabled);  // 7
  node.injectFault(0x3210);
  CHECK(node.state() == PowerState::Fault);           // power stage was off: Fault at once
  CHECK(cw(0x0006) == PowerState::Fault);             // only a fault reset leaves Fault
  CHECK(cw(0x0086) == PowerState::SwitchOnDisabled);  // the edge of bit 7
  CHECK((node.statusword() & 0x004F) == 0x0040);
}

namespace {

/// One simulated drive on its own, talked to by SDO (expedited), NMT and the heartbeat of a
/// controller with node id 127, stepped in 10 ms cycles; the frames it sends are kept.
struct LoneDrive {
  static constexpr std::uint8_t kNode = 5;
  SimCia402Node node;
  Timestamp t{Timestamp::fromSeconds(1.0)};
  std::vector<CanFrame> sent;
  bool controllerAlive = true;

  explicit LoneDrive(const SimCia402NodeParams& p) : node(p) { step(); }
  static SimCia402NodeParams params(bool quickStopToOperationEnabled = false) {
    SimCia402NodeParams p;
    p.nodeId = kNode;
    p.options.quickStopToOperationEnabled = quickStopToOperationEnabled;
    return p;
  }

  void step() {
    if (controllerAlive && (t.ns / 1000000) % 50 == 0) {
      CanFrame hb;
      hb.id = 0x77F;
      hb.dlc = 1;
      hb.data[0] = 0x05;
      node.receive(hb, t);
    }
    t = t + kCycle;
    CanFrame buf[SimCia402Node::kOutbox];
    const std::size_t n = node.step(t, Span<CanFrame>(buf));
    sent.insert(sent.end(), buf, buf + n);
  }
  void run(Duration d) {
    for (Timestamp end = t + d; t < end;)
      step();
  }
  /// Expedited SDO download of `size` bytes; returns the abort code, 0 when confirmed.
  std::uint32_t write(std::uint16_t index, std::uint8_t sub, std::uint32_t value, int size) {
    node.receive(sdoRequest(kNode, static_cast<std::uint8_t>(0x23 | ((4 - size) << 2)), index, sub, value), t);
    const std::size_t before = sent.size();
    step();
    for (std::size_t i = before; i < sent.size(); ++i) {
      const CanFrame& a = sent[i];
      if (a.id == 0x580U + kNode)
        return a.data[0] == 0x80 ? static_cast<std::uint32_t>(a.data[4] | (a.data[5] << 8) | (a.data[6] << 16) |
                                                              (static_cast<std::uint32_t>(a.data[7]) << 24))
                                 : 0U;
    }
    return 0xFFFFFFFFU;
  }
  /// Consumes the controller's heartbeat (200 ms), profile velocity, Operation enabled, target
  /// velocity `v`, run until the ramp reached it (acceleration 1000 units/s^2 as the factory set).
  void driveAt(std::int32_t v) {
    REQUIRE(write(0x1016, 1, (127U << 16) | 200U, 4) == 0);
    REQUIRE(write(0x6060, 0, 3, 1) == 0);
    REQUIRE(write(0x6040, 0, 0x0006, 2) == 0);
    REQUIRE(write(0x6040, 0, 0x000F, 2) == 0);
    REQUIRE(write(0x60FF, 0, static_cast<std::uint32_t>(v), 4) == 0);
    run(Duration::fromSeconds(1.5));
    REQUIRE(node.state() == PowerState::OperationEnabled);
    REQUIRE(node.velocity() == static_cast<double>(v));
  }
  bool sentEmcy(std::uint16_t code) const {
    for (const CanFrame& f : sent) {
      if (f.id == 0x080U + kNode && (f.data[0] | (f.data[1] << 8)) == code)
        return true;
    }
    return false;
  }
};

}  // namespace

TEST_CASE("the simulated drive meets a silent controller with the reaction of 0x6007", "[drives]") {
  LoneDrive d(LoneDrive::params());
  CHECK(d.node.read(0x6007, 0) == 0);  // as it leaves the factory: no reaction
  // 0: no action (only the EMCY), 1: fault signal, 2: disable voltage, 3: quick stop.
  const int option = GENERATE(0, 1, 2, 3);
  INFO("0x6007 = " << option);
  REQUIRE(d.write(0x6007, 0, static_cast<std::uint32_t>(option), 2) == 0);
  d.driveAt(1000);
  d.controllerAlive = false;
  d.run(Duration::fromMilliseconds(250));  // 200 ms consumer time, then the reaction begins
  CHECK(d.node.controllerLost());
  CHECK(d.sentEmcy(0x8130));               // CiA 301 heartbeat error, whatever the reaction
  d.run(Duration::fromMilliseconds(300));  // the quick-stop ramp: 1000 units/s at 5000 /s^2 = 0.2 s
  switch (option) {
    case 0:
      CHECK(d.node.state() == PowerState::OperationEnabled);
      CHECK(d.node.velocity() == 1000.0);
      break;
    case 1:
      CHECK(d.node.state() == PowerState::Fault);
      CHECK(d.node.errorCode() == 0x8130);
      CHECK(d.node.velocity() == 0.0);
      break;
    case 2:
    case 3:
      CHECK(d.node.state() == PowerState::SwitchOnDisabled);  // 3: via Quick stop active
      CHECK(d.node.velocity() == 0.0);
      break;
    default:
      FAIL("no such option");
  }
}

TEST_CASE("the simulated drive's quick stop and fault reaction follow 0x605A and 0x605E", "[drives]") {
  SECTION("values it does not implement are refused") {
    LoneDrive d(LoneDrive::params());
    CHECK(d.write(0x6007, 0, 4, 2) == 0x06090030U);
    CHECK(d.write(0x6007, 0, 0xFFFF, 2) == 0x06090030U);  // -1: manufacturer-specific
    CHECK(d.write(0x605A, 0, 0, 2) == 0x06090030U);       // 0: coast
    CHECK(d.write(0x605A, 0, 3, 2) == 0x06090030U);
    CHECK(d.write(0x605E, 0, 0, 2) == 0x06090030U);
    CHECK(d.write(0x605E, 0, 2, 4) == 0x06070012U);  // an i16 written as 4 bytes
  }
  SECTION("2: the quick-stop ramp, then Switch on disabled; 1: the slow-down ramp") {
    LoneDrive d(LoneDrive::params());
    CHECK(d.node.read(0x605A, 0) == 2);
    const int option = GENERATE(2, 1);
    INFO("0x605A = " << option);
    REQUIRE(d.write(0x605A, 0, static_cast<std::uint32_t>(option), 2) == 0);
    d.driveAt(1000);
    REQUIRE(d.write(0x6040, 0, 0x0002, 2) == 0);  // quick stop (11)
    d.run(Duration::fromMilliseconds(500));
    if (option == 2) {
      CHECK(d.node.state() == PowerState::SwitchOnDisabled);  // stopped after 0.2 s
      CHECK(d.node.velocity() == 0.0);
    } else {
      CHECK(d.node.state() == PowerState::QuickStopActive);  // 1000 /s^2: 1 s to stop
      CHECK(d.node.velocity() == Approx(1000.0 - 1000.0 * 0.51).margin(15.0));
      d.run(Duration::fromMilliseconds(600));
      CHECK(d.node.state() == PowerState::SwitchOnDisabled);
    }
  }
  SECTION("6 (as this drive's factory set it): stays in Quick stop active, may re-enable; 2 written: may not") {
    LoneDrive d(LoneDrive::params(true));
    CHECK(d.node.read(0x605A, 0) == 6);
    const bool configured = GENERATE(false, true);  // the factory's 6, or 2 written
    INFO("0x605A written: " << configured);
    if (configured)
      REQUIRE(d.write(0x605A, 0, 2, 2) == 0);
    d.driveAt(1000);
    REQUIRE(d.write(0x6040, 0, 0x0002, 2) == 0);
    d.run(Duration::fromMilliseconds(500));
    CHECK(d.node.velocity() == 0.0);
    REQUIRE(d.write(0x6040, 0, 0x000F, 2) == 0);  // enable operation (16 where allowed)
    CHECK(d.node.state() == (configured ? PowerState::SwitchOnDisabled : PowerState::OperationEnabled));
  }
  SECTION("fault reaction 1: the slow-down ramp, then Fault") {
    LoneDrive d(LoneDrive::params());
    REQUIRE(d.write(0x605E, 0, 1, 2) == 0);
    d.driveAt(1000);
    d.node.injectFault(0x2310);
    d.run(Duration::fromMilliseconds(500));
    CHECK(d.node.state() == PowerState::FaultReactionActive);
    CHECK(d.node.velocity() > 0.0);
    d.run(Duration::fromMilliseconds(600));
    CHECK(d.node.state() == PowerState::Fault);
    CHECK(d.node.velocity() == 0.0);
  }
}

TEST_CASE("the controller and the simulated drives allocate nothing in steady state", "[drives]") {
  Bench b;
  b.bringUp();
  Cia402DriveController& ctl = *b.ctl;
  std::size_t frames = 0;
  auto oneCycle = [&](double speed) {
    b.now = b.now + kCycle;
    CanFrame buf[32];
    for (SimCia402Node* node : {&b.traction, &b.steering}) {
      const std::size_t n = node->step(b.now, Span<CanFrame>(buf));
      for (std::size_t i = 0; i < n; ++i) {
        ctl.onFrame(buf[i]);
        (node == &b.traction ? b.steering : b.traction).receive(buf[i], b.now);
      }
      frames += n;
    }
    hal::DriveCommand c;
    c.speed = speed;
    c.steeringAngle = speed;
    (void)ctl.command(c);
    ctl.poll(b.now);
    const std::size_t n = ctl.takeFrames(Span<CanFrame>(buf));
    for (std::size_t i = 0; i < n; ++i) {
      b.traction.receive(buf[i], b.now);
      b.steering.receive(buf[i], b.now);
    }
    frames += n;
    (void)ctl.isStandstill();
  };
  AGV_CHECK_NO_ALLOCATIONS(for (int i = 0; i < 100; ++i) oneCycle(0.3));
  CHECK(frames > 300);  // TPDOs, heartbeats and RPDOs did flow
  CHECK(ctl.state() == DriveControllerState::Enabled);
  CHECK(b.steering.counters().setPointsAccepted >= 1);
  // A trigger and its reaction allocate nothing either.
  AGV_CHECK_NO_ALLOCATIONS(ctl.quickStop(SafeStopReason::PlcStop); oneCycle(0.0));
  CHECK(ctl.state() == DriveControllerState::SafeStop);
}
