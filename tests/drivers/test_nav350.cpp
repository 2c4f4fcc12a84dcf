// NAV350 binary CoLa reply to mNPOSGetData: pose, reflectors and scan decoded into SI units from
// payloads built with the documented field layout; request encoding; bad payloads.
#include <cmath>
#include <vector>

#include "agv/core/angle.hpp"
#include "agv/drivers/protocol/sick/nav350.hpp"
#include "agv/drivers/protocol/sick/telegram_framer.hpp"
#include "agv_test.hpp"
#include "sick_telegrams.hpp"

using agv::Span;
using agv::Status;
using agv::Timestamp;
using namespace agv::drivers::sick;

namespace {
Status parse(const std::vector<std::uint8_t>& p, Nav350PoseReply& r, const Nav350Config& c = Nav350Config{}) {
  return parseNav350PoseReply(Span<const std::uint8_t>(p.data(), p.size()), c, Timestamp::fromSeconds(5.0), r);
}

/// Three reflectors seen from a vehicle at (12.345, -6.789, -10 deg), in device units.
agv::test::NavReplyFields scene() {
  agv::test::NavReplyFields f;
  f.xMm = 12345;
  f.yMm = -6789;
  f.phiMdeg = 350000;  // 350 deg = -10 deg
  f.usedReflectors = 3;
  const double world[3][2] = {{15.0, -4.0}, {10.0, -2.5}, {20.5, -9.0}};
  for (int i = 0; i < 3; ++i) {
    const double dx = world[i][0] - 12.345;
    const double dy = world[i][1] + 6.789;
    const double bearing = agv::normalizeAngle(std::atan2(dy, dx) - agv::deg2rad(-10.0));
    double deg = agv::rad2deg(bearing);
    if (deg < 0)
      deg += 360.0;
    agv::test::NavReflectorFields r;
    r.xMm = static_cast<std::int32_t>(std::lround(world[i][0] * 1000));
    r.yMm = static_cast<std::int32_t>(std::lround(world[i][1] * 1000));
    r.distMm = static_cast<std::uint32_t>(std::lround(std::hypot(dx, dy) * 1000));
    r.phiMdeg = static_cast<std::uint32_t>(std::lround(deg * 1000));
    r.localId = static_cast<std::uint16_t>(i);
    r.globalId = static_cast<std::uint16_t>(100 + i);
    r.quality = 90;
    f.reflectors.push_back(r);
  }
  return f;
}
}  // namespace

TEST_CASE("NAV350 request: payload and CoLa B framing", "[drivers][laser]") {
  std::uint8_t payload[32];
  const std::size_t n = encodeNav350PoseRequest(true, Nav350Mask::PoseReflectorsScan, Span<std::uint8_t>(payload));
  REQUIRE(n == 19U);
  CHECK(std::string(reinterpret_cast<const char*>(payload), 17) == "sMN mNPOSGetData ");
  CHECK(payload[17] == 1U);
  CHECK(payload[18] == 2U);
  std::uint8_t tel[40];
  const std::size_t m = encodeColaB(Span<const std::uint8_t>(payload, n), Span<std::uint8_t>(tel));
  const auto expected = agv::test::colaB(std::vector<std::uint8_t>(payload, payload + n));
  REQUIRE(m == expected.size());
  CHECK(std::vector<std::uint8_t>(tel, tel + m) == expected);
  std::uint8_t small[10];
  CHECK(encodeColaB(Span<const std::uint8_t>(payload, n), Span<std::uint8_t>(small)) == 0U);
}

