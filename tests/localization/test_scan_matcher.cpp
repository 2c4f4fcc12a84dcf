// Likelihood field and scan-to-map matching: distances against the geometry they were built from,
// recovery of a known pose from a ray-cast scan with injected range noise, the corridor's
// unobservable direction in the covariance, refusals, the localizer fusing matches (and
// re-synchronising after a slip its odometry model did not cover), zero allocations.
#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <random>
#include <vector>

#include "agv/localization/field_relocalizer.hpp"
#include "agv/localization/likelihood_field.hpp"
#include "agv/localization/localizer.hpp"
#include "agv/localization/scan_matcher.hpp"
#include "agv/localization/surface_map.hpp"
#include "agv_test.hpp"
#include "scan_hall.hpp"

using namespace agv;
using namespace agv::test;

TEST_CASE("likelihood field: signed distances to the surfaces it was given, saturated, with outward gradients",
          "[localization][field]") {
  auto field = std::make_unique<HallField>();
  const std::vector<Segment> segs = hall();
  buildField(*field, segs, 0.0, 0.0, 12.0, 8.0);
  // Signed distance to the nearest segment, computed directly: positive in free space.
  const auto truth = [&](const Eigen::Vector2d& p) {
    double best = 1e9;
    for (const Segment& s : segs) {
      const Eigen::Vector2d e = s.b - s.a;
      const double u = std::clamp((p - s.a).dot(e) / e.squaredNorm(), 0.0, 1.0);
      best = std::min(best, (s.a + u * e - p).norm());
    }
    return inFreeSpace(p) ? best : -best;
  };
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> ux(-0.5, 12.5);
  std::uniform_real_distribution<double> uy(-0.5, 8.5);
  const double maxD = field->params().maxDistance;
  int near = 0;
  for (int k = 0; k < 4000; ++k) {
    const Eigen::Vector2d p(ux(rng), uy(rng));
    const FieldSample s = field->sample(p.x(), p.y());
    const double d = truth(p);
    const double tol = 0.5 * field->params().resolution + maxD / 127.0;
    if (!s.inside) {
      // Unknown only where a cell within one diagonal is out of every surface's reach.
      CHECK(std::fabs(d) > maxD - 1.5 * field->params().resolution - tol);
      CHECK(s.distance == Approx(maxD));
      continue;
    }
    CHECK(std::fabs(s.distance) <= maxD + 1e-9);
    if (d <= 0.0) {
      // Behind a surface: negative where straight behind a long face (below the hall's first wall,
      // away from its ends). Elsewhere behind (past a box's corner) the sign is not defined.
      if (p.y() < 0.0 && p.x() > 0.5 && p.x() < 11.5) {
        CHECK(s.distance < tol);
      }
      continue;
    }
    // In free space the bilinear interpolation of a signed distance between cell centres 5 cm apart
    // is linear across a wall, so the error is the curvature of the distance near corners and
    // between surfaces (within res / 2) plus the 4 mm quantum.
    ++near;
    INFO("point " << p.x() << ", " << p.y() << ": truth " << d << ", field " << s.distance);
    CHECK(std::fabs(s.distance - d) <= tol);
    // The gradient points away from the surfaces and is no longer than a distance's.
    if (d > 0.1 && d < maxD - 0.15) {
      const Eigen::Vector2d step = p + 0.01 * s.gradient.normalized();
      INFO("gradient at " << p.x() << ", " << p.y() << ": " << s.gradient.transpose());
      CHECK(truth(step) > d);
      CHECK(s.gradient.norm() < 1.2);
    }
  }
  CHECK(near > 500);
  // Outside the area, non-finite: not inside, saturated.
  CHECK_FALSE(field->sample(-5.0, 0.0).inside);
  CHECK_FALSE(field->sample(std::nan(""), 1.0).inside);
  CHECK(field->sample(100.0, 100.0).distance == Approx(maxD));
}

TEST_CASE("likelihood field: bad parameters, capacity, points outside and an empty field are refused",
          "[localization][field]") {
  LikelihoodField<100> small;
  LikelihoodFieldParams p;
  CHECK(small.configure(p, 0.0, 0.0, 20, 20) == Status::CapacityExceeded);
  CHECK(small.width() == 0U);
  CHECK(small.addPoint(0.1, 0.1, 1.0, 0.0) == Status::NotInitialized);
  CHECK(small.build() == Status::NotInitialized);
  CHECK(small.configure(p, std::nan(""), 0.0, 10, 10) == Status::NonFiniteInput);
  CHECK(small.configure(p, 0.0, 0.0, 1, 10) == Status::InvalidArgument);
  LikelihoodFieldParams bad = p;
  bad.resolution = 0.0;
  CHECK(small.configure(bad, 0.0, 0.0, 10, 10) == Status::InvalidArgument);
  bad = p;
  bad.maxDistance = 0.05;  // not above two cells
  CHECK(bad.validate() == Status::InvalidArgument);
  bad.maxDistance = 300.0 * p.resolution;  // beyond 255 quanta of a cell
  CHECK(bad.validate() == Status::InvalidArgument);
  bad.maxDistance = std::numeric_limits<double>::infinity();
  CHECK(bad.validate() == Status::NonFiniteInput);
  REQUIRE(small.configure(p, 0.0, 0.0, 10, 10) == Status::Ok);
  CHECK(small.build() == Status::EmptyInput);
  CHECK_FALSE(small.sample(0.2, 0.2).inside);  // not built
  CHECK(small.addPoint(0.6, 0.2, 1.0, 0.0) == Status::OutOfRange);
  CHECK(small.addPoint(-0.01, 0.2, 1.0, 0.0) == Status::OutOfRange);
  CHECK(small.addPoint(std::numeric_limits<double>::infinity(), 0.2, 1.0, 0.0) == Status::NonFiniteInput);
  CHECK(small.addPoint(0.2, 0.2, 0.0, std::nan("")) == Status::NonFiniteInput);
  CHECK(small.addPoint(0.2, 0.2, 0.0, 0.0) == Status::InvalidArgument);
  CHECK(small.pointsOutside() == 2U);
  // A wall of points facing +x at x = 0.26: cells in front are positive, behind negative.
  for (int i = 0; i < 50; ++i) {
    CHECK(small.addPoint(0.26, 0.01 * i, 1.0, 0.0) == Status::Ok);
  }
  REQUIRE(small.build() == Status::Ok);
  CHECK(small.sample(0.36, 0.25).distance == Approx(0.1).margin(0.005));
  CHECK(small.sample(0.16, 0.25).distance == Approx(-0.1).margin(0.005));
  CHECK(small.sample(0.26, 0.25).distance == Approx(0.0).margin(0.005));
  CHECK(small.sample(0.26, 0.25).gradient.x() == Approx(1.0).margin(0.1));
}

TEST_CASE("likelihood field: every cell is the nearest segment's quantized distance, as a brute force computes it",
          "[localization][field]") {
  // Random segments (any direction, some near the edges) in a 4 m x 3 m area with its origin off
  // the cell grid. The reference visits every cell for every segment, in the same order, with the
  // rule of addSegment's documentation (the Euclidean distance to the nearest point of the
  // segment, rounded half away from zero to the stored quantum, kept when nearer to zero, negative
  // within 45 deg of straight behind the normal). Two sets:
  // - sparse: 16 segments (points, short pieces, long walls), few enough that each one's rim is
  //   the nearest surface somewhere (a field that skipped the outer tenth of each segment's reach
  //   fails here in 29 cells);
  // - dense: 240 pieces of 2-15 cm along six walls with 1 cm of scatter, as a surface map paints a
  //   wall seen in many scans: most cells are reached by many pieces, and a cell skipped because
  //   another piece is nearer (addSegment's bounding-box test) must be one the full test would
  //   have left as it is (a skip for stored distances up to the box's plus 1.5 quanta, two more than
  //   the safe margin, fails here in 75 cells, the sparse set in 3).
  struct Set {
    const char* name;
    int segments;
    bool walls;
    std::uint64_t seed;
  };
  const Set set = GENERATE(Set{"sparse", 16, false, 11}, Set{"dense", 240, true, 12});
  CAPTURE(set.name);
  const LikelihoodFieldParams p;  // 5 cm, 0.5 m
  constexpr std::size_t kW = 80;
  constexpr std::size_t kH = 60;
  const double ox = -1.013;
  const double oy = 0.377;
  auto field = std::make_unique<LikelihoodField<kW * kH>>();
  REQUIRE(field->configure(p, ox, oy, kW, kH) == Status::Ok);
  const double quantum = p.maxDistance / 127.0;
  std::vector<int> ref(kW * kH, 127);
  std::mt19937_64 rng(set.seed);
  std::uniform_real_distribution<double> ux(ox + 0.001, ox + kW * p.resolution - 0.001);
  std::uniform_real_distribution<double> uy(oy + 0.001, oy + kH * p.resolution - 0.001);
  std::uniform_real_distribution<double> angle(-kPiD, kPiD);
  std::uniform_real_distribution<double> len(0.0, 1.5);
  std::uniform_real_distribution<double> along(0.0, 1.0);
  std::uniform_real_distribution<double> piece(0.02, 0.15);
  std::normal_distribution<double> scatter(0.0, 0.01);
  // The dense set's walls: three axis-aligned, three oblique, two of them crossing.
  const double walls[6][4] = {{-0.9, 0.6, 2.8, 0.6}, {-0.9, 3.2, 2.8, 3.2}, {0.4, 0.5, 0.4, 3.3},
                              {-0.8, 0.5, 2.7, 3.3}, {2.7, 0.7, 0.2, 2.1},  {-0.9, 2.2, 1.2, 3.3}};
  std::size_t added = 0;
  for (int k = 0; k < set.segments; ++k) {
    double ax = 0.0;
    double ay = 0.0;
    double bx = 0.0;
    double by = 0.0;
    if (set.walls) {
      const double* w = walls[k % 6];
      const double wl = std::hypot(w[2] - w[0], w[3] - w[1]);
      const double ux0 = (w[2] - w[0]) / wl;
      const double uy0 = (w[3] - w[1]) / wl;
      const double s0 = along(rng) * wl;
      const double l = piece(rng);
      ax = w[0] + s0 * ux0 + scatter(rng);
      ay = w[1] + s0 * uy0 + scatter(rng);
      bx = ax + l * ux0 + scatter(rng);
      by = ay + l * uy0 + scatter(rng);
    } else {
      ax = ux(rng);
      ay = uy(rng);
      const double a = angle(rng);
      const double l = k % 5 == 0 ? 0.0 : len(rng);  // every fifth a point
      bx = ax + l * std::cos(a);
      by = ay + l * std::sin(a);
    }
    const double na = angle(rng);
    const double nx = std::cos(na);
    const double ny = std::sin(na);
    if (field->addSegment(ax, ay, bx, by, nx, ny) != Status::Ok) {
      continue;  // an end outside the area: nothing added (checked below by the reference's absence)
    }
    ++added;
    const double ex = bx - ax;
    const double ey = by - ay;
    const double e2 = ex * ex + ey * ey;
    for (std::size_t iy = 0; iy < kH; ++iy) {
      for (std::size_t ix = 0; ix < kW; ++ix) {
        const double cx = ox + (static_cast<double>(ix) + 0.5) * p.resolution;
        const double cy = oy + (static_cast<double>(iy) + 0.5) * p.resolution;
        const double t = e2 > 0.0 ? std::clamp(((cx - ax) * ex + (cy - ay) * ey) / e2, 0.0, 1.0) : 0.0;
        const double dx = cx - (ax + t * ex);
        const double dy = cy - (ay + t * ey);
        const double d = std::sqrt(dx * dx + dy * dy);
        if (d >= p.maxDistance) {
          continue;
        }
        const long q = std::lround(d / quantum);
        int& cell = ref[ix + iy * kW];
        if (q < std::abs(cell)) {
          const bool behind = dx * nx + dy * ny < -std::cos(kPiD / 4.0) * d;
          cell = static_cast<int>(behind ? -q : q);
        }
      }
    }
  }
  REQUIRE(added > static_cast<std::size_t>(set.segments) / 2U);
  REQUIRE(field->build() == Status::Ok);
  std::size_t near = 0;
  std::size_t mismatched = 0;
  for (std::size_t iy = 0; iy < kH; ++iy) {
    for (std::size_t ix = 0; ix < kW; ++ix) {
      const int expected = ref[ix + iy * kW];
      near += expected != 127 ? 1U : 0U;
      mismatched += field->cellDistance(ix, iy) == static_cast<double>(expected) * quantum ? 0U : 1U;
    }
  }
  CHECK(near > kW * kH / 8U);  // the segments reach a good part of the area
  CHECK(mismatched == 0U);
}

