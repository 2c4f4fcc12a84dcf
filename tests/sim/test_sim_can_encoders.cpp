// Simulated CANopen encoder nodes decoded by the vehicle's decoder (canopen::CanopenEncoders):
// measurements -> CiA 402 / CiA 406 TPDOs -> decoded samples equal to the measured ticks (plus the
// drive counter's start) and angles, across the drive's 32-bit wrap and the steering encoder's
// revolution wrap, for every direction setting; NMT start-up, heartbeats, SYNC; a dropped frame and
// missing heartbeats reported as the decoder reports them on a vehicle.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <deque>
#include <vector>

#include "agv/core/angle.hpp"
#include "agv/sim/can_encoder_source.hpp"
#include "agv/sim/sim_can_encoders.hpp"
#include "agv/sim/sim_vehicle.hpp"
#include "agv_test.hpp"

using agv::Duration;
using agv::Pose2d;
using agv::Status;
using agv::Timestamp;
using agv::drivers::CanFrame;
using agv::hal::EncoderSample;
using agv::sim::CanEncoderSource;
using agv::sim::SimCanEncoders;
using agv::sim::SimCanEncodersParams;
namespace canopen = agv::drivers::canopen;

namespace {

constexpr std::uint32_t kCounts = 16384;  // 14-bit steering encoder, as the simulated vehicle
const double kQuantum = agv::kTwoPi<double> / kCounts;

/// A measurement source with a script: the encoder readings of a vehicle at 10 ms intervals.
class ScriptedEncoders final : public agv::hal::EncoderSource {
 public:
  void push(std::int64_t ticks, double angle) {
    EncoderSample s;
    s.stamp = next_;
    s.driveTicks = ticks;
    s.steeringAngle = angle;
    queue_.push_back(s);
    sent_.push_back(s);
    next_ = next_ + Duration::fromMilliseconds(10);
  }
  Status read(EncoderSample& out) noexcept override {
    if (queue_.empty()) {
      return Status::NotFound;
    }
    out = queue_.front();
    queue_.pop_front();
    return Status::Ok;
  }
  Status health() const noexcept override { return Status::Ok; }
  /// Every measurement pushed, by stamp order.
  const std::vector<EncoderSample>& sent() const { return sent_; }
  /// The measurement with stamp `t` (REQUIREs it exists).
  const EncoderSample& at(Timestamp t) const {
    for (const EncoderSample& s : sent_) {
      if (s.stamp == t) {
        return s;
      }
    }
    FAIL("no measurement at " << t.ns);
    return sent_.front();
  }

 private:
  std::deque<EncoderSample> queue_;
  std::vector<EncoderSample> sent_;
  Timestamp next_ = Timestamp::fromSeconds(1.0);
};

/// Tees a source: records what the vehicle's encoders measured before it goes onto the bus.
class Tee final : public agv::hal::EncoderSource {
 public:
  explicit Tee(agv::hal::EncoderSource& src) : src_(src) {}
  Status read(EncoderSample& out) noexcept override {
    const Status s = src_.read(out);
    if (s == Status::Ok) {
      seen.push_back(out);
    }
    return s;
  }
  Status health() const noexcept override { return src_.health(); }
  std::vector<EncoderSample> seen;

 private:
  agv::hal::EncoderSource& src_;
};

double quantised(double angle) {
  return std::round(angle / kQuantum) * kQuantum;
}

/// Reads every sample now available.
std::vector<EncoderSample> drain(CanEncoderSource& src) {
  std::vector<EncoderSample> out;
  EncoderSample s;
  while (src.read(s) == Status::Ok) {
    out.push_back(s);
  }
  return out;
}

}  // namespace