TEST_CASE("NAV350 reply: pose, reflectors and details in SI units", "[drivers][laser]") {
  const auto f = scene();
  static Nav350PoseReply r;
  REQUIRE(parse(agv::test::buildNavReply(f), r) == Status::Ok);
  CHECK(r.errorCode == 0U);
  REQUIRE(r.poseValid);
  AGV_CHECK_NEAR(r.pose.x, 12.345, 1e-9);
  AGV_CHECK_NEAR(r.pose.y, -6.789, 1e-9);
  AGV_CHECK_NEAR(r.pose.theta, agv::deg2rad(-10.0), 1e-9);
  REQUIRE(r.poseDetailsValid);
  AGV_CHECK_NEAR(r.meanDeviation, 0.012, 1e-12);
  CHECK(r.usedReflectors == 3U);
  REQUIRE(r.landmarksValid);
  REQUIRE(r.reflectors.size() == 3U);
  for (std::size_t i = 0; i < 3; ++i) {
    const Nav350Reflector& x = r.reflectors[i];
    REQUIRE(x.hasCartesian);
    REQUIRE(x.hasPolar);
    REQUIRE(x.hasDetails);
    // Polar -> world through the decoded pose reproduces the cartesian position (mm and mdeg rounding).
    const double wx = r.pose.x + x.range * std::cos(r.pose.theta + x.bearing);
    const double wy = r.pose.y + x.range * std::sin(r.pose.theta + x.bearing);
    const double tol = 0.5e-3 + x.range * agv::deg2rad(0.5e-3) + 1e-6;
    AGV_CHECK_NEAR(wx, x.x, 2 * tol);
    AGV_CHECK_NEAR(wy, x.y, 2 * tol);
    CHECK(x.globalId == 100 + i);
    AGV_CHECK_NEAR(x.size, 0.08, 1e-12);
    CHECK(x.bearing > -agv::kPi<double>);
    CHECK(x.bearing <= agv::kPi<double>);
  }
  CHECK_FALSE(r.scanValid);
}

TEST_CASE("NAV350: the device's timestamps on the vehicle clock, across the clock's wrap", "[drivers][laser]") {
  static Nav350PoseReply r;
  const Timestamp received = Timestamp::fromSeconds(5.0);  // what parse() stamps
  auto f = scene();
  // Reflectors seen 40 and 60 ms apart during the turn, the pose 20 ms after the last of them.
  f.reflectors[0].timestampMs = 1000;
  f.reflectors[1].timestampMs = 1040;
  f.reflectors[2].timestampMs = 1100;
  f.poseTimestampMs = 1120;
  REQUIRE(parse(agv::test::buildNavReply(f), r) == Status::Ok);
  CHECK(r.receivedAt == received);
  REQUIRE(r.hasDeviceTime);
  CHECK(r.newestDeviceMs == 1120U);
  Timestamp t;
  const std::int64_t beforeMs[3] = {120, 80, 20};
  for (std::size_t i = 0; i < 3; ++i) {
    REQUIRE(nav350VehicleTime(r, r.reflectors[i].timestampMs, t));
    CHECK(t == received - agv::Duration::fromMilliseconds(beforeMs[i]));
  }
  // Not mappable, `out` unchanged: after the newest instant, more than kNav350MaxSpanMs before it.
  const Timestamp sentinel = Timestamp::fromSeconds(77.0);
  t = sentinel;
  CHECK_FALSE(nav350VehicleTime(r, 1121, t));
  CHECK_FALSE(nav350VehicleTime(r, 1120 - kNav350MaxSpanMs - 1, t));
  CHECK(t == sentinel);
  REQUIRE(nav350VehicleTime(r, 1120 - kNav350MaxSpanMs, t));
  CHECK(t == received - agv::Duration::fromMilliseconds(kNav350MaxSpanMs));

  // The device clock wraps (u32 ms, 49.7 days) in the middle of the turn; the scan channel's
  // instant is the newest here.
  f.reflectors[0].timestampMs = 0xFFFFFFFFU - 49U;  // 50 ms before the wrap
  f.reflectors[1].timestampMs = 0xFFFFFFFFU;
  f.reflectors[2].timestampMs = 10;
  f.poseTimestampMs = 0xFFFFFFF0U;
  f.scan = true;
  f.distMm.assign(1440, 5000U);
  f.scanTimestampMs = 25;
  REQUIRE(parse(agv::test::buildNavReply(f), r) == Status::Ok);
  CHECK(r.newestDeviceMs == 25U);
  const std::int64_t wrappedMs[3] = {75, 26, 15};
  for (std::size_t i = 0; i < 3; ++i) {
    REQUIRE(nav350VehicleTime(r, r.reflectors[i].timestampMs, t));
    CHECK(t == received - agv::Duration::fromMilliseconds(wrappedMs[i]));
  }
  REQUIRE(nav350VehicleTime(r, r.poseTimestampMs, t));
  CHECK(t == received - agv::Duration::fromMilliseconds(41));

  // A reply with no device instant (no pose, no reflectors, no scan) maps nothing, and does not
  // keep the previous reply's clock.
  agv::test::NavReplyFields bare;
  bare.pose = false;
  bare.landmarks = false;
  REQUIRE(parse(agv::test::buildNavReply(bare), r) == Status::Ok);
  CHECK_FALSE(r.hasDeviceTime);
  CHECK_FALSE(nav350VehicleTime(r, 25, t));
}

