#include "agv/localization/pose_ekf.hpp"

#include <cmath>
#include <limits>

#include "spd3.hpp"

namespace agv {

namespace {
bool validCovariance(const Eigen::Matrix3d& P) noexcept {
  if (!P.allFinite()) {
    return false;
  }
  for (int i = 0; i < 3; ++i) {
    if (P(i, i) < 0.0) {
      return false;
    }
    for (int j = 0; j < i; ++j) {
      if (std::fabs(P(i, j) - P(j, i)) > 1e-9 * (std::fabs(P(i, j)) + std::fabs(P(j, i))) + 1e-300) {
        return false;
      }
    }
  }
  return true;
}
}  // namespace

Eigen::Matrix2d polarToCartesianCovariance(double x, double y, double rangeSigma, double bearingSigma) noexcept {
  const double r = std::hypot(x, y);
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  if (r <= 0.0) {
    cov(0, 0) = rangeSigma * rangeSigma;
    cov(1, 1) = rangeSigma * rangeSigma;
    return cov;
  }
  const double c = x / r;
  const double s = y / r;
  Eigen::Matrix2d J;
  J << c, -r * s, s, r * c;
  Eigen::Matrix2d D = Eigen::Matrix2d::Zero();
  D(0, 0) = rangeSigma * rangeSigma;
  D(1, 1) = bearingSigma * bearingSigma;
  cov = J * D * J.transpose();
  return 0.5 * (cov + cov.transpose());
}

Status PoseEkf::reset(const Pose2d& pose, const Eigen::Matrix3d& covariance) noexcept {
  if (!pose.isFinite() || !validCovariance(covariance)) {
    return Status::InvalidArgument;
  }
  pose_ = pose.normalized();
  P_ = 0.5 * (covariance + covariance.transpose());
  condition(P_);
  return Status::Ok;
}

Status PoseEkf::predict(const OdometryIncrement& inc) noexcept {
  if (!inc.isValid()) {
    return Status::NonFiniteInput;
  }
  const double c = std::cos(pose_.theta);
  const double s = std::sin(pose_.theta);
  const Pose2d& d = inc.delta;
  Eigen::Matrix3d F = Eigen::Matrix3d::Identity();
  F(0, 2) = -s * d.x - c * d.y;
  F(1, 2) = c * d.x - s * d.y;
  Eigen::Matrix3d G = Eigen::Matrix3d::Identity();
  G(0, 0) = c;
  G(0, 1) = -s;
  G(1, 0) = s;
  G(1, 1) = c;
  Eigen::Matrix3d P = F * P_ * F.transpose() + G * inc.covariance * G.transpose();
  const Pose2d x = pose_.compose(d);
  if (!x.isFinite() || !P.allFinite()) {
    return Status::NonFiniteInput;
  }
  P = 0.5 * (P + P.transpose()).eval();
  condition(P);
  pose_ = x;
  P_ = P;
  return Status::Ok;
}

PointInnovation PoseEkf::innovation(const Eigen::Vector2d& zLaser, const Eigen::Vector2d& landmarkWorld,
                                    const Eigen::Matrix2d& R, const Pose2d& laserPose) const noexcept {
  PointInnovation out;
  const double c = std::cos(pose_.theta);
  const double s = std::sin(pose_.theta);
  const double dx = landmarkWorld.x() - pose_.x;
  const double dy = landmarkWorld.y() - pose_.y;
  // landmark in the logical-point frame
  const double px = c * dx + s * dy;
  const double py = -s * dx + c * dy;
  const double cl = std::cos(laserPose.theta);
  const double sl = std::sin(laserPose.theta);
  const double qx = px - laserPose.x;
  const double qy = py - laserPose.y;
  const Eigen::Vector2d h(cl * qx + sl * qy, -sl * qx + cl * qy);
  // d(p)/d(x, y, theta)
  Eigen::Matrix<double, 2, 3> Hp;
  Hp << -c, -s, py, s, -c, -px;
  Eigen::Matrix2d Rl;
  Rl << cl, sl, -sl, cl;  // R(l_theta)^T
  out.H = Rl * Hp;
  out.R = R;
  out.innovation = zLaser - h;
  out.S = out.H * P_ * out.H.transpose() + R;
  out.S = 0.5 * (out.S + out.S.transpose()).eval();
  const double det = out.S(0, 0) * out.S(1, 1) - out.S(0, 1) * out.S(1, 0);
  if (!(det > 0.0) || !(out.S(0, 0) > 0.0) || !std::isfinite(det) || !out.innovation.allFinite()) {
    out.valid = false;
    out.mahalanobis2 = 0.0;
    return out;
  }
  Eigen::Matrix2d Sinv;
  Sinv << out.S(1, 1), -out.S(0, 1), -out.S(1, 0), out.S(0, 0);
  Sinv /= det;
  out.mahalanobis2 = out.innovation.dot(Sinv * out.innovation);
  out.valid = std::isfinite(out.mahalanobis2);
  return out;
}

Status PoseEkf::update(const PointInnovation& in, double gate) noexcept {
  if (!in.valid) {
    return Status::Rejected;
  }
  if (!(in.mahalanobis2 <= gate)) {
    return Status::Rejected;
  }
  const double det = in.S(0, 0) * in.S(1, 1) - in.S(0, 1) * in.S(1, 0);
  Eigen::Matrix2d Sinv;
  Sinv << in.S(1, 1), -in.S(0, 1), -in.S(1, 0), in.S(0, 0);
  Sinv /= det;
  const Eigen::Matrix<double, 3, 2> K = P_ * in.H.transpose() * Sinv;
  const Eigen::Vector3d dx = K * in.innovation;
  const Eigen::Matrix3d IKH = Eigen::Matrix3d::Identity() - K * in.H;
  return commit(dx, IKH * P_ * IKH.transpose() + K * in.R * K.transpose());
}

bool PoseEkf::poseInnovation(const Pose2d& z, const Eigen::Matrix3d& R, Eigen::Vector3d& nu,
                             Eigen::Matrix3d& Sinv) const noexcept {
  if (!z.isFinite() || !R.allFinite()) {
    return false;
  }
  nu = Eigen::Vector3d(z.x - pose_.x, z.y - pose_.y, normalizeAngle(z.theta - pose_.theta));
  return detail::invertSpd3(P_ + R, 1e-15, Sinv);
}

double PoseEkf::poseMahalanobis2(const Pose2d& z, const Eigen::Matrix3d& R) const noexcept {
  Eigen::Vector3d nu;
  Eigen::Matrix3d Sinv;
  return poseInnovation(z, R, nu, Sinv) ? nu.dot(Sinv * nu) : std::numeric_limits<double>::infinity();
}

Status PoseEkf::updatePose(const Pose2d& z, const Eigen::Matrix3d& R, double gate) noexcept {
  if (!z.isFinite() || !R.allFinite()) {
    return Status::NonFiniteInput;
  }
  Eigen::Vector3d nu;
  Eigen::Matrix3d Sinv;
  if (!poseInnovation(z, R, nu, Sinv) || !(nu.dot(Sinv * nu) <= gate)) {
    return Status::Rejected;
  }
  const Eigen::Matrix3d K = P_ * Sinv;
  const Eigen::Vector3d dx = K * nu;
  const Eigen::Matrix3d IK = Eigen::Matrix3d::Identity() - K;
  return commit(dx, IK * P_ * IK.transpose() + K * R * K.transpose());
}

Status PoseEkf::commit(const Eigen::Vector3d& dx, Eigen::Matrix3d P) noexcept {
  P = 0.5 * (P + P.transpose()).eval();
  condition(P);
  const Pose2d x{pose_.x + dx(0), pose_.y + dx(1), normalizeAngle(pose_.theta + dx(2))};
  if (!x.isFinite() || !P.allFinite()) {
    return Status::NonFiniteInput;
  }
  pose_ = x;
  P_ = P;
  return Status::Ok;
}

void PoseEkf::condition(Eigen::Matrix3d& P) const noexcept {
  const double floors[3] = {params_.varianceFloorXY, params_.varianceFloorXY, params_.varianceFloorTheta};
  for (int i = 0; i < 3; ++i) {
    if (P(i, i) < floors[i]) {
      P(i, i) = floors[i];
    }
  }
  // Keep |correlation| < 1 so that flooring never makes P indefinite.
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < i; ++j) {
      const double lim = 0.999999 * std::sqrt(P(i, i) * P(j, j));
      double v = P(i, j);
      if (v > lim) {
        v = lim;
      } else if (v < -lim) {
        v = -lim;
      }
      P(i, j) = v;
      P(j, i) = v;
    }
  }
}

}  // namespace agv