TEST_CASE("likelihood field: a window of a larger field, moved by whole cells and completed, equals it cell for cell",
          "[localization][field]") {
  // A 6 m x 4.5 m field holds 24 random segments, many crossing the edges of a 4 m x 3 m window
  // inside it. The window, configured 10 x 5 cells in, takes every segment clipped to it
  // (addSegmentIn), then moves 7 cells right and 4 down (shift) and takes them again in the
  // strips it uncovered: each time every cell equals the large field's cell under it.
  const LikelihoodFieldParams p;
  constexpr std::size_t kBigW = 120;
  constexpr std::size_t kBigH = 90;
  constexpr std::size_t kW = 80;
  constexpr std::size_t kH = 60;
  const double ox = -1.013;
  const double oy = 0.377;
  auto big = std::make_unique<LikelihoodField<kBigW * kBigH>>();
  auto window = std::make_unique<LikelihoodField<kW * kH>>();
  REQUIRE(big->configure(p, ox, oy, kBigW, kBigH) == Status::Ok);
  struct Piece {
    double ax, ay, bx, by, nx, ny;
  };
  std::vector<Piece> pieces;
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> ux(ox + 0.3, ox + kBigW * p.resolution - 0.3);
  std::uniform_real_distribution<double> uy(oy + 0.3, oy + kBigH * p.resolution - 0.3);
  std::uniform_real_distribution<double> angle(-kPiD, kPiD);
  std::uniform_real_distribution<double> len(0.0, 2.0);
  for (int k = 0; k < 24; ++k) {
    Piece s{};
    s.ax = ux(rng);
    s.ay = uy(rng);
    const double a = angle(rng);
    const double l = k % 6 == 0 ? 0.0 : len(rng);
    s.bx = std::clamp(s.ax + l * std::cos(a), ox + 0.01, ox + kBigW * p.resolution - 0.01);
    s.by = std::clamp(s.ay + l * std::sin(a), oy + 0.01, oy + kBigH * p.resolution - 0.01);
    const double na = angle(rng);
    s.nx = std::cos(na);
    s.ny = std::sin(na);
    REQUIRE(big->addSegment(s.ax, s.ay, s.bx, s.by, s.nx, s.ny) == Status::Ok);
    pieces.push_back(s);
  }
  REQUIRE(big->build() == Status::Ok);
  // The window's cells are computed from its own origin, the large field's from another: a
  // distance on a rounding boundary of the quantum may round the other way (one quantum, in a
  // rare cell; every cell is equal here on x86-64 and aarch64).
  const double quantum = p.maxDistance / 127.0;
  const auto compare = [&](std::size_t offX, std::size_t offY) {
    std::size_t near = 0;
    std::size_t differing = 0;
    std::size_t beyondQuantum = 0;
    for (std::size_t iy = 0; iy < kH; ++iy) {
      for (std::size_t ix = 0; ix < kW; ++ix) {
        const double expected = big->cellDistance(ix + offX, iy + offY);
        const double got = window->cellDistance(ix, iy);
        near += expected < p.maxDistance ? 1U : 0U;
        differing += got == expected ? 0U : 1U;
        beyondQuantum += std::fabs(got - expected) <= 1.001 * quantum ? 0U : 1U;
      }
    }
    CHECK(near > kW * kH / 4U);
    CHECK(beyondQuantum == 0U);
    CHECK(differing <= 2U);
  };
  REQUIRE(window->configure(p, ox + 10 * p.resolution, oy + 5 * p.resolution, kW, kH) == Status::Ok);
  std::size_t crossing = 0;  // segments with an end outside the window: addSegment would refuse them
  for (const Piece& s : pieces) {
    REQUIRE(window->addSegmentIn(CellRange{0, 0, kW, kH}, s.ax, s.ay, s.bx, s.by, s.nx, s.ny) == Status::Ok);
    const double ua = (s.ax - window->originX()) / p.resolution;
    const double ub = (s.bx - window->originX()) / p.resolution;
    const double va = (s.ay - window->originY()) / p.resolution;
    const double vb = (s.by - window->originY()) / p.resolution;
    crossing += std::min({ua, ub, va, vb}) < 0.0 || std::max(ua, ub) >= kW || std::max(va, vb) >= kH ? 1U : 0U;
  }
  CHECK(crossing >= 8U);
  REQUIRE(window->build() == Status::Ok);
  compare(10, 5);
  // Move by (7, -4) cells: columns 73..79 and rows 0..3 are uncovered.
  REQUIRE(window->shift(7, -4, ox + 17 * p.resolution, oy + 1 * p.resolution) == Status::Ok);
  CHECK(window->built());
  CHECK(window->cellDistance(kW - 1, kH / 2) == p.maxDistance);  // uncovered: free until filled
  for (const Piece& s : pieces) {
    REQUIRE(window->addSegmentIn(CellRange{kW - 7, 0, kW, kH}, s.ax, s.ay, s.bx, s.by, s.nx, s.ny) == Status::Ok);
    REQUIRE(window->addSegmentIn(CellRange{0, 0, kW - 7, 4}, s.ax, s.ay, s.bx, s.by, s.nx, s.ny) == Status::Ok);
  }
  compare(17, 1);
  // A range beyond the area is clipped to it; refusals leave the field as it was.
  CHECK(window->addSegmentIn(CellRange{0, 0, 10 * kW, 10 * kH}, pieces[0].ax, pieces[0].ay, pieces[0].bx, pieces[0].by,
                             pieces[0].nx, pieces[0].ny) == Status::Ok);
  CHECK(window->addSegmentIn(CellRange{0, 0, kW, kH}, std::numeric_limits<double>::quiet_NaN(), 0.0, 0.0, 0.0, 1.0,
                             0.0) == Status::NonFiniteInput);
  CHECK(window->addSegmentIn(CellRange{0, 0, kW, kH}, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0) == Status::InvalidArgument);
  CHECK(window->shift(static_cast<long>(kW), 0, ox, oy) == Status::OutOfRange);
  CHECK(window->shift(0, -static_cast<long>(kH), ox, oy) == Status::OutOfRange);
  CHECK(window->shift(1, 0, std::numeric_limits<double>::infinity(), oy) == Status::NonFiniteInput);
  compare(17, 1);
  auto empty = std::make_unique<LikelihoodField<16>>();
  CHECK(empty->shift(0, 0, 0.0, 0.0) == Status::NotInitialized);
  CHECK(empty->addSegmentIn(CellRange{0, 0, 4, 4}, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0) == Status::NotInitialized);
}

TEST_CASE("scan matcher: a ray-cast scan is aligned to the pose it was taken from", "[localization][scanmatch]") {
  auto field = std::make_unique<HallField>();
  const std::vector<Segment> segs = hall();
  buildField(*field, segs, 0.0, 0.0, 12.0, 8.0);
  auto scan = std::make_unique<LaserScan>();
  auto matcher = std::make_unique<ScanMatcher>();
  const Pose2d laser{0.6, 0.0, 0.0};
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> px(2.0, 9.5);
  std::uniform_real_distribution<double> py(1.2, 6.8);
  std::uniform_real_distribution<double> pt(-kPiD, kPiD);
  std::uniform_real_distribution<double> off(-1.0, 1.0);
  const double sigma = 0.01;  // range noise [m]
  int tried = 0;
  for (int k = 0; k < 40; ++k) {
    const Pose2d truth{px(rng), py(rng), pt(rng)};
    // Only poses whose vehicle and laser are in free space, 0.3 m clear of every surface.
    const Eigen::Vector2d lw = truth.compose(laser).translation();
    bool clear = true;
    for (const double dx : {-0.3, 0.0, 0.3}) {
      for (const double dy : {-0.3, 0.0, 0.3}) {
        clear = clear && inFreeSpace(lw + Eigen::Vector2d(dx, dy)) &&
                inFreeSpace(truth.translation() + Eigen::Vector2d(dx, dy));
      }
    }
    if (!clear) {
      continue;
    }
    ++tried;
    castScan(segs, truth.compose(laser), sigma, rng, *scan);
    // Prior off by up to 15 cm and 3 deg: within the truncated field's basin.
    const Pose2d prior{truth.x + 0.15 * off(rng), truth.y + 0.15 * off(rng), truth.theta + 0.05 * off(rng)};
    const ScanMatchResult m = matcher->match(*scan, laser, prior, *field);
    REQUIRE(m.status == Status::Ok);
    // ~150 points at 1 cm noise fix the pose to ~1 mm; the surfaces are exact (dense points, exact
    // distances), the bilinear interpolation of the field leaves a few millimetres.
    CHECK(std::hypot(m.pose.x - truth.x, m.pose.y - truth.y) < 0.01);
    CHECK(std::fabs(normalizeAngle(m.pose.theta - truth.theta)) < 0.1 * kPiD / 180.0);
    CHECK(m.inliers > 100U);
    CHECK(m.rmsResidual < 3.0 * sigma);
    // The covariance is a covariance and no tighter than the noise allows.
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(m.covariance);
    CHECK(es.eigenvalues().minCoeff() > 0.0);
    CHECK(std::sqrt(m.covariance(0, 0)) < 0.02);
    CHECK(std::sqrt(m.covariance(2, 2)) < 0.005);
  }
  CHECK(tried >= 30);
}

