// CANopen encoder decoding with frames: NMT/SYNC/heartbeat/EMCY layouts (CiA 301), TPDO positions
// with wraparound, direction, scaling and mapping; heartbeat timeouts; round trip against the
// simulator's encoder on a simulated drive across the 32-bit wrap. Also runs in the Cortex-M7
// image (MCU): only the portable subset of agv_test.hpp (INFO is a no-op there).
#include <cmath>
#include <cstdint>
#include <random>

#include "agv/core/angle.hpp"
#include "agv/drivers/protocol/canopen/canopen_encoders.hpp"
#include "agv_test.hpp"

using agv::Duration;
using agv::Span;
using agv::Status;
using agv::Timestamp;
using agv::drivers::CanFrame;
using namespace agv::drivers::canopen;

namespace {
Timestamp ms(std::int64_t v) {
  return Timestamp::fromNanoseconds(v * 1000000);
}

/// A drive TPDO with `raw` (little-endian) at the given mapping, built byte by byte.
CanFrame rawPdo(std::uint16_t cob, std::uint8_t offset, std::uint8_t size, std::uint32_t raw, Timestamp t) {
  CanFrame f;
  f.id = cob;
  f.dlc = static_cast<std::uint8_t>(offset + size);
  for (int i = 0; i < size; ++i)
    f.data[offset + i] = static_cast<std::uint8_t>((raw >> (8 * i)) & 0xFF);
  f.stamp = t;
  return f;
}

CanopenEncodersConfig baseConfig() {
  CanopenEncodersConfig c;
  c.drive.nodeId = 5;
  c.drive.pdo = {0x185, 0, 4};
  c.steering.nodeId = 6;
  c.steering.pdo = {0x186, 0, 4};
  c.steering.radiansPerCount = agv::kTwoPi<double> / 8192.0;  // 13-bit single-turn on the steering axis
  c.steering.countsPerRevolution = 8192;
  c.steering.zeroCount = 8000;  // straight ahead close to the wrap: crossings must not jump
  return c;
}
}  // namespace

TEST_CASE("CiA 301 frame layouts: NMT, SYNC, heartbeat, EMCY", "[drivers][canopen]") {
  const CanFrame nmt = encodeNmt(NmtCommand::Start, 5);
  CHECK(nmt.id == 0x000U);
  CHECK(nmt.dlc == 2U);
  CHECK(nmt.data[0] == 0x01U);
  CHECK(nmt.data[1] == 5U);
  CHECK(encodeNmt(NmtCommand::ResetNode, 0).data[0] == 0x81U);
  const CanFrame sync = encodeSync(ms(3));
  CHECK(sync.id == 0x080U);
  CHECK(sync.dlc == 0U);
  const CanFrame hb = encodeHeartbeat(6, NmtState::Operational, ms(1));
  CHECK(hb.id == 0x706U);
  CHECK(hb.dlc == 1U);
  CHECK(hb.data[0] == 0x05U);
  const CanFrame em = encodeEmcy(5, 0x7305, 0x81, ms(1));  // 0x7305: incremental sensor 1 fault
  CHECK(em.id == 0x085U);
  CHECK(em.dlc == 8U);
  CHECK(em.data[0] == 0x05U);
  CHECK(em.data[1] == 0x73U);
  CHECK(em.data[2] == 0x81U);

  CanopenEncoders dec(baseConfig());
  REQUIRE(dec.validate() == Status::Ok);
  CanFrame out[4];
  REQUIRE(dec.startupFrames(Span<CanFrame>(out)) == 2U);
  CHECK((out[0].id == 0U && out[0].data[0] == 1U && out[0].data[1] == 5U));
  CHECK((out[1].id == 0U && out[1].data[0] == 1U && out[1].data[1] == 6U));
}

