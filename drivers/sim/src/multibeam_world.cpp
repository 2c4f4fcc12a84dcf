#include "agv/sim/multibeam_world.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

#include "agv/core/angle.hpp"

namespace agv::sim {

double MultibeamWorld::cast(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double maxRange,
                            const std::vector<std::size_t>* candidates, int* surface) const {
  double best = maxRange;
  int what = -1;
  if (dir.z() < -1e-12 && -origin.z() / dir.z() < best) {
    best = -origin.z() / dir.z();  // ground z = 0
    what = 0;
  }
  const std::size_t n = candidates != nullptr ? candidates->size() : boxes.size();
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t index = candidates != nullptr ? (*candidates)[k] : k;
    const Box3& b = boxes[index];
    // Slab test in the box frame.
    const Eigen::Vector3d o = b.rotation.transpose() * (origin - b.centre);
    const Eigen::Vector3d d = b.rotation.transpose() * dir;
    double t0 = 0.0;
    double t1 = best;
    bool hit = true;
    for (int a = 0; a < 3 && hit; ++a) {
      if (std::fabs(d[a]) < 1e-15) {
        hit = std::fabs(o[a]) <= b.half[a];
        continue;
      }
      double ta = (-b.half[a] - o[a]) / d[a];
      double tb = (b.half[a] - o[a]) / d[a];
      if (ta > tb) {
        std::swap(ta, tb);
      }
      t0 = std::max(t0, ta);
      t1 = std::min(t1, tb);
      hit = t0 <= t1;
    }
    if (hit && t0 > 1e-9 && t0 < best) {
      best = t0;
      what = static_cast<int>(index) + 1;
    }
  }
  if (surface != nullptr) {
    *surface = what;
  }
  return best;
}

MultibeamSensor vlp16Sensor() {
  MultibeamSensor s;
  const double elev[16] = {-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15};
  for (const double e : elev) {
    s.elevation.push_back(deg2rad(e));
    s.azimuthOffset.push_back(0.0);
  }
  s.firings = 1800;
  s.height = 1.0;
  s.rangeNoise = 0.03;  // VLP-16 spec: +-3 cm
  s.maxRange = 100.0;
  return s;
}

