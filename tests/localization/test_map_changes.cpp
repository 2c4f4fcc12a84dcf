// Changes since the mapping run (map_changes.hpp) in the simulated hall of scan_hall.hpp: the
// column moved 0.15 m after the field was built. The detector finds the moved column's points and
// no wall's, raises its threshold with the scan's own residuals, and once the changes are kept in
// a surface map the match leaves the moved points out, which holds the pose even from the view
// where the column is most of what fixes an axis (the adaptive band cannot: test_scan_matcher.cpp).
// Bad input and zero allocations.
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <vector>

#include "agv/localization/map_changes.hpp"
#include "agv/localization/scan_matcher.hpp"
#include "agv/localization/surface_map.hpp"
#include "agv_test.hpp"
#include "scan_hall.hpp"

using namespace agv;
using namespace agv::test;

namespace {

using TestSurfaceMap = SurfaceMap<800 * 800, 20000>;

const Pose2d kLaser{0.6, 0.0, 0.0};

/// The hall with the column moved by `dx` along x.
std::vector<Segment> movedHall(double dx) {
  std::vector<Segment> moved = hall();
  for (std::size_t i = 4; i < 8; ++i) {  // the column's four sides (hall(): 4 walls, then it)
    moved[i].a.x() += dx;
    moved[i].b.x() += dx;
  }
  return moved;
}

/// Unsigned distance from `p` to the segments [first, last) of `segs`.
double distanceTo(const std::vector<Segment>& segs, std::size_t first, std::size_t last, const Eigen::Vector2d& p) {
  double best = 1e9;
  for (std::size_t i = first; i < last; ++i) {
    const Eigen::Vector2d e = segs[i].b - segs[i].a;
    const double u = std::clamp((p - segs[i].a).dot(e) / e.squaredNorm(), 0.0, 1.0);
    best = std::min(best, (segs[i].a + u * e - p).norm());
  }
  return best;
}

struct World {
  std::unique_ptr<HallField> field = std::make_unique<HallField>();
  std::unique_ptr<LaserScan> scan = std::make_unique<LaserScan>();
  std::unique_ptr<MatchPoints> points = std::make_unique<MatchPoints>();
  std::unique_ptr<MatchPoints> out = std::make_unique<MatchPoints>();
  std::vector<Segment> moved = movedHall(0.15);
  std::mt19937_64 rng{11};
  World() { buildField(*field, hall(), 0.0, 0.0, 12.0, 8.0); }
  /// Scans the moved hall from vehicle pose `truth`.
  void view(const Pose2d& truth, double sigma) {
    castScan(moved, truth.compose(kLaser), sigma, rng, *scan);
    scanToMatchPoints(*scan, *points);
  }
};

}  // namespace

TEST_CASE("map changes: the moved column's points are selected, no wall's", "[localization][changes]") {
  World w;
  auto detector = std::make_unique<MapChangeDetector>();
  const double sigma = 0.01;
  for (const Pose2d truth : {Pose2d{3.0, 3.5, 0.0}, Pose2d{2.5, 2.0, 0.3}, Pose2d{3.5, 5.5, -0.4},
                             Pose2d{8.0, 1.5, 2.5}, Pose2d{7.5, 3.5, kPiD}}) {
    w.view(truth, sigma);
    const Pose2d sensor = truth.compose(kLaser);
    REQUIRE(detector->select(*w.points, sensor, *w.field, *w.out) == Status::Ok);
    // 1 cm noise: the threshold stays at its 4 cm floor (3 robust sigmas are about 3 cm).
    CHECK(detector->threshold() == Approx(0.04));
    std::size_t onMovedColumn = 0;  // column points farther than 5 cm (the threshold + 1 sigma) from the old column
    std::size_t selectedThere = 0;
    for (const MatchPoint& p : *w.points) {
      const Eigen::Vector2d q = sensor.transformPoint(Eigen::Vector2d(p.x, p.y));
      if (distanceTo(w.moved, 4, 8, q) < 3.0 * sigma && distanceTo(hall(), 4, 8, q) > 0.05 &&
          distanceTo(hall(), 0, 4, q) > 0.05) {
        ++onMovedColumn;
      }
    }
    for (const MatchPoint& p : *w.out) {
      const Eigen::Vector2d q = sensor.transformPoint(Eigen::Vector2d(p.x, p.y));
      INFO("selected point " << q.x() << " " << q.y());
      // Every selected point lies on the moved column, none on a wall or the rack.
      CHECK(distanceTo(w.moved, 4, 8, q) < 4.0 * sigma);
      selectedThere += distanceTo(hall(), 4, 8, q) > 0.05 && distanceTo(hall(), 0, 4, q) > 0.05 ? 1U : 0U;
    }
    INFO("view " << truth.x << " " << truth.y << ": " << selectedThere << " of " << onMovedColumn);
    CHECK(onMovedColumn > 10U);
    CHECK(selectedThere >= onMovedColumn * 95 / 100);
  }
}

