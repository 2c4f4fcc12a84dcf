// FALKO on simulated rooms: accuracy under noise, invariance to scan rotation and resolution,
// 360 deg wrap-around, descriptor distinctiveness (host only: uses Catch2 sections and loops over
// many scans).
#include <cmath>
#include <cstdint>
#include <memory>

#include "agv/core/angle.hpp"
#include "agv/falko/falko_descriptors.hpp"
#include "agv/falko/falko_detector.hpp"
#include "agv/falko/scan_points.hpp"
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
constexpr double kPi = 3.141592653589793;
}  // namespace

TEST_CASE("falko geometry: 1 cm range noise keeps keypoints within 3 cm of the corners", "[falko]") {
  const t::World w = t::testRoom();
  auto det = std::make_unique<FalkoDetector>();
  auto scan = std::make_unique<LaserScan>();
  auto kps = std::make_unique<FalkoKeypoints>();
  const t::SensorPose poses[] = {{3.5, 2.5, 0.3}, {2.5, 3.5, -1.0}, {4.5, 4.0, 2.0}, {5.0, 1.0, 0.0}};
  int scans = 0;
  for (const auto& pose : poses) {
    for (std::uint32_t seed = 1; seed <= 10; ++seed) {
      // 360 deg at 0.5 deg and a 180 deg scan at 0.5 deg
      for (int fov = 0; fov < 2; ++fov) {
        const bool full = fov == 0;
        t::simulateScan(w, pose, full ? -180.0F * kDeg : -90.0F * kDeg, 0.5F * kDeg, full ? 720 : 361, 0.01, seed,
                        *scan);
        REQUIRE(det->detect(*scan, *kps) == Status::Ok);
        std::array<t::P2, 16> expected{};
        const std::size_t n = full ? t::expectedCorners(w, pose, -4.0, 4.0, 0.3, 0.0, expected)
                                   : t::expectedCorners(w, pose, -kPi / 2, kPi / 2, 0.3, 0.05, expected);
        INFO("pose " << pose.x << "," << pose.y << "," << pose.theta << " seed " << seed << " full " << full);
        CHECK(t::worstMiss(*kps, expected, n) <= 0.03);
        // No keypoint on a wall: every keypoint is at a corner (visible or cut by the field of view
        // or by an occlusion: at least at a true polygon vertex).
        std::array<t::P2, 16> all{};
        const std::size_t na = t::allCorners(w, pose, all);
        CHECK(t::worstSpurious(*kps, all, na) <= 0.03);
        ++scans;
      }
    }
  }
  CHECK(scans == 80);
}

TEST_CASE("falko geometry: changing angle_min rotates the keypoints and nothing else", "[falko]") {
  const t::World w = t::testRoom();
  auto det = std::make_unique<FalkoDetector>();
  auto scan = std::make_unique<LaserScan>();
  auto kps0 = std::make_unique<FalkoKeypoints>();
  auto kps1 = std::make_unique<FalkoKeypoints>();
  const t::SensorPose pose{3.5, 2.5, 0.3};
  for (std::uint32_t seed = 1; seed <= 5; ++seed) {
    t::simulateScan(w, pose, -135.0F * kDeg, 0.25F * kDeg, 1081, 0.01, seed, *scan);
    REQUIRE(det->detect(*scan, *kps0) == Status::Ok);
    for (const float delta : {0.7F, -2.0F, 3.0F}) {
      LaserScan rotated = *scan;
      rotated.angleMin = scan->angleMin + delta;
      REQUIRE(det->detect(rotated, *kps1) == Status::Ok);
      REQUIRE(kps1->size() == kps0->size());
      const float c = std::cos(delta);
      const float s = std::sin(delta);
      for (std::size_t k = 0; k < kps0->size(); ++k) {
        const auto& a = (*kps0)[k];
        const auto& b = (*kps1)[k];
        CHECK(a.beamIndex == b.beamIndex);
        AGV_CHECK_NEAR(b.x, c * a.x - s * a.y, 2e-3);
        AGV_CHECK_NEAR(b.y, s * a.x + c * a.y, 2e-3);
        AGV_CHECK_NEAR(agv::angleDiff(b.orientation, a.orientation + delta), 0.0, 2e-3);
      }
    }
  }
}