TEST_CASE("Default bus: valid, and the simulated nodes' frames are the CiA 402 / CiA 406 TPDOs", "[sim][can]") {
  const SimCanEncodersParams p = agv::sim::defaultSimCanEncoders(kCounts);
  REQUIRE(agv::sim::validateSimCanEncoders(p) == Status::Ok);
  CHECK(p.bus.steering.radiansPerCount == Approx(kQuantum).epsilon(1e-15));
  CHECK(p.bus.steering.zeroCount == 16000U);
  // Refused: the decoder refuses the bus, or the drive start outside the INTEGER32 position range.
  SimCanEncodersParams bad = p;
  bad.bus.steering.nodeId = p.bus.drive.nodeId;
  CHECK(agv::sim::validateSimCanEncoders(bad) == Status::InvalidArgument);
  bad = p;
  bad.driveTicksAtZero = std::int64_t{1} << 31;
  CHECK(agv::sim::validateSimCanEncoders(bad) == Status::InvalidArgument);

  SimCanEncoders nodes(p);
  CanFrame frames[SimCanEncoders::kMaxFramesPerMeasurement];
  EncoderSample m;
  m.stamp = Timestamp::fromSeconds(2.0);
  m.driveTicks = 1234;
  m.steeringAngle = 500 * kQuantum;
  // Pre-operational after power-on: boot-up messages, no PDOs.
  std::size_t n = nodes.measure(m, agv::Span<CanFrame>(frames));
  REQUIRE(n == 2U);
  CHECK((frames[0].id == 0x701U && frames[0].dlc == 1U && frames[0].data[0] == 0x00U));
  CHECK((frames[1].id == 0x702U && frames[1].dlc == 1U && frames[1].data[0] == 0x00U));
  CHECK(nodes.driveState() == canopen::NmtState::PreOperational);
  nodes.receive(canopen::encodeNmt(canopen::NmtCommand::Start, 0));  // all nodes
  CHECK(nodes.driveState() == canopen::NmtState::Operational);
  CHECK(nodes.steeringState() == canopen::NmtState::Operational);
  m.stamp = m.stamp + Duration::fromMilliseconds(10);
  n = nodes.measure(m, agv::Span<CanFrame>(frames));
  REQUIRE(n == 2U);
  // Drive: position actual value = -(ticks + start) (counts down forward), INTEGER32 little-endian.
  const auto driveRaw = static_cast<std::uint32_t>(-(1234 + p.driveTicksAtZero));
  CHECK(frames[0].id == 0x181U);
  CHECK(frames[0].dlc == 4U);
  CHECK((frames[0].data[0] == (driveRaw & 0xFFU) && frames[0].data[3] == (driveRaw >> 24U)));
  // Steering: position value = zero + counts, wrapped into the revolution (16000 + 500 - 16384).
  CHECK(frames[1].id == 0x182U);
  const std::uint32_t steerRaw = frames[1].data[0] | (static_cast<std::uint32_t>(frames[1].data[1]) << 8U);
  CHECK(steerRaw == 16000U + 500U - kCounts);
  CHECK(frames[0].stamp == m.stamp);
  // Stopped nodes send heartbeats (state 04) but no PDOs.
  nodes.receive(canopen::encodeNmt(canopen::NmtCommand::Stop, 1));
  m.stamp = m.stamp + Duration::fromMilliseconds(100);
  n = nodes.measure(m, agv::Span<CanFrame>(frames));
  REQUIRE(n == 3U);
  CHECK((frames[0].id == 0x701U && frames[0].data[0] == 0x04U));
  CHECK((frames[1].id == 0x702U && frames[1].data[0] == 0x05U));
  CHECK(frames[2].id == 0x182U);
}