TEST_CASE("NAV350 reply with ANGL1 + DIST1 + RSSI1: the scan is the DIST1 channel", "[drivers][laser]") {
  auto f = scene();
  f.scan = true;
  f.angleChannel = true;
  f.remission = true;
  for (int i = 0; i < 1440; ++i) {
    f.distMm.push_back(i == 17 ? 0U : static_cast<std::uint32_t>(1000 + 3 * i));
  }
  static Nav350PoseReply r;
  Nav350Config cfg;
  cfg.angleOffset = -agv::kPi<double>;
  REQUIRE(parse(agv::test::buildNavReply(f), r, cfg) == Status::Ok);
  REQUIRE(r.scanValid);
  REQUIRE(r.scan.size() == 1440U);
  AGV_CHECK_NEAR(r.scan.angleIncrement, agv::deg2rad(0.25), 1e-7);
  AGV_CHECK_NEAR(agv::normalizeAngle(static_cast<double>(r.scan.angleMin) + agv::kPi<double>), 0.0, 1e-6);
  AGV_CHECK_NEAR(r.scan.ranges[100], 1.3, 1e-6);
  CHECK_FALSE(r.scan.isValid(17));
  CHECK(r.scan.stamp == Timestamp::fromSeconds(5.0));
  AGV_CHECK_NEAR(r.scan.fieldOfView(), 2 * agv::kPi<double>, 1e-5);
}

TEST_CASE("NAV350 reply without pose (device error) and header-only error replies", "[drivers][laser]") {
  agv::test::NavReplyFields f;
  f.errorCode = 4;  // no position available
  f.pose = false;
  f.landmarks = false;
  static Nav350PoseReply r;
  REQUIRE(parse(agv::test::buildNavReply(f), r) == Status::Ok);
  CHECK(r.errorCode == 4U);
  CHECK_FALSE(r.poseValid);
  auto p = agv::test::buildNavReply(f);
  p.resize(17 + 5);  // header only
  CHECK(parse(p, r) == Status::Ok);
  CHECK(r.errorCode == 4U);
}

TEST_CASE("NAV350: more reflectors than the capacity are refused and reported", "[drivers][laser]") {
  agv::test::NavReplyFields f;
  f.reflectors.resize(agv::kMaxReflectors + 5);
  static Nav350PoseReply r;
  CHECK(parse(agv::test::buildNavReply(f), r) == Status::CapacityExceeded);
  CHECK(r.reflectors.size() == agv::kMaxReflectors);
  CHECK(r.reflectors.refusedCount() == 5U);
  CHECK(r.reflectorCount == agv::kMaxReflectors + 5);
}

