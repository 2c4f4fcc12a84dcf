#pragma once
// Ray-cast simulation of a 2D laser in polygonal rooms with pillars, for the FALKO tests.
// Geometry in double (ground truth), output as a float LaserScan. No heap: usable on the MCU.

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>

#include "agv/core/angle.hpp"
#include "agv/scan/laser_scan.hpp"

namespace agv {
namespace test {

struct P2 {
  double x = 0.0;
  double y = 0.0;
};

/// A closed polygon (walls between consecutive vertices and from the last to the first).
struct Polygon {
  std::array<P2, 12> v{};
  std::size_t n = 0;
};

/// Room outline plus obstacles; every polygon is opaque.
struct World {
  std::array<Polygon, 4> polys{};
  std::size_t count = 0;
  void add(const Polygon& p) { polys[count++] = p; }
};

/// Distance from o along unit direction (dx, dy) to the first wall; +inf if none.
inline double castRay(const World& w, P2 o, double dx, double dy) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t p = 0; p < w.count; ++p) {
    const Polygon& poly = w.polys[p];
    for (std::size_t k = 0; k < poly.n; ++k) {
      const P2 a = poly.v[k];
      const P2 b = poly.v[(k + 1) % poly.n];
      const double ex = b.x - a.x;
      const double ey = b.y - a.y;
      const double den = dx * ey - dy * ex;
      if (std::fabs(den) < 1e-12) {
        continue;
      }
      const double ax = a.x - o.x;
      const double ay = a.y - o.y;
      const double t = (ax * ey - ay * ex) / den;  // along the ray
      const double u = (ax * dy - ay * dx) / den;  // along the edge
      if (t > 1e-9 && u >= 0.0 && u <= 1.0 && t < best) {
        best = t;
      }
    }
  }
  return best;
}

/// Small deterministic Gaussian generator (xorshift32 + Box-Muller), identical on every target.
class Gauss {
 public:
  explicit Gauss(std::uint32_t seed) : s_(seed == 0U ? 1U : seed) {}
  double uniform() {
    s_ ^= s_ << 13U;
    s_ ^= s_ >> 17U;
    s_ ^= s_ << 5U;
    return (static_cast<double>(s_) + 1.0) / 4294967297.0;
  }
  double next() {
    const double u1 = uniform();
    const double u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
  }

 private:
  std::uint32_t s_;
};

/// Sensor pose in the world (x, y, heading).
struct SensorPose {
  double x = 0.0;
  double y = 0.0;
  double theta = 0.0;
};

/// Ray-casts `beams` beams from `angleMin` (sensor frame) in steps of `increment`; ranges get
/// Gaussian noise of `sigma` metres. rangeMax 30 m (misses stored as +inf).
inline void simulateScan(const World& w, SensorPose s, float angleMin, float increment, std::size_t beams, double sigma,
                         std::uint32_t seed, LaserScan& out) {
  Gauss g(seed);
  out.angleMin = angleMin;
  out.angleIncrement = increment;
  out.rangeMin = 0.05F;
  out.rangeMax = 30.0F;
  out.ranges.clear();
  for (std::size_t i = 0; i < beams; ++i) {
    const double a = s.theta + static_cast<double>(angleMin + static_cast<float>(i) * increment);
    double r = castRay(w, P2{s.x, s.y}, std::cos(a), std::sin(a));
    if (sigma > 0.0) {
      r += sigma * g.next();
    }
    (void)out.ranges.push_back(static_cast<float>(r));
  }
}

/// World point to sensor frame.
inline P2 toSensor(SensorPose s, P2 p) {
  const double dx = p.x - s.x;
  const double dy = p.y - s.y;
  const double c = std::cos(s.theta);
  const double sn = std::sin(s.theta);
  return P2{c * dx + sn * dy, -sn * dx + c * dy};
}

/// True when the world point is seen by the sensor (not occluded) and lies within the angular
/// field [fovMin, fovMax] (sensor frame, radians).
inline bool isVisible(const World& w, SensorPose s, P2 p, double fovMin, double fovMax) {
  const P2 q = toSensor(s, p);
  const double bearing = std::atan2(q.y, q.x);
  if (bearing < fovMin || bearing > fovMax) {
    return false;
  }
  const double d = std::hypot(p.x - s.x, p.y - s.y);
  const double a = std::atan2(p.y - s.y, p.x - s.x);
  return castRay(w, P2{s.x, s.y}, std::cos(a), std::sin(a)) >= d - 1e-6;
}

