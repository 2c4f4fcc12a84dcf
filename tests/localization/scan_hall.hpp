#pragma once
// The simulated hall of the scan-matching tests: wall segments, a ray-cast laser with range noise,
// and a likelihood field built from the segments themselves (test_scan_matcher.cpp,
// test_surface_map.cpp).
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "agv/localization/likelihood_field.hpp"
#include "agv/scan/laser_scan.hpp"
#include "agv_test.hpp"

namespace agv::test {

constexpr double kPiD = 3.14159265358979323846;

/// A wall segment of the simulated hall.
struct Segment {
  Eigen::Vector2d a;
  Eigen::Vector2d b;
};

/// An axis-aligned box [x0, x1] x [y0, y1] of the hall.
struct Box {
  double x0, y0, x1, y1;
  bool contains(const Eigen::Vector2d& p) const { return p.x() > x0 && p.x() < x1 && p.y() > y0 && p.y() < y1; }
};

/// A 12 m x 8 m hall with a 1 m x 1 m column and a rack end (an L of two boxes): enough
/// structure in every direction to fix x, y and theta. Free space lies to the left of every
/// segment (walls counter-clockwise, obstacles clockwise).
const Box kColumn{5.0, 3.0, 6.0, 4.0};
const Box kRack{8.5, 6.0, 10.5, 6.3};
const Box kRackEnd{10.2, 6.3, 10.5, 7.2};

inline std::vector<Segment> hall() {
  std::vector<Segment> segs;
  const auto seg = [&segs](double ax, double ay, double bx, double by) {
    segs.push_back(Segment{Eigen::Vector2d(ax, ay), Eigen::Vector2d(bx, by)});
  };
  seg(0, 0, 12, 0);
  seg(12, 0, 12, 8);
  seg(12, 8, 0, 8);
  seg(0, 8, 0, 0);
  for (const Box& b : {kColumn, kRack}) {  // clockwise
    seg(b.x0, b.y0, b.x0, b.y1);
    seg(b.x0, b.y1, b.x1, b.y1);
    seg(b.x1, b.y1, b.x1, b.y0);
    seg(b.x1, b.y0, b.x0, b.y0);
  }
  seg(kRackEnd.x0, kRackEnd.y0, kRackEnd.x0, kRackEnd.y1);
  seg(kRackEnd.x0, kRackEnd.y1, kRackEnd.x1, kRackEnd.y1);
  seg(kRackEnd.x1, kRackEnd.y1, kRackEnd.x1, kRackEnd.y0);
  return segs;
}

/// True for a point of the hall's free space.
inline bool inFreeSpace(const Eigen::Vector2d& p) {
  return p.x() > 0.0 && p.x() < 12.0 && p.y() > 0.0 && p.y() < 8.0 && !kColumn.contains(p) && !kRack.contains(p) &&
         !kRackEnd.contains(p);
}

/// A corridor 2 m wide and 60 m long: walls along x only, nothing across within range.
inline std::vector<Segment> corridor() {
  return {Segment{Eigen::Vector2d(-30, -1), Eigen::Vector2d(30, -1)},
          Segment{Eigen::Vector2d(30, 1), Eigen::Vector2d(-30, 1)}};
}

/// A surface point with the normal of its segment (to the left of a -> b: the segments run
/// counter-clockwise around the free space).
struct SegmentPoint {
  Eigen::Vector2d p;
  Eigen::Vector2d n;
};

/// Surface points every `step` metres along the segments.
inline std::vector<SegmentPoint> sampleSegments(const std::vector<Segment>& segs, double step) {
  std::vector<SegmentPoint> pts;
  for (const Segment& s : segs) {
    const Eigen::Vector2d e = s.b - s.a;
    const int n = static_cast<int>(std::ceil(e.norm() / step));
    for (int i = 0; i <= n; ++i) {
      pts.push_back(SegmentPoint{s.a + e * (static_cast<double>(i) / n), Eigen::Vector2d(-e.y(), e.x()).normalized()});
    }
  }
  return pts;
}

/// Ray-casts a 270 deg, 0.5 deg scan from laser pose `laser` (world) with Gaussian range noise.
inline void castScan(const std::vector<Segment>& segs, const Pose2d& laser, double sigma, std::mt19937_64& rng,
                     LaserScan& scan, double rangeMax = 30.0) {
  std::normal_distribution<double> noise(0.0, sigma);
  scan.angleMin = static_cast<float>(-0.75 * kPiD);
  scan.angleIncrement = static_cast<float>(0.5 * kPiD / 180.0);
  scan.rangeMin = 0.1F;
  scan.rangeMax = static_cast<float>(rangeMax);
  scan.ranges.clear();
  for (int i = 0; i < 541; ++i) {
    const double a = laser.theta + static_cast<double>(scan.angleMin) + i * static_cast<double>(scan.angleIncrement);
    const Eigen::Vector2d d(std::cos(a), std::sin(a));
    double best = 1e9;
    for (const Segment& s : segs) {
      // laser + t d = s.a + u (s.b - s.a)
      const Eigen::Vector2d e = s.b - s.a;
      const double den = d.x() * (-e.y()) - d.y() * (-e.x());
      if (std::fabs(den) < 1e-12) {
        continue;
      }
      const Eigen::Vector2d w = s.a - laser.translation();
      const double t = (w.x() * (-e.y()) - w.y() * (-e.x())) / den;
      const double u = (d.x() * w.y() - d.y() * w.x()) / den;
      if (t > 0.0 && u >= 0.0 && u <= 1.0 && t < best) {
        best = t;
      }
    }
    const double r = best < rangeMax ? best + noise(rng) : std::numeric_limits<double>::infinity();
    REQUIRE(scan.ranges.push_back(static_cast<float>(r)) == Status::Ok);
  }
}

/// Field of the segments at the default geometry, area with a 1 m margin.
template <std::size_t N>
void buildField(LikelihoodField<N>& field, const std::vector<Segment>& segs, double minX, double minY, double maxX,
                double maxY, const LikelihoodFieldParams& params = LikelihoodFieldParams{}) {
  const auto w = static_cast<std::size_t>(std::ceil((maxX - minX + 2.0) / params.resolution));
  const auto h = static_cast<std::size_t>(std::ceil((maxY - minY + 2.0) / params.resolution));
  REQUIRE(field.configure(params, minX - 1.0, minY - 1.0, w, h) == Status::Ok);
  for (const SegmentPoint& s : sampleSegments(segs, 0.02)) {
    REQUIRE(field.addPoint(s.p.x(), s.p.y(), s.n.x(), s.n.y()) == Status::Ok);
  }
  REQUIRE(field.build() == Status::Ok);
}

using HallField = LikelihoodField<300 * 220>;

}  // namespace agv::test