TEST_CASE("Drive position: 32-bit wraparound unwrapped to int64, both directions", "[drivers][canopen]") {
  for (std::int8_t direction : {std::int8_t{1}, std::int8_t{-1}}) {
    auto cfg = baseConfig();
    cfg.drive.direction = direction;
    cfg.trigger = SampleTrigger::DriveUpdated;
    CanopenEncoders dec(cfg);
    dec.onFrame(rawPdo(0x186, 0, 4, 8000, ms(0)));  // steering straight
    // Raw counts climbing through 0x7FFFFFFF and 0xFFFFFFFF (the device counter wraps twice).
    const std::uint32_t raws[] = {0x7FFFFF00U, 0x7FFFFFFFU, 0x80000100U, 0xFFFFFF00U,
                                  0x00000100U, 0x00000000U, 0xFFFFFFF0U};
    std::int64_t expected = static_cast<std::int64_t>(0x7FFFFF00) * direction;  // first value = absolute position
    std::uint32_t prev = raws[0];
    for (std::size_t i = 0; i < sizeof raws / sizeof raws[0]; ++i) {
      if (i > 0) {
        // true travel = modular difference in the signed 32-bit sense
        expected += static_cast<std::int64_t>(static_cast<std::int32_t>(raws[i] - prev)) * direction;
        prev = raws[i];
      }
      REQUIRE(dec.onFrame(rawPdo(0x185, 0, 4, raws[i], ms(10 * static_cast<std::int64_t>(i)))) ==
              FrameKind::DrivePosition);
      agv::hal::EncoderSample s;
      REQUIRE(dec.takeSample(s));
      CHECK(s.driveTicks == expected);
      CHECK(s.stamp == ms(10 * static_cast<std::int64_t>(i)));
    }
    // 0x7FFFFF00 + 0xFF + 0x101 + 0x7FFFFE00 + 0x200 - 0x100 - 0x10: past 2^31 and 2^32 without a sign flip.
    CHECK(dec.driveTicks() == direction * std::int64_t{0xFFFFFFF0});
  }
}

TEST_CASE("Narrow PDO field at an offset: 16-bit counter unwrapped", "[drivers][canopen]") {
  auto cfg = baseConfig();
  cfg.drive.pdo = {0x285, 2, 2};  // TPDO2, bytes 2..3
  cfg.trigger = SampleTrigger::DriveUpdated;
  CanopenEncoders dec(cfg);
  REQUIRE(dec.validate() == Status::Ok);
  dec.onFrame(rawPdo(0x186, 0, 4, 8000, ms(0)));
  std::int64_t truth = 30000;
  for (int i = 0; i < 200; ++i) {  // 200 x +500 ticks crosses the 16-bit wrap (65536) once
    CHECK(dec.onFrame(rawPdo(0x285, 2, 2, static_cast<std::uint32_t>(truth & 0xFFFF), ms(i))) ==
          FrameKind::DrivePosition);
    truth += 500;
  }
  CHECK(dec.driveTicks() == truth - 500);
  // A PDO shorter than the mapping is refused.
  CanFrame shortPdo = rawPdo(0x285, 0, 2, 5, ms(300));
  CHECK(dec.onFrame(shortPdo) == FrameKind::Malformed);
  CHECK(dec.malformedFrames() == 1U);
}

TEST_CASE("Steering angle: scaling, direction, zero near the wrap of a single-turn encoder", "[drivers][canopen]") {
  for (std::int8_t direction : {std::int8_t{1}, std::int8_t{-1}}) {
    auto cfg = baseConfig();
    cfg.steering.direction = direction;
    CanopenEncoders dec(cfg);
    const double perCount = agv::kTwoPi<double> / 8192.0;
    // raw 8000 = straight; raw 100 = 292 counts left of zero across the wrap; raw 7000 = 1000 counts right.
    struct Case {
      std::uint32_t raw;
      std::int64_t counts;
    } cases[] = {{8000, 0}, {100, 292}, {7000, -1000}, {8191, 191}, {0, 192}};
    for (const auto& c : cases) {
      REQUIRE(dec.onFrame(rawPdo(0x186, 0, 4, c.raw, ms(1))) == FrameKind::SteeringPosition);
      AGV_CHECK_NEAR(dec.steeringAngle(), direction * c.counts * perCount, 1e-12);
    }
    // A value outside the revolution is malformed and leaves the angle alone.
    const double before = dec.steeringAngle();
    CHECK(dec.onFrame(rawPdo(0x186, 0, 4, 8192, ms(2))) == FrameKind::Malformed);
    CHECK(dec.steeringAngle() == before);
  }
}

