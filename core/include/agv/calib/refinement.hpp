#pragma once
/// @file refinement.hpp
/// Joint maximum-likelihood refinement of the six calibration parameters (s_w, alpha_F, alpha_B,
/// lx, ly, ltheta) from the closed-form estimate: Levenberg-Marquardt on the full egomotion
/// residuals s^k ⊖ (l^-1 ⊕ r^k ⊕ l) (translation and rotation, where the closed forms use the
/// rotations for the odometry and the translations for the laser separately), each weighted by
/// the inverse of its covariance: the egomotion noise plus the steering-encoder noise propagated
/// through the model. Returns the covariance of the result.
///
/// Precision: double (6x6 normal matrices of terms spanning 1e-8..1e8; see calibration.hpp).
/// Heap-free: fixed-size Eigen matrices, iterations bounded by RefinementOptions::maxIterations,
/// loops by kMaxCalibSegments.

#include <Eigen/Core>

#include "agv/calib/calibration.hpp"

namespace agv {

/// Index of each parameter in RefinementResult::covariance.
enum CalibParam : int {
  kParamDriveScale = 0,
  kParamOffsetForward,
  kParamOffsetBackward,
  kParamLaserX,
  kParamLaserY,
  kParamLaserTheta,
  kCalibParamCount
};

/// Noise model and iteration bounds. Defaults: a navigation laser's scan-matching egomotion
/// (5 mm, 0.1 deg) and a 14-bit absolute steering encoder (quantisation step 2 pi / 2^14).
struct RefinementOptions {
  double sigmaTranslation = 5e-3;       ///< egomotion noise per axis [m]
  double sigmaRotation = deg2rad(0.1);  ///< egomotion rotation noise [rad]
  /// Steering-encoder noise per segment [rad]: quantisation step / sqrt(12) by default; add the
  /// steering controller's jitter in quadrature when the angle varies within a segment.
  double sigmaSteering = kTwoPi<double> / 16384.0 / 3.4641016151377544;
  /// true: one steering offset for both directions (alpha_B is tied to alpha_F, STC model).
  bool sharedOffset = false;
  int maxIterations = 30;            ///< bound on Levenberg-Marquardt iterations
  double relativeTolerance = 1e-12;  ///< stop when the cost decreases by less than this fraction
};

/// Refined parameters, their covariance and the costs before/after.
struct RefinementResult {
  TricycleParams params{};
  Pose2d laserPose{};
  /// Covariance of (s_w [m/tick], alpha_F, alpha_B [rad], lx, ly [m], ltheta [rad]) from the
  /// inverse information matrix at the solution, with the noise model of the options.
  Eigen::Matrix<double, kCalibParamCount, kCalibParamCount> covariance =
      Eigen::Matrix<double, kCalibParamCount, kCalibParamCount>::Zero();
  double initialCost = 0.0;  ///< sum of squared normalised residuals at the closed-form start
  double finalCost = 0.0;    ///< the same at the result (never larger than initialCost)
  int iterations = 0;
};

/// Refines `initial` / `initialLaser` (normally the ATC or STC closed form) on `segments`.
/// Returns Ok; NotEnoughData / CapacityExceeded for the segment count; NonFiniteInput;
/// InvalidArgument for bad noise figures; Unobservable when the information matrix is singular
/// (e.g. no backward segment without sharedOffset). On failure `result` holds the start values.
Status refineCalibration(Span<const CalibSegment> segments, const TricycleParams& initial, const Pose2d& initialLaser,
                         const RefinementOptions& options, RefinementResult& result) noexcept;

}  // namespace agv