TEST_CASE("scan matcher: the adaptive band keeps a moved object from biasing the pose", "[localization][scanmatch]") {
  // The field is the hall as mapped; the scans see it after the column was moved 0.15 m along x
  // (a pallet put down a little farther along a lane). Its points lie 0.15 m off the mapped
  // column: inside the wide band (0.3 m), where Huber's constant force pulls the pose towards
  // the old column; 3 robust sigmas of the residuals (1 cm range noise: a few centimetres)
  // leave them out. The views keep the column a minority of what fixes each axis: where it is most
  // of it (from (7.5, 3.5) facing it, the far wall 7.5 m behind), both bands follow the column, and
  // no band can tell which surface moved.
  auto field = std::make_unique<HallField>();
  buildField(*field, hall(), 0.0, 0.0, 12.0, 8.0);
  std::vector<Segment> moved = hall();
  for (std::size_t i = 4; i < 8; ++i) {  // the column's four sides (hall(): 4 walls, then it)
    moved[i].a.x() += 0.15;
    moved[i].b.x() += 0.15;
  }
  auto scan = std::make_unique<LaserScan>();
  auto matcher = std::make_unique<ScanMatcher>();
  const Pose2d laser{0.6, 0.0, 0.0};
  std::mt19937_64 rng(5);
  const double sigma = 0.01;
  double wideSum = 0.0;
  double bandSum = 0.0;
  int n = 0;
  for (const Pose2d truth : {Pose2d{3.0, 3.5, 0.0}, Pose2d{2.5, 2.0, 0.3}, Pose2d{3.5, 5.5, -0.4},
                             Pose2d{8.0, 1.5, 2.5}, Pose2d{2.0, 6.0, -0.8}}) {
    castScan(moved, truth.compose(laser), sigma, rng, *scan);
    ScanMatchParams p;
    p.adaptiveBand = false;
    matcher->setParams(p);
    const ScanMatchResult wide = matcher->match(*scan, laser, truth, *field);
    p.adaptiveBand = true;
    matcher->setParams(p);
    ScanMatchResult band;
    AGV_CHECK_NO_ALLOCATIONS(band = matcher->match(*scan, laser, truth, *field));
    REQUIRE(wide.status == Status::Ok);
    REQUIRE(band.status == Status::Ok);
    const double ew = std::hypot(wide.pose.x - truth.x, wide.pose.y - truth.y);
    const double eb = std::hypot(band.pose.x - truth.x, band.pose.y - truth.y);
    // Without the moved points the pose is held to the noise-only figure of the test above.
    INFO("pose " << truth.x << " " << truth.y << " " << truth.theta << " wide " << ew << " band " << eb);
    CHECK(eb < 0.01);
    CHECK(std::fabs(normalizeAngle(band.pose.theta - truth.theta)) < 0.1 * kPiD / 180.0);
    wideSum += ew;
    bandSum += eb;
    ++n;
  }
  // The wide band is pulled towards the mapped column by several millimetres on average.
  CHECK(wideSum / n > 2.0 * bandSum / n);
  CHECK(wideSum / n > 0.005);
}

TEST_CASE("scan matcher: with the prior's covariance, a coarse search finds poses beyond the refinement's basin",
          "[localization][scanmatch]") {
  auto field = std::make_unique<HallField>();
  const std::vector<Segment> segs = hall();
  buildField(*field, segs, 0.0, 0.0, 12.0, 8.0);
  auto scan = std::make_unique<LaserScan>();
  auto matcher = std::make_unique<ScanMatcher>();
  std::mt19937_64 rng(17);
  const Pose2d laser{0.6, 0.0, 0.0};
  const Pose2d truth{3.0, 5.5, 0.7};
  castScan(segs, truth.compose(laser), 0.01, rng, *scan);
  // 0.4 m and 12 deg off: the truncated field's basin is ~0.3 m and a few degrees.
  const Pose2d prior{truth.x + 0.3, truth.y - 0.25, truth.theta + 0.21};
  Eigen::Matrix3d P = Eigen::Matrix3d::Zero();
  P.diagonal() << 0.15 * 0.15, 0.15 * 0.15, 0.1 * 0.1;  // 3 sigma covers the offset
  const ScanMatchResult local = matcher->match(*scan, laser, prior, *field);
  const bool localFound =
      local.status == Status::Ok && std::hypot(local.pose.x - truth.x, local.pose.y - truth.y) < 0.01;
  CHECK_FALSE(localFound);  // the refinement alone does not get there (else the test shows nothing)
  const ScanMatchResult searched = matcher->match(*scan, laser, prior, P, *field);
  REQUIRE(searched.status == Status::Ok);
  CHECK(searched.searched > 1000U);
  CHECK(searched.searched <= matcher->params().maxSearchPoses + 1U);
  CHECK(std::hypot(searched.pose.x - truth.x, searched.pose.y - truth.y) < 0.01);
  CHECK(std::fabs(normalizeAngle(searched.pose.theta - truth.theta)) < 0.1 * kPiD / 180.0);
  // A tight covariance: no search (the refinement alone), as without one.
  const ScanMatchResult tight = matcher->match(*scan, laser, truth, Eigen::Matrix3d::Identity() * 1e-6, *field);
  CHECK(tight.status == Status::Ok);
  CHECK(tight.searched == 0U);
  // A non-finite covariance is refused.
  Eigen::Matrix3d bad = P;
  bad(0, 0) = std::nan("");
  CHECK(matcher->match(*scan, laser, prior, bad, *field).status == Status::NonFiniteInput);
}

TEST_CASE("scan matcher: in a featureless corridor the covariance says the along-track position is unknown",
          "[localization][scanmatch]") {
  auto field = std::make_unique<LikelihoodField<1300 * 100>>();
  const std::vector<Segment> segs = corridor();
  buildField(*field, segs, -30.0, -1.0, 30.0, 1.0);
  auto scan = std::make_unique<LaserScan>();
  ScanMatcher matcher;
  std::mt19937_64 rng(5);
  const Pose2d truth{0.3, 0.2, 0.1};
  const Pose2d laser{};
  castScan(segs, truth, 0.01, rng, *scan, 20.0);
  const ScanMatchResult m = matcher.match(*scan, laser, Pose2d{0.3, 0.25, 0.12}, *field);
  if (m.status == Status::Ok) {
    // Across the corridor and in heading it is fixed; along it the walls say nothing.
    CHECK(std::fabs(m.pose.y - truth.y) < 0.01);
    CHECK(std::fabs(m.pose.theta - truth.theta) < 0.002);
    CHECK(m.covariance(0, 0) > 100.0 * m.covariance(1, 1));
  } else {
    CHECK(m.status == Status::Unobservable);
  }
}

TEST_CASE("scan matcher: refusals (no map, no beams, off the map, non-finite input)", "[localization][scanmatch]") {
  auto field = std::make_unique<HallField>();
  auto scan = std::make_unique<LaserScan>();
  ScanMatcher matcher;
  std::mt19937_64 rng(3);
  const std::vector<Segment> segs = hall();
  const Pose2d truth{3.0, 2.0, 0.4};
  castScan(segs, truth, 0.01, rng, *scan);
  CHECK(matcher.match(*scan, Pose2d{}, truth, *field).status == Status::NotInitialized);
  buildField(*field, segs, 0.0, 0.0, 12.0, 8.0);
  CHECK(matcher.match(*scan, Pose2d{}, truth, *field).status == Status::Ok);
  CHECK(matcher.match(*scan, Pose2d{}, Pose2d{std::nan(""), 0.0, 0.0}, *field).status == Status::NonFiniteInput);
  // A prior 3 m away: the points fall far from every surface.
  const ScanMatchResult far = matcher.match(*scan, Pose2d{}, Pose2d{6.0, 5.0, 2.0}, *field);
  CHECK(far.status != Status::Ok);
  // A scan of another building (every beam at 1.5 m: a round room): too few inliers.
  for (float& r : scan->ranges) {
    r = 1.5F;
  }
  CHECK(matcher.match(*scan, Pose2d{}, Pose2d{3.0, 4.0, 0.0}, *field).status == Status::NotEnoughData);
  // No valid beam.
  for (float& r : scan->ranges) {
    r = std::numeric_limits<float>::quiet_NaN();
  }
  CHECK(matcher.match(*scan, Pose2d{}, truth, *field).status == Status::EmptyInput);
  ScanMatchParams p;
  p.maxIterations = 0;
  CHECK(p.validate() == Status::InvalidArgument);
  p = ScanMatchParams{};
  p.huber = std::nan("");
  CHECK(p.validate() == Status::NonFiniteInput);
  p = ScanMatchParams{};
  p.minInlierFraction = 1.5;
  CHECK(p.validate() == Status::InvalidArgument);
  LocalizerParams lp;
  lp.scanMatchGate = -1.0;
  CHECK(lp.validate() == Status::InvalidArgument);
}

namespace {

/// A vehicle driving through the hall on the localizer with a likelihood field and no landmarks.
struct FieldRun {
  std::unique_ptr<HallField> field = std::make_unique<HallField>();
  std::vector<Segment> segs = hall();
  LocalizerParams params;
  std::unique_ptr<Localizer> loc;
  std::unique_ptr<LandmarkMap> map;
  std::unique_ptr<ScanObservations> obs = std::make_unique<ScanObservations>();
  std::unique_ptr<LaserScan> scan = std::make_unique<LaserScan>();
  Pose2d truth{2.0, 2.0, 0.0};
  Timestamp t = Timestamp::fromSeconds(1.0);
  std::mt19937_64 rng{21};

  explicit FieldRun(const ScanMatchParams& scanMatch = ScanMatchParams{}) {
    buildField(*field, segs, 0.0, 0.0, 12.0, 8.0);
    params.scanMatch = scanMatch;
    params.laser.mounting = Pose2d{0.6, 0.0, 0.0};
    loc = std::make_unique<Localizer>(params);
    LandmarkMapParams mp;
    mp.mode = MapMode::Static;
    map = std::make_unique<LandmarkMap>(mp);
    Eigen::Matrix3d P0 = Eigen::Matrix3d::Zero();
    P0.diagonal() << 0.01 * 0.01, 0.01 * 0.01, 0.005 * 0.005;
    REQUIRE(loc->reset(t, truth, P0) == Status::Ok);
  }

  /// Drives `delta` (vehicle frame) in 10 steps reporting `reported` to the filter, then one scan.
  /// `headingVariance` [rad^2]: what the odometry model says its heading may be off by over the
  /// cycle.
  const LocalizerHealth& step(const Pose2d& delta, const Pose2d& reported, double headingVariance = 1e-6) {
    for (int k = 0; k < 10; ++k) {
      t = t + Duration::fromMilliseconds(10);
      OdometryIncrement inc;
      inc.stamp = t;
      inc.delta = Pose2d{reported.x / 10.0, reported.y / 10.0, reported.theta / 10.0};
      inc.covariance = Eigen::Matrix3d::Identity() * 1e-6;
      inc.covariance(2, 2) = headingVariance / 10.0;
      REQUIRE(loc->predict(inc) == Status::Ok);
      truth = truth.compose(Pose2d{delta.x / 10.0, delta.y / 10.0, delta.theta / 10.0});
    }
    castScan(segs, truth.compose(params.laser.mounting), 0.01, rng, *scan);
    scan->stamp = t;
    obs->stamp = t;
    obs->points.clear();
    return loc->correct(*obs, *scan, *map, *field);
  }
};

}  // namespace

TEST_CASE("localizer with a likelihood field: holds 2 cm / 0.1 deg on biased odometry without landmarks",
          "[localization][scanmatch][localizer]") {
  FieldRun run;
  double worst = 0.0;
  double worstHeading = 0.0;
  for (int c = 0; c < 60; ++c) {
    // 10 cm per cycle along a gentle arc; the odometry reports 3 % less distance and 2 % less turn.
    const Pose2d d{0.1, 0.0, 0.01};
    const LocalizerHealth& h = run.step(d, Pose2d{0.097, 0.0, 0.0098});
    REQUIRE(h.scanMatch.attempted);
    CHECK(h.scanMatch.fused);
    CHECK_FALSE(hasFlag(h.flags, LocalizerFlag::NoFix));
    CHECK_FALSE(h.lost);
    worst = std::max(worst, std::hypot(run.loc->pose().x - run.truth.x, run.loc->pose().y - run.truth.y));
    worstHeading = std::max(worstHeading, std::fabs(normalizeAngle(run.loc->pose().theta - run.truth.theta)));
  }
  CHECK(worst < 0.02);
  CHECK(worstHeading < 0.1 * kPiD / 180.0);
  // The same drive on dead reckoning would be 18 cm short: the matches did the work.
}

