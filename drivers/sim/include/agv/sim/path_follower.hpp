#pragma once
/// @file path_follower.hpp
/// Pure-pursuit path following for the simulated vehicle.

#include <cstddef>
#include <vector>

#include "agv/core/angle.hpp"
#include "agv/core/pose2.hpp"
#include "agv/hal/drive_command.hpp"
#include "agv/sim/world.hpp"

namespace agv::sim {

/// Pure-pursuit and speed-profile settings.
struct PathFollowerParams {
  double lookahead = 1.0;              ///< [m] distance of the pursued point ahead along the path
  double cruiseSpeed = 1.0;            ///< [m/s]
  double deceleration = 0.3;           ///< [m/s^2] planned braking to the end point
  double creepSpeed = 0.03;            ///< [m/s] minimum speed until the end point
  double stopTolerance = 0.002;        ///< [m] remaining path length at which the stop is commanded
  double wheelbase = 1.5;              ///< [m] L used to turn curvature into a steering angle
  double steerOffset = 0.0;            ///< [rad] offset the controller believes in (nominal)
  double maxSteering = deg2rad(80.0);  ///< [rad]
};

/// Follows a `Path` forward with the logical point: steering from pure pursuit
/// (curvature 2*y/d^2 to the point `lookahead` ahead, alpha = atan(curvature * L)), speed from a
/// braking profile that stops at the end point.
///
/// The pose it is given is the one it steers by: the true pose for ideal guidance, an estimate
/// to see the localizer's effect on path tracking.
class PathFollower {
 public:
  PathFollower(const Path& path, const PathFollowerParams& params);

  /// Command for the vehicle at `pose` (world frame). After `finished()` it commands a stop.
  hal::DriveCommand update(const Pose2d& pose) noexcept;
  /// True once the stop at the end point has been commanded.
  bool finished() const noexcept { return finished_; }
  /// Arc length of the projection of the last pose onto the path [m], and what remains of it.
  double progress() const noexcept { return progress_; }
  double remaining() const noexcept { return total_ - progress_; }

 private:
  Pose2d pointAt(double s) const noexcept;

  const Path* path_;
  PathFollowerParams params_;
  std::vector<double> cumulative_;  // arc length at each sample
  double total_ = 0.0;
  std::size_t index_ = 0;  // segment [index_, index_+1] the vehicle is on
  double progress_ = 0.0;
  bool finished_ = false;
};

}  // namespace agv::sim
