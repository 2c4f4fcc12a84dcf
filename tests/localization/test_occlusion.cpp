// Occlusion-aware "in view": beam lookup by bearing (scan ends, wrap-around, invalid beams, bad
// geometry) and the localizer's map lifecycle and matched/expected check on scans ray-cast in a
// simulated scene with a wall between the laser and some landmarks (host only).
#include <Eigen/Core>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <random>
#include <vector>

#include "agv/core/angle.hpp"
#include "agv/localization/beam_lookup.hpp"
#include "agv/localization/localizer.hpp"
#include "agv_test.hpp"
#include "stand_still.hpp"

using namespace agv;

namespace {

/// A scan with `n` beams from `angleMin` by `inc`, every range `r`.
std::unique_ptr<LaserScan> uniformScan(std::size_t n, double angleMin, double inc, float r) {
  auto s = std::make_unique<LaserScan>();
  s->angleMin = static_cast<float>(angleMin);
  s->angleIncrement = static_cast<float>(inc);
  s->rangeMin = 0.05F;
  s->rangeMax = 30.0F;
  for (std::size_t i = 0; i < n; ++i) {
    REQUIRE(s->ranges.push_back(r) == Status::Ok);
  }
  return s;
}

constexpr double kInc = kPi<double> / 720.0;  // 0.25 deg

}  // namespace

TEST_CASE("beam lookup: the beams bracketing a bearing, the farther valid one wins", "[localization][occlusion]") {
  // 270 deg scan, 1081 beams from -135 deg
  auto s = uniformScan(1081, -0.75 * kPi<double>, kInc, 10.0F);
  s->ranges[540] = 4.0F;  // beam at 0 deg
  s->ranges[541] = 6.0F;
  const double a540 = static_cast<double>(s->angle(540));
  // on a beam: that beam and the next; between two beams: the farther of the two
  CHECK(farthestReturnNear(*s, a540).value() == Approx(6.0));
  CHECK(farthestReturnNear(*s, a540 + 0.5 * kInc).value() == Approx(6.0));
  CHECK(farthestReturnNear(*s, a540 - 0.5 * kInc).value() == Approx(10.0));  // beams 539 and 540
  // any representation of the angle
  CHECK(farthestReturnNear(*s, a540 + 0.5 * kInc + 4.0 * kPi<double>).value() == Approx(6.0));

  SECTION("invalid beams: NaN, inf, no return, too close") {
    const float bad[] = {std::numeric_limits<float>::quiet_NaN(),
                         std::numeric_limits<float>::infinity(),
                         -std::numeric_limits<float>::infinity(),
                         30.0F,
                         31.0F,
                         0.01F};
    for (const float v : bad) {
      s->ranges[540] = v;
      s->ranges[541] = 6.0F;
      CHECK(farthestReturnNear(*s, a540 + 0.5 * kInc).value() == Approx(6.0));  // the valid neighbour
      s->ranges[541] = v;
      CHECK(farthestReturnNear(*s, a540 + 0.5 * kInc).status() == Status::NotFound);
    }
  }
  SECTION("scan ends of a 270 deg scan") {
    s->ranges[0] = 3.0F;
    s->ranges[1080] = 5.0F;
    const double first = static_cast<double>(s->angle(0));
    const double last = static_cast<double>(s->angle(1080));
    CHECK(farthestReturnNear(*s, last).value() == Approx(5.0));
    CHECK(farthestReturnNear(*s, last + 0.4 * kInc).value() == Approx(5.0));  // within half a beam
    CHECK(farthestReturnNear(*s, first - 0.4 * kInc).value() == Approx(3.0));
    CHECK(farthestReturnNear(*s, last + 0.6 * kInc).status() == Status::OutOfRange);
    CHECK(farthestReturnNear(*s, first - 0.6 * kInc).status() == Status::OutOfRange);
    CHECK(farthestReturnNear(*s, kPi<double>).status() == Status::OutOfRange);  // behind the laser
  }
  SECTION("non-finite bearing") {
    CHECK(farthestReturnNear(*s, std::nan("")).status() == Status::NonFiniteInput);
    CHECK(farthestReturnNear(*s, INFINITY).status() == Status::NonFiniteInput);
  }
}