TEST_CASE(
    "localizer with a likelihood field: the fit scatter keeps a map that is off from making the filter overconfident",
    "[localization][scanmatch][localizer]") {
  // The map's east wall is 8 cm east of where the world has it (a surface that moved since the
  // mapping run, or the mapping run's own pose error): every point on it pulls the match the same
  // way, and no number of points averages that out. The match's covariance (how well the points
  // fit) shrinks with their number; the fit scatter adds what their residual says.
  std::vector<Segment> mapped = hall();
  for (Segment& sg : mapped) {
    if (sg.a.x() == 12.0 && sg.b.x() == 12.0) {
      sg.a.x() = 12.08;
      sg.b.x() = 12.08;
    }
  }
  struct Outcome {
    double d2 = 0.0;   // position error against the filter's own position covariance
    double rms = 0.0;  // the match's inlier residual
    bool fused = false;
  };
  const auto once = [&mapped](double fitScatter) {
    ScanMatchParams sp;
    sp.fitScatter = fitScatter;
    FieldRun run(sp);
    buildField(*run.field, mapped, 0.0, 0.0, 12.1, 8.0);
    Eigen::Matrix3d P0 = Eigen::Matrix3d::Zero();
    P0.diagonal() << 0.05 * 0.05, 0.05 * 0.05, 0.01 * 0.01;
    REQUIRE(run.loc->reset(run.t, run.truth, P0) == Status::Ok);
    const LocalizerHealth& h = run.step(Pose2d{0.1, 0.0, 0.0}, Pose2d{0.1, 0.0, 0.0});
    Outcome o;
    o.fused = h.scanMatch.fused;
    o.rms = h.scanMatch.rmsResidual;
    const Eigen::Vector2d e(run.loc->pose().x - run.truth.x, run.loc->pose().y - run.truth.y);
    o.d2 = e.dot(run.loc->covariance().topLeftCorner<2, 2>().inverse() * e);
    return o;
  };
  const Outcome plain = once(0.0);
  const Outcome scatter = once(1.0);
  INFO("rms " << plain.rms << " m, d2 " << plain.d2 << " (covariance alone) / " << scatter.d2 << " (fit scatter 1)");
  REQUIRE(plain.fused);
  REQUIRE(scatter.fused);
  // The same scan against the same map: the same match, the same residual (above the 1 cm noise).
  CHECK(plain.rms == scatter.rms);
  CHECK(plain.rms > 0.015);
  // The covariance alone: the biased pose is far outside it (chi-square 2 dof, 99.9 %: 13.8).
  CHECK(plain.d2 > 13.8);
  // With the fit scatter the same error is within it (99 %: 9.2).
  CHECK(scatter.d2 < 9.2);
}

TEST_CASE("scan matcher: the fit scatter must be finite and not negative; the lever is the points' RMS distance",
          "[localization][scanmatch]") {
  ScanMatchParams p;
  CHECK(p.fitScatter == 0.0);
  p.fitScatter = -0.1;
  CHECK(p.validate() == Status::InvalidArgument);
  p.fitScatter = std::numeric_limits<double>::quiet_NaN();
  CHECK(p.validate() == Status::NonFiniteInput);
  p.fitScatter = 0.5;
  CHECK(p.validate() == Status::Ok);
  // Every valid beam kept (no thinning), the laser at the vehicle's origin: the lever is the RMS
  // range of the scan.
  p.pointSpacing = 0.0;
  auto field = std::make_unique<HallField>();
  buildField(*field, hall(), 0.0, 0.0, 12.0, 8.0);
  auto scan = std::make_unique<LaserScan>();
  std::mt19937_64 rng{5};
  const Pose2d truth{6.0, 4.0, 0.3};
  castScan(hall(), truth, 0.0, rng, *scan);
  ScanMatcher matcher(p);
  const ScanMatchResult m = matcher.match(*scan, Pose2d{}, truth, *field);
  REQUIRE(m.status == Status::Ok);
  MatchPoints points;
  scanToMatchPoints(*scan, points);
  REQUIRE(points.size() == m.points);
  double sum = 0.0;
  for (const MatchPoint& q : points) {
    sum += static_cast<double>(q.x) * static_cast<double>(q.x) + static_cast<double>(q.y) * static_cast<double>(q.y);
  }
  CHECK(m.lever == Approx(std::sqrt(sum / static_cast<double>(points.size()))).epsilon(1e-12));
  CHECK(m.lever > 1.0);
}

TEST_CASE("localizer with a likelihood field: a slip beyond the odometry model is gated, then re-synchronised",
          "[localization][scanmatch][localizer]") {
  FieldRun run;
  for (int c = 0; c < 5; ++c) {
    REQUIRE(run.step(Pose2d{0.1, 0.0, 0.0}, Pose2d{0.1, 0.0, 0.0}).scanMatch.fused);
  }
  // The wheels slip: the vehicle moves 25 cm sideways that the odometry never reports. The
  // filter's covariance (mm) makes a match that far off a 25-sigma outlier: one such match is
  // refused.
  const LocalizerHealth& first = run.step(Pose2d{0.0, 0.25, 0.0}, Pose2d{0.0, 0.0, 0.0});
  CHECK(first.scanMatch.status == Status::Rejected);
  CHECK(hasFlag(first.flags, LocalizerFlag::ScanMatchRejected));
  int resyncAt = -1;
  for (int c = 0; c < 10 && resyncAt < 0; ++c) {
    const LocalizerHealth& h = run.step(Pose2d{0.05, 0.0, 0.0}, Pose2d{0.05, 0.0, 0.0});
    if (h.scanMatch.resynced) {
      CHECK(hasFlag(h.flags, LocalizerFlag::ScanMatchResync));
      resyncAt = c;
    }
  }
  // `resyncAfter` agreeing refusals in a row (the slip cycle and those after it) reset the pose to
  // the map.
  CHECK(resyncAt == run.params.scanMatch.resyncAfter - 2);
  CHECK(std::hypot(run.loc->pose().x - run.truth.x, run.loc->pose().y - run.truth.y) < 0.02);
  const LocalizerHealth& after = run.step(Pose2d{0.05, 0.0, 0.0}, Pose2d{0.05, 0.0, 0.0});
  CHECK(after.scanMatch.fused);
  CHECK_FALSE(after.scanMatch.resynced);
}

TEST_CASE("localizer with a likelihood field: a match counts for the re-synchronisation only with resyncMinInliers",
          "[localization][scanmatch][localizer]") {
  // The slip of the test above, with the re-synchronisation asking for more inliers than the
  // matches have: the right matches are refused and the 25 cm stay; with the limit at half their
  // count, the reset comes as before.
  const auto slip = [](std::size_t minInliers, std::uint16_t& fewest) {
    ScanMatchParams settings;
    settings.resyncMinInliers = minInliers;
    FieldRun run(settings);
    for (int c = 0; c < 5; ++c) {
      REQUIRE(run.step(Pose2d{0.1, 0.0, 0.0}, Pose2d{0.1, 0.0, 0.0}).scanMatch.fused);
    }
    const LocalizerHealth& first = run.step(Pose2d{0.0, 0.25, 0.0}, Pose2d{0.0, 0.0, 0.0});
    REQUIRE(first.scanMatch.status == Status::Rejected);
    fewest = first.scanMatch.inliers;
    bool resynced = false;
    for (int c = 0; c < 10 && !resynced; ++c) {
      const LocalizerHealth& h = run.step(Pose2d{0.05, 0.0, 0.0}, Pose2d{0.05, 0.0, 0.0});
      fewest = h.scanMatch.inliers < fewest ? h.scanMatch.inliers : fewest;
      resynced = h.scanMatch.resynced;
    }
    return resynced ? std::hypot(run.loc->pose().x - run.truth.x, run.loc->pose().y - run.truth.y) : -1.0;
  };
  CHECK(ScanMatchParams{}.resyncMinInliers == 0U);  // the default: the matcher's own minimum
  std::uint16_t fewest = 0;
  const double plain = slip(0, fewest);
  CHECK(plain >= 0.0);
  CHECK(plain < 0.02);
  REQUIRE(fewest > 2U * ScanMatchParams{}.minInliers);
  std::uint16_t unused = 0;
  const double half = slip(fewest / 2U, unused);
  CHECK(half >= 0.0);
  CHECK(half < 0.02);
  CHECK(slip(std::size_t{fewest} * 2U, unused) < 0.0);  // never reset
}

TEST_CASE(
    "localizer with a likelihood field: a turn the odometry under-reports is re-synchronised by a hypothesis it "
    "carries",
    "[localization][scanmatch][localizer]") {
  // Real odometry in turns (the intel log): the wheels slip, and the reported turn falls short
  // cycle after cycle. One bad turn puts the filter beyond its gate; the match is right and
  // refused, and the filter's heading drifts on by the shortfall of every later turn. The odometry
  // model knows its turns are uncertain (its heading sigma per turning cycle covers the later
  // shortfalls), so the hypothesis started at the refused match and carried by the odometry with
  // that noise is confirmed by the next matches and resets the pose. A fixed agreement bound
  // tighter than the odometry's own noise would refuse every confirmation.
  FieldRun run;
  for (int c = 0; c < 5; ++c) {
    REQUIRE(run.step(Pose2d{0.1, 0.0, 0.0}, Pose2d{0.1, 0.0, 0.0}).scanMatch.fused);
  }
  const double sigmaTurn = 0.015;  // [rad] the odometry model's heading sigma per turning cycle
  const LocalizerHealth& first = run.step(Pose2d{0.1, 0.0, 0.16}, Pose2d{0.1, 0.0, 0.10}, sigmaTurn * sigmaTurn);
  CHECK(first.scanMatch.status == Status::Rejected);
  int resyncAt = -1;
  for (int c = 0; c < 6 && resyncAt < 0; ++c) {
    // Turning on, 1.4 deg per cycle more than reported (1.6 sigma of the model).
    const LocalizerHealth& h = run.step(Pose2d{0.1, 0.0, 0.10}, Pose2d{0.1, 0.0, 0.075}, sigmaTurn * sigmaTurn);
    CHECK_FALSE(h.scanMatch.fused != h.scanMatch.resynced);  // nothing fused but the resync
    if (h.scanMatch.resynced) {
      resyncAt = c;
    }
  }
  CHECK(resyncAt == run.params.scanMatch.resyncAfter - 2);
  // The hypothesis blends its matches (each with the matcher's real-world scatter,
  // `resyncMatchSigma*`) with the odometry that carried it, which under-reports: within a
  // centimetre and half a degree at the reset, and the tracking takes over from there.
  CHECK(std::hypot(run.loc->pose().x - run.truth.x, run.loc->pose().y - run.truth.y) < 0.01);
  CHECK(std::fabs(normalizeAngle(run.loc->pose().theta - run.truth.theta)) < 0.5 * kPiD / 180.0);
  for (int c = 0; c < 3; ++c) {
    CHECK(run.step(Pose2d{0.1, 0.0, 0.0}, Pose2d{0.1, 0.0, 0.0}).scanMatch.fused);
  }
  CHECK(std::hypot(run.loc->pose().x - run.truth.x, run.loc->pose().y - run.truth.y) < 0.02);
  CHECK(std::fabs(normalizeAngle(run.loc->pose().theta - run.truth.theta)) < 0.1 * kPiD / 180.0);
}

