#pragma once
/// @file dead_reckoning.hpp
/// Odometry of the logical point from encoder samples with a given set of vehicle parameters
/// (RK2 of the core's tricycle kinematics), the baseline the localizer improves on.

#include "agv/hal/encoder_sample.hpp"
#include "agv/kinematics/tricycle.hpp"

namespace agv::hil {

/// Integrates `EncoderSample`s with `tricycleRk2Step`: travel = tick difference * s_w, true
/// steering = measured + alpha_F (forward) or alpha_B (backward).
class DeadReckoning {
 public:
  explicit DeadReckoning(const TricycleParams& params) : params_(params) {}

  /// Starts at `pose` with `sample` as the reference reading.
  void reset(const Pose2d& pose, const hal::EncoderSample& sample) noexcept {
    pose_ = pose;
    prev_ = sample;
    travel_ = 0.0;
  }
  /// Integrates up to `sample` (which must be newer than the previous one).
  void update(const hal::EncoderSample& sample) noexcept {
    const double ds = static_cast<double>(sample.driveTicks - prev_.driveTicks) * params_.driveScale;
    const double offset = ds >= 0.0 ? params_.steerOffsetForward : params_.steerOffsetBackward;
    pose_ = tricycleRk2Step(pose_, ds, prev_.steeringAngle + offset, sample.steeringAngle + offset, params_.wheelbase);
    travel_ += ds;
    prev_ = sample;
  }
  const Pose2d& pose() const noexcept { return pose_; }
  /// Signed drive-wheel travel since reset [m].
  double travel() const noexcept { return travel_; }
  const TricycleParams& params() const noexcept { return params_; }

 private:
  TricycleParams params_;
  Pose2d pose_;
  hal::EncoderSample prev_;
  double travel_ = 0.0;
};

}  // namespace agv::hil