TEST_CASE("beam lookup: a full revolution wraps from the last beam to the first", "[localization][occlusion]") {
  // 360 deg scan, 1440 beams from -180 deg: the last beam is at 180 - 0.25 deg
  auto s = uniformScan(1440, -kPi<double>, kInc, 10.0F);
  s->ranges[1439] = 2.0F;
  s->ranges[0] = 7.0F;
  s->ranges[1] = 1.0F;
  s->ranges[1438] = 1.0F;
  // between the last beam and the first (across the seam at +-180 deg), from either side
  CHECK(farthestReturnNear(*s, kPi<double> - 0.1 * kInc).value() == Approx(7.0));
  CHECK(farthestReturnNear(*s, -kPi<double> + 0.5 * kInc).value() == Approx(7.0));  // beams 0 and 1
  s->ranges[0] = std::numeric_limits<float>::quiet_NaN();
  CHECK(farthestReturnNear(*s, kPi<double> - 0.1 * kInc).value() == Approx(2.0));
  s->ranges[1439] = 30.0F;  // no return
  CHECK(farthestReturnNear(*s, kPi<double> - 0.1 * kInc).status() == Status::NotFound);
  // a 360 deg scan starting at 0 (a common driver convention): -90 deg is beam 1080
  auto z = uniformScan(1440, 0.0, kInc, 10.0F);
  z->ranges[1080] = 3.0F;
  z->ranges[1081] = 3.0F;
  CHECK(farthestReturnNear(*z, -0.5 * kPi<double>).value() == Approx(3.0));
}

TEST_CASE("beam lookup: unusable scan geometry is refused", "[localization][occlusion]") {
  auto s = uniformScan(0, 0.0, kInc, 10.0F);
  CHECK(checkBeamGeometry(*s) == Status::EmptyInput);
  CHECK(farthestReturnNear(*s, 0.0).status() == Status::EmptyInput);
  s = uniformScan(100, std::nan(""), kInc, 10.0F);
  CHECK(checkBeamGeometry(*s) == Status::NonFiniteInput);
  s = uniformScan(100, 0.0, INFINITY, 10.0F);
  CHECK(checkBeamGeometry(*s) == Status::NonFiniteInput);
  for (const double inc : {0.0, -kInc, 1.0}) {
    s = uniformScan(100, 0.0, inc, 10.0F);
    CHECK(checkBeamGeometry(*s) == Status::InvalidArgument);
  }
  s = uniformScan(1450, 0.0, kInc, 10.0F);  // more than one revolution
  CHECK(checkBeamGeometry(*s) == Status::InvalidArgument);
  s = uniformScan(1440, 0.0, kInc, 10.0F);
  CHECK(checkBeamGeometry(*s) == Status::Ok);
}

namespace {

struct Wall {
  Eigen::Vector2d a;
  Eigen::Vector2d b;
};

/// Distance along the ray o + t d (|d| = 1) to the segment, or +inf.
double rayToSegment(const Eigen::Vector2d& o, const Eigen::Vector2d& d, const Wall& w) {
  const Eigen::Vector2d e = w.b - w.a;
  const double den = d.x() * e.y() - d.y() * e.x();
  if (std::fabs(den) < 1e-12) {
    return INFINITY;
  }
  const Eigen::Vector2d q = w.a - o;
  const double t = (q.x() * e.y() - q.y() * e.x()) / den;
  const double u = (q.x() * d.y() - q.y() * d.x()) / den;
  return t > 0.0 && u >= 0.0 && u <= 1.0 ? t : INFINITY;
}

/// Distance along the ray to the circle's near side, or +inf.
double rayToCircle(const Eigen::Vector2d& o, const Eigen::Vector2d& d, const Eigen::Vector2d& c, double radius) {
  const Eigen::Vector2d q = c - o;
  const double along = q.dot(d);
  const double h2 = q.squaredNorm() - along * along;
  if (h2 > radius * radius || along <= 0.0) {
    return INFINITY;
  }
  return along - std::sqrt(radius * radius - h2);
}

/// Reflector poles (radius 4 cm) at 6 m around the laser, a wall at ~3 m hiding some of them, and
/// the hall beyond at 25 m. The scan is ray-cast from the true laser pose with the laser model's
/// range noise; the observations are the visible poles' centres.
struct OcclusionScene {
  static constexpr double kPoleRadius = 0.04;
  LocalizerParams params;
  std::unique_ptr<Localizer> loc;
  std::unique_ptr<LandmarkMap> map;
  std::unique_ptr<ScanObservations> obs;
  std::unique_ptr<LaserScan> beams;
  Pose2d truth{2.0, 1.0, 0.3};
  Timestamp t = Timestamp::fromSeconds(10.0);
  std::vector<Eigen::Vector2d> poles;
  std::vector<LandmarkIndex> index;
  std::vector<Wall> walls;
  std::mt19937_64 rng{11};