TEST_CASE("Samples pair SYNC-driven PDOs; SYNC is produced on its period", "[drivers][canopen]") {
  auto cfg = baseConfig();
  cfg.syncPeriod = Duration::fromMilliseconds(10);
  cfg.heartbeatTimeout = Duration{};
  CanopenEncoders dec(cfg);
  CanFrame out[4];
  int syncs = 0;
  for (int t = 0; t <= 100; ++t) {  // 100 ms of 1 ms service calls
    const std::size_t n = dec.service(ms(t), Span<CanFrame>(out));
    for (std::size_t k = 0; k < n; ++k)
      syncs += out[k].id == 0x080U ? 1 : 0;
  }
  CHECK(syncs == 11);  // t = 0, 10, ..., 100
  // A late service call does not produce a burst.
  CHECK(dec.service(ms(500), Span<CanFrame>(out)) == 1U);
  CHECK(dec.service(ms(501), Span<CanFrame>(out)) == 0U);

  agv::hal::EncoderSample s;
  dec.onFrame(rawPdo(0x185, 0, 4, 1000, ms(600)));
  CHECK_FALSE(dec.takeSample(s));  // steering of this SYNC not there yet
  dec.onFrame(rawPdo(0x186, 0, 4, 8010, ms(601)));
  REQUIRE(dec.takeSample(s));
  CHECK(s.driveTicks == 1000);
  AGV_CHECK_NEAR(s.steeringAngle, 10 * agv::kTwoPi<double> / 8192.0, 1e-12);
  CHECK(s.stamp == ms(601));
  CHECK_FALSE(dec.takeSample(s));  // once
}

TEST_CASE("A lost TPDO drops its cycle: the next samples pair positions of the same cycle", "[drivers][canopen]") {
  const double perCount = agv::kTwoPi<double> / 8192.0;
  for (bool sync : {false, true}) {
    auto cfg = baseConfig();
    cfg.heartbeatTimeout = Duration{};
    cfg.syncPeriod = sync ? Duration::fromMilliseconds(10) : Duration{};
    CanopenEncoders dec(cfg);
    CanFrame out[4];
    int samples = 0;
    // Cycle i (10 ms apart): drive = 100 i ticks, steering = zero + i counts; the drive TPDO of
    // cycle 5 and the steering TPDO of cycle 9 are lost on the bus.
    for (int i = 0; i < 15; ++i) {
      dec.service(ms(10 * i), Span<CanFrame>(out));
      if (i != 5) {
        dec.onFrame(rawPdo(0x185, 0, 4, static_cast<std::uint32_t>(100 * i), ms(10 * i + 1)));
      }
      if (i != 9) {
        dec.onFrame(rawPdo(0x186, 0, 4, static_cast<std::uint32_t>(8000 + i), ms(10 * i + 2)));
      }
      agv::hal::EncoderSample s;
      const bool got = dec.takeSample(s);
      INFO("sync " << sync << ", cycle " << i);
      CHECK(got == (i != 5 && i != 9));
      if (got) {
        ++samples;
        CHECK(s.driveTicks == 100 * i);  // drive and steering of the same cycle, never a stale angle
        AGV_CHECK_NEAR(s.steeringAngle, i * perCount, 1e-12);
        CHECK(s.stamp == ms(10 * i + 2));
      }
    }
    CHECK(samples == 13);
    CHECK(dec.incompleteCycles() == 2U);
  }
}

