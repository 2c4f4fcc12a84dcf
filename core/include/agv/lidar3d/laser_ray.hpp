#pragma once
/// @file laser_ray.hpp
/// The thesis' per-laser point model (laser_intrinsics.hpp) written as a ray: for a laser with
/// parameters p and head angle phi, every point of the model lies on the line
///   P(D) = origin(p, phi) + D * direction(p, phi),   D = D_ret + D_corr,
/// because Px, Py, Pz are affine in D. The same algebra serves three uses: the simulator inverts
/// the model (cast the true ray, read D off the hit, report D_ret = D - D_corr), the calibration
/// evaluates it in any scalar type (double, or Ceres' Jet for automatic derivatives; header-only,
/// no Ceres here), and tests compare it with `LaserIntrinsics::laserPoint` (float, cached sines).
///
/// Frame: the library's sensor frame (REP-103: x forward, y left, z up), as `laserPoint`:
///   direction = (cos(theta) cos(beta), -cos(theta) sin(beta), sin(theta)),  beta = phi - alpha,
///   origin    = (-V_o sin(theta) cos(beta) + H_o sin(beta), V_o sin(theta) sin(beta) + H_o cos(beta),
///                V_o cos(theta)).
/// phi is the head azimuth in radians, clockwise seen from above from +x (the packet's 0.01 deg
/// count times pi/18000).

#include <Eigen/Core>
#include <cmath>
#include <cstdint>

#include "agv/lidar3d/laser_intrinsics.hpp"

namespace agv {

/// Position of each parameter in the 5-vector form of `LaserParams` (the calibration's block).
enum LaserParamIndex : int { kDistCorrection = 0, kVertOffset = 1, kHorizOffset = 2, kTheta = 3, kAlpha = 4 };
/// Number of parameters per laser.
inline constexpr int kLaserParamCount = 5;

/// `p` as [D_corr, V_o, H_o, theta, alpha] (SI).
inline Eigen::Matrix<double, kLaserParamCount, 1> toVector(const LaserParams& p) noexcept {
  Eigen::Matrix<double, kLaserParamCount, 1> v;
  v << p.distCorrection, p.vertOffset, p.horizOffset, p.theta, p.alpha;
  return v;
}

/// The inverse of `toVector`.
inline LaserParams toLaserParams(const Eigen::Matrix<double, kLaserParamCount, 1>& v) noexcept {
  return LaserParams{v[kDistCorrection], v[kVertOffset], v[kHorizOffset], v[kTheta], v[kAlpha]};
}

/// One return before the model: laser id, head azimuth phi [rad], D_ret = raw count times the
/// distance resolution [m] (double: the simulator and the calibration keep sub-count values).
struct RawReturn {
  std::uint16_t laser = 0;
  double phi = 0.0;    ///< [rad] head azimuth, clockwise from +x seen from above
  double range = 0.0;  ///< [m] D_ret (without D_corr)
};

/// The beam of one laser at one head angle: the model's points are origin + D * direction.
template <typename T>
struct LaserRay {
  Eigen::Matrix<T, 3, 1> origin;
  Eigen::Matrix<T, 3, 1> direction;  ///< unit vector
};

/// The ray of the laser with parameters `p` ([D_corr, V_o, H_o, theta, alpha], any scalar type)
/// at head angle `phi` [rad].
template <typename T>
LaserRay<T> laserRay(const T* p, double phi) {
  using std::cos;
  using std::sin;
  const T beta = T(phi) - p[kAlpha];
  const T cb = cos(beta);
  const T sb = sin(beta);
  const T ct = cos(p[kTheta]);
  const T st = sin(p[kTheta]);
  LaserRay<T> ray;
  ray.direction << ct * cb, -ct * sb, st;
  ray.origin << -p[kVertOffset] * st * cb + p[kHorizOffset] * sb, p[kVertOffset] * st * sb + p[kHorizOffset] * cb,
      p[kVertOffset] * ct;
  return ray;
}

/// The model's point of a return with D_ret = `range` [m] (double precision counterpart of
/// `LaserIntrinsics::laserPoint`).
template <typename T>
Eigen::Matrix<T, 3, 1> laserModelPoint(const T* p, double phi, double range) {
  const LaserRay<T> ray = laserRay(p, phi);
  return ray.origin + (T(range) + p[kDistCorrection]) * ray.direction;
}

}  // namespace agv
