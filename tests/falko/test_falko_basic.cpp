// FALKO detector and descriptors: light tests (also run on the Cortex-M7 image).
#include <cmath>
#include <limits>

#include "agv/falko/falko_descriptors.hpp"
#include "agv/falko/falko_detector.hpp"
#include "agv_test.hpp"
#include "falko_test_util.hpp"
#include "room_sim.hpp"

using agv::FalkoDetector;
using agv::FalkoKeypoints;
using agv::LaserScan;
using agv::Status;
namespace t = agv::test;

namespace {
constexpr float kDeg = 0.017453292519943295F;
const t::SensorPose kPose{3.5, 2.5, 0.3};

// Big objects live in static storage (64 KiB stack on the MCU).
FalkoDetector& detector() {
  static FalkoDetector d;
  return d;
}
LaserScan& scanA() {
  static LaserScan s;
  return s;
}
FalkoKeypoints& keypoints() {
  static FalkoKeypoints k;
  return k;
}
}  // namespace

TEST_CASE("falko: noise-free 360 deg room, keypoints at the true corners within 1 cm", "[falko]") {
  const t::World w = t::testRoom();
  LaserScan& scan = scanA();
  t::simulateScan(w, kPose, -180.0F * kDeg, 1.0F * kDeg, 360, 0.0, 1U, scan);
  FalkoKeypoints& kps = keypoints();
  REQUIRE(detector().detect(scan, kps) == Status::Ok);
  std::array<t::P2, 16> expected{};
  const std::size_t n = t::expectedCorners(w, kPose, -4.0, 4.0, 0.3, 0.0, expected);
  CHECK(n == 6U);  // 5 room corners + the pillar corner facing the sensor
  CHECK(kps.size() == n);
  CHECK(t::worstMiss(kps, expected, n) <= 0.01);
  CHECK(t::worstSpurious(kps, expected, n) <= 0.01);
  for (const auto& kp : kps) {
    CHECK(kp.refined);
  }
}

TEST_CASE("falko: parameter check, and the reference implementation's defaults", "[falko]") {
  CHECK(agv::isValid(agv::FalkoParams{}));
  const agv::FalkoParams ref = agv::falkoReferenceParams();
  CHECK(agv::isValid(ref));
  CHECK(ref.neighA == 0.1F);
  CHECK(ref.beta == 2.5F);
  CHECK(ref.nmsRadius == 0.1F);
  CHECK(ref.neighB == agv::FalkoParams{}.neighB);  // the rest stays at the thesis defaults
  CHECK(ref.gridSectors == agv::FalkoParams{}.gridSectors);
  // Each field out of its domain is refused on its own.
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  auto refused = [](void (*edit)(agv::FalkoParams&)) {
    agv::FalkoParams p;
    edit(p);
    return !agv::isValid(p);
  };
  CHECK(refused([](agv::FalkoParams& p) { p.neighA = 0.0F; }));
  CHECK(refused([](agv::FalkoParams& p) { p.neighA = std::numeric_limits<float>::quiet_NaN(); }));
  CHECK(refused([](agv::FalkoParams& p) { p.neighB = -0.01F; }));
  CHECK(refused([](agv::FalkoParams& p) { p.beta = 0.0F; }));
  CHECK(refused([](agv::FalkoParams& p) { p.beta = std::numeric_limits<float>::infinity(); }));
  CHECK(refused([](agv::FalkoParams& p) { p.minSidePoints = 0; }));
  CHECK(refused([](agv::FalkoParams& p) { p.gridSectors = 3; }));
  CHECK(refused([](agv::FalkoParams& p) { p.gridSectors = 65; }));
  CHECK(refused([](agv::FalkoParams& p) { p.maxScore = -1.0F; }));
  CHECK(refused([](agv::FalkoParams& p) { p.nmsRadius = -0.1F; }));
  CHECK(refused([](agv::FalkoParams& p) { p.refineRadiusFactor = 0.5F; }));
  CHECK(refused([](agv::FalkoParams& p) { p.refineInlierDistance = 0.0F; }));
  CHECK(refused([](agv::FalkoParams& p) { p.maxRadiusRangeRatio = 1.0F; }));
  CHECK(refused([](agv::FalkoParams& p) { p.maxExtractionRange = std::numeric_limits<float>::quiet_NaN(); }));
  agv::FalkoParams p;
  p.maxExtractionRange = inf;  // no upper limit is a valid choice
  CHECK(agv::isValid(p));
  p.subbeamMaxShift = nan;
  CHECK_FALSE(agv::isValid(p));
  // The detector refuses exactly what isValid refuses.
  static FalkoDetector refusing(p);
  LaserScan& scan = scanA();
  t::simulateScan(t::testRoom(), kPose, -180.0F * kDeg, 1.0F * kDeg, 360, 0.0, 1U, scan);
  CHECK(refusing.detect(scan, keypoints()) == Status::InvalidArgument);
  // With the reference's parameters the noise-free room gives the same six corners. Their
  // neighbourhood (a = 0.1 m) holds few points on a coarse scan: in this room no corner is found
  // at 1 deg and two are missed at 0.5 deg, so this part scans at 0.25 deg.
  static FalkoDetector withRef(ref);
  t::simulateScan(t::testRoom(), kPose, -180.0F * kDeg, 0.25F * kDeg, 1440, 0.0, 1U, scan);
  REQUIRE(withRef.detect(scan, keypoints()) == Status::Ok);
  std::array<t::P2, 16> expected{};
  const std::size_t n = t::expectedCorners(t::testRoom(), kPose, -4.0, 4.0, 0.3, 0.0, expected);
  CHECK(keypoints().size() == n);
  CHECK(t::worstMiss(keypoints(), expected, n) <= 0.01);
  CHECK(t::worstSpurious(keypoints(), expected, n) <= 0.01);
}