TEST_CASE("NAV350: every truncation and wrong content is refused without overrun", "[drivers][laser]") {
  auto f = scene();
  f.scan = true;
  f.remission = true;
  f.distMm.assign(50, 2000);
  const auto good = agv::test::buildNavReply(f);
  static Nav350PoseReply r;
  REQUIRE(parse(good, r) == Status::Ok);
  for (std::size_t len = 0; len < good.size(); ++len) {
    std::vector<std::uint8_t> cut(good.begin(), good.begin() + static_cast<std::ptrdiff_t>(len));
    const Status s = parse(cut, r);
    INFO("length " << len);
    CHECK((s == Status::Truncated || s == Status::Malformed));
    CHECK_FALSE(r.poseValid);
  }
  auto bad = good;
  bad[1] = 'X';  // "sXN"
  CHECK(parse(bad, r) == Status::Malformed);
  // Wrong channel name.
  auto f2 = f;
  auto p2 = agv::test::buildNavReply(f2);
  const std::string needle = "DIST1";
  auto it = std::search(p2.begin(), p2.end(), needle.begin(), needle.end());
  REQUIRE(it != p2.end());
  *(it + 4) = '7';
  CHECK(parse(p2, r) == Status::Malformed);
}

TEST_CASE("NAV350: framed reply through the framer, decoded without allocation", "[drivers][laser]") {
  auto f = scene();
  f.scan = true;
  f.distMm.assign(1440, 4321);
  const auto tel = agv::test::colaB(agv::test::buildNavReply(f));
  static TelegramFramer framer(Framing::ColaB);
  static Nav350PoseReply r;
  Status s = Status::NotInitialized;
  AGV_CHECK_NO_ALLOCATIONS({
    std::size_t pos = 0;
    while (pos < tel.size()) {
      pos += framer.feed(Span<const std::uint8_t>(tel.data() + pos, std::min<std::size_t>(333, tel.size() - pos)));
      Span<const std::uint8_t> t;
      while (framer.next(t)) {
        s = parseNav350PoseReply(t, Nav350Config{}, Timestamp{}, r);
      }
    }
  });
  CHECK(s == Status::Ok);
  CHECK(r.scan.size() == 1440U);
}

