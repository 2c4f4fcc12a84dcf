#include "agv/sim/path_follower.hpp"

#include <algorithm>
#include <cmath>

namespace agv::sim {

PathFollower::PathFollower(const Path& path, const PathFollowerParams& params) : path_(&path), params_(params) {
  cumulative_.resize(path.points.size(), 0.0);
  for (std::size_t i = 1; i < path.points.size(); ++i) {
    const Pose2d& a = path.points[i - 1];
    const Pose2d& b = path.points[i];
    cumulative_[i] = cumulative_[i - 1] + std::hypot(b.x - a.x, b.y - a.y);
  }
  total_ = cumulative_.empty() ? 0.0 : cumulative_.back();
  finished_ = path.points.size() < 2;
}

Pose2d PathFollower::pointAt(double s) const noexcept {
  const std::vector<Pose2d>& p = path_->points;
  if (s >= total_) {  // beyond the end: continue straight along the final heading
    const Pose2d& e = p.back();
    const double d = s - total_;
    return Pose2d{e.x + d * std::cos(e.theta), e.y + d * std::sin(e.theta), e.theta};
  }
  const auto it = std::upper_bound(cumulative_.begin(), cumulative_.end(), s);
  const std::size_t i = static_cast<std::size_t>(std::max<std::ptrdiff_t>(1, it - cumulative_.begin())) - 1;
  const double seg = cumulative_[i + 1] - cumulative_[i];
  const double f = seg > 0.0 ? (s - cumulative_[i]) / seg : 0.0;
  return Pose2d{p[i].x + f * (p[i + 1].x - p[i].x), p[i].y + f * (p[i + 1].y - p[i].y), p[i].theta};
}

hal::DriveCommand PathFollower::update(const Pose2d& pose) noexcept {
  hal::DriveCommand cmd;
  if (finished_) {
    return cmd;
  }
  // Progress: project onto the segments near the last one (bounded forward window).
  const std::vector<Pose2d>& p = path_->points;
  const std::size_t last = p.size() - 2;
  const std::size_t hiIdx = std::min(last, index_ + 50);
  double bestD2 = 1e300;
  for (std::size_t i = index_; i <= hiIdx; ++i) {
    const double ax = p[i].x;
    const double ay = p[i].y;
    const double dx = p[i + 1].x - ax;
    const double dy = p[i + 1].y - ay;
    const double len2 = dx * dx + dy * dy;
    double f = len2 > 0.0 ? ((pose.x - ax) * dx + (pose.y - ay) * dy) / len2 : 0.0;
    // The last segment extends beyond the end so that an overshoot shows as negative remaining.
    f = i == last ? std::max(0.0, f) : std::clamp(f, 0.0, 1.0);
    const double ex = ax + f * dx - pose.x;
    const double ey = ay + f * dy - pose.y;
    const double d2 = ex * ex + ey * ey;
    if (d2 < bestD2) {
      bestD2 = d2;
      index_ = i;
      progress_ = cumulative_[i] + f * std::sqrt(len2);
    }
  }
  const double rem = total_ - progress_;
  if (rem <= params_.stopTolerance) {
    finished_ = true;
    return cmd;
  }
  const Pose2d target = pointAt(progress_ + params_.lookahead);
  const Pose2d::Vector2 local = pose.inverseTransformPoint(Pose2d::Vector2(target.x, target.y));
  const double d2 = local.squaredNorm();
  const double curvature = d2 > 1e-9 ? 2.0 * local.y() / d2 : 0.0;
  const double alpha = std::atan(curvature * params_.wheelbase);
  cmd.steeringAngle = std::clamp(alpha - params_.steerOffset, -params_.maxSteering, params_.maxSteering);
  const double brake = std::sqrt(2.0 * params_.deceleration * rem);
  cmd.speed = std::max(params_.creepSpeed, std::min(params_.cruiseSpeed, brake));
  return cmd;
}

}  // namespace agv::sim