/// Corners of the world that a FALKO detector must find: visible, with both walls visible for
/// `sideLength` metres from the corner and seen at less than 75 deg incidence (a grazing wall
/// holds too few points for a line), in the field of view with `margin` rad to spare. Written
/// in sensor frame to `out`; returns the count.
template <std::size_t N>
std::size_t expectedCorners(const World& w, SensorPose s, double fovMin, double fovMax, double sideLength,
                            double margin, std::array<P2, N>& out) {
  std::size_t count = 0;
  for (std::size_t p = 0; p < w.count; ++p) {
    const Polygon& poly = w.polys[p];
    for (std::size_t k = 0; k < poly.n; ++k) {
      const P2 c = poly.v[k];
      const P2 prev = poly.v[(k + poly.n - 1) % poly.n];
      const P2 next = poly.v[(k + 1) % poly.n];
      auto along = [&](P2 to) {
        const double L = std::hypot(to.x - c.x, to.y - c.y);
        const double f = sideLength / L;
        return P2{c.x + f * (to.x - c.x), c.y + f * (to.y - c.y)};
      };
      // Points slightly off the exact corner (the corner itself is hit ambiguously by rays).
      auto nudge = [&](P2 to) {
        const double L = std::hypot(to.x - c.x, to.y - c.y);
        const double f = 0.01 / L;
        return P2{c.x + f * (to.x - c.x), c.y + f * (to.y - c.y)};
      };
      // cos of the incidence angle of the view ray on the wall from c towards `to`
      auto incidenceCos = [&](P2 to) {
        const double ex = to.x - c.x;
        const double ey = to.y - c.y;
        const double vx = c.x - s.x;
        const double vy = c.y - s.y;
        return std::fabs(ex * vy - ey * vx) / (std::hypot(ex, ey) * std::hypot(vx, vy));
      };
      const double cos75 = 0.25881904510252074;
      if (incidenceCos(prev) >= cos75 && incidenceCos(next) >= cos75 &&
          isVisible(w, s, nudge(prev), fovMin + margin, fovMax - margin) &&
          isVisible(w, s, nudge(next), fovMin + margin, fovMax - margin) &&
          isVisible(w, s, along(prev), fovMin, fovMax) && isVisible(w, s, along(next), fovMin, fovMax) && count < N) {
        out[count++] = toSensor(s, c);
      }
    }
  }
  return count;
}

/// Every corner of the world in sensor frame (visible or not); returns the count.
template <std::size_t N>
std::size_t allCorners(const World& w, SensorPose s, std::array<P2, N>& out) {
  std::size_t count = 0;
  for (std::size_t p = 0; p < w.count; ++p) {
    for (std::size_t k = 0; k < w.polys[p].n && count < N; ++k) {
      out[count++] = toSensor(s, w.polys[p].v[k]);
    }
  }
  return count;
}

/// A convex room whose corners all have different angles, and a square pillar turned -10 deg.
inline World testRoom() {
  World w;
  Polygon room;
  room.v[0] = P2{0.0, 0.0};
  room.v[1] = P2{8.0, -0.5};
  room.v[2] = P2{9.5, 4.0};
  room.v[3] = P2{6.0, 7.5};
  room.v[4] = P2{1.0, 6.0};
  room.n = 5;
  w.add(room);
  Polygon pillar;
  const double cx = 6.5;
  const double cy = 2.0;
  const double h = 0.4;
  const double a = -0.17453292519943295;  // one corner faces the usual sensor poses
  for (std::size_t k = 0; k < 4; ++k) {
    const double ang = a + 1.5707963267948966 * static_cast<double>(k);
    pillar.v[k] = P2{cx + h * std::sqrt(2.0) * std::cos(ang), cy + h * std::sqrt(2.0) * std::sin(ang)};
  }
  pillar.n = 4;
  w.add(pillar);
  return w;
}

/// A convex room whose corners differ by at least 25 deg (interior angles 135, 50, 165, 80, 110
/// deg): two-wall corners are told apart by their angle only, so descriptor tests need this.
inline World distinctRoom() {
  World w;
  Polygon room;
  room.v[0] = P2{0.0, 0.0};
  room.v[1] = P2{9.0, 0.0};
  room.v[2] = P2{3.858, 6.128};
  room.v[3] = P2{-1.876, 10.143};
  room.v[4] = P2{-4.505, 4.505};
  room.n = 5;
  w.add(room);
  return w;
}

/// A single long straight wall (y = 3 in the world), nothing else.
inline World straightWall() {
  World w;
  Polygon wall;
  wall.v[0] = P2{-100.0, 3.0};
  wall.v[1] = P2{100.0, 3.0};
  wall.v[2] = P2{100.0, 3.1};
  wall.v[3] = P2{-100.0, 3.1};
  wall.n = 4;
  w.add(wall);
  return w;
}

}  // namespace test
}  // namespace agv