TEST_CASE("Heartbeat supervision: timeout fault, recovery, boot-up restarts the node", "[drivers][canopen]") {
  auto cfg = baseConfig();
  cfg.heartbeatTimeout = Duration::fromMilliseconds(300);
  CanopenEncoders dec(cfg);
  CanFrame out[4];
  dec.service(ms(0), Span<CanFrame>(out));
  CHECK(dec.health() == Status::NotInitialized);
  dec.onFrame(encodeHeartbeat(5, NmtState::Operational, ms(100)));
  dec.onFrame(encodeHeartbeat(6, NmtState::Operational, ms(100)));
  dec.onFrame(rawPdo(0x185, 0, 4, 1, ms(100)));
  dec.onFrame(rawPdo(0x186, 0, 4, 8000, ms(100)));
  dec.service(ms(350), Span<CanFrame>(out));
  CHECK(dec.health() == Status::Ok);
  dec.onFrame(encodeHeartbeat(5, NmtState::Operational, ms(390)));
  dec.service(ms(401), Span<CanFrame>(out));  // node 6 silent since 100 ms
  CHECK(dec.health() == Status::Timeout);
  CHECK(dec.steeringHealth().heartbeatTimedOut);
  CHECK_FALSE(dec.driveHealth().heartbeatTimedOut);
  // Node 6 reboots: boot-up, then pre-operational; the decoder re-sends NMT start for it.
  dec.onFrame(encodeHeartbeat(6, NmtState::BootUp, ms(450)));
  const std::size_t n = dec.service(ms(451), Span<CanFrame>(out));
  REQUIRE(n == 1U);
  CHECK((out[0].id == 0U && out[0].data[0] == 0x01U && out[0].data[1] == 6U));
  CHECK(dec.steeringHealth().bootUps == 1U);
  CHECK(dec.health() == Status::DeviceFault);  // not operational yet
  dec.onFrame(encodeHeartbeat(6, NmtState::Operational, ms(460)));
  dec.onFrame(encodeHeartbeat(5, NmtState::Operational, ms(460)));
  dec.service(ms(470), Span<CanFrame>(out));
  CHECK(dec.health() == Status::Ok);
  // A node that never sends a heartbeat times out too.
  CanopenEncoders silent(cfg);
  silent.service(ms(0), Span<CanFrame>(out));
  silent.service(ms(301), Span<CanFrame>(out));
  CHECK(silent.health() == Status::Timeout);
}

TEST_CASE("EMCY frames are reported in order, a reset clears the fault, overflow is counted", "[drivers][canopen]") {
  auto cfg = baseConfig();
  cfg.heartbeatTimeout = Duration{};
  CanopenEncoders dec(cfg);
  dec.onFrame(rawPdo(0x185, 0, 4, 1, ms(1)));
  dec.onFrame(rawPdo(0x186, 0, 4, 8000, ms(1)));
  CHECK(dec.health() == Status::Ok);
  CHECK(dec.onFrame(encodeEmcy(5, 0x2310, 0x03, ms(2))) == FrameKind::Emcy);  // over-current
  CHECK(dec.health() == Status::DeviceFault);
  EmcyRecord r;
  REQUIRE(dec.takeEmcy(r));
  CHECK(r.nodeId == 5U);
  CHECK(r.errorCode == 0x2310U);
  CHECK(r.errorRegister == 0x03U);
  CHECK(r.stamp == ms(2));
  CHECK_FALSE(dec.takeEmcy(r));
  dec.onFrame(encodeEmcy(5, 0x0000, 0x00, ms(3)));  // error reset
  CHECK(dec.health() == Status::Ok);
  for (int i = 0; i < 12; ++i)
    dec.onFrame(encodeEmcy(6, static_cast<std::uint16_t>(0x1000 + i), 1, ms(4 + i)));
  int got = 0;
  while (dec.takeEmcy(r))
    ++got;
  CHECK(got == 8);  // the reset record + 7 of the 12; the newest 5 dropped and counted
  CHECK(dec.emcyDropped() == 5U);
  CHECK(dec.steeringHealth().emcyCount == 12U);
  CanFrame tooShort = encodeEmcy(6, 1, 1, ms(20));
  tooShort.dlc = 2;
  CHECK(dec.onFrame(tooShort) == FrameKind::Malformed);
}