TEST_CASE("map changes: an unchanged hall has no change, and the threshold follows the scan's noise",
          "[localization][changes]") {
  auto field = std::make_unique<HallField>();
  buildField(*field, hall(), 0.0, 0.0, 12.0, 8.0);
  auto scan = std::make_unique<LaserScan>();
  auto points = std::make_unique<MatchPoints>();
  auto out = std::make_unique<MatchPoints>();
  auto detector = std::make_unique<MapChangeDetector>();
  std::mt19937_64 rng(4);
  for (const double sigma : {0.005, 0.01, 0.03}) {
    std::size_t selected = 0;
    std::size_t total = 0;
    for (const Pose2d truth : {Pose2d{3.0, 3.5, 0.0}, Pose2d{2.5, 2.0, 0.3}, Pose2d{8.0, 1.5, 2.5}}) {
      castScan(hall(), truth.compose(kLaser), sigma, rng, *scan);
      scanToMatchPoints(*scan, *points);
      REQUIRE(detector->select(*points, truth.compose(kLaser), *field, *out) == Status::Ok);
      // At least the floor; 3 robust sigmas of the residuals across the surfaces, which are the
      // range noise times the cosine of the incidence (1.5-3 sigma of the range noise here), plus a
      // little of the field's own error.
      CHECK(detector->threshold() >= 0.04);
      CHECK(detector->threshold() >= 1.5 * sigma);
      CHECK(detector->threshold() <= std::max(0.04, 3.0 * sigma * 1.3));
      if (sigma > 0.02) {
        CHECK(detector->threshold() > 0.05);  // the noisy scan raises it above the floor
      }
      selected += out->size();
      total += points->size();
    }
    // Beyond 3 sigmas of a Gaussian: 0.27 %; allow ten times that.
    INFO("sigma " << sigma << ": " << selected << " of " << total);
    CHECK(selected * 1000 <= total * 27);
  }
}