  /// Poles at laser bearings -1.75 + 0.5 i, i = 0..7; the wall hides poles first..lastHidden.
  OcclusionScene(MapMode mode, int firstHidden, int lastHidden) {
    params.laser.mounting = Pose2d{1.0, 0.2, 0.1};
    loc = std::make_unique<Localizer>(params);
    LandmarkMapParams mp;
    mp.mode = mode;
    mp.initialHits = 5;
    map = std::make_unique<LandmarkMap>(mp);
    obs = std::make_unique<ScanObservations>();
    beams = std::make_unique<LaserScan>();
    const Pose2d lw = laserWorld();
    for (int i = 0; i < 8; ++i) {
      const double a = 0.5 * i - 1.75;
      poles.push_back(lw.transformPoint(Eigen::Vector2d(6.0 * std::cos(a), 6.0 * std::sin(a))));
    }
    const double a0 = 0.5 * firstHidden - 1.75 - 0.2;
    const double a1 = 0.5 * lastHidden - 1.75 + 0.2;
    walls.push_back(Wall{lw.transformPoint(Eigen::Vector2d(3.0 * std::cos(a0), 3.0 * std::sin(a0))),
                         lw.transformPoint(Eigen::Vector2d(3.0 * std::cos(a1), 3.0 * std::sin(a1)))});
    std::uint32_t id = 1;
    for (const auto& p : poles) {
      Result<LandmarkIndex> r = mode == MapMode::Static
                                    ? map->addSurveyed(LandmarkKind::Reflector, p.x(), p.y(), 0.0, id++)
                                    : map->insert(LandmarkKind::Reflector, p.x(), p.y(), 1e-6);
      REQUIRE(r.ok());
      index.push_back(r.value());
    }
    Eigen::Matrix3d P0 = Eigen::Matrix3d::Zero();
    P0(0, 0) = P0(1, 1) = 1e-4;
    P0(2, 2) = 1e-5;
    REQUIRE(loc->reset(t, truth, P0) == Status::Ok);
  }
  Pose2d laserWorld() const { return truth.compose(params.laser.mounting); }
  /// Ground truth: the segment from the laser to pole i crosses no wall.
  bool visible(std::size_t i) const {
    const Eigen::Vector2d o = laserWorld().translation();
    const Eigen::Vector2d v = poles[i] - o;
    const double dist = v.norm();
    for (const Wall& w : walls) {
      if (rayToSegment(o, v / dist, w) < dist) {
        return false;
      }
    }
    return true;
  }
  void stand(int steps) { test::standStill(*loc, t, steps); }
  /// 270 deg, 0.25 deg scan ray-cast from the true laser pose, with the laser model's range noise.
  void castScan() {
    std::normal_distribution<double> n(0.0, params.laser.rangeSigma);
    beams->stamp = t;
    beams->angleMin = static_cast<float>(-0.75 * kPi<double>);
    beams->angleIncrement = static_cast<float>(kInc);
    beams->rangeMin = 0.05F;
    beams->rangeMax = 30.0F;
    beams->ranges.clear();
    const Pose2d lw = laserWorld();
    for (std::size_t i = 0; i < 1081; ++i) {
      const double b = lw.theta + static_cast<double>(beams->angle(i));
      const Eigen::Vector2d d(std::cos(b), std::sin(b));
      double r = 25.0;
      for (const Wall& w : walls) {
        r = std::fmin(r, rayToSegment(lw.translation(), d, w));
      }
      for (const auto& p : poles) {
        r = std::fmin(r, rayToCircle(lw.translation(), d, p, kPoleRadius));
      }
      REQUIRE(beams->ranges.push_back(static_cast<float>(r + n(rng))) == Status::Ok);
    }
  }
  /// Observes the poles listed (laser frame, 2 mm noise), stamped now.
  void observe(const std::vector<std::size_t>& which) {
    std::normal_distribution<double> n(0.0, 0.002);
    obs->stamp = t;
    obs->kindsDetected = kAllLandmarkKinds;
    obs->points.clear();
    const Pose2d lw = laserWorld();
    for (const std::size_t i : which) {
      const Eigen::Vector2d z = lw.inverseTransformPoint(poles[i]);
      REQUIRE(obs->points.push_back(PointObservation{z.x() + n(rng), z.y() + n(rng), LandmarkKind::Reflector}) ==
              Status::Ok);
    }
  }
  std::int16_t hits(std::size_t i) const {
    const Landmark* l = map->at(index[i]);
    return l == nullptr ? std::int16_t{0} : l->hits;
  }
};

}  // namespace