TEST_CASE("falko geometry: half the angular resolution finds the same corners", "[falko]") {
  const t::World w = t::testRoom();
  auto det = std::make_unique<FalkoDetector>();
  auto fine = std::make_unique<LaserScan>();
  auto coarse = std::make_unique<LaserScan>();
  auto kf = std::make_unique<FalkoKeypoints>();
  auto kc = std::make_unique<FalkoKeypoints>();
  const t::SensorPose poses[] = {{3.5, 2.5, 0.3}, {2.5, 3.5, -1.0}};
  for (const auto& pose : poses) {
    t::simulateScan(w, pose, -180.0F * kDeg, 0.25F * kDeg, 1440, 0.0, 1U, *fine);
    t::simulateScan(w, pose, -180.0F * kDeg, 0.5F * kDeg, 720, 0.0, 1U, *coarse);
    REQUIRE(det->detect(*fine, *kf) == Status::Ok);
    REQUIRE(det->detect(*coarse, *kc) == Status::Ok);
    std::array<t::P2, 16> expected{};
    const std::size_t n = t::expectedCorners(w, pose, -4.0, 4.0, 0.3, 0.0, expected);
    CHECK(n >= 5U);
    CHECK(kf->size() == n);
    CHECK(kc->size() == n);
    CHECK(t::worstMiss(*kf, expected, n) <= 0.01);
    CHECK(t::worstMiss(*kc, expected, n) <= 0.01);
  }
}

TEST_CASE("falko geometry: a corner across the seam of a 360 deg scan", "[falko]") {
  const t::World w = t::testRoom();
  auto det = std::make_unique<FalkoDetector>();
  auto scan = std::make_unique<LaserScan>();
  auto kps = std::make_unique<FalkoKeypoints>();
  const t::SensorPose pose{3.5, 2.5, 0.0};
  std::array<t::P2, 16> expected{};
  const std::size_t n = t::expectedCorners(w, pose, -4.0, 4.0, 0.3, 0.0, expected);
  REQUIRE(n >= 5U);
  for (std::size_t c = 0; c < n; ++c) {
    const double bearing = std::atan2(expected[c].y, expected[c].x);
    // Put the seam (between the last and the first beam) right at the corner, and 2 beams off.
    for (const double off : {0.0, 0.5, 2.0, -2.0}) {
      const float inc = 0.5F * kDeg;
      const auto angleMin = static_cast<float>(bearing + off * static_cast<double>(inc));
      t::simulateScan(w, pose, angleMin, inc, 720, 0.0, 1U, *scan);
      REQUIRE(det->detect(*scan, *kps) == Status::Ok);
      REQUIRE(det->points().wraps());
      INFO("corner " << c << " offset " << off);
      CHECK(kps->size() == n);
      CHECK(t::worstMiss(*kps, expected, n) <= 0.01);
      CHECK(t::worstSpurious(*kps, expected, n) <= 0.01);
    }
  }
  // The same corner at the end of a 180 deg scan is not a corner: only one side is seen.
  t::simulateScan(w, pose, static_cast<float>(std::atan2(expected[0].y, expected[0].x)), 0.5F * kDeg, 361, 0.0, 1U,
                  *scan);
  REQUIRE(det->detect(*scan, *kps) == Status::Ok);
  REQUIRE_FALSE(det->points().wraps());
  CHECK(t::nearestKeypoint(*kps, expected[0]) > 0.05);
}