TEST_CASE("falko: a straight wall gives no keypoint", "[falko]") {
  const t::World w = t::straightWall();
  LaserScan& scan = scanA();
  t::simulateScan(w, t::SensorPose{0.0, 0.0, 0.0}, -180.0F * kDeg, 1.0F * kDeg, 360, 0.0, 1U, scan);
  FalkoKeypoints& kps = keypoints();
  REQUIRE(detector().detect(scan, kps) == Status::Ok);
  CHECK(kps.empty());
  t::simulateScan(w, t::SensorPose{0.0, 0.0, 0.0}, -180.0F * kDeg, 1.0F * kDeg, 360, 0.01, 7U, scan);
  REQUIRE(detector().detect(scan, kps) == Status::Ok);
  CHECK(kps.empty());
}

TEST_CASE("falko: empty, all-invalid and NaN/inf/zero scans give no keypoints", "[falko]") {
  LaserScan& scan = scanA();
  scan.angleMin = -1.5F;
  scan.angleIncrement = 0.01F;
  scan.rangeMin = 0.1F;
  scan.rangeMax = 50.0F;
  scan.ranges.clear();
  FalkoKeypoints& kps = keypoints();
  CHECK(detector().detect(scan, kps) == Status::Ok);
  CHECK(kps.empty());
  const float bad[] = {std::numeric_limits<float>::quiet_NaN(),
                       std::numeric_limits<float>::infinity(),
                       -std::numeric_limits<float>::infinity(),
                       0.0F,
                       -1.0F,
                       0.05F,
                       50.0F,
                       81.83F};
  for (std::size_t i = 0; i < 300; ++i) {
    (void)scan.ranges.push_back(bad[i % 8]);
  }
  CHECK(detector().detect(scan, kps) == Status::Ok);
  CHECK(kps.empty());
  CHECK(detector().points().validCount() == 0U);
}

TEST_CASE("falko: invalid readings in a room are never used as points", "[falko]") {
  const t::World w = t::testRoom();
  LaserScan& scan = scanA();
  t::simulateScan(w, kPose, -180.0F * kDeg, 0.5F * kDeg, 720, 0.0, 1U, scan);
  // Every 5th reading spoiled: NaN, inf, zero, the "no return" value, below range_min.
  const float bad[] = {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(), 0.0F, 81.91F,
                       0.01F};
  for (std::size_t i = 0; i < scan.size(); i += 5) {
    scan.ranges[i] = bad[(i / 5) % 5];
  }
  scan.rangeMax = 50.0F;
  FalkoKeypoints& kps = keypoints();
  REQUIRE(detector().detect(scan, kps) == Status::Ok);
  std::array<t::P2, 16> expected{};
  const std::size_t n = t::expectedCorners(w, kPose, -4.0, 4.0, 0.3, 0.0, expected);
  CHECK(t::worstMiss(kps, expected, n) <= 0.01);
  CHECK(t::worstSpurious(kps, expected, n) <= 0.01);
  for (const auto& kp : kps) {
    CHECK(std::isfinite(kp.x));
    CHECK(std::isfinite(kp.orientation));
  }
}