TEST_CASE(
    "occlusion: a landmark behind a wall keeps its hits and is not expected; one in clear view and not "
    "matched loses a hit",
    "[localization][occlusion]") {
  OcclusionScene s(MapMode::Dynamic, 2, 3);
  // ground truth from the scene geometry
  std::vector<std::size_t> hidden;
  std::vector<std::size_t> clear;
  for (std::size_t i = 0; i < s.poles.size(); ++i) {
    (s.visible(i) ? clear : hidden).push_back(i);
  }
  REQUIRE(hidden == std::vector<std::size_t>{2, 3});
  // every visible pole is seen except one (a missed detection)
  const std::size_t missed = 6;
  std::vector<std::size_t> seen;
  for (const std::size_t i : clear) {
    if (i != missed) {
      seen.push_back(i);
    }
  }
  const std::int16_t h0 = s.map->params().initialHits;
  s.stand(10);
  s.castScan();
  s.observe(seen);

  SECTION("with the scan's ranges") {
    const LocalizerHealth& h = s.loc->correct(*s.obs, *s.beams, *s.map);
    CHECK(h.used == seen.size());
    CHECK(h.expectedInView == clear.size());
    CHECK(h.occluded == hidden.size());
    CHECK(h.noReturn == 0U);
    CHECK_FALSE(hasFlag(h.flags, LocalizerFlag::BadCycle));
    CHECK_FALSE(hasFlag(h.flags, LocalizerFlag::OcclusionUnchecked));
    for (const std::size_t i : hidden) {
      CHECK(s.hits(i) == h0);  // hidden: untouched
    }
    CHECK(s.hits(missed) == h0 - 1);  // in clear view, not matched
    for (const std::size_t i : seen) {
      CHECK(s.hits(i) == h0 + 1);
    }
  }
  SECTION("a young landmark (fewer than minHitsConfirmed hits) hidden behind the wall is still decremented") {
    while (s.hits(2) >= s.params.map.minHitsConfirmed) {
      (void)s.map->weaken(s.index[2]);
    }
    const std::int16_t young = s.hits(2);
    REQUIRE(young > 1);
    const LocalizerHealth& h = s.loc->correct(*s.obs, *s.beams, *s.map);
    CHECK(h.occluded == hidden.size());
    CHECK(s.hits(2) == young - 1);
    CHECK(s.hits(3) == h0);  // confirmed: kept
  }
  SECTION("without a scan (reflector list only): every landmark inside the limits is in view") {
    const LocalizerHealth& h = s.loc->correct(*s.obs, *s.map);
    CHECK(h.expectedInView == s.poles.size());
    CHECK(h.occluded == 0U);
    for (const std::size_t i : hidden) {
      CHECK(s.hits(i) == h0 - 1);
    }
    CHECK(s.hits(missed) == h0 - 1);
  }
  SECTION("modelOcclusion off: the same as without a scan") {
    s.params.occlusion.enabled = false;
    Localizer plain(s.params);
    Eigen::Matrix3d P0 = Eigen::Matrix3d::Identity() * 1e-5;
    REQUIRE(plain.reset(s.t, s.truth, P0) == Status::Ok);
    const LocalizerHealth& h = plain.correct(*s.obs, *s.beams, *s.map);
    CHECK(h.expectedInView == s.poles.size());
    CHECK(s.hits(2) == h0 - 1);
  }
  SECTION("invalid beams at the bearing of the missed pole: no evidence, no decrement") {
    const Pose2d lw = s.laserWorld();
    const Eigen::Vector2d z = lw.inverseTransformPoint(s.poles[missed]);
    const double b = std::atan2(z.y(), z.x());
    const float bad[] = {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(), 30.0F, 0.0F};
    for (const float v : bad) {
      for (std::size_t i = 0; i < s.beams->size(); ++i) {
        if (std::fabs(static_cast<double>(s.beams->angle(i)) - b) < 2.0 * kInc) {
          s.beams->ranges[i] = v;
        }
      }
      Localizer other(s.params);
      Eigen::Matrix3d P0 = Eigen::Matrix3d::Identity() * 1e-5;
      REQUIRE(other.reset(s.t, s.truth, P0) == Status::Ok);
      const std::int16_t before = s.hits(missed);
      const LocalizerHealth& h = other.correct(*s.obs, *s.beams, *s.map);
      CHECK(h.noReturn == 1U);
      CHECK(h.expectedInView == clear.size() - 1U);
      CHECK(s.hits(missed) == before);
    }
  }
  SECTION("unusable beams: fallback to the limits, flagged") {
    s.beams->angleIncrement = 0.0F;
    const LocalizerHealth& h = s.loc->correct(*s.obs, *s.beams, *s.map);
    CHECK(hasFlag(h.flags, LocalizerFlag::OcclusionUnchecked));
    CHECK(h.expectedInView == s.poles.size());
    CHECK(s.hits(2) == h0 - 1);
  }
}