TEST_CASE("localizer with a likelihood field: the soft gate pulls an overconfident filter back, a few sigmas a cycle",
          "[localization][scanmatch][localizer]") {
  // The settings of a map with no authority over the filter (`surfaceMapMatching`): no
  // re-synchronisation, no widened search, the soft gate on.
  const auto slipThenDrive = [](const ScanMatchParams& settings, double& firstCorrection, bool& firstSoft) {
    FieldRun run(settings);
    for (int c = 0; c < 5; ++c) {
      REQUIRE(run.step(Pose2d{0.1, 0.0, 0.0}, Pose2d{0.1, 0.0, 0.0}).scanMatch.fused);
    }
    // A 5 cm sideways slip the odometry never reports: far outside the filter's millimetre
    // covariance, so the gate refuses the (right) match.
    const LocalizerHealth& h = run.step(Pose2d{0.0, 0.05, 0.0}, Pose2d{0.0, 0.0, 0.0});
    firstCorrection = h.correction;
    firstSoft = h.scanMatch.softGated;
    if (h.scanMatch.softGated) {
      CHECK(h.scanMatch.fused);
      CHECK(h.scanMatch.status == Status::Ok);
      CHECK(h.scanMatch.mahalanobis2 > run.params.scanMatchGate);
    }
    for (int c = 0; c < 12; ++c) {
      (void)run.step(Pose2d{0.05, 0.0, 0.0}, Pose2d{0.05, 0.0, 0.0});
    }
    return std::hypot(run.loc->pose().x - run.truth.x, run.loc->pose().y - run.truth.y);
  };
  const ScanMatchParams soft = surfaceMapMatching(ScanMatchParams{});
  REQUIRE(soft.softGate);
  double correction = 0.0;
  bool softGated = false;
  const double softError = slipThenDrive(soft, correction, softGated);
  CHECK(softGated);
  // Never a jump: the first cycle moves the pose by a fraction of the 5 cm offset (gate / d^2 of
  // the gated correction), and later cycles finish the job.
  CHECK(correction > 0.002);
  CHECK(correction < 0.025);
  CHECK(softError < 0.01);

  // Off, or with a fit limit no match meets: every match refused, the 5 cm stay.
  ScanMatchParams hard = soft;
  hard.softGate = false;
  CHECK(slipThenDrive(hard, correction, softGated) > 0.045);
  CHECK_FALSE(softGated);
  ScanMatchParams strict = soft;
  strict.resyncMaxRms = 0.001;
  CHECK(slipThenDrive(strict, correction, softGated) > 0.045);
  CHECK_FALSE(softGated);
}

TEST_CASE("localizer with a likelihood field: a slip beyond the search window is found by the widened search",
          "[localization][scanmatch][localizer]") {
  // The vehicle is carried 0.9 m sideways and turned 8 deg that the odometry never reports: far
  // outside the tracking window of the filter's millimetre covariance (3 sigma) and beyond the
  // refinement's basin. Without recovery the filter never finds the map again; with it, the
  // window doubles per failed cycle and three agreeing matches re-synchronise the pose.
  const auto drive = [](std::uint8_t widenAfter, int& resyncAt, double& error) {
    ScanMatchParams sm;
    sm.widenAfter = widenAfter;
    FieldRun run(sm);
    // The recovery search alone: with the field check (on by default) a jump this large
    // contradicts the field at the old estimate and is declared lost first (the pipeline's field
    // relocalization takes it from there), before the widened window reaches it.
    run.params.health.minFieldInlierFraction = 0.0;
    run.loc = std::make_unique<Localizer>(run.params);
    Eigen::Matrix3d P0 = Eigen::Matrix3d::Zero();
    P0.diagonal() << 0.01 * 0.01, 0.01 * 0.01, 0.005 * 0.005;
    REQUIRE(run.loc->reset(run.t, run.truth, P0) == Status::Ok);
    for (int c = 0; c < 5; ++c) {
      REQUIRE(run.step(Pose2d{0.1, 0.0, 0.0}, Pose2d{0.1, 0.0, 0.0}).scanMatch.fused);
    }
    (void)run.step(Pose2d{0.0, 0.9, 0.14}, Pose2d{0.0, 0.0, 0.0});
    resyncAt = -1;
    bool widened = false;
    for (int c = 0; c < 12 && resyncAt < 0; ++c) {
      const LocalizerHealth& h = run.step(Pose2d{0.05, 0.0, 0.0}, Pose2d{0.05, 0.0, 0.0});
      widened = widened || h.scanMatch.widened;
      CHECK(h.scanMatch.window <= run.params.scanMatch.maxRecoveryTranslation + 1e-9);
      if (h.scanMatch.resynced) {
        resyncAt = c;
      }
    }
    CHECK(widened == (widenAfter > 0U));
    error = std::hypot(run.loc->pose().x - run.truth.x, run.loc->pose().y - run.truth.y);
  };
  int resyncAt = -1;
  double error = 0.0;
  drive(0, resyncAt, error);
  CHECK(resyncAt < 0);  // off: the tracking window cannot reach (else the test shows nothing)
  CHECK(error > 0.5);
  drive(2, resyncAt, error);
  CHECK(resyncAt >= 0);
  CHECK(error < 0.02);
}

TEST_CASE("scan matcher: an explicit search window reaches beyond the tracking caps; bad windows are refused",
          "[localization][scanmatch]") {
  auto field = std::make_unique<HallField>();
  const std::vector<Segment> segs = hall();
  buildField(*field, segs, 0.0, 0.0, 12.0, 8.0);
  auto scan = std::make_unique<LaserScan>();
  auto matcher = std::make_unique<ScanMatcher>();
  std::mt19937_64 rng(5);
  const Pose2d laser{0.6, 0.0, 0.0};
  const Pose2d truth{4.0, 4.5, -0.4};
  castScan(segs, truth.compose(laser), 0.01, rng, *scan);
  const Pose2d prior{truth.x - 1.1, truth.y + 0.8, truth.theta + 0.3};
  // A covariance as wide as the offset: the window is capped at maxSearchTranslation (0.6 m).
  Eigen::Matrix3d P = Eigen::Matrix3d::Zero();
  P.diagonal() << 0.5 * 0.5, 0.5 * 0.5, 0.15 * 0.15;
  const SearchWindow capped = matcher->searchWindow(P);
  CHECK(capped.x == Approx(matcher->params().maxSearchTranslation));
  CHECK(capped.theta == Approx(matcher->params().maxSearchRotation));
  const ScanMatchResult tracking = matcher->match(*scan, laser, prior, P, *field);
  CHECK_FALSE(
      (tracking.status == Status::Ok && std::hypot(tracking.pose.x - truth.x, tracking.pose.y - truth.y) < 0.02));
  const ScanMatchResult wide = matcher->match(*scan, laser, prior, SearchWindow{1.6, 1.6, 0.5}, *field);
  REQUIRE(wide.status == Status::Ok);
  CHECK(wide.searched <= matcher->params().maxSearchPoses + 1U);
  CHECK(std::hypot(wide.pose.x - truth.x, wide.pose.y - truth.y) < 0.02);
  CHECK(std::fabs(normalizeAngle(wide.pose.theta - truth.theta)) < 0.2 * kPiD / 180.0);
  CHECK(matcher->match(*scan, laser, prior, SearchWindow{-0.1, 0.5, 0.1}, *field).status == Status::InvalidArgument);
  CHECK(matcher->match(*scan, laser, prior, SearchWindow{0.5, std::nan(""), 0.1}, *field).status ==
        Status::InvalidArgument);
  CHECK(matcher->match(*scan, laser, prior, SearchWindow{0.5, 0.5, INFINITY}, *field).status ==
        Status::InvalidArgument);
  ScanMatchParams bad;
  bad.maxRecoveryTranslation = bad.recoveryTranslation / 2.0;
  CHECK(bad.validate() == Status::InvalidArgument);
  bad = ScanMatchParams{};
  bad.resyncMaxRms = 0.0;
  CHECK(bad.validate() == Status::InvalidArgument);
}

TEST_CASE("localizer with a likelihood field: the steady-state cycle allocates nothing",
          "[localization][scanmatch][alloc]") {
  FieldRun run;
  (void)run.step(Pose2d{0.05, 0.0, 0.0}, Pose2d{0.05, 0.0, 0.0});
  for (int c = 0; c < 3; ++c) {
    run.truth = run.truth.compose(Pose2d{0.05, 0.0, 0.0});
    castScan(run.segs, run.truth.compose(run.params.laser.mounting), 0.01, run.rng, *run.scan);
    OdometryIncrement inc;
    inc.delta = Pose2d{0.05, 0.0, 0.0};
    inc.covariance = Eigen::Matrix3d::Identity() * 1e-6;
    AGV_CHECK_NO_ALLOCATIONS(run.t = run.t + Duration::fromMilliseconds(100); inc.stamp = run.t;
                             (void)run.loc->predict(inc); run.scan->stamp = run.t; run.obs->stamp = run.t;
                             (void)run.loc->correct(*run.obs, *run.scan, *run.map, *run.field));
    CHECK(run.loc->health().scanMatch.fused);
  }
}

namespace {

/// The field relocalizer's test hall: the hall's field (12 m x 8 m), a relocalizer, the laser
/// mounting, and scan storage that `castAt` fills with a ray-cast scan from a vehicle pose.
struct RelocHall {
  std::vector<Segment> segs = hall();
  std::unique_ptr<HallField> field = std::make_unique<HallField>();
  std::unique_ptr<LaserScan> scan = std::make_unique<LaserScan>();
  std::unique_ptr<MatchPoints> points = std::make_unique<MatchPoints>();
  std::unique_ptr<FieldRelocalizer> reloc = std::make_unique<FieldRelocalizer>();
  Pose2d laser{0.6, 0.0, 0.0};

  RelocHall() { buildField(*field, segs, 0.0, 0.0, 12.0, 8.0); }

  /// The scan (1 cm range noise) and its points from the vehicle at `vehicle`.
  void castAt(const Pose2d& vehicle, std::mt19937_64& rng) {
    castScan(segs, vehicle.compose(laser), 0.01, rng, *scan);
    scanToMatchPoints(*scan, *points);
  }
};

}  // namespace