TEST_CASE("map changes: kept changes leave the moved column out of the match, from every view",
          "[localization][changes]") {
  World w;
  auto detector = std::make_unique<MapChangeDetector>();
  // As the pipeline keeps them: the field saturated at three cells.
  const SurfaceMapParams changeParams = changeMapParams(SurfaceMapParams{}, MapChangeParams{});
  REQUIRE(changeParams.validate() == Status::Ok);
  CHECK(changeParams.field.maxDistance == Approx(0.15));
  auto changes = std::make_unique<TestSurfaceMap>(changeParams);
  auto kept = std::make_unique<MatchPoints>();
  auto matcher = std::make_unique<ScanMatcher>();
  const double sigma = 0.01;
  // Two views place the changes (at the true pose: what a fused match against the walls gives).
  for (const Pose2d truth : {Pose2d{3.0, 3.5, 0.0}, Pose2d{8.0, 1.5, 2.5}}) {
    w.view(truth, sigma);
    REQUIRE(detector->select(*w.points, truth.compose(kLaser), *w.field, *w.out) == Status::Ok);
    REQUIRE(changes->insert(*w.out, truth.compose(kLaser)).status == Status::Ok);
  }
  REQUIRE(changes->field().built());
  // Including (7.5, 3.5) facing the column, the far wall 7.5 m behind: there the column is most of
  // what fixes x, and a match of every point follows it.
  double allSum = 0.0;
  double keptSum = 0.0;
  int n = 0;
  for (const Pose2d truth :
       {Pose2d{3.0, 3.5, 0.0}, Pose2d{2.5, 2.0, 0.3}, Pose2d{3.5, 5.5, -0.4}, Pose2d{7.5, 3.5, kPiD}}) {
    w.view(truth, sigma);
    const Pose2d sensor = truth.compose(kLaser);
    std::size_t dropped = 0;
    REQUIRE(detector->keepUnchanged(*w.points, sensor, *w.field, changes->field(), *kept, dropped) == Status::Ok);
    CHECK(kept->size() + dropped == w.points->size());
    // Only moved-column points are dropped.
    std::size_t droppedWall = 0;
    for (const MatchPoint& p : *w.points) {
      const Eigen::Vector2d q = sensor.transformPoint(Eigen::Vector2d(p.x, p.y));
      const bool onWall = distanceTo(w.moved, 4, 8, q) > 4.0 * sigma;
      const bool isKept =
          std::any_of(kept->begin(), kept->end(), [&](const MatchPoint& k) { return k.x == p.x && k.y == p.y; });
      droppedWall += onWall && !isKept ? 1U : 0U;
    }
    CHECK(droppedWall == 0U);
    const ScanMatchResult all = matcher->match(*w.points, kLaser, truth, Eigen::Matrix3d::Zero(), *w.field);
    const ScanMatchResult unchanged = matcher->match(*kept, kLaser, truth, Eigen::Matrix3d::Zero(), *w.field);
    REQUIRE(all.status == Status::Ok);
    REQUIRE(unchanged.status == Status::Ok);
    const double ea = std::hypot(all.pose.x - truth.x, all.pose.y - truth.y);
    const double ek = std::hypot(unchanged.pose.x - truth.x, unchanged.pose.y - truth.y);
    INFO("view " << truth.x << " " << truth.y << ": dropped " << dropped << ", every point " << ea << " m, kept " << ek
                 << " m");
    CHECK(dropped > 10U);
    CHECK(ek < 0.01);
    CHECK(std::fabs(normalizeAngle(unchanged.pose.theta - truth.theta)) < 0.1 * kPiD / 180.0);
    allSum += ea;
    keptSum += ek;
    ++n;
  }
  // Every point: pulled towards the mapped column by centimetres where it fixes an axis.
  CHECK(allSum / n > 3.0 * keptSum / n);
}

TEST_CASE("map changes: a change next to an unchanged surface takes nothing from it", "[localization][changes]") {
  // A change recorded at the column's old place (it moved away and back, or a pallet stood in
  // front of it): the column's points fit the mapped field and are all kept.
  World w;
  auto detector = std::make_unique<MapChangeDetector>();
  auto changes = std::make_unique<TestSurfaceMap>();
  auto kept = std::make_unique<MatchPoints>();
  const Pose2d truth{3.0, 3.5, 0.0};
  w.view(truth, 0.01);
  REQUIRE(detector->select(*w.points, truth.compose(kLaser), *w.field, *w.out) == Status::Ok);
  REQUIRE(changes->insert(*w.out, truth.compose(kLaser)).status == Status::Ok);
  castScan(hall(), truth.compose(kLaser), 0.01, w.rng, *w.scan);  // the column back where mapped
  scanToMatchPoints(*w.scan, *w.points);
  std::size_t dropped = 99;
  REQUIRE(detector->keepUnchanged(*w.points, truth.compose(kLaser), *w.field, changes->field(), *kept, dropped) ==
          Status::Ok);
  CHECK(dropped == 0U);
  CHECK(kept->size() == w.points->size());
}