TEST_CASE("Decoded samples equal the measurements across the 32-bit drive wrap, every direction setting",
          "[sim][can]") {
  struct Setting {
    std::int8_t driveDirection;
    std::int8_t steerDirection;
    std::int64_t start;    // drive ticks at zero
    std::uint32_t zero;    // steering zero count
    std::uint8_t pdoSize;  // drive position field
  };
  const Setting settings[] = {
      {1, 1, (std::int64_t{1} << 31) - 3000, 16000, 4},   // forward crosses the INTEGER32 overflow
      {-1, 1, (std::int64_t{1} << 31) - 3000, 16000, 4},  // same, counter counting down
      {1, -1, -(std::int64_t{1} << 31) + 3000, 200, 4},   // backward crosses it
      {-1, -1, -2000, 8000, 4},                           // through 0xFFFFFFFF / 0 (no signed jump)
      {1, 1, 32000, 16383, 2},                            // a 16-bit position field wraps every 6.5 m
  };
  for (const Setting& st : settings) {
    SimCanEncodersParams p = agv::sim::defaultSimCanEncoders(kCounts);
    p.bus.drive.direction = st.driveDirection;
    p.bus.drive.pdo.size = st.pdoSize;
    p.bus.steering.direction = st.steerDirection;
    p.bus.steering.zeroCount = st.zero;
    p.driveTicksAtZero = st.start;
    INFO("drive direction " << int{st.driveDirection} << ", steering direction " << int{st.steerDirection} << ", start "
                            << st.start << ", zero " << st.zero << ", size " << int{st.pdoSize});
    ScriptedEncoders script;
    CanEncoderSource src(script, p);
    REQUIRE(src.validate() == Status::Ok);
    // At rest for 0.2 s (start-up), then 6000 ticks forward and 12000 back in steps of 0..117
    // ticks while the steering sweeps +-70 deg through both sides of the zero.
    std::int64_t ticks = 0;
    for (int i = 0; i < 20; ++i) {
      script.push(ticks, 0.0);
    }
    for (int i = 0; i < 300; ++i) {
      ticks += (st.start < 0 ? -1 : 1) * ((i * 37) % 41);
      script.push(ticks, quantised(agv::deg2rad(70.0) * std::sin(0.05 * i)));
    }
    for (int i = 0; i < 600; ++i) {
      ticks -= (st.start < 0 ? -1 : 1) * ((i * 37) % 41);
      script.push(ticks, quantised(agv::deg2rad(-70.0) * std::sin(0.03 * i)));
    }
    const std::vector<EncoderSample> out = drain(src);
    // Every measurement decodes once the nodes report operational (first heartbeat after 100 ms).
    REQUIRE(out.size() >= script.sent().size() - 10U);
    REQUIRE(out.size() < script.sent().size());
    for (const EncoderSample& s : out) {
      const EncoderSample& m = script.at(s.stamp);
      CHECK(s.driveTicks == m.driveTicks + st.start);
      CHECK(s.steeringAngle == m.steeringAngle);  // exact: the measurement is a whole count
    }
    CHECK(out.back().driveTicks == ticks + st.start);
    const agv::sim::CanBusCounters c = src.counters();
    CHECK(c.sampleMismatches == 0U);
    CHECK(c.samplesWithheld == script.sent().size() - out.size());
    CHECK(c.malformed == 0U);
    // Forward over the wrap and back: the signed position value jumped by 2^32 (2^16) twice,
    // except through 0xFFFFFFFF / 0, where the signed value does not jump.
    CHECK(c.driveCounterWraps == (st.start == -2000 ? 0U : 2U));
    CHECK(src.decoder().health() == Status::Ok);
  }
}

