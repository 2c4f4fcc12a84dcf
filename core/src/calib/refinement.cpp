#include "agv/calib/refinement.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>

namespace agv {
namespace {

using Vector6 = Eigen::Matrix<double, kCalibParamCount, 1>;
using Matrix6 = Eigen::Matrix<double, kCalibParamCount, kCalibParamCount>;
using Matrix36 = Eigen::Matrix<double, 3, kCalibParamCount>;

/// Central-difference steps per parameter (s_w is scaled by its value).
constexpr double kAngleStep = 1e-6;   // [rad]
constexpr double kLengthStep = 1e-6;  // [m]
constexpr double kRelativeScaleStep = 1e-6;

TricycleParams paramsOf(const Vector6& p, double wheelbase) noexcept {
  return TricycleParams{wheelbase, p(kParamDriveScale), p(kParamOffsetForward), p(kParamOffsetBackward)};
}

Pose2d laserOf(const Vector6& p) noexcept {
  return Pose2d{p(kParamLaserX), p(kParamLaserY), p(kParamLaserTheta)};
}

Pose2d predict(const CalibSegment& s, const Vector6& p, double wheelbase, double steeringDelta) noexcept {
  CalibSegment moved = s;
  moved.steering += steeringDelta;
  return predictedEgomotion(moved, paramsOf(p, wheelbase), laserOf(p));
}

Eigen::Vector3d residual(const CalibSegment& s, const Pose2d& pred) noexcept {
  return Eigen::Vector3d(s.egomotion.x - pred.x, s.egomotion.y - pred.y, angleDiff(s.egomotion.theta, pred.theta));
}

Eigen::Vector3d difference(const Pose2d& plus, const Pose2d& minus, double twoH) noexcept {
  return Eigen::Vector3d((plus.x - minus.x) / twoH, (plus.y - minus.y) / twoH,
                         angleDiff(plus.theta, minus.theta) / twoH);
}

/// Inverse covariance of one segment's residual: egomotion noise plus the steering noise mapped
/// through d(prediction)/d(steering).
Eigen::Matrix3d weightOf(const CalibSegment& s, const Vector6& p, double wheelbase,
                         const RefinementOptions& opt) noexcept {
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  cov(0, 0) = cov(1, 1) = opt.sigmaTranslation * opt.sigmaTranslation;
  cov(2, 2) = opt.sigmaRotation * opt.sigmaRotation;
  if (opt.sigmaSteering > 0.0) {
    const Eigen::Vector3d ja =
        difference(predict(s, p, wheelbase, kAngleStep), predict(s, p, wheelbase, -kAngleStep), 2.0 * kAngleStep);
    cov.noalias() += (opt.sigmaSteering * opt.sigmaSteering) * (ja * ja.transpose());
  }
  return cov.inverse();
}

int offsetIndex(const CalibSegment& s, bool shared) noexcept {
  return (shared || s.ticks >= 0) ? kParamOffsetForward : kParamOffsetBackward;
}

double cost(Span<const CalibSegment> segs, const Vector6& p, double wheelbase, const RefinementOptions& opt) noexcept {
  double sum = 0.0;
  for (const CalibSegment& s : segs) {
    const Eigen::Vector3d e = residual(s, predict(s, p, wheelbase, 0.0));
    sum += e.dot(weightOf(s, p, wheelbase, opt) * e);
  }
  return sum;
}

/// Gauss-Newton normal equations H = sum J^T W J, g = sum J^T W e at p; returns the cost.
double linearise(Span<const CalibSegment> segs, const Vector6& p, double wheelbase, const RefinementOptions& opt,
                 Matrix6& h, Vector6& g) noexcept {
  h.setZero();
  g.setZero();
  double sum = 0.0;
  for (const CalibSegment& s : segs) {
    const Eigen::Vector3d e = residual(s, predict(s, p, wheelbase, 0.0));
    const Eigen::Matrix3d w = weightOf(s, p, wheelbase, opt);
    Matrix36 j = Matrix36::Zero();
    const int cols[4] = {kParamDriveScale, offsetIndex(s, opt.sharedOffset), kParamLaserX, kParamLaserY};
    for (int c : cols) {
      const double step = c == kParamDriveScale ? kRelativeScaleStep * std::fabs(p(c)) : kLengthStep;
      Vector6 hi = p;
      Vector6 lo = p;
      hi(c) += step;
      lo(c) -= step;
      if (c == kParamOffsetForward || c == kParamOffsetBackward) {
        // the shared offset moves both directions' angle
        if (opt.sharedOffset) {
          hi(kParamOffsetBackward) = hi(kParamOffsetForward);
          lo(kParamOffsetBackward) = lo(kParamOffsetForward);
        }
      }
      j.col(c) = difference(predict(s, hi, wheelbase, 0.0), predict(s, lo, wheelbase, 0.0), 2.0 * step);
    }
    {
      Vector6 hi = p;
      Vector6 lo = p;
      hi(kParamLaserTheta) += kAngleStep;
      lo(kParamLaserTheta) -= kAngleStep;
      j.col(kParamLaserTheta) =
          difference(predict(s, hi, wheelbase, 0.0), predict(s, lo, wheelbase, 0.0), 2.0 * kAngleStep);
    }
    const Matrix36 wj = w * j;
    h.noalias() += j.transpose() * wj;
    g.noalias() += wj.transpose() * e;
    sum += e.dot(w * e);
  }
  if (opt.sharedOffset) {
    h.row(kParamOffsetBackward).setZero();
    h.col(kParamOffsetBackward).setZero();
    h(kParamOffsetBackward, kParamOffsetBackward) = 1.0;
    g(kParamOffsetBackward) = 0.0;
  }
  return sum;
}

/// Smallest eigenvalue of the information matrix scaled to unit diagonal (0 when a diagonal is 0).
double scaledMinEigenvalue(const Matrix6& h) noexcept {
  Vector6 d;
  for (int i = 0; i < kCalibParamCount; ++i) {
    if (!(h(i, i) > 0.0)) {
      return 0.0;
    }
    d(i) = 1.0 / std::sqrt(h(i, i));
  }
  const Matrix6 scaled = d.asDiagonal() * h * d.asDiagonal();
  Eigen::SelfAdjointEigenSolver<Matrix6> es(scaled, Eigen::EigenvaluesOnly);
  return es.eigenvalues()(0);
}

}  // namespace

Status refineCalibration(Span<const CalibSegment> segments, const TricycleParams& initial, const Pose2d& initialLaser,
                         const RefinementOptions& opt, RefinementResult& result) noexcept {
  result = RefinementResult{};
  result.params = initial;
  result.laserPose = initialLaser;
  if (!(opt.sigmaTranslation > 0.0) || !(opt.sigmaRotation > 0.0) || !(opt.sigmaSteering >= 0.0) ||
      !std::isfinite(opt.sigmaTranslation) || !std::isfinite(opt.sigmaRotation) || !std::isfinite(opt.sigmaSteering) ||
      opt.maxIterations < 1 || !(opt.relativeTolerance >= 0.0) || !(initial.wheelbase > 0.0)) {
    return Status::InvalidArgument;
  }
  if (segments.size() > kMaxCalibSegments) {
    return Status::CapacityExceeded;
  }
  if (segments.size() < 2) {
    return Status::NotEnoughData;
  }
  if (!std::isfinite(initial.wheelbase) || !std::isfinite(initial.driveScale) || !(initial.driveScale > 0.0) ||
      !std::isfinite(initial.steerOffsetForward) || !std::isfinite(initial.steerOffsetBackward) ||
      !initialLaser.isFinite()) {
    return Status::NonFiniteInput;
  }
  for (const CalibSegment& s : segments) {
    if (!std::isfinite(s.steering) || !s.egomotion.isFinite()) {
      return Status::NonFiniteInput;
    }
  }
  const double wheelbase = initial.wheelbase;
  Vector6 p;
  p << initial.driveScale, initial.steerOffsetForward,
      opt.sharedOffset ? initial.steerOffsetForward : initial.steerOffsetBackward, initialLaser.x, initialLaser.y,
      initialLaser.theta;
  Matrix6 h;
  Vector6 g;
  double current = linearise(segments, p, wheelbase, opt, h, g);
  result.initialCost = current;
  if (!std::isfinite(current)) {
    return Status::NonFiniteInput;
  }
  if (!(scaledMinEigenvalue(h) > 1e-12)) {
    result.finalCost = current;
    return Status::Unobservable;
  }
  double mu = 1e-6;
  int it = 0;
  for (; it < opt.maxIterations; ++it) {
    Matrix6 a = h;
    for (int i = 0; i < kCalibParamCount; ++i) {
      a(i, i) += mu * h(i, i);
    }
    const Vector6 delta = a.ldlt().solve(g);
    Vector6 next = p + delta;
    if (opt.sharedOffset) {
      next(kParamOffsetBackward) = next(kParamOffsetForward);
    }
    next(kParamLaserTheta) = normalizeAngle(next(kParamLaserTheta));
    const double trial = (delta.allFinite() && next(kParamDriveScale) > 0.0) ? cost(segments, next, wheelbase, opt)
                                                                             : std::numeric_limits<double>::infinity();
    if (trial < current) {
      const double decrease = (current - trial) / current;
      p = next;
      current = linearise(segments, p, wheelbase, opt, h, g);
      mu = std::fmax(mu * 0.1, 1e-12);
      if (decrease < opt.relativeTolerance) {
        ++it;
        break;
      }
    } else {
      mu *= 10.0;
      if (mu > 1e8) {
        ++it;
        break;  // no descent left: p is the minimum to working precision
      }
    }
  }
  result.iterations = it;
  result.finalCost = current;
  result.params = paramsOf(p, wheelbase);
  result.laserPose = laserOf(p);
  result.covariance = h.ldlt().solve(Matrix6::Identity());
  if (opt.sharedOffset) {
    result.covariance.row(kParamOffsetBackward) = result.covariance.row(kParamOffsetForward);
    result.covariance.col(kParamOffsetBackward) = result.covariance.col(kParamOffsetForward);
  }
  return Status::Ok;
}

}  // namespace agv
