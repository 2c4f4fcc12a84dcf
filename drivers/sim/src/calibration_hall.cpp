#include "agv/sim/calibration_hall.hpp"

#include <cmath>

#include "agv/core/angle.hpp"

namespace agv::sim {

namespace {
Box3 slab(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  Box3 b;
  b.centre = (lo + hi) / 2.0;
  b.half = (hi - lo) / 2.0;
  return b;
}
}  // namespace

CalibrationHall calibrationHall(const CalibrationHallConfig& c) {
  CalibrationHall hall;
  hall.config = c;
  std::vector<Box3>& boxes = hall.world.boxes;
  const double t = 0.3;  // wall thickness
  // The target: its face at x = 0.
  boxes.push_back(
      slab({0.0, -c.targetWidth / 2, c.targetBottom}, {0.05, c.targetWidth / 2, c.targetBottom + c.targetHeight}));
  hall.targetSurface = 1;
  // Hall: back wall behind the placements, front wall beyond the target, side walls, ceiling.
  const double x0 = -c.hallBehind;
  const double x1 = c.hallFront;
  const double w = c.hallHalfWidth;
  boxes.push_back(slab({x0 - t, -w - t, 0.0}, {x0, w + t, c.hallHeight}));
  boxes.push_back(slab({x1, -w - t, 0.0}, {x1 + t, w + t, c.hallHeight}));
  boxes.push_back(slab({x0, -w - t, 0.0}, {x1, -w, c.hallHeight}));
  boxes.push_back(slab({x0, w, 0.0}, {x1, w + t, c.hallHeight}));
  boxes.push_back(slab({x0 - t, -w - t, c.hallHeight}, {x1 + t, w + t, c.hallHeight + t}));
  // A pillar beside the target and pallets on the floor, away from the line of sight (|y| > 3 m)
  // and at least 1 m off the target's plane.
  boxes.push_back(slab({-1.5, 3.2, 0.0}, {-1.0, 3.7, c.hallHeight}));
  std::mt19937_64 rng(c.seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int k = 0; k < c.pallets; ++k) {
    const double x = -c.hallBehind + 2.0 + u(rng) * (c.hallBehind + c.hallFront - 4.0);
    const double side = u(rng) < 0.5 ? -1.0 : 1.0;
    const double y = side * (3.0 + u(rng) * (w - 4.0));
    if (std::fabs(x) < 1.5) {
      continue;  // keep the target's plane clear
    }
    const double h = 0.15 + u(rng) * 1.4;
    Box3 b = slab({x - 0.6, y - 0.4, 0.0}, {x + 0.6, y + 0.4, h});
    b.rotation = Eigen::AngleAxisd(u(rng) * kPi<double>, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    boxes.push_back(b);
  }
  return hall;
}

std::vector<HallPlacement> hallProtocol(int distances, double nearest, double farthest, int tilts, double lowestTilt,
                                        double highestTilt) {
  std::vector<HallPlacement> out;
  for (int i = 0; i < distances; ++i) {
    const double d = distances > 1 ? nearest + (farthest - nearest) * i / (distances - 1) : nearest;
    for (int j = 0; j < tilts; ++j) {
      HallPlacement p;
      p.distance = d;
      p.tilt = tilts > 1 ? lowestTilt + (highestTilt - lowestTilt) * j / (tilts - 1) : lowestTilt;
      out.push_back(p);
    }
  }
  return out;
}

Eigen::Isometry3d placementPose(const HallPlacement& p) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(-p.distance, 0.0, p.height);
  // Pitch up by `tilt`: a rotation of -tilt about y lifts +x.
  pose.linear() =
      (Eigen::AngleAxisd(p.yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(-p.tilt, Eigen::Vector3d::UnitY()))
          .toRotationMatrix();
  return pose;
}

void scanModel(const MultibeamWorld& world, const Eigen::Isometry3d& pose, const LaserIntrinsics& truth,
               const ModelSensorConfig& sensor, std::mt19937_64& rng, ModelScan& out) {
  out.returns.clear();
  out.surface.clear();
  std::normal_distribution<double> noise(0.0, 1.0);
  const double res = truth.distanceResolution();
  for (std::size_t f = 0; f < sensor.firings; ++f) {
    double phi = kTwoPi<double> * (static_cast<double>(f) + 0.5) / static_cast<double>(sensor.firings);
    if (sensor.azimuthWindow > 0.0 && std::fabs(normalizeAngle(phi)) > sensor.azimuthWindow) {
      continue;
    }
    for (std::size_t l = 0; l < truth.size(); ++l) {
      const Eigen::Matrix<double, kLaserParamCount, 1> p = toVector(truth.params(l));
      const LaserRay<double> ray = laserRay(p.data(), phi);
      // The model's points for D >= 0; the beam leaves the head at D = 0.
      const Eigen::Vector3d origin = pose * ray.origin;
      const Eigen::Vector3d dir = pose.linear() * ray.direction;
      int surface = -1;
      const double d = world.cast(origin, dir, sensor.maxRange, nullptr, &surface);
      if (surface < 0) {
        continue;
      }
      double range = d - p[kDistCorrection] + sensor.rangeNoise * noise(rng);
      if (sensor.quantize) {
        range = std::round(range / res) * res;
      }
      if (range <= 0.0) {
        continue;
      }
      out.returns.push_back(RawReturn{static_cast<std::uint16_t>(l), phi, range});
      out.surface.push_back(surface);
    }
  }
}

LaserIntrinsics perturbIntrinsics(const LaserIntrinsics& factory, double distCorrection, double theta, double alpha,
                                  double vertHoriz, std::mt19937_64& rng, bool zeroMeanAngles) {
  LaserIntrinsics out = factory;
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<LaserParams> moved;
  double meanTheta = 0.0;
  double meanAlpha = 0.0;
  for (std::size_t l = 0; l < factory.size(); ++l) {
    LaserParams p = factory.params(l);
    p.distCorrection += distCorrection * u(rng);
    p.theta += theta * u(rng);
    p.alpha += alpha * u(rng);
    p.vertOffset += vertHoriz * u(rng);
    p.horizOffset += vertHoriz * u(rng);
    meanTheta += (p.theta - factory.params(l).theta) / static_cast<double>(factory.size());
    meanAlpha += (p.alpha - factory.params(l).alpha) / static_cast<double>(factory.size());
    moved.push_back(p);
  }
  for (std::size_t l = 0; l < factory.size(); ++l) {
    if (zeroMeanAngles) {
      moved[l].theta -= meanTheta;
      moved[l].alpha -= meanAlpha;
    }
    static_cast<void>(out.set(l, moved[l]));  // finite, |angles| < pi: cannot fail for a valid factory table
  }
  return out;
}

}  // namespace agv::sim
