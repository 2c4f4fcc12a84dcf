#pragma once
/// @file pose_ekf.hpp
/// Extended Kalman filter over the planar pose (x, y, theta) of the vehicle's logical point:
/// prediction by an odometry increment, correction by one point landmark observed in the laser
/// frame (Cartesian), Joseph-form covariance update with symmetrisation and a variance floor.
///
/// Precision: double. Position variances after corrections are ~1e-6 m^2 and heading variances
/// ~1e-8 rad^2 while dead-reckoning can grow them to ~1 m^2: the Joseph update subtracts nearly
/// equal products over that range, which float's 24-bit mantissa turns into a non-positive-definite
/// covariance within minutes; and the state itself must keep sub-millimetre increments at hundreds
/// of metres. On a single-precision MCU the double arithmetic is emulated: 3x3 matrices keep that
/// affordable (see docs/localization.md for measured cycle cost).
///
/// Observation model (Cartesian, laser frame): the landmark at world point m is seen at
///   z = h(x, m) = l ⊖ (x ⊖ m)  i.e.  z = R(l_theta)^T (R(theta)^T (m - t) - l_t),
/// with l the calibrated laser mounting pose in the logical-point frame. Cartesian is chosen over
/// range-bearing because (a) the innovation has no angle wrap-around and no singularity at short
/// range, (b) FALKO keypoints and reflector centres are produced as points, (c) the gate, the map
/// update and the landmark uncertainty are all in metres; the laser's range/bearing noise is
/// carried exactly to first order by the per-observation covariance (`polarToCartesianCovariance`).

#include <Eigen/Core>

#include "agv/core/pose2.hpp"
#include "agv/core/status.hpp"
#include "agv/localization/odometry.hpp"

namespace agv {

/// Parameters of the pose filter.
struct PoseEkfParams {
  double varianceFloorXY = 1e-10;     ///< [m^2] lowest x/y variance kept ((10 um)^2)
  double varianceFloorTheta = 1e-12;  ///< [rad^2] lowest heading variance kept ((1 urad)^2)
  /// `Ok`, `NonFiniteInput`, or `InvalidArgument` (a floor not positive).
  Status validate() const noexcept;
};

/// The linearised prediction of one point observation at the current state.
struct PointInnovation {
  Eigen::Vector2d innovation = Eigen::Vector2d::Zero();                 ///< z - h(x, m) [m], laser frame
  Eigen::Matrix2d S = Eigen::Matrix2d::Identity();                      ///< H P H^T + R [m^2]
  Eigen::Matrix<double, 2, 3> H = Eigen::Matrix<double, 2, 3>::Zero();  ///< dh/dx
  Eigen::Matrix2d R = Eigen::Matrix2d::Zero();                          ///< observation + landmark noise [m^2]
  double mahalanobis2 = 0.0;                                            ///< nu^T S^-1 nu
  bool valid = false;                                                   ///< false when S is not positive definite
};

/// Covariance [m^2] of a laser-frame point measured at range r, bearing b with independent range
/// and bearing noise: J diag(sr^2, sb^2) J^T, J = d(r cos b, r sin b)/d(r, b).
Eigen::Matrix2d polarToCartesianCovariance(double x, double y, double rangeSigma, double bearingSigma) noexcept;

/// The filter. Holds no history; see `Localizer` for latency handling and association.
class PoseEkf {
 public:
  PoseEkf() noexcept = default;
  explicit PoseEkf(const PoseEkfParams& params) noexcept : params_(params) {}

  /// Sets the state. `InvalidArgument` (state unchanged) if not finite, not symmetric or a
  /// diagonal term is negative.
  Status reset(const Pose2d& pose, const Eigen::Matrix3d& covariance) noexcept;

  /// x <- x ⊕ delta, P <- F P F^T + G Q G^T. `NonFiniteInput` (state unchanged) for an invalid
  /// increment.
  Status predict(const OdometryIncrement& increment) noexcept;

  /// Linearised observation of landmark `landmarkWorld` measured at `zLaser` through the laser
  /// mounting pose `laserPose`, with total noise `R` (sensor + landmark) in the laser frame.
  PointInnovation innovation(const Eigen::Vector2d& zLaser, const Eigen::Vector2d& landmarkWorld,
                             const Eigen::Matrix2d& R, const Pose2d& laserPose) const noexcept;

  /// Applies one point correction in Joseph form, symmetrises and floors the variances.
  /// `Rejected` when the innovation is invalid or its Mahalanobis distance exceeds `gate`;
  /// `NonFiniteInput` if the result would not be finite. State unchanged on failure.
  Status update(const PointInnovation& innovation, double gate) noexcept;

  /// Squared Mahalanobis distance of a direct pose measurement `z` with covariance `R` from the
  /// current state (heading difference wrapped): nu^T (P + R)^-1 nu. Infinity when P + R is not
  /// positive definite or an input is not finite.
  double poseMahalanobis2(const Pose2d& z, const Eigen::Matrix3d& R) const noexcept;

  /// Corrects with a direct measurement `z` of the pose (H = I, e.g. a scan-to-map match) whose
  /// covariance is `R`, Joseph form. `Rejected` when the squared Mahalanobis distance exceeds
  /// `gate` (3 dof) or P + R is not positive definite; `NonFiniteInput` for non-finite input or
  /// result. State unchanged on failure.
  Status updatePose(const Pose2d& z, const Eigen::Matrix3d& R, double gate) noexcept;

  const Pose2d& pose() const noexcept { return pose_; }
  const Eigen::Matrix3d& covariance() const noexcept { return P_; }
  const PoseEkfParams& params() const noexcept { return params_; }

 private:
  void condition(Eigen::Matrix3d& P) const noexcept;
  /// x <- x + dx, P <- P symmetrised and conditioned; `NonFiniteInput` (state unchanged) when
  /// either is not finite.
  Status commit(const Eigen::Vector3d& dx, Eigen::Matrix3d P) noexcept;
  /// Innovation of a direct pose measurement and (P + R)^-1; false for non-finite input or P + R
  /// not positive definite.
  bool poseInnovation(const Pose2d& z, const Eigen::Matrix3d& R, Eigen::Vector3d& nu,
                      Eigen::Matrix3d& Sinv) const noexcept;

  PoseEkfParams params_{};
  Pose2d pose_{};
  Eigen::Matrix3d P_ = Eigen::Matrix3d::Identity();
};

}  // namespace agv
