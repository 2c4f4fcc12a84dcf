#include "agv/mapping/scan_odometry.hpp"

#include <algorithm>
#include <cmath>

#include "agv/core/angle.hpp"

namespace agv::mapping {

double StepSigmas::sigmaXY(const Pose2d& step) const noexcept {
  return xy + xyPerMetre * std::hypot(step.x, step.y);
}

double StepSigmas::sigmaTheta(const Pose2d& step) const noexcept {
  return theta + thetaPerMetre * std::hypot(step.x, step.y) + thetaPerRadian * std::fabs(normalizeAngle(step.theta));
}

Eigen::Matrix3d StepSigmas::covariance(const Pose2d& step) const noexcept {
  const double s = sigmaXY(step);
  const double t = sigmaTheta(step);
  Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
  c.diagonal() << s * s, s * s, t * t;
  return c;
}

ScanOdometry::ScanOdometry(const Pose2d& mount, const ScanMatchParams& match, const SurfaceMapParams& surface,
                           double retryWiden)
    : map_(std::make_unique<HallSurfaceMap>(surface)),
      matcher_(match),
      mount_(mount),
      retryWiden_(retryWiden > 1.0 ? retryWiden : 0.0) {}

ScanOdometry::~ScanOdometry() = default;

void ScanOdometry::start(const LaserScan& scan, const Pose2d& pose) {
  map_->clear();
  pose_ = pose;
  started_ = true;
  lastMatched_ = false;
  matched_ = 0;
  retried_ = 0;
  scans_ = 1;
  (void)map_->insert(scan, pose_.compose(mount_));
}

const Pose2d& ScanOdometry::next(const LaserScan& scan, const Pose2d& step, const Eigen::Matrix3d& covariance) {
  if (!started_) {
    start(scan, Pose2d{});
    return pose_;
  }
  ++scans_;
  const Pose2d prior = pose_.compose(step);
  const bool built = map_->field().built();
  ScanMatchResult r = built ? matcher_.match(scan, mount_, prior, covariance, map_->field()) : ScanMatchResult{};
  if (built && retryWiden_ > 0.0 && r.status != Status::Ok && r.status != Status::NotEnoughData) {
    const ScanMatchResult wide =
        matcher_.match(scan, mount_, prior, (retryWiden_ * retryWiden_) * covariance, map_->field());
    if (wide.status == Status::Ok) {
      r = wide;
      ++retried_;
    }
  }
  lastMatched_ = built && r.status == Status::Ok;
  pose_ = lastMatched_ ? r.pose : prior;
  matched_ += lastMatched_ ? 1U : 0U;
  if (lastMatched_ || r.status == Status::NotEnoughData || !built) {
    (void)map_->insert(scan, pose_.compose(mount_));  // a refused match writes nothing but new ground
  }
  return pose_;
}

std::size_t scanMatchedTrack(const std::vector<LaserScan>& scans, const Pose2d& mount, const Pose2d& start,
                             const std::vector<Pose2d>& steps, const std::vector<Eigen::Matrix3d>& covariances,
                             std::vector<Pose2d>& track) {
  const std::size_t n = std::min(scans.size(), std::min(steps.size(), covariances.size()));
  track.assign(n, start);
  if (n == 0) {
    return 0;
  }
  ScanOdometry odometry(mount);
  odometry.start(scans.front(), start);
  for (std::size_t i = 1; i < n; ++i) {
    track[i] = odometry.next(scans[i], steps[i], covariances[i]);
  }
  return odometry.matched();
}

}  // namespace agv::mapping
