#include "agv/localization/odometry.hpp"

#include <cmath>

namespace agv {

bool OdometryIncrement::isValid() const noexcept {
  if (!delta.isFinite() || !covariance.allFinite()) {
    return false;
  }
  for (int i = 0; i < 3; ++i) {
    if (covariance(i, i) < 0.0) {
      return false;
    }
    for (int j = 0; j < i; ++j) {
      const double a = covariance(i, j);
      const double b = covariance(j, i);
      if (std::fabs(a - b) > 1e-9 * (std::fabs(a) + std::fabs(b)) + 1e-300) {
        return false;
      }
    }
  }
  return true;
}

OdometryIncrement TricycleOdometry::increment(Timestamp stamp, double ds, double alphaPrev, double alphaCur,
                                              bool tickChanged) const noexcept {
  const double L = vehicle_.wheelbase;
  const double a = 0.5 * (alphaPrev + alphaCur);
  const double ca = std::cos(a);
  const double sa = std::sin(a);
  const double d = ds * ca;           // forward travel of the logical point
  const double dTheta = ds * sa / L;  // rotation
  const double h = 0.5 * dTheta;      // heading of the chord (RK2 midpoint)
  const double ch = std::cos(h);
  const double sh = std::sin(h);

  OdometryIncrement inc;
  inc.stamp = stamp;
  // Same as tricycleRk2Step(identity, ds, alphaPrev, alphaCur, L), expressed in the start frame.
  inc.delta = Pose2d{d * ch, d * sh, normalizeAngle(dTheta)};

  // Jacobian of (dx, dy, dtheta) with respect to the inputs (ds, a).
  Eigen::Matrix<double, 3, 2> J;
  const double dd_ds = ca;
  const double dd_da = -ds * sa;
  const double dt_ds = sa / L;
  const double dt_da = ds * ca / L;
  J(0, 0) = dd_ds * ch - d * sh * 0.5 * dt_ds;
  J(0, 1) = dd_da * ch - d * sh * 0.5 * dt_da;
  J(1, 0) = dd_ds * sh + d * ch * 0.5 * dt_ds;
  J(1, 1) = dd_da * sh + d * ch * 0.5 * dt_da;
  J(2, 0) = dt_ds;
  J(2, 1) = dt_da;

  // Input noise (docs/localization.md): slip is a random walk in rolled distance; the quantisation
  // error telescopes and is spread over the samples of one correction interval; each steering
  // reading enters two consecutive RK2 means with weight 1/2, so its long-run white-equivalent
  // variance per step is the full reading variance.
  const double sw = vehicle_.driveScale;
  const double m = noise_.samplesPerCorrection >= 1.0 ? noise_.samplesPerCorrection : 1.0;
  // A bias is the same for the m samples of a correction interval: m increments each with m times
  // its variance add up to the variance of the summed, fully correlated error.
  const double scaleBias = noise_.scaleBiasSigma * ds;
  const double varDs = noise_.slipVariancePerMetre * std::fabs(ds) + (tickChanged ? sw * sw / (6.0 * m) : 0.0) +
                       m * scaleBias * scaleBias;
  const double varA =
      noise_.steeringSigma * noise_.steeringSigma + m * noise_.steeringBiasSigma * noise_.steeringBiasSigma;
  Eigen::Matrix2d U = Eigen::Matrix2d::Zero();
  U(0, 0) = varDs;
  U(1, 1) = varA;
  inc.covariance = J * U * J.transpose();
  inc.covariance = 0.5 * (inc.covariance + inc.covariance.transpose()).eval();
  return inc;
}

Result<OdometryIncrement> TricycleOdometry::step(const TricycleSample& sample) noexcept {
  if (!std::isfinite(sample.steeringAngle)) {
    return Status::NonFiniteInput;
  }
  if (!hasPrevious_) {
    previous_ = sample;
    hasPrevious_ = true;
    return Status::NotEnoughData;
  }
  if (sample.stamp <= previous_.stamp) {
    return Status::InvalidArgument;
  }
  const std::int64_t dn = sample.driveTicks - previous_.driveTicks;
  if (dn > noise_.maxTicksPerSample || dn < -noise_.maxTicksPerSample) {
    previous_ = sample;  // restart the sequence here
    return Status::OutOfRange;
  }
  const double ds = static_cast<double>(dn) * vehicle_.driveScale;
  const double offset = ds >= 0.0 ? vehicle_.steerOffsetForward : vehicle_.steerOffsetBackward;
  OdometryIncrement inc =
      increment(sample.stamp, ds, previous_.steeringAngle + offset, sample.steeringAngle + offset, dn != 0);
  previous_ = sample;
  return inc;
}

OdometryIncrement unicycleIncrement(Timestamp stamp, const Pose2d& delta, const UnicycleNoiseParams& noise) noexcept {
  OdometryIncrement inc;
  inc.stamp = stamp;
  inc.delta = delta;
  const double dist = std::hypot(delta.x, delta.y);
  const double rot = std::fabs(delta.theta);
  const double varT = noise.translationVariancePerMetre * dist + noise.floorVariance;
  const double varR =
      noise.rotationVariancePerRadian * rot + noise.rotationVariancePerMetre * dist + noise.floorVariance;
  inc.covariance = Eigen::Matrix3d::Zero();
  inc.covariance(0, 0) = varT;
  inc.covariance(1, 1) = varT;
  inc.covariance(2, 2) = varR;
  return inc;
}

Pose2d partialIncrement(const Pose2d& delta, double f) noexcept {
  const double rho = std::hypot(delta.x, delta.y);
  const double dTheta = delta.theta;
  if (rho == 0.0) {
    return Pose2d{0.0, 0.0, normalizeAngle(f * dTheta)};
  }
  const double phi = std::atan2(delta.y, delta.x) - 0.5 * dTheta;  // chord direction vs half-way heading
  const double dir = phi + 0.5 * f * dTheta;
  return Pose2d{f * rho * std::cos(dir), f * rho * std::sin(dir), normalizeAngle(f * dTheta)};
}

Status TricycleNoiseParams::validate() const noexcept {
  if (!std::isfinite(slipVariancePerMetre) || !std::isfinite(steeringSigma) || !std::isfinite(samplesPerCorrection) ||
      !std::isfinite(steeringBiasSigma) || !std::isfinite(scaleBiasSigma)) {
    return Status::NonFiniteInput;
  }
  return slipVariancePerMetre >= 0.0 && steeringSigma >= 0.0 && steeringBiasSigma >= 0.0 && scaleBiasSigma >= 0.0 &&
                 samplesPerCorrection >= 1.0 && maxTicksPerSample > 0
             ? Status::Ok
             : Status::InvalidArgument;
}

}  // namespace agv