TEST_CASE(
    "occlusion: most of the map behind a wall does not make a correctly placed vehicle lost, and one "
    "that matches nothing in view still is",
    "[localization][occlusion]") {
  // poles 1..5 hidden; 0, 6, 7 visible; 0 and 7 detected (6 missed): 2 of 3 expected matched.
  OcclusionScene s(MapMode::Static, 1, 5);
  std::size_t nVisible = 0;
  for (std::size_t i = 0; i < s.poles.size(); ++i) {
    nVisible += s.visible(i) ? 1U : 0U;
  }
  REQUIRE(nVisible == 3U);
  const std::vector<std::size_t> seen{0, 7};
  const int cycles = 3 * s.params.health.lostAfterBadCycles;
  SECTION("with the scan's ranges: good cycles, never lost") {
    for (int c = 0; c < cycles; ++c) {
      s.stand(10);
      s.castScan();
      s.observe(seen);
      const LocalizerHealth& h = s.loc->correct(*s.obs, *s.beams, *s.map);
      CHECK(h.expectedInView == nVisible);
      CHECK(h.used == seen.size());
      CHECK_FALSE(hasFlag(h.flags, LocalizerFlag::BadCycle));
    }
    CHECK_FALSE(s.loc->lost());
  }
  SECTION("without: 2 of 8 'expected' is below 30 %, lost after lostAfterBadCycles") {
    int lostAt = -1;
    for (int c = 1; c <= cycles && lostAt < 0; ++c) {
      s.stand(10);
      s.observe(seen);
      if (s.loc->correct(*s.obs, *s.map).lost) {
        lostAt = c;
      }
    }
    CHECK(lostAt == s.params.health.lostAfterBadCycles);
  }
  SECTION("with the scan's ranges, nothing matched: lost after lostAfterBadCycles") {
    int lostAt = -1;
    for (int c = 1; c <= cycles && lostAt < 0; ++c) {
      s.stand(10);
      s.castScan();
      s.observe({});
      if (s.loc->correct(*s.obs, *s.beams, *s.map).lost) {
        lostAt = c;
      }
    }
    CHECK(lostAt == s.params.health.lostAfterBadCycles);
  }
}

