#pragma once
/// @file tricycle.hpp
/// Tricycle kinematics of the logical point (the projection of the steered drive wheel's centre
/// onto the rear axle) of a forklift AGV: one steered, driven front wheel at wheelbase L ahead of
/// the passive rear axle.
///
/// Symbols: ds = distance rolled by the drive wheel [m] (signed, + forward), alpha = steering
/// angle [rad] (+ left), L = wheelbase [m]. The logical point moves forward by ds*cos(alpha) along
/// its heading and turns by ds*sin(alpha)/L.

#include <cmath>

#include "agv/core/pose2.hpp"
#include "agv/core/status.hpp"

namespace agv {

/// Geometric and encoder parameters of a tricycle vehicle (the calibration's unknowns except L).
struct TricycleParams {
  double wheelbase = 1.5;            ///< L [m], known from the drawing
  double driveScale = 5e-4;          ///< s_w [m/tick]: drive-wheel travel per encoder tick
  double steerOffsetForward = 0.0;   ///< alpha_F [rad]: added to the measured steering when driving forward
  double steerOffsetBackward = 0.0;  ///< alpha_B [rad]: the same for backward motion (= alpha_F in the standard model)

  /// `Ok`, `NonFiniteInput`, or `InvalidArgument` (wheelbase or drive scale not positive).
  Status validate() const noexcept {
    if (!std::isfinite(wheelbase) || !std::isfinite(driveScale) || !std::isfinite(steerOffsetForward) ||
        !std::isfinite(steerOffsetBackward)) {
      return Status::NonFiniteInput;
    }
    return wheelbase > 0.0 && driveScale > 0.0 ? Status::Ok : Status::InvalidArgument;
  }
};

/// (1 - cos t) / t and sin t / t, evaluated without cancellation near t = 0 (series to t^4).
inline void arcFactors(double t, double* sinc, double* cosc) noexcept {
  if (std::fabs(t) < 1e-4) {
    const double t2 = t * t;
    *sinc = 1.0 - t2 / 6.0 + t2 * t2 / 120.0;
    *cosc = t * (0.5 - t2 / 24.0);
  } else {
    *sinc = std::sin(t) / t;
    *cosc = (1.0 - std::cos(t)) / t;
  }
}

/// Exact motion of the logical point over a constant-steering segment, as a pose increment in the
/// start frame: rotation t = ds*sin(alpha)/L, translation ds*cos(alpha)*[sin t / t, (1 - cos t)/t].
/// Finite for straight motion (alpha = 0) and for ds = 0; `alpha` is the *true* steering angle
/// (measured + offset).
inline Pose2d tricycleArc(double ds, double alpha, double wheelbase) noexcept {
  const double d = ds * std::cos(alpha);
  const double t = ds * std::sin(alpha) / wheelbase;
  double sinc = 1.0;
  double cosc = 0.0;
  arcFactors(t, &sinc, &cosc);
  return Pose2d{d * sinc, d * cosc, normalizeAngle(t)};
}

/// One second-order Runge-Kutta (midpoint) step of the logical point between two encoder samples:
/// the steering angle is taken as the mean of the previous and current (true) angles, the heading
/// at mid-step. Used by the localizer's prediction; for a constant steering angle it agrees with
/// `tricycleArc` to O(ds^3).
inline Pose2d tricycleRk2Step(const Pose2d& pose, double ds, double alphaPrev, double alphaCur,
                              double wheelbase) noexcept {
  const double alpha = 0.5 * (alphaPrev + alphaCur);
  const double dTheta = ds * std::sin(alpha) / wheelbase;
  const double forward = ds * std::cos(alpha);
  const double heading = pose.theta + 0.5 * dTheta;
  return Pose2d{pose.x + forward * std::cos(heading), pose.y + forward * std::sin(heading),
                normalizeAngle(pose.theta + dTheta)};
}

}  // namespace agv