TEST_CASE("field relocalizer: finds the pose of a scan anywhere in the hall with no prior, allocation-free",
          "[localization][scanmatch][reloc]") {
  RelocHall h;
  auto& [segs, field, scan, points, reloc, laser] = h;
  std::mt19937_64 rng(31);
  std::uniform_real_distribution<double> ux(0.8, 11.2);
  std::uniform_real_distribution<double> uy(0.8, 7.2);
  std::uniform_real_distribution<double> ut(-kPiD, kPiD);
  int tried = 0;
  int found = 0;
  for (int k = 0; k < 60 && tried < 12; ++k) {
    const Pose2d truth{ux(rng), uy(rng), ut(rng)};
    if (!inFreeSpace(truth.translation()) || !inFreeSpace(truth.compose(laser).translation())) {
      continue;
    }
    ++tried;
    h.castAt(truth, rng);
    FieldRelocResult r;
    AGV_CHECK_NO_ALLOCATIONS(r = reloc->localize(*points, laser, *field));
    INFO("truth " << truth.x << " " << truth.y << " " << truth.theta << ": outcome " << static_cast<int>(r.outcome));
    CHECK(r.scored > 10000U);
    if (r.outcome != FieldRelocOutcome::Found) {
      // Never a wrong pose: the only other answers say why there is none.
      CHECK((r.outcome == FieldRelocOutcome::Ambiguous || r.outcome == FieldRelocOutcome::WeakSupport));
      WARN("not found: outcome " << static_cast<int>(r.outcome) << " runner-up " << r.runnerUp << " of " << r.close
                                 << " at " << truth.x << " " << truth.y << " " << truth.theta);
      continue;
    }
    ++found;
    CHECK(r.status == Status::Ok);
    CHECK(std::hypot(r.pose.x - truth.x, r.pose.y - truth.y) < 0.02);
    CHECK(std::fabs(normalizeAngle(r.pose.theta - truth.theta)) < 0.2 * kPiD / 180.0);
    // Confirmation: the next scan, 0.3 m on, carried by an odometry 8 cm / 3 deg off.
    const Pose2d next = truth.compose(Pose2d{0.3, 0.0, 0.0});
    if (inFreeSpace(next.compose(laser).translation())) {
      h.castAt(next, rng);
      Pose2d refined;
      CHECK(reloc->confirm(*points, laser, r.pose.compose(Pose2d{0.38, 0.0, 0.05}), *field, refined));
      CHECK(std::hypot(refined.x - next.x, refined.y - next.y) < 0.02);
      // A candidate 0.8 m off is not confirmed.
      CHECK_FALSE(reloc->confirm(*points, laser, next.compose(Pose2d{0.0, 0.8, 0.0}), *field, refined));
    }
  }
  CHECK(tried >= 10);
  CHECK(found >= tried * 3 / 4);  // the hall's column and rack make most poses unique
}

TEST_CASE("field relocalizer: spread over calls with a pose budget, the same answer as in one call",
          "[localization][scanmatch][reloc]") {
  RelocHall h;
  auto& [segs, field, scan, points, once, laser] = h;
  auto sliced = std::make_unique<FieldRelocalizer>();
  std::mt19937_64 rng(7);
  int compared = 0;
  for (const Pose2d& truth : {Pose2d{3.1, 2.2, 0.7}, Pose2d{8.4, 5.9, -2.5}, Pose2d{6.0, 1.4, 3.0}}) {
    REQUIRE(inFreeSpace(truth.compose(laser).translation()));
    h.castAt(truth, rng);
    const FieldRelocResult a = once->localize(*points, laser, *field);
    constexpr std::uint32_t kBudget = 4999;  // slices end at varied grid positions
    std::uint32_t calls = 0;
    Status st = Status::NotInitialized;
    bool ended = false;
    AGV_CHECK_NO_ALLOCATIONS({
      st = sliced->start(*points, laser, *field);
      while (!ended && calls < 100000U) {
        CHECK(sliced->searching());
        ended = sliced->advance(kBudget);
        ++calls;
      }
    });
    REQUIRE(st == Status::Ok);
    REQUIRE(ended);
    CHECK_FALSE(sliced->searching());
    const FieldRelocResult& b = sliced->result();
    INFO("truth " << truth.x << " " << truth.y << " " << truth.theta << ", " << calls << " calls");
    CHECK(b.outcome == a.outcome);
    CHECK(b.status == a.status);
    CHECK(b.scored == a.scored);
    CHECK(b.pose.x == a.pose.x);
    CHECK(b.pose.y == a.pose.y);
    CHECK(b.pose.theta == a.pose.theta);
    CHECK(b.close == a.close);
    CHECK(b.runnerUp == a.runnerUp);
    // The coarse stage takes ceil(visited / budget) calls (each visits at most the budget), then one
    // call per refined candidate and the deciding call.
    CHECK(b.visited == a.visited);
    CHECK(a.visited >= a.scored);
    const auto coarseCalls = static_cast<std::uint32_t>((a.visited + kBudget - 1U) / kBudget);
    CHECK(calls >= coarseCalls + 1U);
    CHECK(calls <= coarseCalls + 1U + static_cast<std::uint32_t>(FieldRelocalizerParams{}.candidates) + 1U);
    compared += a.outcome == FieldRelocOutcome::Found ? 1 : 0;
  }
  CHECK(compared >= 2);
  // A search abandoned part-way ends with no answer; the next one starts afresh.
  h.castAt(Pose2d{3.1, 2.2, 0.7}, rng);
  REQUIRE(sliced->start(*points, laser, *field) == Status::Ok);
  CHECK_FALSE(sliced->advance(100));
  sliced->cancel();
  CHECK_FALSE(sliced->searching());
  CHECK(sliced->result().outcome == FieldRelocOutcome::NoCandidate);
  CHECK(sliced->advance(100));  // nothing under way: ended
  // Input refused at start ends the search at once, with the outcome localize gives.
  MatchPoints none;
  CHECK(sliced->start(none, laser, *field) == Status::EmptyInput);
  CHECK_FALSE(sliced->searching());
  CHECK(sliced->result().outcome == FieldRelocOutcome::NoPoints);
  // A budget of 0 still makes progress (one pose).
  REQUIRE(sliced->start(*points, laser, *field) == Status::Ok);
  CHECK_FALSE(sliced->advance(0));
}

TEST_CASE("field relocalizer: a symmetric room is ambiguous, a region bounds the search, bad input is refused",
          "[localization][scanmatch][reloc]") {
  // An empty 10 m x 6 m room: every pose has a twin turned by 180 deg about the centre.
  const std::vector<Segment> room = {
      Segment{Eigen::Vector2d(0, 0), Eigen::Vector2d(10, 0)}, Segment{Eigen::Vector2d(10, 0), Eigen::Vector2d(10, 6)},
      Segment{Eigen::Vector2d(10, 6), Eigen::Vector2d(0, 6)}, Segment{Eigen::Vector2d(0, 6), Eigen::Vector2d(0, 0)}};
  auto field = std::make_unique<HallField>();
  buildField(*field, room, 0.0, 0.0, 10.0, 6.0);
  auto scan = std::make_unique<LaserScan>();
  auto points = std::make_unique<MatchPoints>();
  auto reloc = std::make_unique<FieldRelocalizer>();
  std::mt19937_64 rng(3);
  const Pose2d laser{0.6, 0.0, 0.0};
  const Pose2d truth{3.0, 2.0, 0.4};
  castScan(room, truth.compose(laser), 0.01, rng, *scan);
  scanToMatchPoints(*scan, *points);
  const FieldRelocResult sym = reloc->localize(*points, laser, *field);
  CHECK(sym.outcome == FieldRelocOutcome::Ambiguous);
  CHECK(sym.status == Status::Rejected);
  CHECK(sym.runnerUp > 0U);
  // Around the true pose only (a dead-reckoned estimate 0.5 m off, 2 m radius): the twin is
  // outside the disc, the pose is found, with far fewer poses scored.
  const FieldRelocResult near = reloc->localize(*points, laser, *field, RelocRegion{3.4, 2.3, 2.0});
  REQUIRE(near.outcome == FieldRelocOutcome::Found);
  CHECK(std::hypot(near.pose.x - truth.x, near.pose.y - truth.y) < 0.02);
  CHECK(near.scored * 4U < sym.scored);
  // A region outside the field has no candidate position.
  CHECK(reloc->localize(*points, laser, *field, RelocRegion{50.0, 50.0, 2.0}).outcome ==
        FieldRelocOutcome::NoCandidate);
  // Bad input.
  CHECK(reloc->localize(*points, laser, *field, RelocRegion{std::nan(""), 0.0, 1.0}).outcome ==
        FieldRelocOutcome::InvalidInput);
  CHECK(reloc->localize(*points, laser, *field, RelocRegion{0.0, 0.0, -1.0}).status == Status::NonFiniteInput);
  CHECK(reloc->localize(*points, Pose2d{INFINITY, 0.0, 0.0}, *field).outcome == FieldRelocOutcome::InvalidInput);
  auto unbuilt = std::make_unique<HallField>();
  CHECK(reloc->localize(*points, laser, *unbuilt).status == Status::NotInitialized);
  MatchPoints none;
  CHECK(reloc->localize(none, laser, *field).outcome == FieldRelocOutcome::NoPoints);
  MatchPoints nan;
  REQUIRE(nan.push_back(MatchPoint{std::nanf(""), 1.0F}) == Status::Ok);
  CHECK(reloc->localize(nan, laser, *field).status == Status::EmptyInput);
  FieldRelocalizerParams tiny;
  tiny.maxPoses = 1000;
  auto bounded = std::make_unique<FieldRelocalizer>(tiny);
  CHECK(bounded->localize(*points, laser, *field).outcome == FieldRelocOutcome::WorkBoundHit);
  FieldRelocalizerParams bad;
  bad.candidates = FieldRelocalizer::kMaxCandidates + 1U;
  CHECK(bad.validate() == Status::InvalidArgument);
  auto invalid = std::make_unique<FieldRelocalizer>(bad);
  CHECK(invalid->localize(*points, laser, *field).outcome == FieldRelocOutcome::InvalidInput);
  bad = FieldRelocalizerParams{};
  bad.positionStep = std::nan("");
  CHECK(bad.validate() == Status::NonFiniteInput);
  bad = FieldRelocalizerParams{};
  bad.ambiguityRatio = 1.5;
  CHECK(bad.validate() == Status::InvalidArgument);
}