TEST_CASE("occlusion: the steady-state cycle with the scan's ranges allocates nothing",
          "[localization][occlusion][alloc]") {
  OcclusionScene s(MapMode::Dynamic, 2, 3);
  std::vector<std::size_t> seen{0, 1, 4, 5, 6, 7};
  s.stand(10);
  s.castScan();
  s.observe(seen);
  (void)s.loc->correct(*s.obs, *s.beams, *s.map);
  OdometryIncrement inc;
  inc.covariance = Eigen::Matrix3d::Identity() * 1e-9;
  for (int c = 0; c < 5; ++c) {
    s.observe(seen);
    s.obs->stamp = s.t + Duration::fromMilliseconds(70);  // 30 ms before the newest odometry below
    AGV_CHECK_NO_ALLOCATIONS(for (int i = 0; i < 10; ++i) {
      s.t = s.t + Duration::fromMilliseconds(10);
      inc.stamp = s.t;
      (void)s.loc->predict(inc);
    }(void)s.loc->correct(*s.obs, *s.beams, *s.map));
    CHECK(s.loc->health().used == seen.size());
    CHECK(s.loc->health().occluded == 2U);
  }
}

TEST_CASE("side support: points of the surfaces on each side of a bearing", "[localization][occlusion]") {
  // a round wall at 5 m around the laser (270 deg, 0.25 deg)
  auto s = uniformScan(1081, -0.75 * kPi<double>, kInc, 5.0F);
  const double b = static_cast<double>(s->angle(540)) + 0.3 * kInc;
  Result<SideSupport> r = sideSupport(*s, 5.0, b, 0.2, 1000);
  REQUIRE(r.ok());
  // 0.2 m at 5 m spans 0.04 rad = 9.2 beams on each side
  CHECK(r.value().before >= 9U);
  CHECK(r.value().before <= 10U);
  CHECK(r.value().after >= 9U);
  CHECK(r.value().after <= 10U);
  CHECK(sideSupport(*s, 5.0, b, 0.2, 2).value().before == 2U);  // capped
  // a jump edge: beyond the bearing the beams reach a wall at 10 m (one face only)
  for (std::size_t i = 541; i < s->size(); ++i) {
    s->ranges[i] = 10.0F;
  }
  r = sideSupport(*s, 5.0, b, 0.2, 1000);
  CHECK(r.value().before >= 9U);
  CHECK(r.value().after == 0U);
  // a point in free space, 2 m in front of the wall: nothing near it
  r = sideSupport(*s, 3.0, b - 0.5, 0.2, 1000);
  CHECK(r.value().before == 0U);
  CHECK(r.value().after == 0U);
  // invalid beams do not count
  for (std::size_t i = 0; i <= 540; ++i) {
    s->ranges[i] = std::numeric_limits<float>::quiet_NaN();
  }
  CHECK(sideSupport(*s, 5.0, b, 0.2, 1000).value().before == 0U);
  // across the seam of a full revolution
  auto z = uniformScan(1440, -kPi<double>, kInc, 5.0F);
  r = sideSupport(*z, 5.0, kPi<double> - 0.1 * kInc, 0.2, 1000);
  CHECK(r.value().before >= 9U);
  CHECK(r.value().after >= 9U);
  // at the end of a 270 deg scan, nothing beyond it
  auto e = uniformScan(1081, -0.75 * kPi<double>, kInc, 5.0F);
  CHECK(sideSupport(*e, 5.0, static_cast<double>(e->angle(1080)), 0.2, 1000).value().after <= 1U);
  // bad arguments
  CHECK(sideSupport(*e, 0.0, 0.0, 0.2, 2).status() == Status::InvalidArgument);
  CHECK(sideSupport(*e, 5.0, 0.0, -1.0, 2).status() == Status::InvalidArgument);
  CHECK(sideSupport(*e, std::nan(""), 0.0, 0.2, 2).status() == Status::InvalidArgument);
  CHECK(sideSupport(*e, 5.0, kPi<double>, 0.2, 2).status() == Status::OutOfRange);
}