TEST_CASE("Simulator encoding: encodeNav350PoseReply round-trips through CoLa B and the decoder", "[drivers][laser]") {
  static Nav350PoseReply truth;
  truth.version = 1;
  truth.mask = 2;
  truth.poseValid = true;
  truth.pose = agv::Pose2d(-12.3456, 7.891, -2.9);
  truth.poseDetailsValid = true;
  truth.meanDeviation = 0.015;
  truth.usedReflectors = 4;
  truth.landmarksValid = true;
  for (int i = 0; i < 5; ++i) {
    Nav350Reflector f;
    f.hasCartesian = true;
    f.x = 3.0 * i - 4.0;
    f.y = -1.5 * i;
    f.hasPolar = true;
    f.range = 2.0 + i;
    f.bearing = -3.0 + 1.4 * i;
    f.hasDetails = i % 2 == 0;
    f.globalId = static_cast<std::uint16_t>(10 + i);
    f.size = 0.08;
    REQUIRE(truth.reflectors.push_back(f) == Status::Ok);
  }
  truth.scanValid = true;
  Nav350Config cfg;
  cfg.angleOffset = -agv::kPi<double>;
  truth.scan.angleMin = static_cast<float>(-agv::kPi<double>);
  truth.scan.angleIncrement = static_cast<float>(agv::deg2rad(0.25));
  truth.scan.rangeMin = cfg.rangeMin;
  truth.scan.rangeMax = cfg.rangeMax;
  for (int i = 0; i < 1440; ++i)
    REQUIRE(truth.scan.ranges.push_back(1.0F + 0.01F * static_cast<float>(i % 300)) == Status::Ok);

  static std::uint8_t payload[16384];
  static std::uint8_t telegram[16384 + 9];
  const std::size_t n = encodeNav350PoseReply(truth, cfg, Span<std::uint8_t>(payload));
  REQUIRE(n > 0U);
  const std::size_t m = encodeColaB(Span<const std::uint8_t>(payload, n), Span<std::uint8_t>(telegram));
  REQUIRE(m == n + 9);
  static TelegramFramer framer(Framing::ColaB);
  REQUIRE(framer.feed(Span<const std::uint8_t>(telegram, m)) == m);
  Span<const std::uint8_t> t;
  REQUIRE(framer.next(t));
  static Nav350PoseReply back;
  REQUIRE(parseNav350PoseReply(t, cfg, Timestamp{}, back) == Status::Ok);
  REQUIRE(back.poseValid);
  AGV_CHECK_NEAR(back.pose.x, truth.pose.x, 0.5e-3 + 1e-9);
  AGV_CHECK_NEAR(back.pose.y, truth.pose.y, 0.5e-3 + 1e-9);
  AGV_CHECK_NEAR(agv::angleDiff(back.pose.theta, truth.pose.theta), 0.0, agv::deg2rad(0.5e-3) + 1e-9);
  AGV_CHECK_NEAR(back.meanDeviation, 0.015, 1e-9);
  REQUIRE(back.reflectors.size() == 5U);
  for (std::size_t i = 0; i < 5; ++i) {
    AGV_CHECK_NEAR(back.reflectors[i].x, truth.reflectors[i].x, 0.5e-3 + 1e-9);
    AGV_CHECK_NEAR(back.reflectors[i].range, truth.reflectors[i].range, 0.5e-3 + 1e-9);
    AGV_CHECK_NEAR(agv::angleDiff(back.reflectors[i].bearing, truth.reflectors[i].bearing), 0.0,
                   agv::deg2rad(0.5e-3) + 1e-9);
    CHECK(back.reflectors[i].hasDetails == truth.reflectors[i].hasDetails);
  }
  REQUIRE(back.scanValid);
  REQUIRE(back.scan.size() == 1440U);
  AGV_CHECK_NEAR(agv::angleDiff(static_cast<double>(back.scan.angleMin), static_cast<double>(truth.scan.angleMin)), 0.0,
                 1e-6);
  for (std::size_t i = 0; i < 1440; ++i)
    AGV_CHECK_NEAR(back.scan.ranges[i], truth.scan.ranges[i], 0.5e-3 + 1e-6);
  static std::uint8_t small[64];
  CHECK(encodeNav350PoseReply(truth, cfg, Span<std::uint8_t>(small)) == 0U);
}

TEST_CASE("NAV350: implausible scan channel headers are refused as OutOfRange and leave nothing valid",
          "[drivers][laser]") {
  static Nav350PoseReply r;
  for (int k = 0; k < 4; ++k) {
    agv::test::NavReplyFields f;
    f.scan = true;
    f.distMm.assign(1440, 5000);  // 0.25 deg x 1440: one turn
    const char* what = "scale 3.4e38";
    if (k == 0) {
      f.scale = 3.4e38F;
    } else if (k == 1) {
      f.offset = 1e30F;
      what = "offset 1e30 mm";
    } else if (k == 2) {
      f.stepMdeg = 65535;
      what = "step 65.535 deg";
    } else {
      f.stepMdeg = 500;
      what = "0.5 deg x 1440 beams: two turns";
    }
    INFO(what);
    CHECK(parse(agv::test::buildNavReply(f), r) == Status::OutOfRange);
    CHECK_FALSE(r.scanValid);
    CHECK_FALSE(r.poseValid);
    CHECK(r.scan.size() == 0U);
  }
  agv::test::NavReplyFields f;
  f.scan = true;
  f.distMm.assign(1440, 5000);
  CHECK(parse(agv::test::buildNavReply(f), r) == Status::Ok);
  CHECK(r.scan.size() == 1440U);
}