TEST_CASE("field relocalizer: the confirmation window follows the carry's odometry covariance, within its caps",
          "[localization][scanmatch][reloc]") {
  RelocHall h;
  auto& [segs, field, scan, points, reloc, laser] = h;
  const FieldRelocalizerParams& p = reloc->params();

  SECTION("the window: fixed for a small carry, sigmas for a large one, capped, frame-independent") {
    const SearchWindow fixed = reloc->confirmWindow(Eigen::Matrix3d::Zero());
    CHECK(fixed.x == p.confirmDistance);
    CHECK(fixed.y == p.confirmDistance);
    CHECK(fixed.theta == p.confirmAngle);
    // A 25 Hz vehicle's carry (a few mm, a few mrad): the fixed window.
    Eigen::Matrix3d small = Eigen::Matrix3d::Zero();
    small.diagonal() << 1e-5, 4e-6, 1e-5;
    CHECK(reloc->confirmWindow(small).x == p.confirmDistance);
    CHECK(reloc->confirmWindow(small).theta == p.confirmAngle);
    // A log's metre of Pioneer odometry: sigma 0.1 m across, 0.06 rad.
    Eigen::Matrix3d large = Eigen::Matrix3d::Zero();
    large.diagonal() << 0.0025, 0.01, 0.0036;
    const SearchWindow w = reloc->confirmWindow(large);
    CHECK(w.x == Approx(p.confirmSigmas * 0.1));
    CHECK(w.y == w.x);
    CHECK(w.theta == Approx(p.confirmSigmas * 0.06));
    // The position bound is the largest variance in any direction: rotating the carry's frame
    // (any angle) leaves it unchanged, a correlated block included.
    Eigen::Matrix3d corr = large;
    corr(0, 1) = corr(1, 0) = 0.004;
    for (const double a : {0.3, 1.2, -2.5}) {
      Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
      r(0, 0) = r(1, 1) = std::cos(a);
      r(1, 0) = std::sin(a);
      r(0, 1) = -r(1, 0);
      CHECK(reloc->confirmWindow(r * corr * r.transpose()).x == Approx(reloc->confirmWindow(corr).x));
    }
    CHECK(reloc->confirmWindow(corr).x > w.x);
    // Beyond the caps: the caps (the confirmation's search covers them, bounded).
    const SearchWindow capped = reloc->confirmWindow(Eigen::Matrix3d::Identity() * 4.0);
    CHECK(capped.x == p.confirmMaxDistance);
    CHECK(capped.theta == p.confirmMaxAngle);
    // Non-finite or negative: nothing agrees.
    Eigen::Matrix3d nan = Eigen::Matrix3d::Zero();
    nan(2, 2) = std::nan("");
    CHECK(reloc->confirmWindow(nan).x == 0.0);
    Eigen::Matrix3d neg = Eigen::Matrix3d::Zero();
    neg(0, 0) = -1e-3;
    CHECK(reloc->confirmWindow(neg).theta == 0.0);
    // withinWindow: the distance and the wrapped heading difference.
    const Pose2d c{1.0, 2.0, kPiD - 0.01};
    CHECK(FieldRelocalizer::withinWindow(Pose2d{1.1, 2.1, -kPiD + 0.02}, c, SearchWindow{0.15, 0.15, 0.04}));
    CHECK_FALSE(FieldRelocalizer::withinWindow(Pose2d{1.2, 2.1, c.theta}, c, SearchWindow{0.15, 0.15, 0.04}));
    CHECK_FALSE(FieldRelocalizer::withinWindow(Pose2d{1.0, 2.0, -kPiD + 0.04}, c, SearchWindow{0.15, 0.15, 0.04}));
  }

  SECTION(
      "a candidate carried 0.15 rad off by a metre of odometry: refused by the fixed window, confirmed by "
      "the carry's") {
    std::mt19937_64 rng(5);
    const Pose2d truth{4.0, 2.5, 0.3};
    h.castAt(truth, rng);
    // The odometry turned 0.15 rad short and carried the position 0.12 m off: beyond the fixed
    // window's 0.08 rad, within 3 sigma of a carry with sigma 0.06 rad, 0.07 m.
    const Pose2d carried{truth.x + 0.10, truth.y - 0.066, truth.theta - 0.15};
    Eigen::Matrix3d carry = Eigen::Matrix3d::Zero();
    carry.diagonal() << 0.0049, 0.0049, 0.0036;
    Pose2d refined;
    CHECK_FALSE(reloc->confirm(*points, laser, carried, *field, refined));
    bool ok = false;
    AGV_CHECK_NO_ALLOCATIONS(ok = reloc->confirm(*points, laser, carried, *field, carry, refined));
    REQUIRE(ok);
    CHECK(std::hypot(refined.x - truth.x, refined.y - truth.y) < 0.02);
    CHECK(std::fabs(normalizeAngle(refined.theta - truth.theta)) < 0.2 * kPiD / 180.0);
    // The same carry never stretches beyond the caps: a candidate 0.9 m off is not confirmed by a
    // carry whose 3 sigma would cover it.
    Eigen::Matrix3d huge = Eigen::Matrix3d::Identity();
    CHECK_FALSE(reloc->confirm(*points, laser, truth.compose(Pose2d{0.0, 0.9, 0.0}), *field, huge, refined));
    // A non-finite covariance confirms nothing, not even the true pose.
    Eigen::Matrix3d bad = carry;
    bad(0, 0) = INFINITY;
    CHECK_FALSE(reloc->confirm(*points, laser, truth, *field, bad, refined));
    CHECK(reloc->confirm(*points, laser, truth, *field, carry, refined));
  }

  SECTION("parameters") {
    FieldRelocalizerParams bad;
    bad.confirmSigmas = -1.0;
    CHECK(bad.validate() == Status::InvalidArgument);
    bad = FieldRelocalizerParams{};
    bad.confirmMaxDistance = bad.confirmDistance - 0.01;
    CHECK(bad.validate() == Status::InvalidArgument);
    bad = FieldRelocalizerParams{};
    bad.confirmMaxAngle = bad.confirmAngle - 0.01;
    CHECK(bad.validate() == Status::InvalidArgument);
    bad = FieldRelocalizerParams{};
    bad.confirmMaxAngle = std::nan("");
    CHECK(bad.validate() == Status::NonFiniteInput);
    bad = FieldRelocalizerParams{};
    bad.confirmSigmas = 0.0;  // the fixed window
    CHECK(bad.validate() == Status::Ok);
  }
}

TEST_CASE("field confirmation: the scans a candidate needs, and the motion they must span",
          "[localization][scanmatch][reloc]") {
  FieldRelocalizerParams p;  // the core's default: no motion asked, the caller's count alone
  FieldConfirmation c;
  CHECK_FALSE(c.complete(1, p));
  c.add(Pose2d{0.0, 0.0, 0.0});  // standing
  CHECK(c.complete(1, p));
  CHECK_FALSE(c.complete(2, p));
  c.add(Pose2d{0.0, 0.0, 0.0});
  CHECK(c.complete(2, p));

  // Motion asked (a log's robot keeps driving): scans 0.11 m apart need five for 0.5 m.
  p.confirmTravel = 0.5;
  p.confirmTurn = 0.5;
  c.restart();
  CHECK(c.scans() == 0U);
  CHECK(c.travel() == 0.0);
  for (int k = 1; k <= 4; ++k) {
    c.add(Pose2d{0.066, -0.088, 0.01});  // 0.11 m
    CHECK_FALSE(c.complete(2, p));
  }
  c.add(Pose2d{0.066, -0.088, 0.01});
  CHECK(c.travel() == Approx(0.55));
  CHECK(c.complete(2, p));
  // Scans a metre apart: the count, not the motion, is what they wait for.
  c.restart();
  c.add(Pose2d{1.0, 0.2, 0.0});
  CHECK_FALSE(c.complete(2, p));
  c.add(Pose2d{1.0, 0.2, 0.0});
  CHECK(c.complete(2, p));
  // Turning on the spot: the turn counts, whatever its sign and across the +-pi cut.
  c.restart();
  c.add(Pose2d{0.0, 0.0, -0.3});
  CHECK_FALSE(c.complete(2, p));
  c.add(Pose2d{0.0, 0.0, 2.0 * kPiD + 0.3});
  CHECK(c.turn() == Approx(0.6));
  CHECK(c.complete(2, p));
  // Standing: the cap ends the wait (a standing vehicle's view does not change).
  c.restart();
  for (std::uint32_t k = 1; k < p.confirmMaxScans; ++k) {
    c.add(Pose2d{0.001, 0.0, 0.0});
    CHECK_FALSE(c.complete(2, p));
  }
  c.add(Pose2d{0.001, 0.0, 0.0});
  CHECK(c.complete(2, p));
  // Travel alone asked: turning does not complete it.
  p.confirmTurn = 0.0;
  c.restart();
  c.add(Pose2d{0.0, 0.0, 1.0});
  c.add(Pose2d{0.0, 0.0, 1.0});
  CHECK_FALSE(c.complete(2, p));
  // A non-finite step is no motion.
  c.restart();
  c.add(Pose2d{std::nan(""), 0.0, 0.0});
  c.add(Pose2d{INFINITY, 0.0, std::nan("")});
  CHECK(c.scans() == 2U);
  CHECK(c.travel() == 0.0);
  CHECK(c.turn() == 0.0);
  CHECK_FALSE(c.complete(2, p));
  // Validation.
  FieldRelocalizerParams bad;
  bad.confirmTravel = -0.1;
  CHECK(bad.validate() == Status::InvalidArgument);
  bad = FieldRelocalizerParams{};
  bad.confirmTurn = std::nan("");
  CHECK(bad.validate() == Status::NonFiniteInput);
  bad = FieldRelocalizerParams{};
  bad.confirmMaxScans = 0;
  CHECK(bad.validate() == Status::InvalidArgument);
}

TEST_CASE("scanToMatchPoints: the valid beams within the range limit, in beam order, laser frame", "[scanmatch]") {
  auto scan = std::make_unique<LaserScan>();
  scan->angleMin = -1.0F;
  scan->angleIncrement = 0.5F;
  scan->rangeMin = 0.1F;
  scan->rangeMax = 30.0F;
  const float ranges[] = {2.0F,  std::numeric_limits<float>::quiet_NaN(), 0.05F, 12.0F,
                          30.0F, std::numeric_limits<float>::infinity(),  5.0F};
  for (float r : ranges) {
    REQUIRE(scan->ranges.push_back(r) == Status::Ok);
  }
  MatchPoints points;
  REQUIRE(points.push_back(MatchPoint{9.0F, 9.0F}) == Status::Ok);  // cleared first
  scanToMatchPoints(*scan, points);
  // Beams 0, 3 and 6 are valid: NaN, below rangeMin, at rangeMax and inf are not.
  REQUIRE(points.size() == 3U);
  const int beams[] = {0, 3, 6};
  for (std::size_t k = 0; k < 3U; ++k) {
    const double a = -1.0 + 0.5 * beams[k];
    const double r = static_cast<double>(ranges[beams[k]]);
    CHECK(static_cast<double>(points[k].x) == Approx(r * std::cos(a)).margin(1e-5));
    CHECK(static_cast<double>(points[k].y) == Approx(r * std::sin(a)).margin(1e-5));
    CHECK(std::hypot(static_cast<double>(points[k].x), static_cast<double>(points[k].y)) == Approx(r).margin(1e-5));
  }
  scanToMatchPoints(*scan, points, 10.0);  // the 12 m beam left out
  REQUIRE(points.size() == 2U);
  CHECK(static_cast<double>(points[1].x) == Approx(5.0 * std::cos(2.0)).margin(1e-5));
  scan->ranges.clear();
  scanToMatchPoints(*scan, points);
  CHECK(points.empty());
}

