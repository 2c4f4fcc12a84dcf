// CornerMapper: clustering of corner sightings and the freeze into a static corner map, on
// sightings with a known truth: true corners seen with Gaussian noise, stray keypoints of other
// objects falling into their clusters, and a round pillar whose "corner" moves with the viewpoint.
#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <vector>

#include "agv/localization/landmark_map.hpp"
#include "agv/mapping/corner_mapper.hpp"
#include "agv_test.hpp"

using agv::LandmarkMap;
using agv::mapping::CornerFreezeParams;
using agv::mapping::CornerFreezeStats;
using agv::mapping::CornerMapper;

namespace {

constexpr double kNoise = 0.004;  // [m] per coordinate, of one sighting of a true corner

/// The landmark of `map` nearest (x, y), or nullptr.
const agv::Landmark* nearestLandmark(const LandmarkMap& map, double x, double y) {
  const agv::Landmark* best = nullptr;
  double bestD = 1e300;
  map.forEach([&](agv::LandmarkIndex, const agv::Landmark& l) {
    const double d = std::hypot(l.x - x, l.y - y);
    if (d < bestD) {
      bestD = d;
      best = &l;
    }
  });
  return best;
}

/// `n` sightings of a true corner at (x, y) with kNoise.
void seeCorner(CornerMapper& m, std::mt19937_64& rng, double x, double y, int n) {
  std::normal_distribution<double> noise(0.0, kNoise);
  for (int k = 0; k < n; ++k) {
    m.add(Eigen::Vector2d(x + noise(rng), y + noise(rng)));
  }
}

/// The apparent corner of a pillar of radius r at (cx, cy) seen from n viewpoints around it: the
/// point of the circle facing each viewpoint (spread over `arc` radians).
void seePillar(CornerMapper& m, double cx, double cy, double r, double arc, int n) {
  for (int k = 0; k < n; ++k) {
    const double a = -0.5 * arc + arc * static_cast<double>(k) / static_cast<double>(n - 1);
    m.add(Eigen::Vector2d(cx + r * std::cos(a), cy + r * std::sin(a)));
  }
}

}  // namespace

TEST_CASE("corner mapper: true corners frozen at their place, a moving pillar corner refused, strays left out",
          "[mapping][corners]") {
  std::mt19937_64 rng(20261128U);
  CornerMapper m(0.2);
  // Two true corners 0.5 m apart, each seen 40 times; into the first fall 8 strays 5-12 cm away
  // (keypoints of a neighbouring object, inside the merge radius).
  seeCorner(m, rng, 3.0, 4.0, 40);
  seeCorner(m, rng, 3.5, 4.0, 40);
  std::uniform_real_distribution<double> strayR(0.05, 0.12);
  std::uniform_real_distribution<double> strayA(0.0, 6.283185307179586);
  for (int k = 0; k < 8; ++k) {
    const double r = strayR(rng);
    const double a = strayA(rng);
    m.add(Eigen::Vector2d(3.0 + r * std::cos(a), 4.0 + r * std::sin(a)));
  }
  // A pillar of radius 0.25 m seen from viewpoints over 60 degrees: its apparent corner slides 0.26 m.
  seePillar(m, 10.0, 2.0, 0.25, 1.0471975511965976, 30);
  // A corner seen 3 times only.
  seeCorner(m, rng, -2.0, 7.0, 3);
  CHECK(m.sightings() == 40U + 40U + 8U + 30U + 3U);

  auto map = std::make_unique<LandmarkMap>();
  SECTION("robust freeze: median, inliers within 3 cm, most sightings agreeing, scatter <= 15 mm") {
    CornerFreezeParams p;
    p.minSightings = 5;
    p.inlierRadius = 0.03;
    p.minInlierFraction = 0.5;
    p.maxScatter = 0.015;
    const CornerFreezeStats st = m.freeze(p, *map);
    CHECK(st.frozen == 2U);
    CHECK(map->size() == 2U);
    CHECK(map->mode() == agv::MapMode::Static);
    CHECK(st.tooFew >= 1U);  // the corner seen 3 times
    CHECK(st.frozen + st.tooFew + st.viewDependent + st.scattered + st.refusedByMap == st.clusters);
    // Each frozen corner within 4 sigma of the mean of 40 sightings (sigma kNoise / sqrt(40)) of its
    // truth, its sigma the scatter of one sighting (kNoise within 30 %), surveyed.
    for (const double x : {3.0, 3.5}) {
      const agv::Landmark* l = nearestLandmark(*map, x, 4.0);
      REQUIRE(l != nullptr);
      CHECK(std::fabs(l->x - x) < 4.0 * kNoise / std::sqrt(40.0));
      CHECK(std::fabs(l->y - 4.0) < 4.0 * kNoise / std::sqrt(40.0));
      CHECK(std::sqrt(l->variance) > 0.7 * kNoise);
      CHECK(std::sqrt(l->variance) < 1.3 * kNoise);
      CHECK(l->surveyed);
      CHECK(l->kind == agv::LandmarkKind::Corner);
    }
    // nothing at the pillar
    const agv::Landmark* atPillar = nearestLandmark(*map, 10.25, 2.0);
    REQUIRE(atPillar != nullptr);
    CHECK(std::hypot(atPillar->x - 10.25, atPillar->y - 2.0) > 1.0);
  }
  SECTION("the thesis' count rule alone: the strays pull the first corner, the pillar is frozen") {
    CornerFreezeParams p;  // defaults: 5 sightings, every sighting, no scatter test
    p.sigma = 0.02;
    const CornerFreezeStats st = m.freeze(p, *map);
    CHECK(st.viewDependent == 0U);
    CHECK(st.scattered == 0U);
    const agv::Landmark* atPillar = nearestLandmark(*map, 10.25, 2.0);
    REQUIRE(atPillar != nullptr);
    CHECK(std::hypot(atPillar->x - 10.25, atPillar->y - 2.0) < 0.2);
    const agv::Landmark* first = nearestLandmark(*map, 3.0, 4.0);
    REQUIRE(first != nullptr);
    CHECK(std::fabs(std::sqrt(first->variance) - 0.02) < 1e-12);  // the declared sigma
  }
  SECTION("the scatter test alone refuses the corner its strays spread") {
    CornerFreezeParams p;
    p.maxScatter = 0.015;
    const CornerFreezeStats st = m.freeze(p, *map);
    CHECK(st.scattered >= 2U);  // the first corner and the pillar
    CHECK(nearestLandmark(*map, 3.0, 4.0) != nullptr);
    CHECK(std::hypot(nearestLandmark(*map, 3.0, 4.0)->x - 3.5, nearestLandmark(*map, 3.0, 4.0)->y - 4.0) < 0.01);
  }
}