TEST_CASE("map changes: refusals, non-finite points, an empty change map", "[localization][changes]") {
  World w;
  w.view(Pose2d{3.0, 3.5, 0.0}, 0.01);
  const Pose2d sensor = Pose2d{3.0, 3.5, 0.0}.compose(kLaser);
  auto changes = std::make_unique<TestSurfaceMap>();
  auto kept = std::make_unique<MatchPoints>();
  std::size_t dropped = 0;
  {
    MapChangeDetector d;
    const double nan = std::numeric_limits<double>::quiet_NaN();
    REQUIRE(w.out->push_back(MatchPoint{}) == Status::Ok);
    CHECK(d.select(*w.points, Pose2d{nan, 0.0, 0.0}, *w.field, *w.out) == Status::NonFiniteInput);
    CHECK(w.out->empty());
    auto empty = std::make_unique<HallField>();
    CHECK(d.select(*w.points, sensor, *empty, *w.out) == Status::NotInitialized);
    CHECK(w.out->empty());
    // Not built: every point is kept.
    CHECK(d.keepUnchanged(*w.points, sensor, *w.field, changes->field(), *kept, dropped) == Status::Ok);
    CHECK(kept->size() == w.points->size());
    CHECK(dropped == 0U);
    CHECK(d.keepUnchanged(*w.points, Pose2d{0.0, nan, 0.0}, *w.field, changes->field(), *kept, dropped) ==
          Status::NonFiniteInput);
    CHECK(kept->size() == w.points->size());
  }
  for (const auto& bad :
       {MapChangeParams{0.0, 3.0, 0.3}, MapChangeParams{0.04, -1.0, 0.3}, MapChangeParams{0.04, 3.0, 0.03},
        MapChangeParams{std::nan(""), 3.0, 0.3}, MapChangeParams{0.04, std::numeric_limits<double>::infinity(), 0.3}}) {
    MapChangeDetector d(bad);
    CHECK(bad.validate() != Status::Ok);
    CHECK(d.select(*w.points, sensor, *w.field, *w.out) == bad.validate());
    CHECK(w.out->empty());
    CHECK(d.keepUnchanged(*w.points, sensor, *w.field, changes->field(), *kept, dropped) == bad.validate());
    CHECK(kept->size() == w.points->size());
  }
  // Non-finite points are skipped by the detection, and kept (for the matcher to skip) otherwise.
  MapChangeDetector d;
  const std::size_t n = w.points->size();
  REQUIRE(w.points->push_back(MatchPoint{std::numeric_limits<float>::quiet_NaN(), 1.0F}) == Status::Ok);
  REQUIRE(w.points->push_back(MatchPoint{1.0F, std::numeric_limits<float>::infinity()}) == Status::Ok);
  REQUIRE(d.select(*w.points, sensor, *w.field, *w.out) == Status::Ok);
  for (const MatchPoint& p : *w.out) {
    CHECK(std::isfinite(p.x));
    CHECK(std::isfinite(p.y));
  }
  REQUIRE(changes->insert(*w.out, sensor).status == Status::Ok);
  REQUIRE(d.keepUnchanged(*w.points, sensor, *w.field, changes->field(), *kept, dropped) == Status::Ok);
  CHECK(kept->size() + dropped == n + 2U);
}

TEST_CASE("map changes: detection and filtering allocate nothing", "[localization][changes][alloc]") {
  World w;
  auto detector = std::make_unique<MapChangeDetector>();
  auto changes = std::make_unique<TestSurfaceMap>();
  auto kept = std::make_unique<MatchPoints>();
  const Pose2d truth{3.0, 3.5, 0.0};
  w.view(truth, 0.01);
  const Pose2d sensor = truth.compose(kLaser);
  Status st = Status::InvalidArgument;
  AGV_CHECK_NO_ALLOCATIONS(st = detector->select(*w.points, sensor, *w.field, *w.out));
  CHECK(st == Status::Ok);
  REQUIRE(changes->insert(*w.out, sensor).status == Status::Ok);
  std::size_t dropped = 0;
  AGV_CHECK_NO_ALLOCATIONS(st = detector->keepUnchanged(*w.points, sensor, *w.field, changes->field(), *kept, dropped));
  CHECK(st == Status::Ok);
  CHECK(dropped > 0U);
}
