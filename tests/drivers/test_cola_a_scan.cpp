// CoLa A LMDscandata decoding against telegrams built from the documented field layout, with the
// ranges of a known room (ground truth) quantised as the device would.
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "agv/core/angle.hpp"
#include "agv/drivers/protocol/sick/cola_a_scan.hpp"
#include "agv_test.hpp"
#include "sick_telegrams.hpp"

using agv::LaserScan;
using agv::Span;
using agv::Status;
using agv::Timestamp;
using agv::drivers::sick::ColaAScanConfig;
using agv::drivers::sick::ColaAScanInfo;
using agv::drivers::sick::parseColaAScan;

namespace {
/// Range [m] from the sensor at (sx, sy) along sensor-frame angle a inside the box [-4,4]x[-3,3].
double roomRange(double a, double sx = 1.0, double sy = 0.5) {
  const double c = std::cos(a);
  const double s = std::sin(a);
  double best = std::numeric_limits<double>::infinity();
  if (c > 1e-12)
    best = std::min(best, (4.0 - sx) / c);
  if (c < -1e-12)
    best = std::min(best, (-4.0 - sx) / c);
  if (s > 1e-12)
    best = std::min(best, (3.0 - sy) / s);
  if (s < -1e-12)
    best = std::min(best, (-3.0 - sy) / s);
  return best;
}

/// Device values of the room for a channel: raw = (mm - offset) / scale, rounded.
agv::test::ColaChannel roomChannel(std::int32_t start, std::uint16_t step, int n, float scale, float offset) {
  agv::test::ColaChannel c;
  c.scale = scale;
  c.offset = offset;
  c.startAngle = start;
  c.step = step;
  for (int i = 0; i < n; ++i) {
    const double deviceDeg = (start + static_cast<double>(i) * step) * 1e-4;
    const double a = agv::deg2rad(deviceDeg - 90.0);
    const double mm = roomRange(a) * 1000.0;
    c.values.push_back(static_cast<std::uint32_t>(std::lround((mm - offset) / scale)));
  }
  return c;
}

Status parse(const std::string& text, LaserScan& scan, ColaAScanInfo* info = nullptr, Timestamp at = Timestamp{}) {
  const auto* p = reinterpret_cast<const std::uint8_t*>(text.data());
  return parseColaAScan(Span<const std::uint8_t>(p, text.size()), ColaAScanConfig{}, at, scan, info);
}
}  // namespace

TEST_CASE("LMS1xx scan: angles, ranges in metres, header fields, time stamp", "[drivers][laser]") {
  agv::test::ColaScanFields f;
  f.channels16.push_back(roomChannel(-450000, 5000, 541, 1.0F, 0.0F));
  static LaserScan scan;
  ColaAScanInfo info;
  const Timestamp at = Timestamp::fromSeconds(100.0);
  REQUIRE(parse(agv::test::buildColaScan(f), scan, &info, at) == Status::Ok);
  REQUIRE(scan.size() == 541U);
  AGV_CHECK_NEAR(scan.angleMin, agv::deg2rad(-135.0), 1e-6);
  AGV_CHECK_NEAR(scan.angleIncrement, agv::deg2rad(0.5), 1e-7);
  for (std::size_t i = 0; i < scan.size(); ++i) {
    INFO("beam " << i);
    REQUIRE(scan.isValid(i));
    AGV_CHECK_NEAR(scan.ranges[i], roomRange(static_cast<double>(scan.angle(i))), 0.5e-3 + 1e-5);
  }
  CHECK(info.serialNumber == 0x89A27FU);
  CHECK(info.telegramCounter == 0x343U);
  CHECK(info.scanCounter == 0x347U);
  AGV_CHECK_NEAR(info.scanFrequency, 50.0, 1e-9);
  // 3 ms between scan and transmission on the device clock is taken off the receive time.
  CHECK(scan.stamp.ns == at.ns - 3000000);
  // 270 deg of a 20 ms revolution.
  AGV_CHECK_NEAR(scan.sweepDuration.seconds(), 0.02 * 270.0 / 360.0, 1e-9);
}

