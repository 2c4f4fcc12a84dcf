#pragma once
/// @file lidar3d_sim.hpp
/// A ray-cast multi-beam lidar for the 3D-lidar tests: planes, a per-laser elevation model, range
/// noise, written straight into a range image (one cell per laser and firing, as a decoder would).
/// Portable (also compiled into the Cortex-M7 image): no heap, no <random>.

#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "../loop/loop_test_util.hpp"
#include "agv/core/angle.hpp"
#include "agv/lidar3d/range_image.hpp"

namespace agv::test {

/// An infinite plane n . x = d (n unit), with an id.
struct SimPlane {
  Eigen::Vector3d n = Eigen::Vector3d::UnitZ();
  double d = 0.0;
};

/// Up to 8 planes; a ray stops at the nearest one in front (the inside of a convex room).
struct SimScene {
  SimPlane planes[8];
  std::size_t count = 0;
  void add(const Eigen::Vector3d& n, double d) noexcept {
    planes[count].n = n.normalized();
    planes[count].d = d;
    ++count;
  }
};

/// A box room [x0, x1] x [y0, y1] x [z0, z1] around the sensor (floor z0 < 0; with or without
/// ceiling). Plane 0 is the floor, 1..4 the walls, 5 the ceiling.
inline SimScene boxRoom(double x0, double x1, double y0, double y1, double z0, double z1, bool ceiling) noexcept {
  SimScene s;
  s.add(Eigen::Vector3d::UnitZ(), z0);
  s.add(Eigen::Vector3d::UnitX(), x0);
  s.add(Eigen::Vector3d::UnitX(), x1);
  s.add(Eigen::Vector3d::UnitY(), y0);
  s.add(Eigen::Vector3d::UnitY(), y1);
  if (ceiling) {
    s.add(Eigen::Vector3d::UnitZ(), z1);
  }
  return s;
}

/// The sensor: lasers in elevation order (row 0 lowest), elevation[l] = first + l * step + a fixed
/// per-laser irregularity of up to +-irregularity (what a factory calibration file corrects).
struct SimLidar {
  std::size_t lasers = 16;
  std::size_t firings = 900;
  double firstElevation = deg2rad(-15.0);
  double elevationStep = deg2rad(2.0);
  double irregularity = deg2rad(0.05);
  double rangeNoise = 0.0;  ///< [m] standard deviation of the range
  double maxRange = 100.0;  ///< [m]
  double elevation(std::size_t l) const noexcept {
    // Deterministic irregularity from the laser index (no generator state).
    const double u = std::sin(12.9898 * static_cast<double>(l + 1)) * 0.5;
    return firstElevation + static_cast<double>(l) * elevationStep + 2.0 * u * irregularity;
  }
};

/// The ray of laser l at firing f of a sensor turned by `yaw` (counter-clockwise) in the world,
/// expressed in the sensor frame (the firing azimuth is the column centre plus `phase` columns).
inline Eigen::Vector3d simRay(const SimLidar& lidar, std::size_t l, std::size_t f, double phase) noexcept {
  const double az = (static_cast<double>(f) + 0.5 + phase) * kTwoPi<double> / static_cast<double>(lidar.firings);
  const double el = lidar.elevation(l);
  return {std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el)};
}

/// Casts every laser and firing from a sensor at `position` turned by `yaw` into `image` (reset to
/// lasers x firings), range noise from `rng`; planeOf[l * firings + f] (when not null) receives the
/// id of the plane hit or -1. Returns the number of returns.
inline std::size_t castScene(const SimScene& scene, const SimLidar& lidar, const Eigen::Vector3d& position, double yaw,
                             double phase, LoopRng& rng, RangeImageBase& image,
                             std::int8_t* planeOf = nullptr) noexcept {
  if (image.reset(lidar.lasers, lidar.firings) != Status::Ok) {
    return 0;
  }
  const double c = std::cos(yaw);
  const double s = std::sin(yaw);
  std::size_t hits = 0;
  for (std::size_t l = 0; l < lidar.lasers; ++l) {
    for (std::size_t f = 0; f < lidar.firings; ++f) {
      const Eigen::Vector3d local = simRay(lidar, l, f, phase);
      const Eigen::Vector3d dir(c * local.x() - s * local.y(), s * local.x() + c * local.y(), local.z());
      double best = lidar.maxRange;
      int id = -1;
      for (std::size_t i = 0; i < scene.count; ++i) {
        const double den = scene.planes[i].n.dot(dir);
        if (std::fabs(den) < 1e-12) {
          continue;
        }
        const double t = (scene.planes[i].d - scene.planes[i].n.dot(position)) / den;
        if (t > 1e-6 && t < best) {
          best = t;
          id = static_cast<int>(i);
        }
      }
      if (planeOf != nullptr) {
        planeOf[l * lidar.firings + f] = static_cast<std::int8_t>(id);
      }
      if (id < 0) {
        continue;
      }
      const double r = best + lidar.rangeNoise * rng.normal();
      const Eigen::Vector3d p = local * r;
      if (image.set(l, f, p.cast<float>()) == Status::Ok) {
        ++hits;
      }
    }
  }
  return hits;
}

/// The benchmark scene: a 40 x 30 m box room without ceiling around the sensor (floor 1.8 m below)
/// with a ramp rising at 35 deg towards +x from (6, 0, -1.8).
inline SimScene rampYard() noexcept {
  SimScene scene = boxRoom(-16.0, 24.0, -12.0, 18.0, -1.8, 5.0, false);
  const Eigen::Vector3d ramp(-std::sin(deg2rad(35.0)), 0.0, std::cos(deg2rad(35.0)));
  scene.add(ramp, ramp.dot(Eigen::Vector3d(6.0, 0.0, -1.8)));
  return scene;
}

/// A VLP-16 at 10 Hz (16 lasers -15..+15 deg, 1800 firings) with range noise [m].
inline SimLidar vlp16At10Hz(double noise) noexcept {
  SimLidar lidar;
  lidar.lasers = 16;
  lidar.firings = 1800;
  lidar.rangeNoise = noise;
  return lidar;
}

}  // namespace agv::test