TEST_CASE("Other frames are ignored: other ids, extended, remote, error frames", "[drivers][canopen]") {
  CanopenEncoders dec(baseConfig());
  CanFrame f = rawPdo(0x185, 0, 4, 42, ms(1));
  f.extended = true;
  CHECK(dec.onFrame(f) == FrameKind::Ignored);
  f.extended = false;
  f.rtr = true;
  CHECK(dec.onFrame(f) == FrameKind::Ignored);
  f.rtr = false;
  f.error = true;
  CHECK(dec.onFrame(f) == FrameKind::Ignored);
  CHECK(dec.onFrame(rawPdo(0x187, 0, 4, 42, ms(1))) == FrameKind::Ignored);
  CHECK(dec.onFrame(encodeHeartbeat(9, NmtState::Operational, ms(1))) == FrameKind::Ignored);
  CHECK(dec.driveHealth().pdoCount == 0U);
}

TEST_CASE("Bad configurations are refused", "[drivers][canopen]") {
  auto bad = [](auto edit) {
    auto c = baseConfig();
    edit(c);
    return CanopenEncoders(c).validate();
  };
  CHECK(bad([](CanopenEncodersConfig& c) { c.drive.nodeId = 0; }) == Status::InvalidArgument);
  CHECK(bad([](CanopenEncodersConfig& c) { c.steering.nodeId = 128; }) == Status::InvalidArgument);
  CHECK(bad([](CanopenEncodersConfig& c) { c.steering.nodeId = 5; }) == Status::InvalidArgument);
  CHECK(bad([](CanopenEncodersConfig& c) { c.drive.pdo.size = 5; }) == Status::InvalidArgument);
  CHECK(bad([](CanopenEncodersConfig& c) { c.drive.pdo.byteOffset = 6; }) == Status::InvalidArgument);
  CHECK(bad([](CanopenEncodersConfig& c) { c.steering.pdo.cobId = 0x185; }) == Status::InvalidArgument);
  CHECK(bad([](CanopenEncodersConfig& c) { c.drive.pdo.cobId = 0x706; }) == Status::InvalidArgument);
  CHECK(bad([](CanopenEncodersConfig& c) { c.drive.direction = 0; }) == Status::InvalidArgument);
  CHECK(bad([](CanopenEncodersConfig& c) { c.steering.radiansPerCount = 0.0; }) == Status::InvalidArgument);
  CHECK(bad([](CanopenEncodersConfig& c) { c.steering.radiansPerCount = std::nan(""); }) == Status::InvalidArgument);
  CHECK(bad([](CanopenEncodersConfig& c) { c.steering.zeroCount = 8192; }) == Status::InvalidArgument);
  CHECK(bad([](CanopenEncodersConfig& c) { c.steering.pdo.size = 1; }) == Status::InvalidArgument);  // 8192 > 256
}

TEST_CASE("Simulator frames decode back to the true motion across the 32-bit wrap, without allocation",
          "[drivers][canopen]") {
  auto cfg = baseConfig();
  cfg.drive.direction = -1;  // a drive mounted so that forward counts down
  cfg.steering.direction = -1;
  CanopenEncoders dec(cfg);
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> step(-5000, 250000);
  std::uniform_real_distribution<double> steer(-1.5, 1.5);
  std::int64_t truth = (std::int64_t{1} << 31) - 500000;  // 0x7FFFFFFF is crossed (and passed several times)
  const double perCount = cfg.steering.radiansPerCount;
  int samples = 0;
  AGV_CHECK_NO_ALLOCATIONS({
    for (int i = 0; i < 20000; ++i) {
      truth += step(rng);
      const double angle = steer(rng);
      const Timestamp t = ms(10 * i);
      dec.onFrame(encodeDrivePdo(cfg.drive, truth, t));
      dec.onFrame(encodeSteeringPdo(cfg.steering, angle, t));
      agv::hal::EncoderSample s;
      if (dec.takeSample(s)) {
        ++samples;
        const bool match = s.driveTicks == truth && std::fabs(s.steeringAngle - angle) <= 0.5 * perCount + 1e-12;
        if (!match) {  // the message only on failure: building it allocates on the host
          INFO("sample " << i << " ticks " << s.driveTicks << " vs " << truth);
          CHECK(match);
          break;
        }
      }
    }
  });
  CHECK(samples == 20000);
  CHECK(truth > (std::int64_t{1} << 32));  // really went past the unsigned wrap as well
}