TEST_CASE("LMS5xx scan: scale factor 2 and offset always applied; DIST1 found in the 8-bit list", "[drivers][laser]") {
  agv::test::ColaScanFields f;
  f.encoders.push_back({0x1234, 0x10});
  agv::test::ColaChannel rssi = roomChannel(-50000, 1667, 571, 1.0F, 0.0F);
  rssi.name = "RSSI1";
  f.channels16.push_back(rssi);
  f.channels8.push_back(roomChannel(-50000, 1667, 571, 2.0F, 7.0F));
  static LaserScan scan;
  REQUIRE(parse(agv::test::buildColaScan(f), scan) == Status::Ok);
  REQUIRE(scan.size() == 571U);
  for (std::size_t i = 0; i < scan.size(); ++i) {
    AGV_CHECK_NEAR(scan.ranges[i], roomRange(static_cast<double>(scan.angle(i))), 1.0e-3 + 1e-5);  // half of 2 mm
  }
}

TEST_CASE("No-echo readings become invalid, others stay", "[drivers][laser]") {
  agv::test::ColaScanFields f;
  agv::test::ColaChannel c = roomChannel(-450000, 5000, 20, 1.0F, 0.0F);
  c.values[3] = 0;
  c.values[7] = 0;
  f.channels16.push_back(c);
  static LaserScan scan;
  ColaAScanInfo info;
  REQUIRE(parse(agv::test::buildColaScan(f), scan, &info) == Status::Ok);
  CHECK_FALSE(scan.isValid(3));
  CHECK_FALSE(scan.isValid(7));
  CHECK(scan.isValid(4));
  CHECK(info.noReturnBeams == 2U);
}

TEST_CASE("More beams than the capacity: the first are kept, the rest refused and reported", "[drivers][laser]") {
  agv::test::ColaScanFields f;
  const int n = static_cast<int>(agv::kMaxScanBeams) + 100;
  f.channels16.push_back(roomChannel(0, 1000, n, 1.0F, 0.0F));
  static LaserScan scan;
  CHECK(parse(agv::test::buildColaScan(f), scan) == Status::CapacityExceeded);
  CHECK(scan.size() == agv::kMaxScanBeams);
  CHECK(scan.ranges.refusedCount() == 100U);
}

TEST_CASE("Bad telegrams are refused with a reason and leave no data", "[drivers][laser]") {
  agv::test::ColaScanFields f;
  f.channels16.push_back(roomChannel(-450000, 5000, 30, 1.0F, 0.0F));
  const std::string good = agv::test::buildColaScan(f);
  static LaserScan scan;

  CHECK(parse("sRA LMDscandatX 1", scan) == Status::Malformed);
  CHECK(parse("sEA LMDscandata 1", scan) == Status::Malformed);
  CHECK(parse("", scan) == Status::Truncated);
  std::string bad = good;
  bad[bad.find(" 343 ") + 2] = 'G';
  CHECK(parse(bad, scan) == Status::Malformed);
  CHECK(scan.size() == 0U);

  agv::test::ColaScanFields g = f;
  g.channels16[0].name = "DIST2";
  CHECK(parse(agv::test::buildColaScan(g), scan) == Status::Malformed);  // no DIST1
  g = f;
  g.channels16[0].scale = 0.0F;
  CHECK(parse(agv::test::buildColaScan(g), scan) == Status::Malformed);
  g.channels16[0].scale = std::numeric_limits<float>::quiet_NaN();
  CHECK(parse(agv::test::buildColaScan(g), scan) == Status::Malformed);
  g = f;
  g.channels16[0].step = 0;
  CHECK(parse(agv::test::buildColaScan(g), scan) == Status::Malformed);

  // Every prefix of a good telegram is refused without reading past it (ASan would tell).
  const std::size_t payloadEnd = good.find(" 0 0 0 0 0");
  for (std::size_t len = 0; len < payloadEnd; ++len) {
    std::vector<std::uint8_t> prefix(good.begin(), good.begin() + static_cast<std::ptrdiff_t>(len));
    const Status s =
        parseColaAScan(Span<const std::uint8_t>(prefix.data(), prefix.size()), ColaAScanConfig{}, Timestamp{}, scan);
    // A cut inside the last value still forms a valid hex number: only the full length may pass.
    if (s == Status::Ok) {
      CHECK(len > good.rfind(' ', payloadEnd - 1));
    } else {
      CHECK((s == Status::Truncated || s == Status::Malformed));
    }
  }
}