TEST_CASE("falko geometry: descriptors of one corner from two poses match best", "[falko]") {
  const t::World w = t::distinctRoom();
  auto det = std::make_unique<FalkoDetector>();
  auto scan = std::make_unique<LaserScan>();
  auto kpa = std::make_unique<FalkoKeypoints>();
  auto kpb = std::make_unique<FalkoKeypoints>();
  auto bscA = std::make_unique<agv::BscDescriptors>();
  auto bscB = std::make_unique<agv::BscDescriptors>();
  auto cghA = std::make_unique<agv::CghDescriptors>();
  auto cghB = std::make_unique<agv::CghDescriptors>();
  const agv::FalkoDescriber describer;
  const t::SensorPose pa{1.5, 4.0, 0.3};
  const t::SensorPose pb{0.5, 5.5, -1.2};
  t::simulateScan(w, pa, -180.0F * kDeg, 0.5F * kDeg, 720, 0.005, 11U, *scan);
  REQUIRE(det->detect(*scan, *kpa) == Status::Ok);
  REQUIRE(describer.describe(det->points(), *kpa, *bscA, *cghA) == Status::Ok);
  t::simulateScan(w, pb, -180.0F * kDeg, 0.5F * kDeg, 720, 0.005, 12U, *scan);
  REQUIRE(det->detect(*scan, *kpb) == Status::Ok);
  REQUIRE(describer.describe(det->points(), *kpb, *bscB, *cghB) == Status::Ok);
  // Identify each keypoint with a world corner.
  std::array<t::P2, 16> ca{};
  std::array<t::P2, 16> cb{};
  const std::size_t na = t::allCorners(w, pa, ca);
  const std::size_t nb = t::allCorners(w, pb, cb);
  REQUIRE(na == nb);
  auto cornerOf = [](const agv::FalkoKeypoint& kp, const std::array<t::P2, 16>& c, std::size_t n) {
    std::size_t idx = 99;
    const double d = t::nearestDistance(kp.x, kp.y, c, n, &idx);
    return d < 0.05 ? idx : std::size_t{99};
  };
  // Interior angle of room vertex k [deg].
  auto interiorAngle = [&](std::size_t k) {
    const t::Polygon& poly = w.polys[0];
    const t::P2 c = poly.v[k];
    const t::P2 a = poly.v[(k + poly.n - 1) % poly.n];
    const t::P2 b = poly.v[(k + 1) % poly.n];
    const double ang = std::atan2(b.y - c.y, b.x - c.x) - std::atan2(a.y - c.y, a.x - c.x);
    return std::fabs(agv::normalizeAngle(ang)) * 180.0 / kPi;
  };
  int compared = 0;
  int bscCompared = 0;
  for (std::size_t i = 0; i < kpa->size(); ++i) {
    const std::size_t corner = cornerOf((*kpa)[i], ca, na);
    REQUIRE(corner != 99U);
    std::size_t same = 99;
    for (std::size_t j = 0; j < kpb->size(); ++j) {
      if (cornerOf((*kpb)[j], cb, nb) == corner) {
        same = j;
      }
    }
    if (same == 99U) {
      continue;
    }
    ++compared;
    for (std::size_t j = 0; j < kpb->size(); ++j) {
      if (j == same) {
        continue;
      }
      const std::size_t otherCorner = cornerOf((*kpb)[j], cb, nb);
      INFO("corner " << corner << " vs corner " << otherCorner);
      CHECK(agv::cghDistance((*cghA)[i], (*cghB)[same]) < agv::cghDistance((*cghA)[i], (*cghB)[j]));
      // A two-wall corner is described by its walls only; each wall turns by half the difference
      // of corner angles, so BSC (22.5 deg sectors) separates corners 45 deg or more apart.
      if (otherCorner < 99U && std::fabs(interiorAngle(corner) - interiorAngle(otherCorner)) >= 44.0) {
        CHECK(agv::bscDistance((*bscA)[i], (*bscB)[same]) < agv::bscDistance((*bscA)[i], (*bscB)[j]));
        ++bscCompared;
      }
    }
  }
  CHECK(compared >= 4);
  CHECK(bscCompared >= 4);
}

TEST_CASE("falko geometry: the beam window bound holds every neighbour and is tight", "[falko]") {
  // Beam i + k carries the point of its ray nearest to the centre point (range rho cos(k inc), at
  // distance rho sin(k inc)): the hardest case for an angular bound. Every such point within the
  // radius must lie inside the window, and the window must not exceed asin(q) by more than 2.5 %
  // and two beams (q = radius / range), for q on both sides of the 3/4 switch of the bound.
  auto scan = std::make_unique<LaserScan>();
  auto pts = std::make_unique<agv::ScanPoints>();
  for (const float incDeg : {0.25F, 0.5F, 1.0F}) {
    const float inc = incDeg * kDeg;
    const auto n = static_cast<std::size_t>(180.0F / incDeg) + 1;  // 180 deg: no wrap
    const std::size_t i = n / 2;
    for (const float rho : {0.3F, 1.0F, 3.0F, 10.0F}) {
      scan->angleMin = -90.0F * kDeg;
      scan->angleIncrement = inc;
      scan->rangeMin = 0.01F;
      scan->rangeMax = 50.0F;
      scan->ranges.clear();
      for (std::size_t j = 0; j < n; ++j) {
        const float off = static_cast<float>(j > i ? j - i : i - j) * inc;
        REQUIRE(agv::isOk(scan->ranges.push_back(off < 89.0F * kDeg ? rho * std::cos(off) : 100.0F)));
      }
      REQUIRE(pts->assign(*scan) == Status::Ok);
      for (const float q : {0.05F, 0.2F, 0.45F, 0.5F, 0.55F, 0.7F, 0.75F, 0.8F, 0.9F, 0.99F}) {
        const float radius = q * rho;
        const std::size_t kmax = pts->maxOffset(rho, radius);
        CHECK(pts->maxOffsetAt(i, radius) == kmax);
        CHECK(static_cast<double>(kmax) <= 1.025 * std::asin(static_cast<double>(q)) / static_cast<double>(inc) + 2.0);
        for (std::size_t k = 1; k < i; ++k) {
          for (const std::size_t j : {i - k, i + k}) {
            const float dx = pts->x(j) - pts->x(i);
            const float dy = pts->y(j) - pts->y(i);
            if (dx * dx + dy * dy <= radius * radius) {
              CHECK(k <= kmax);
            }
          }
        }
      }
    }
  }
}
