#include "agv/localization/sweep_motion.hpp"

#include <algorithm>
#include <cmath>

#include "agv/core/angle.hpp"

namespace agv {

Status MotionHistory::add(Timestamp stamp, const Pose2d& pose) noexcept {
  if (!std::isfinite(pose.x) || !std::isfinite(pose.y) || !std::isfinite(pose.theta)) {
    return Status::NonFiniteInput;
  }
  if (!samples_.empty() && !(newest() < stamp)) {
    return Status::InvalidArgument;
  }
  (void)samples_.push(Sample{stamp, pose});  // when full, the oldest pose makes room
  while (samples_.size() > 2 && stamp - oldest() > maxAge_) {
    samples_.pop_front();
  }
  return Status::Ok;
}

Result<Pose2d> MotionHistory::at(Timestamp t) const noexcept {
  if (samples_.empty()) {
    return Status::NotEnoughData;
  }
  if (!(oldest() < t)) {
    return samples_.front().pose;
  }
  if (newest() < t) {
    return samples_.back().pose;
  }
  // The first pose at or after t (binary search: stamps strictly increase); oldest < t <= newest.
  std::size_t lo = 1;
  std::size_t hi = samples_.size() - 1;
  while (lo < hi) {
    const std::size_t mid = lo + (hi - lo) / 2;
    if (samples_[mid].stamp < t) {
      lo = mid + 1;
    } else {
      hi = mid;
    }
  }
  const Sample& a = samples_[lo - 1];
  const Sample& b = samples_[lo];
  const double f = (t - a.stamp).seconds() / (b.stamp - a.stamp).seconds();
  return Pose2d{a.pose.x + f * (b.pose.x - a.pose.x), a.pose.y + f * (b.pose.y - a.pose.y),
                normalizeAngle(a.pose.theta + f * angleDiff(b.pose.theta, a.pose.theta))};
}

SweepCompensation::SweepCompensation(const MotionHistory& history, const LaserScan& scan, const Pose2d& mount) noexcept
    : history_(history),
      mount_(mount),
      start_(scan.stamp),
      reference_(scan.stamp + scan.sweepDuration),
      sweepSeconds_(scan.sweepDuration.seconds()),
      angleMin_(static_cast<double>(scan.angleMin)),
      lastBeamAngle_(scan.size() > 1 ? static_cast<double>(scan.size() - 1) * static_cast<double>(scan.angleIncrement)
                                     : 0.0),
      lastBeam_(scan.size() > 1 ? static_cast<double>(scan.size() - 1) : 0.0) {
  const Result<Pose2d> ref = history.at(reference_);
  const Result<Pose2d> first = history.at(start_);
  if (ref.ok()) {
    referencePose_ = ref.value() * mount_;
    haveReference_ = true;
  }
  if (haveReference_ && first.ok() && sweepSeconds_ > 0.0 && std::isfinite(sweepSeconds_)) {
    const Pose2d d = between(first.value(), ref.value());
    moves_ = d.x != 0.0 || d.y != 0.0 || d.theta != 0.0;
  }
}

double SweepCompensation::fractionOf(double x, double y) const noexcept {
  if (!(lastBeamAngle_ > 0.0)) {
    return 1.0;
  }
  // Bearing from beam 0 in [0, 2 pi): a 360 deg scan starting anywhere is handled.
  double rel = std::fmod(std::atan2(y, x) - angleMin_, kTwoPi<double>);
  if (rel < 0.0) {
    rel += kTwoPi<double>;
  }
  return std::clamp(rel / lastBeamAngle_, 0.0, 1.0);
}

Pose2d::Vector2 SweepCompensation::atFraction(double f, double x, double y) const noexcept {
  if (!moves_) {
    return Pose2d::Vector2(x, y);
  }
  const double c = std::clamp(f, 0.0, 1.0);
  return atStamp(start_ + Duration::fromSeconds(c * sweepSeconds_), x, y);
}

Pose2d::Vector2 SweepCompensation::atStamp(Timestamp t, double x, double y) const noexcept {
  if (!haveReference_) {
    return Pose2d::Vector2(x, y);
  }
  const Pose2d rel = between(referencePose_, history_.at(t).value() * mount_);
  return rel.transformPoint(Pose2d::Vector2(x, y));
}

Pose2d::Vector2 SweepCompensation::atBeam(std::size_t beam, double x, double y) const noexcept {
  return atFraction(lastBeam_ > 0.0 ? static_cast<double>(beam) / lastBeam_ : 1.0, x, y);
}

}  // namespace agv