TEST_CASE("Decoding a scan does not allocate", "[drivers][laser]") {
  agv::test::ColaScanFields f;
  f.channels16.push_back(roomChannel(-450000, 5000, 541, 1.0F, 0.0F));
  const std::string text = agv::test::buildColaScan(f);
  static LaserScan scan;
  Status s = Status::NotInitialized;
  AGV_CHECK_NO_ALLOCATIONS(s = parse(text, scan));
  CHECK(s == Status::Ok);
}

TEST_CASE("Simulator encoding: encodeColaAScan round-trips through the framer and the decoder", "[drivers][laser]") {
  static LaserScan truth;
  truth.angleMin = static_cast<float>(agv::deg2rad(-135.0));
  truth.angleIncrement = static_cast<float>(agv::deg2rad(0.25));
  truth.rangeMin = 0.05F;
  truth.rangeMax = 80.0F;
  for (int i = 0; i < 1081; ++i) {
    const double r = roomRange(static_cast<double>(truth.angle(static_cast<std::size_t>(i))));
    REQUIRE(truth.ranges.push_back(i == 500 ? std::numeric_limits<float>::infinity() : static_cast<float>(r)) ==
            Status::Ok);
  }
  for (float scale : {1.0F, 2.0F}) {
    agv::drivers::sick::ColaAScanEncodeParams p;
    p.scaleFactor = scale;
    p.scanCounter = 77;
    static std::uint8_t buf[16384];
    const std::size_t n = agv::drivers::sick::encodeColaAScan(truth, p, Span<std::uint8_t>(buf));
    REQUIRE(n > 0U);
    REQUIRE(buf[0] == 0x02);
    REQUIRE(buf[n - 1] == 0x03);
    static LaserScan back;
    ColaAScanInfo info;
    REQUIRE(parseColaAScan(Span<const std::uint8_t>(buf + 1, n - 2), ColaAScanConfig{}, Timestamp{}, back, &info) ==
            Status::Ok);
    CHECK(info.scanCounter == 77U);
    REQUIRE(back.size() == truth.size());
    AGV_CHECK_NEAR(back.angleMin, truth.angleMin, 1e-6);
    AGV_CHECK_NEAR(back.angleIncrement, truth.angleIncrement, 1e-7);
    for (std::size_t i = 0; i < back.size(); ++i) {
      if (i == 500) {
        CHECK_FALSE(back.isValid(i));
        continue;
      }
      AGV_CHECK_NEAR(back.ranges[i], truth.ranges[i], 0.5e-3 * scale + 1e-5);
    }
    static std::uint8_t small[100];
    CHECK(agv::drivers::sick::encodeColaAScan(truth, p, Span<std::uint8_t>(small)) == 0U);
  }
}

TEST_CASE("Implausible channel headers are refused as OutOfRange and leave no data", "[drivers][laser]") {
  static LaserScan scan;
  struct Bad {
    const char* what;
    std::int32_t start;
    std::uint16_t step;
    int beams;
    float scale;
    float offset;
  };
  const Bad bad[] = {
      {"scale 3.4e38", -450000, 5000, 541, 3.4e38F, 0.0F},
      {"scale 1e-6", -450000, 5000, 541, 1e-6F, 0.0F},
      {"offset 1e30 mm", -450000, 5000, 541, 1.0F, 1e30F},
      {"offset -20 m", -450000, 5000, 541, 1.0F, -20000.0F},
      {"step 65535 (6.5535 deg)", -450000, 65535, 541, 1.0F, 0.0F},
      {"0.5 deg x 1000 beams: 499.5 deg", -450000, 5000, 1000, 1.0F, 0.0F},
      {"start 214748 deg", 0x7FFFFFFF, 5000, 541, 1.0F, 0.0F},
  };
  for (const Bad& b : bad) {
    INFO(b.what);
    agv::test::ColaScanFields f;
    agv::test::ColaChannel c = roomChannel(b.start, b.step, b.beams, 1.0F, 0.0F);
    c.scale = b.scale;
    c.offset = b.offset;
    f.channels16.push_back(c);
    CHECK(parse(agv::test::buildColaScan(f), scan) == Status::OutOfRange);
    CHECK(scan.size() == 0U);
  }
  // The edges of what devices send stay accepted: scale 2, one full turn in 1 deg steps.
  agv::test::ColaScanFields f;
  f.channels16.push_back(roomChannel(-1800000, 10000, 361, 2.0F, 0.0F));
  CHECK(parse(agv::test::buildColaScan(f), scan) == Status::Ok);
  CHECK(scan.size() == 361U);
}