TEST_CASE("corner mapper: sightings merge within the radius only; bad input", "[mapping][corners]") {
  CornerMapper m(0.1);
  m.add(Eigen::Vector2d(0.0, 0.0));
  m.add(Eigen::Vector2d(0.09, 0.0));     // joins (mean now 0.045)
  m.add(Eigen::Vector2d(0.2, 0.0));      // 0.155 from the mean: a new cluster
  m.add(Eigen::Vector2d(-50.0, -50.0));  // negative cells
  m.add(Eigen::Vector2d(-50.05, -50.05));
  CHECK(m.clusters() == 3U);
  m.add(Eigen::Vector2d(std::nan(""), 1.0));
  m.add(Eigen::Vector2d(1.0, std::numeric_limits<double>::infinity()));
  CHECK(m.sightings() == 5U);
  CHECK(m.clusters() == 3U);
  auto map = std::make_unique<LandmarkMap>();
  REQUIRE(map->insert(agv::LandmarkKind::Reflector, 1.0, 1.0, 1e-4).ok());  // cleared by the freeze
  CornerFreezeParams p;
  p.minSightings = 2;
  const CornerFreezeStats st = m.freeze(p, *map);
  CHECK(st.frozen == 2U);
  CHECK(st.tooFew == 1U);
  CHECK(map->size() == 2U);
  CHECK(map->findById(1U) != agv::kNoLandmark);
  CHECK(map->findById(2U) != agv::kNoLandmark);
  const agv::Landmark* a = map->at(map->findById(1U));
  REQUIRE(a != nullptr);
  CHECK(a->x == 0.045);
  CHECK(a->y == 0.0);
  const agv::Landmark* b = map->at(map->findById(2U));
  REQUIRE(b != nullptr);
  AGV_CHECK_NEAR(b->x, -50.025, 1e-12);
  // An empty mapper freezes nothing and still leaves a cleared, static map.
  const CornerMapper empty;
  const CornerFreezeStats none = empty.freeze(p, *map);
  CHECK(none.clusters == 0U);
  CHECK(map->size() == 0U);
  CHECK(map->mode() == agv::MapMode::Static);
}
