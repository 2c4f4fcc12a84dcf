#include "reloc_oracle.hpp"

#include <cmath>
#include <cstddef>
#include <vector>

#include "agv/core/angle.hpp"

namespace agv::hil {
namespace {

/// Observations placed by `pose` that land within `gate` of a landmark; with `refit`, also the
/// least-squares rigid pose of those associations (Umeyama without scale, closed form in 2D).
std::size_t support(const std::vector<OraclePoint>& map, const std::vector<OraclePoint>& obs, const Pose2d& pose,
                    double gate, Pose2d* refit) {
  std::size_t n = 0;
  double so[2] = {0.0, 0.0};
  double sl[2] = {0.0, 0.0};
  std::vector<OraclePoint> pairsObs;
  std::vector<OraclePoint> pairsMap;
  const double c = std::cos(pose.theta);
  const double s = std::sin(pose.theta);
  for (const OraclePoint& o : obs) {
    const double wx = pose.x + c * o.x - s * o.y;
    const double wy = pose.y + s * o.x + c * o.y;
    double best = gate * gate;
    const OraclePoint* match = nullptr;
    for (const OraclePoint& l : map) {
      const double d2 = (l.x - wx) * (l.x - wx) + (l.y - wy) * (l.y - wy);
      if (d2 <= best) {
        best = d2;
        match = &l;
      }
    }
    if (match == nullptr) {
      continue;
    }
    ++n;
    if (refit != nullptr) {
      pairsObs.push_back(o);
      pairsMap.push_back(*match);
      so[0] += o.x;
      so[1] += o.y;
      sl[0] += match->x;
      sl[1] += match->y;
    }
  }
  if (refit != nullptr && n >= 2) {
    const double k = 1.0 / static_cast<double>(n);
    const double ox = so[0] * k;
    const double oy = so[1] * k;
    const double lx = sl[0] * k;
    const double ly = sl[1] * k;
    double sc = 0.0;  // sum of dot products of the centred pairs
    double ss = 0.0;  // sum of cross products
    for (std::size_t i = 0; i < n; ++i) {
      const double ax = pairsObs[i].x - ox;
      const double ay = pairsObs[i].y - oy;
      const double bx = pairsMap[i].x - lx;
      const double by = pairsMap[i].y - ly;
      sc += ax * bx + ay * by;
      ss += ax * by - ay * bx;
    }
    const double th = std::atan2(ss, sc);
    const double rc = std::cos(th);
    const double rs = std::sin(th);
    *refit = Pose2d{lx - (rc * ox - rs * oy), ly - (rs * ox + rc * oy), th};
  } else if (refit != nullptr) {
    *refit = pose;
  }
  return n;
}

bool distinct(const Pose2d& a, const Pose2d& b, const UniquenessParams& p) {
  return std::hypot(a.x - b.x, a.y - b.y) > p.distinctDistance ||
         std::fabs(normalizeAngle(a.theta - b.theta)) > p.distinctAngle;
}

}  // namespace

Uniqueness judgeUniqueness(const std::vector<OraclePoint>& map, const std::vector<OraclePoint>& observations,
                           const Pose2d& truth, const UniquenessParams& params) {
  Uniqueness u;
  u.visible = observations.size();
  u.truthSupport = support(map, observations, truth, params.tolerance, nullptr);
  if (observations.size() < 2) {
    // One point leaves the heading free, none everything: any rotation about the landmark (or
    // any pose) explains it as well.
    u.otherSupport = u.truthSupport;
    u.unique = false;
    return u;
  }
  // The two observations farthest apart anchor the search.
  std::size_t a = 0;
  std::size_t b = 1;
  double dMax = -1.0;
  for (std::size_t i = 0; i < observations.size(); ++i) {
    for (std::size_t j = i + 1; j < observations.size(); ++j) {
      const double d = std::hypot(observations[i].x - observations[j].x, observations[i].y - observations[j].y);
      if (d > dMax) {
        dMax = d;
        a = i;
        b = j;
      }
    }
  }
  const OraclePoint& oa = observations[a];
  const OraclePoint& ob = observations[b];
  const double obsAngle = std::atan2(ob.y - oa.y, ob.x - oa.x);
  // A two-point fit misplaces the other observations of a pose that explains them all by less
  // than 4 tolerances (midpoint off by one, the rotation error of 2 tolerances over the anchors'
  // distance acting over at most 0.87 of it, the point's own residual): associate within that,
  // refit, and count within the tolerance.
  const double wideGate = 4.0 * params.tolerance;
  for (std::size_t j = 0; j < map.size(); ++j) {
    for (std::size_t k = 0; k < map.size(); ++k) {
      if (j == k) {
        continue;
      }
      const double d = std::hypot(map[k].x - map[j].x, map[k].y - map[j].y);
      if (std::fabs(d - dMax) > 2.0 * params.tolerance) {
        continue;
      }
      ++u.hypotheses;
      const double th = normalizeAngle(std::atan2(map[k].y - map[j].y, map[k].x - map[j].x) - obsAngle);
      const double c = std::cos(th);
      const double s = std::sin(th);
      // Midpoints aligned.
      const double mx = 0.5 * (oa.x + ob.x);
      const double my = 0.5 * (oa.y + ob.y);
      const Pose2d pose{0.5 * (map[j].x + map[k].x) - (c * mx - s * my),
                        0.5 * (map[j].y + map[k].y) - (s * mx + c * my), th};
      Pose2d refit = pose;
      (void)support(map, observations, pose, wideGate, &refit);
      const std::size_t n = support(map, observations, refit, params.tolerance, nullptr);
      if (distinct(refit, truth, params) && n > u.otherSupport) {
        u.otherSupport = n;
        u.other = refit;
      }
    }
  }
  u.unique = u.otherSupport < u.truthSupport;
  return u;
}

std::vector<OraclePoint> visibleReflectors(const sim::RayCaster& caster, const sim::SimLaserParams& laser,
                                           const Pose2d& laserPose) {
  std::vector<OraclePoint> out;
  if (!laser.reportsReflectors) {
    return out;
  }
  const sim::World& w = caster.world();
  for (std::size_t k = 0; k < w.circles.size(); ++k) {
    const sim::Circle& c = w.circles[k];
    if (c.kind != sim::ObstacleKind::Reflector) {
      continue;
    }
    const Pose2d::Vector2 v = laserPose.inverseTransformPoint(Pose2d::Vector2(c.centre.x, c.centre.y));
    const double bearing = std::atan2(v.y(), v.x());
    if (std::fabs(bearing) > 0.5 * laser.fieldOfView) {
      continue;
    }
    const double dist = v.norm();
    if (dist - c.radius > laser.reflectorMaxRange || dist - c.radius < laser.rangeMin) {
      continue;
    }
    const sim::RayHit hit = caster.cast(sim::Point2{laserPose.x, laserPose.y}, laserPose.theta + bearing, dist);
    if (!hit.hit || !hit.circle || hit.index != k) {
      continue;
    }
    out.push_back(OraclePoint{c.centre.x, c.centre.y});
  }
  return out;
}

std::vector<OraclePoint> visibleMapPoints(const sim::RayCaster& caster, const sim::SimLaserParams& laser,
                                          const Pose2d& laserPose, const std::vector<OraclePoint>& points,
                                          double maxRange) {
  constexpr double kOnSurface = 0.10;  // [m]
  std::vector<OraclePoint> out;
  for (const OraclePoint& p : points) {
    const Pose2d::Vector2 v = laserPose.inverseTransformPoint(Pose2d::Vector2(p.x, p.y));
    const double bearing = std::atan2(v.y(), v.x());
    const double dist = v.norm();
    if (std::fabs(bearing) > 0.5 * laser.fieldOfView || dist > maxRange || dist > laser.rangeMax ||
        dist < laser.rangeMin) {
      continue;
    }
    // Nothing in the way: no surface hit short of the point (a ray aimed exactly at a convex
    // corner may graze past it, so the point itself need not be hit).
    const sim::RayHit hit =
        caster.cast(sim::Point2{laserPose.x, laserPose.y}, laserPose.theta + bearing, dist - kOnSurface);
    if (!hit.hit) {
      out.push_back(p);
    }
  }
  return out;
}

}  // namespace agv::hil