TEST_CASE("The simulated vehicle's encoders through CAN: decoded = measured, over a drive across the wrap",
          "[sim][can]") {
  agv::sim::SimVehicle vehicle(agv::sim::SimVehicleParams{}, 42);
  Tee tee(vehicle);
  const SimCanEncodersParams p = agv::sim::defaultSimCanEncoders(kCounts);
  CanEncoderSource src(tee, p);
  vehicle.reset(Pose2d{}, Timestamp{});
  std::vector<EncoderSample> out;
  Timestamp t{};
  const auto run = [&](double speed, double steer, double seconds) {
    REQUIRE(vehicle.command(agv::hal::DriveCommand{t, speed, steer}) == Status::Ok);
    for (int i = 0; i < static_cast<int>(seconds * 50.0); ++i) {
      t = t + Duration::fromMilliseconds(20);
      vehicle.advanceTo(t);
      for (const EncoderSample& s : drain(src)) {
        out.push_back(s);
      }
    }
  };
  run(0.0, agv::deg2rad(30.0), 1.0);  // steer at rest
  run(1.0, agv::deg2rad(30.0), 5.0);  // ~4.5 m forward: past the drive's overflow (3 m)
  run(-1.0, agv::deg2rad(-40.0), 8.0);
  run(0.0, 0.0, 2.0);
  REQUIRE(out.size() > 1400U);
  std::size_t k = 0;
  for (const EncoderSample& s : out) {
    while (k < tee.seen.size() && tee.seen[k].stamp != s.stamp) {
      ++k;
    }
    REQUIRE(k < tee.seen.size());
    CHECK(s.driveTicks == tee.seen[k].driveTicks + p.driveTicksAtZero);
    CHECK(s.steeringAngle == tee.seen[k].steeringAngle);
  }
  CHECK(out.size() == tee.seen.size() - src.counters().samplesWithheld);
  CHECK(src.counters().driveCounterWraps == 2U);
  std::int64_t maxTicks = 0;
  for (const EncoderSample& s : out) {
    maxTicks = std::max(maxTicks, s.driveTicks);
  }
  CHECK(maxTicks > std::int64_t{1} << 31);  // decoded into int64 past the INTEGER32 range
}

TEST_CASE("SYNC: synchronous TPDOs only on the vehicle's SYNC", "[sim][can]") {
  for (int periodMs : {10, 20}) {
    SimCanEncodersParams p = agv::sim::defaultSimCanEncoders(kCounts);
    p.bus.syncPeriod = Duration::fromMilliseconds(periodMs);
    ScriptedEncoders script;
    CanEncoderSource src(script, p);
    for (int i = 0; i < 200; ++i) {
      script.push(10 * i, quantised(0.001 * i));
    }
    const std::vector<EncoderSample> out = drain(src);
    const agv::sim::CanBusCounters c = src.counters();
    INFO("SYNC period " << periodMs << " ms");
    CHECK(src.nodes().counters().syncsReceived == static_cast<std::uint64_t>(200 * 10 / periodMs));
    CHECK(c.drivePositions == src.nodes().counters().syncsReceived);
    CHECK(c.samples == c.drivePositions);
    CHECK(c.sampleMismatches == 0U);
    for (const EncoderSample& s : out) {
      CHECK(s.driveTicks == script.at(s.stamp).driveTicks + p.driveTicksAtZero);
      CHECK(s.steeringAngle == script.at(s.stamp).steeringAngle);
    }
  }
}

TEST_CASE("A dropped drive TPDO: no sample for that cycle, counted, no travel lost, no stale pairing", "[sim][can]") {
  const SimCanEncodersParams p = agv::sim::defaultSimCanEncoders(kCounts);
  ScriptedEncoders script;
  CanEncoderSource src(script, p);
  const Timestamp dropAt = Timestamp::fromSeconds(1.0) + Duration::fromMilliseconds(10 * 50);
  src.setFilter([&](const CanFrame& f, bool toDecoder) { return !(toDecoder && f.id == 0x181U && f.stamp == dropAt); });
  for (int i = 0; i < 100; ++i) {
    script.push(25 * i, quantised(0.002 * i));
  }
  const std::vector<EncoderSample> out = drain(src);
  CHECK(src.counters().framesDropped == 1U);
  CHECK(src.decoder().driveHealth().pdoCount == src.decoder().steeringHealth().pdoCount - 1U);
  bool sawDropped = false;
  for (const EncoderSample& s : out) {
    sawDropped = sawDropped || s.stamp == dropAt;
    CHECK(s.driveTicks == script.at(s.stamp).driveTicks + p.driveTicksAtZero);  // absolute position: no travel lost
  }
  CHECK_FALSE(sawDropped);
  CHECK(src.decoder().incompleteCycles() == 1U);
  CHECK(out.size() == 100U - 10U - 1U);          // 10 withheld at start-up, the incomplete cycle
  CHECK(src.counters().sampleMismatches == 0U);  // the steering angles after the loss are of their own cycle
  CHECK(src.decoder().health() == Status::Ok);
}