TEST_CASE("occlusion: corners need both faces seen to be expected; in the line of sight they are weakened either way",
          "[localization][occlusion]") {
  LocalizerParams p;  // laser at the logical point
  Localizer loc(p);
  LandmarkMapParams mp;
  mp.initialHits = 5;
  auto map = std::make_unique<LandmarkMap>(mp);
  // round wall at 10 m; beyond bearing 1.0 rad the wall steps back to 20 m
  auto beams = uniformScan(1081, -0.75 * kPi<double>, kInc, 10.0F);
  for (std::size_t i = 0; i < beams->size(); ++i) {
    if (static_cast<double>(beams->angle(i)) > 1.0) {
      beams->ranges[i] = 20.0F;
    }
  }
  const LandmarkIndex onWall = map->insert(LandmarkKind::Corner, 10.0, 0.0, 1e-6).value();
  const LandmarkIndex freeSpace =
      map->insert(LandmarkKind::Corner, 5.0 * std::cos(0.5), 5.0 * std::sin(0.5), 1e-6).value();
  const double a = 1.0 - 0.5 * kInc;  // the last beam of the near wall, its face turned away beyond
  const LandmarkIndex edge = map->insert(LandmarkKind::Corner, 10.0 * std::cos(a), 10.0 * std::sin(a), 1e-6).value();
  Eigen::Matrix3d P0 = Eigen::Matrix3d::Identity() * 1e-6;
  REQUIRE(loc.reset(Timestamp::fromSeconds(1.0), Pose2d{}, P0) == Status::Ok);
  auto obs = std::make_unique<ScanObservations>();
  obs->stamp = Timestamp::fromSeconds(1.0);
  obs->kindsDetected = landmarkKindBit(LandmarkKind::Corner);
  const LocalizerHealth& h = loc.correct(*obs, *beams, *map);
  CHECK(h.expectedInView == 1U);  // on the wall, both faces seen
  CHECK(h.unsupported == 2U);     // the edge and the point in free space
  CHECK(map->at(onWall)->hits == mp.initialHits - 1);
  CHECK(map->at(freeSpace)->hits == mp.initialHits - 1);  // nothing there
  CHECK(map->at(edge)->hits == mp.initialHits - 1);       // in the line of sight, but cannot be detected
}

TEST_CASE("occlusion: a kidnapped vehicle is still flagged lost within 5 cycles when the scan's ranges are used",
          "[localization][occlusion]") {
  const Pose2d offsets[] = {{0.5, 0.0, 0.0}, {0.0, 0.0, 0.2}, {-1.0, 0.5, -0.3}, {2.0, 1.0, 0.5}};
  for (const Pose2d& off : offsets) {
    OcclusionScene s(MapMode::Static, 2, 3);
    const std::vector<std::size_t> seen{0, 1, 4, 5, 6, 7};
    for (int c = 0; c < 5; ++c) {
      s.stand(10);
      s.castScan();
      s.observe(seen);
      REQUIRE_FALSE(s.loc->correct(*s.obs, *s.beams, *s.map).lost);
    }
    // teleport: the scan and the detections now come from elsewhere; the filter does not know
    s.truth = s.truth.compose(off);
    std::vector<std::size_t> visibleNow;
    for (std::size_t i = 0; i < s.poles.size(); ++i) {
      const Eigen::Vector2d z = s.laserWorld().inverseTransformPoint(s.poles[i]);
      const double b = std::atan2(z.y(), z.x());
      if (s.visible(i) && std::fabs(b) < 2.3 && z.norm() > 1.0) {
        visibleNow.push_back(i);
      }
    }
    int lostAfter = -1;
    for (int c = 1; c <= 10 && lostAfter < 0; ++c) {
      s.stand(10);
      s.castScan();
      s.observe(visibleNow);
      if (s.loc->correct(*s.obs, *s.beams, *s.map).lost) {
        lostAfter = c;
      }
    }
    std::printf("kidnap by (%.1f m, %.1f m, %.2f rad) with scan ranges: lost %d cycles after\n", off.x, off.y,
                off.theta, lostAfter);
    CHECK(lostAfter > 0);
    CHECK(lostAfter <= 5);
  }
}

TEST_CASE("beam lookup: a tiny increment (a few beams covering a sliver) stays bounded", "[localization][occlusion]") {
  auto s = uniformScan(4, 0.0, 1e-30, 5.0F);
  REQUIRE(checkBeamGeometry(*s) == Status::Ok);
  CHECK(farthestReturnNear(*s, 0.0).value() == Approx(5.0));
  CHECK(farthestReturnNear(*s, 1.0).status() == Status::OutOfRange);
  const Result<SideSupport> r = sideSupport(*s, 5.0, 0.0, 0.2, 1000);
  REQUIRE(r.ok());
  CHECK(r.value().before + r.value().after <= 8U);
}