TEST_CASE("falko: keypoint capacity overflow is reported and counted", "[falko]") {
  const t::World w = t::testRoom();
  LaserScan& scan = scanA();
  t::simulateScan(w, kPose, -180.0F * kDeg, 1.0F * kDeg, 360, 0.0, 1U, scan);
  agv::FixedVector<agv::FalkoKeypoint, 2> small;
  CHECK(detector().detect(scan, small) == Status::CapacityExceeded);
  CHECK(small.size() == 2U);
  CHECK(small.refusedCount() == 4U);  // 6 corners found, 2 kept
  static agv::BscDescriptors bsc;
  agv::FixedVector<agv::CghDescriptor, 1> cgh;
  const agv::FalkoDescriber describer;
  CHECK(describer.describe(detector().points(), small, bsc, cgh) == Status::CapacityExceeded);
  CHECK(bsc.size() == 2U);
  CHECK(cgh.refusedCount() == 1U);
}

TEST_CASE("falko: bad geometry and parameters are refused", "[falko]") {
  LaserScan& scan = scanA();
  scan.angleMin = 0.0F;
  scan.angleIncrement = 0.0F;
  scan.rangeMin = 0.1F;
  scan.rangeMax = 50.0F;
  scan.ranges.clear();
  (void)scan.ranges.push_back(1.0F);
  FalkoKeypoints& kps = keypoints();
  CHECK(detector().detect(scan, kps) == Status::InvalidArgument);
  scan.angleIncrement = std::numeric_limits<float>::quiet_NaN();
  CHECK(detector().detect(scan, kps) == Status::InvalidArgument);
  agv::FalkoParams p;
  p.gridSectors = 2;
  static FalkoDetector bad(p);
  scan.angleIncrement = 0.01F;
  CHECK(bad.detect(scan, kps) == Status::InvalidArgument);
  agv::FalkoDescriptorParams dp;
  dp.radius = -1.0F;
  const agv::FalkoDescriber badDescriber(dp);
  agv::BscDescriptor b;
  agv::CghDescriptor g;
  CHECK(badDescriber.describe(detector().points(), agv::FalkoKeypoint{}, b, g) == Status::InvalidArgument);
}

TEST_CASE("falko: descriptor distances", "[falko]") {
  agv::BscDescriptor a;
  agv::BscDescriptor b;
  a.rings[0] = 0x00FFU;
  b.rings[0] = 0x0F0FU;
  b.rings[7] = 0x8000U;
  CHECK(agv::bscDistance(a, a) == 0U);
  CHECK(agv::bscDistance(a, b) == 9U);
  agv::CghDescriptor h1;
  agv::CghDescriptor h2;
  h1.bins[0] = 1.0F;
  h2.bins[1] = 1.0F;
  AGV_CHECK_NEAR(agv::cghDistance(h1, h1), 0.0, 1e-7);
  AGV_CHECK_NEAR(agv::cghDistance(h1, h2), 1.0, 1e-6);
}

TEST_CASE("falko: detect + describe allocate nothing", "[falko]") {
  const t::World w = t::testRoom();
  LaserScan& scan = scanA();
  t::simulateScan(w, kPose, -180.0F * kDeg, 1.0F * kDeg, 360, 0.01, 3U, scan);
  FalkoKeypoints& kps = keypoints();
  static agv::BscDescriptors bsc;
  static agv::CghDescriptors cgh;
  static const agv::FalkoDescriber describer;
  Status s1 = Status::InvalidArgument;
  Status s2 = Status::InvalidArgument;
  AGV_CHECK_NO_ALLOCATIONS(s1 = detector().detect(scan, kps);
                           s2 = describer.describe(detector().points(), kps, bsc, cgh));
  CHECK(s1 == Status::Ok);
  CHECK(s2 == Status::Ok);
  CHECK(bsc.size() == kps.size());
  CHECK(!kps.empty());
}