TEST_CASE("localizer with a likelihood field: a vehicle carried away at rest is declared lost by the field check",
          "[localization][scanmatch][localizer]") {
  // Localized at rest, then carried (wheels still, no odometry) to a random free place of the hall
  // 2.5 m or more away, facing anywhere: its covariance does not grow and no landmark is expected,
  // so only the sweep can tell. With the check, a sweep that fits no pose of the tracking search
  // counts as a bad cycle and lostAfterBadCycles of them latch lost; without it nothing does.
  // (Measured over 25 such trials and 15 sweeps each: 23 declared lost with the check, none
  // without, and the widening recovery search fused 2 wrong poses with it, 5 without: docs/
  // localization.md, "Lost". Kept to 10 trials and a few sweeps here: each widened search costs
  // ~15 ms, minutes under the cross targets' emulation.)
  const int lostAfter = LocalizerHealthParams{}.lostAfterBadCycles;
  const auto trial = [lostAfter](double fraction, const Pose2d& to, int& lostAt, int& contradicted, bool& fused) {
    FieldRun run;
    run.params.health.minFieldInlierFraction = fraction;
    run.loc = std::make_unique<Localizer>(run.params);
    Eigen::Matrix3d P0 = Eigen::Matrix3d::Zero();
    P0.diagonal() << 0.01 * 0.01, 0.01 * 0.01, 0.005 * 0.005;
    REQUIRE(run.loc->reset(run.t, run.truth, P0) == Status::Ok);
    for (int c = 0; c < 3; ++c) {
      const LocalizerHealth& h = run.step(Pose2d{}, Pose2d{});
      REQUIRE(h.scanMatch.fused);  // where it stands, the sweep fits: never judged
      REQUIRE_FALSE(hasFlag(h.flags, LocalizerFlag::FieldContradicted));
    }
    run.truth = to;
    lostAt = -1;
    contradicted = 0;
    fused = false;
    for (int c = 0; c < lostAfter + 1 && lostAt < 0; ++c) {
      const LocalizerHealth& h = run.step(Pose2d{}, Pose2d{});
      contradicted += hasFlag(h.flags, LocalizerFlag::FieldContradicted) ? 1 : 0;
      CHECK(hasFlag(h.flags, LocalizerFlag::FieldContradicted) <= hasFlag(h.flags, LocalizerFlag::BadCycle));
      fused = fused || h.scanMatch.fused;
      lostAt = h.lost ? c : lostAt;
    }
  };
  std::mt19937_64 rng{5};
  std::uniform_real_distribution<double> ux(0.5, 11.5);
  std::uniform_real_distribution<double> uy(0.5, 7.5);
  std::uniform_real_distribution<double> ut(-kPiD, kPiD);
  int trials = 0;
  int detected = 0;
  int detectedOff = 0;
  while (trials < 10) {
    const Pose2d to{ux(rng), uy(rng), ut(rng)};
    if (!inFreeSpace(Eigen::Vector2d(to.x, to.y)) || std::hypot(to.x - 2.0, to.y - 2.0) < 2.5) {
      continue;
    }
    ++trials;
    int lostAt = -1;
    int contradicted = 0;
    bool fused = false;
    trial(0.25, to, lostAt, contradicted, fused);
    if (lostAt >= 0) {
      // Detected: at once, by the field check alone, before any match was fused.
      ++detected;
      CHECK(lostAt == lostAfter - 1);
      CHECK(contradicted == lostAfter);
      CHECK_FALSE(fused);
    }
    trial(0.0, to, lostAt, contradicted, fused);
    detectedOff += lostAt >= 0 ? 1 : 0;
    CHECK(contradicted == 0);
  }
  UNSCOPED_INFO("detected " << detected << " of 10 with the check, " << detectedOff << " without");
  CHECK(detected >= 8);
  CHECK(detectedOff == 0);
}

TEST_CASE("scan matcher: costAt is lowest at the pose the scan was taken from, NaN without points or field",
          "[localization][scanmatch]") {
  auto field = std::make_unique<HallField>();
  const std::vector<Segment> segs = hall();
  buildField(*field, segs, 0.0, 0.0, 12.0, 8.0);
  auto scan = std::make_unique<LaserScan>();
  auto matcher = std::make_unique<ScanMatcher>();
  const Pose2d laser{0.6, 0.0, 0.0};
  const Pose2d truth{2.5, 2.0, 0.3};
  std::mt19937_64 rng(3);
  castScan(segs, truth.compose(laser), 0.01, rng, *scan);
  const double atTruth = matcher->costAt(*scan, laser, truth, *field);
  REQUIRE(std::isfinite(atTruth));
  // Every displacement of 5 cm or 1 deg, and more, costs more; the cost grows with the offset.
  for (const Pose2d& d : {Pose2d{0.05, 0.0, 0.0}, Pose2d{0.0, -0.05, 0.0}, Pose2d{0.0, 0.0, 0.0175}}) {
    const Pose2d near{truth.x + d.x, truth.y + d.y, truth.theta + d.theta};
    const Pose2d far{truth.x + 4.0 * d.x, truth.y + 4.0 * d.y, truth.theta + 4.0 * d.theta};
    const double cNear = matcher->costAt(*scan, laser, near, *field);
    const double cFar = matcher->costAt(*scan, laser, far, *field);
    CHECK(cNear > atTruth);
    CHECK(cFar > cNear);
  }
  // The same points given as MatchPoints cost the same.
  auto points = std::make_unique<MatchPoints>();
  scanToMatchPoints(*scan, *points);
  CHECK(std::fabs(matcher->costAt(*points, laser, truth, *field) - atTruth) <= 1e-4 * atTruth);
  // Refusals: an unbuilt field, a non-finite pose, no valid beam.
  auto empty = std::make_unique<HallField>();
  CHECK(std::isnan(matcher->costAt(*scan, laser, truth, *empty)));
  CHECK(std::isnan(matcher->costAt(*scan, laser, Pose2d{NAN, 0.0, 0.0}, *field)));
  for (float& r : scan->ranges) {
    r = std::numeric_limits<float>::quiet_NaN();
  }
  CHECK(std::isnan(matcher->costAt(*scan, laser, truth, *field)));
}

namespace {

/// A `FieldRun` whose matches never fuse (the matcher demands more inliers than a scan has), with
/// surveyed corners at `corners` in its static map: the landmarks are the only correction, and
/// the field can only cross-check them.
struct CornersOnField {
  FieldRun run;
  std::vector<Eigen::Vector2d> world;  // where the corners are in the hall

  CornersOnField(const std::vector<Eigen::Vector2d>& truthCorners, const Eigen::Vector2d& mapOffset,
                 const AssociationParams& association, double priorSigma) {
    world = truthCorners;
    run.params.scanMatch.minInliers = 10000;
    run.params.association = association;
    run.loc = std::make_unique<Localizer>(run.params);
    std::uint32_t id = 1;
    for (const Eigen::Vector2d& c : truthCorners) {
      const Eigen::Vector2d m = c + mapOffset;
      REQUIRE(run.map->addSurveyed(LandmarkKind::Corner, m.x(), m.y(), 0.005, id++).ok());
    }
    Eigen::Matrix3d P0 = Eigen::Matrix3d::Zero();
    P0.diagonal() << priorSigma * priorSigma, priorSigma * priorSigma, 0.01 * 0.01;
    REQUIRE(run.loc->reset(run.t, run.truth, P0) == Status::Ok);
  }

  /// One cycle at rest observing `count` of the corners where they are (laser frame, exact).
  const LocalizerHealth& observe(std::size_t count) {
    for (int k = 0; k < 10; ++k) {
      run.t = run.t + Duration::fromMilliseconds(10);
      OdometryIncrement inc;
      inc.stamp = run.t;
      inc.covariance = Eigen::Matrix3d::Identity() * 1e-8;
      REQUIRE(run.loc->predict(inc) == Status::Ok);
    }
    castScan(run.segs, run.truth.compose(run.params.laser.mounting), 0.01, run.rng, *run.scan);
    run.scan->stamp = run.t;
    run.obs->stamp = run.t;
    run.obs->points.clear();
    const Pose2d laserPose = run.truth.compose(run.params.laser.mounting);
    for (std::size_t i = 0; i < count && i < world.size(); ++i) {
      const Eigen::Vector2d p = laserPose.inverse().transformPoint(world[i]);
      REQUIRE(run.obs->points.push_back(PointObservation{p.x(), p.y(), LandmarkKind::Corner}) == Status::Ok);
    }
    return run.loc->correct(*run.obs, *run.scan, *run.map, *run.field);
  }
};

// The column's four corners, seen from the vehicle at (2, 2) facing +x.
const std::vector<Eigen::Vector2d> kColumnCorners = {Eigen::Vector2d(5.0, 3.0), Eigen::Vector2d(5.0, 4.0),
                                                     Eigen::Vector2d(6.0, 3.0), Eigen::Vector2d(6.0, 4.0)};

}  // namespace

TEST_CASE("localizer with a likelihood field: a landmark correction that moves the scan off the field is undone",
          "[localization][scanmatch][localizer]") {
  // The static map's corners sit 0.3 m from where the hall has them (a map that is wrong there, or
  // the wrong landmarks associated: the same to the filter). The prior is right and 0.15 m
  // uncertain, so the gate admits them and three corners give support: fused, they pull the pose
  // 0.3 m off the walls the scan sees, which the field check refuses; without the check they do.
  AssociationParams checked;
  AssociationParams unchecked;
  unchecked.fieldCheckGate = 0.0;
  const Eigen::Vector2d offset(0.3, 0.0);
  CornersOnField wrong(kColumnCorners, offset, checked, 0.15);
  const Pose2d before = wrong.run.loc->pose();
  const LocalizerHealth h = wrong.observe(3);
  REQUIRE(h.scanMatch.attempted);
  REQUIRE_FALSE(h.scanMatch.fused);
  CHECK(h.used == 0U);
  CHECK(h.rejectedField == 3U);
  CHECK(h.sources[static_cast<std::size_t>(LandmarkKind::Corner)].rejected == 3U);
  CHECK(hasFlag(h.flags, LocalizerFlag::LandmarksContradictField));
  CHECK(std::hypot(wrong.run.loc->pose().x - before.x, wrong.run.loc->pose().y - before.y) < 1e-9);

  CornersOnField off(kColumnCorners, offset, unchecked, 0.15);
  const LocalizerHealth u = off.observe(3);
  CHECK(u.used == 3U);
  CHECK(u.rejectedField == 0U);
  CHECK(off.run.loc->pose().x - off.run.truth.x > 0.15);  // pulled toward the offset map

  // Right corners from a prior 0.1 m off: the correction moves the scan onto the walls, kept.
  CornersOnField right(kColumnCorners, Eigen::Vector2d::Zero(), checked, 0.15);
  Eigen::Matrix3d P0 = Eigen::Matrix3d::Zero();
  P0.diagonal() << 0.15 * 0.15, 0.15 * 0.15, 0.01 * 0.01;
  REQUIRE(right.run.loc->reset(right.run.t, Pose2d{2.1, 2.05, 0.0}, P0) == Status::Ok);
  const LocalizerHealth r = right.observe(3);
  CHECK(r.used == 3U);
  CHECK(r.rejectedField == 0U);
  CHECK_FALSE(hasFlag(r.flags, LocalizerFlag::LandmarksContradictField));
  CHECK(std::hypot(right.run.loc->pose().x - right.run.truth.x, right.run.loc->pose().y - right.run.truth.y) < 0.02);

  LocalizerParams bad;
  bad.association.fieldCheckGate = -1.0;
  CHECK(bad.validate() == Status::InvalidArgument);
  bad.association.fieldCheckGate = NAN;
  CHECK(bad.validate() == Status::NonFiniteInput);
}

TEST_CASE("localizer with a likelihood field: a lone corner waits for support while the field cannot fix the pose",
          "[localization][scanmatch][localizer]") {
  // A confident prior (5 cm, below supportSigma): without a field one corner corrects it. With a
  // static map and a field whose match is not fused, one corner is held back (fieldSupport), two
  // correct; with fieldSupport off one corrects again.
  AssociationParams fieldSupport;
  CornersOnField one(kColumnCorners, Eigen::Vector2d::Zero(), fieldSupport, 0.05);
  const LocalizerHealth h1 = one.observe(1);
  REQUIRE_FALSE(h1.scanMatch.fused);
  CHECK(h1.used == 0U);
  CHECK(h1.rejectedSupport == 1U);
  CHECK(hasFlag(h1.flags, LocalizerFlag::SupportRejected));
  CornersOnField two(kColumnCorners, Eigen::Vector2d::Zero(), fieldSupport, 0.05);
  CHECK(two.observe(2).used == 2U);
  AssociationParams off;
  off.fieldSupport = false;
  CornersOnField alone(kColumnCorners, Eigen::Vector2d::Zero(), off, 0.05);
  const LocalizerHealth h3 = alone.observe(1);
  CHECK(h3.used == 1U);
  CHECK(h3.rejectedSupport == 0U);
}