TEST_CASE("Missing heartbeats: Timeout after the consumer time, samples withheld, recovery", "[sim][can]") {
  const SimCanEncodersParams p = agv::sim::defaultSimCanEncoders(kCounts);
  ScriptedEncoders script;
  CanEncoderSource src(script, p);
  bool silent = false;
  src.setFilter([&](const CanFrame& f, bool toDecoder) { return !(silent && toDecoder && f.id == 0x702U); });
  for (int i = 0; i < 50; ++i) {
    script.push(i, 0.0);
  }
  REQUIRE_FALSE(drain(src).empty());
  REQUIRE(src.decoder().health() == Status::Ok);
  // The steering node's heartbeats stop (cable of its supply, node hung...): its PDOs still come.
  silent = true;
  std::size_t timeoutAfter = 0;
  EncoderSample s;
  for (int i = 50; i < 150; ++i) {
    script.push(i, 0.0);
    const Status st = src.read(s);
    if (st == Status::Timeout && timeoutAfter == 0U) {
      timeoutAfter = static_cast<std::size_t>(i - 50 + 1);
    }
  }
  // Heartbeats every 100 ms from the boot-up at measurement 0: the last one delivered is at
  // measurement 40; consumer time 300 ms: the read of measurement 71, the first more than 300 ms
  // after it, is the 22nd read of the silence and reports the timeout.
  CHECK(src.decoder().steeringHealth().heartbeatTimedOut);
  CHECK_FALSE(src.decoder().driveHealth().heartbeatTimedOut);
  CHECK(timeoutAfter == 22U);
  CHECK(src.decoder().health() == Status::Timeout);
  CHECK(src.counters().faultReads > 0U);
  CHECK(src.counters().samplesWithheld >= 70U);
  // Heartbeats again: Ok with the next heartbeat, samples flow.
  silent = false;
  for (int i = 150; i < 170; ++i) {
    script.push(i, 0.0);
  }
  const std::vector<EncoderSample> after = drain(src);
  CHECK(src.decoder().health() == Status::Ok);
  REQUIRE_FALSE(after.empty());
  CHECK(after.back().driveTicks == 169 + p.driveTicksAtZero);
}

TEST_CASE("A node reset: boot-up, NMT Start again from the decoder, samples resume", "[sim][can]") {
  const SimCanEncodersParams p = agv::sim::defaultSimCanEncoders(kCounts);
  ScriptedEncoders script;
  CanEncoderSource src(script, p);
  for (int i = 0; i < 30; ++i) {
    script.push(i, 0.0);
  }
  REQUIRE_FALSE(drain(src).empty());
  const std::uint64_t toNodes = src.counters().framesToNodes;
  // The drive resets itself (as after a supply dip): boot-up, pre-operational, no PDOs.
  SimCanEncoders& nodes = src.nodes();
  nodes.receive(canopen::encodeNmt(canopen::NmtCommand::ResetNode, 1));
  for (int i = 30; i < 60; ++i) {
    script.push(i, 0.0);
  }
  const std::vector<EncoderSample> after = drain(src);
  CHECK(src.decoder().driveHealth().bootUps == 2U);
  CHECK(src.counters().framesToNodes == toNodes + 1U);  // the decoder's NMT Start for node 1
  CHECK(nodes.driveState() == canopen::NmtState::Operational);
  REQUIRE_FALSE(after.empty());
  CHECK(after.back().driveTicks == 59 + p.driveTicksAtZero);
}