void scanRevolution(const MultibeamWorld& world, const MultibeamSensor& sensor, const Pose2d& pose,
                    std::mt19937_64& rng, std::vector<RingPoint>& out) {
  out.clear();
  const std::size_t lasers = sensor.elevation.size();
  // Rings: elevation ranks.
  std::vector<std::uint16_t> ring(lasers);
  for (std::size_t i = 0; i < lasers; ++i) {
    std::uint16_t r = 0;
    for (std::size_t j = 0; j < lasers; ++j) {
      if (sensor.elevation[j] < sensor.elevation[i] || (sensor.elevation[j] == sensor.elevation[i] && j < i)) {
        ++r;
      }
    }
    ring[i] = r;
  }
  const Eigen::Vector3d origin(pose.x, pose.y, sensor.height);
  // Boxes that may be hit: within maxRange of the sensor (by their bounding sphere).
  std::vector<std::size_t> near;
  for (std::size_t k = 0; k < world.boxes.size(); ++k) {
    const Box3& b = world.boxes[k];
    if ((b.centre - origin).norm() - b.half.norm() < sensor.maxRange) {
      near.push_back(k);
    }
  }
  std::normal_distribution<double> noise(0.0, sensor.rangeNoise);
  const double c = std::cos(pose.theta);
  const double s = std::sin(pose.theta);
  for (std::size_t f = 0; f < sensor.firings; ++f) {
    const double azimuth = kTwoPi<double> * (static_cast<double>(f) + 0.5) / static_cast<double>(sensor.firings);
    for (std::size_t l = 0; l < lasers; ++l) {
      const double az = azimuth + sensor.azimuthOffset[l];
      const double el = sensor.elevation[l];
      const Eigen::Vector3d local(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
      const Eigen::Vector3d dir(c * local.x() - s * local.y(), s * local.x() + c * local.y(), local.z());
      const double t = world.cast(origin, dir, sensor.maxRange, &near);
      if (t >= sensor.maxRange) {
        continue;
      }
      const double r = t + noise(rng);
      if (r <= 0.0) {
        continue;
      }
      out.push_back(RingPoint{(local * r).cast<float>(), ring[l]});
    }
  }
}

namespace {
Eigen::Matrix3d rotation(double yaw, double pitch, double roll) {
  return (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}
}  // namespace

MultibeamWorld yardWorld(double width, double height, std::uint64_t seed) {
  MultibeamWorld w;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const auto uni = [&](double lo, double hi) { return lo + (hi - lo) * u(rng); };
  // Walk along each side of the rectangle, placing structures on the outer and inner sides of
  // the road (the road is 12 m wide, centred on the rectangle's edges).
  const Eigen::Vector2d corners[5] = {{0, 0}, {width, 0}, {width, height}, {0, height}, {0, 0}};
  for (int side = 0; side < 4; ++side) {
    const Eigen::Vector2d a = corners[side];
    const Eigen::Vector2d b = corners[side + 1];
    const double len = (b - a).norm();
    const Eigen::Vector2d along = (b - a) / len;
    const Eigen::Vector2d left(-along.y(), along.x());  // towards the block's inside
    const double sideYaw = std::atan2(along.y(), along.x());
    for (const double sign : {1.0, -1.0}) {
      double s = -10.0;
      while (s < len + 10.0) {
        const double kind = u(rng);
        const double gap = uni(2.0, 8.0);
        double length = 0.0;
        Box3 box;
        const double offset = uni(9.0, 16.0);  // from the centreline to the near face
        if (kind < 0.35) {                     // building
          length = uni(8.0, 25.0);
          const double depth = uni(6.0, 15.0);
          const double h = uni(4.0, 14.0);
          box.half = Eigen::Vector3d(length / 2, depth / 2, h / 2);
          box.rotation = rotation(sideYaw + uni(-0.15, 0.15), 0.0, 0.0);
          const Eigen::Vector2d c = a + along * (s + length / 2) + left * sign * (offset + depth / 2);
          box.centre = Eigen::Vector3d(c.x(), c.y(), h / 2);
          w.boxes.push_back(box);
          if (u(rng) < 0.5) {  // a sloped roof: a slab tilted about the building's long axis
            Box3 roof;
            const double tilt = uni(0.2, 0.6) * (u(rng) < 0.5 ? -1.0 : 1.0);
            roof.half = Eigen::Vector3d(length / 2, depth / 2 / std::cos(tilt), 0.2);
            roof.rotation = box.rotation * rotation(0.0, 0.0, tilt);
            roof.centre = box.centre + Eigen::Vector3d(0, 0, h / 2 + depth / 4 * std::fabs(std::tan(tilt)));
            w.boxes.push_back(roof);
          }
        } else if (kind < 0.55) {  // rack row: long, thin, 2..6 m high, perpendicular or parallel
          length = uni(10.0, 30.0);
          const double h = uni(2.0, 6.0);
          const bool perpendicular = u(rng) < 0.5;
          box.half = perpendicular ? Eigen::Vector3d(0.6, length / 4, h / 2) : Eigen::Vector3d(length / 2, 0.6, h / 2);
          box.rotation = rotation(sideYaw, 0.0, 0.0);
          const double depth = perpendicular ? length / 2 : 1.2;
          const Eigen::Vector2d c =
              a + along * (s + (perpendicular ? 0.6 : length / 2)) + left * sign * (offset + depth / 2);
          box.centre = Eigen::Vector3d(c.x(), c.y(), h / 2);
          w.boxes.push_back(box);
          length = perpendicular ? 1.2 + uni(2.0, 4.0) : length;
        } else if (kind < 0.75) {  // ramp / embankment: a slab pitched 8..35 deg
          length = uni(6.0, 16.0);
          const double pitch = uni(0.14, 0.6);
          box.half = Eigen::Vector3d(length / 2, uni(2.0, 5.0), 0.5);
          box.rotation = rotation(sideYaw + uni(-1.2, 1.2), pitch * (u(rng) < 0.5 ? -1 : 1), uni(-0.2, 0.2));
          const Eigen::Vector2d c = a + along * (s + length / 2) + left * sign * (offset + 3.0);
          box.centre = Eigen::Vector3d(c.x(), c.y(), length / 2 * std::sin(pitch) * 0.6);
          w.boxes.push_back(box);
        } else if (kind < 0.9) {  // wall segment
          length = uni(5.0, 20.0);
          const double h = uni(1.0, 4.0);
          box.half = Eigen::Vector3d(length / 2, 0.15, h / 2);
          box.rotation = rotation(sideYaw + uni(-0.3, 0.3), 0.0, 0.0);
          const Eigen::Vector2d c = a + along * (s + length / 2) + left * sign * offset;
          box.centre = Eigen::Vector3d(c.x(), c.y(), h / 2);
          w.boxes.push_back(box);
        } else {  // tilted panel (a solar rack, a billboard): 20..60 deg
          length = uni(3.0, 8.0);
          box.half = Eigen::Vector3d(length / 2, uni(1.0, 2.5), 0.05);
          box.rotation = rotation(sideYaw + uni(-3.0, 3.0), 0.0, uni(0.35, 1.05));
          const Eigen::Vector2d c = a + along * (s + length / 2) + left * sign * (offset + 2.0);
          box.centre = Eigen::Vector3d(c.x(), c.y(), uni(1.5, 3.0));
          w.boxes.push_back(box);
        }
        s += length + gap;
      }
    }
  }
  return w;
}

std::vector<RoutePose> yardRoute(double width, double height, double step, double backFraction, double againFraction,
                                 double lateral) {
  std::vector<RoutePose> route;
  const Eigen::Vector2d corners[5] = {{0, 0}, {width, 0}, {width, height}, {0, height}, {0, 0}};
  const double lap = 2.0 * (width + height);
  // Position and heading at arc length s of the counter-clockwise lap.
  const auto at = [&](double s) {
    s = std::fmod(std::fmod(s, lap) + lap, lap);
    for (int side = 0; side < 4; ++side) {
      const Eigen::Vector2d a = corners[side];
      const Eigen::Vector2d b = corners[side + 1];
      const double len = (b - a).norm();
      if (s <= len || side == 3) {
        const Eigen::Vector2d d = (b - a) / len;
        const Eigen::Vector2d p = a + d * std::min(s, len);
        return Pose2d{p.x(), p.y(), std::atan2(d.y(), d.x())};
      }
      s -= len;
    }
    return Pose2d{};
  };
  double travel = 0.0;
  const auto add = [&](double s, bool reverse, int pass) {
    Pose2d p = at(s);
    const double off = pass == 0 ? 0.0 : lateral * std::sin(s / 17.0);
    p.x += -std::sin(p.theta) * off;
    p.y += std::cos(p.theta) * off;
    if (reverse) {
      p.theta = normalizeAngle(p.theta + kPi<double>);
    }
    route.push_back(RoutePose{p, travel, pass});
    travel += step;
  };
  for (double s = 0.0; s < lap; s += step) {
    add(s, false, 0);
  }
  for (double s = 0.0; s < backFraction * lap; s += step) {
    add(lap - s, true, 1);  // clockwise from the start
  }
  for (double s = 0.0; s < againFraction * lap; s += step) {
    add(s, false, 2);
  }
  return route;
}

}  // namespace agv::sim
