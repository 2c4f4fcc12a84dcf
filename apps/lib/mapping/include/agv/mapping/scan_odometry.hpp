#pragma once
/// @file scan_odometry.hpp
/// Laser odometry: the wheel odometry's steps corrected by scan matching, scan after scan. Each
/// scan is matched (`ScanMatcher`) against a `HallSurfaceMap` of the scans before it, from the
/// prior `pose (+) wheel step`, searched over the step's covariance; the matched pose is the next
/// pose, and a refused match keeps the prior and writes nothing into the map unless the scan saw
/// too little of it (new ground). What a vehicle with a laser knows of its own motion between two
/// places: the walls it just saw hold the heading and the distance where the wheels slip or turn
/// short. It drifts where nothing seen before is in view, and snaps to earlier surfaces when it
/// returns to them (no loop closure). Used as the pose graph's front end (`agvnav-loops`) and as
/// the replay's prediction input (`agvnav-replay --scan-odometry`; docs/localization.md,
/// "Laser odometry as the prediction"). Host code (heap).

#include <Eigen/Core>
#include <cstddef>
#include <memory>
#include <vector>

#include "agv/core/pose2.hpp"
#include "agv/localization/scan_matcher.hpp"
#include "agv/localization/surface_map.hpp"
#include "agv/scan/laser_scan.hpp"

namespace agv::mapping {

/// Standard deviations of one odometry step, as the search window of its match: a floor plus a
/// part per metre driven and (heading) per radian turned. The defaults are the pose graph's
/// odometry edges (`agvnav-loops --pose-graph`).
struct StepSigmas {
  double xy = 0.02;              ///< [m]
  double xyPerMetre = 0.10;      ///< [m/m]
  double theta = 0.01;           ///< [rad]
  double thetaPerMetre = 0.05;   ///< [rad/m]
  double thetaPerRadian = 0.05;  ///< [rad/rad]
  /// Position sigma [m] of `step` (per axis).
  double sigmaXY(const Pose2d& step) const noexcept;
  /// Heading sigma [rad] of `step`.
  double sigmaTheta(const Pose2d& step) const noexcept;
  /// Diagonal covariance of `step` (x, y, theta).
  Eigen::Matrix3d covariance(const Pose2d& step) const noexcept;
};

class ScanOdometry {
 public:
  /// `mount`: the laser in the poses' frame (identity when the poses are the laser's); `surface`:
  /// the map of the scans before.
  /// `retryWiden`: a scan whose match is refused (not for lack of points) is matched again over a
  /// window this many times as wide (the covariance times its square) before the track falls back
  /// on the wheel step; 0 or 1: no retry (the pose graph's front end).
  explicit ScanOdometry(const Pose2d& mount, const ScanMatchParams& match = ScanMatchParams{},
                        const SurfaceMapParams& surface = SurfaceMapParams{}, double retryWiden = 0.0);
  ScanOdometry(const ScanOdometry&) = delete;
  ScanOdometry& operator=(const ScanOdometry&) = delete;
  ~ScanOdometry();

  /// Starts the track at `pose` with `scan` as the map's first surfaces (drops any earlier map).
  void start(const LaserScan& scan, const Pose2d& pose);
  /// The next scan, `step` the wheel odometry since the previous one and `covariance` its
  /// uncertainty (the match's search window): returns the scan's pose. Before `start` it starts
  /// the track at the origin.
  const Pose2d& next(const LaserScan& scan, const Pose2d& step, const Eigen::Matrix3d& covariance);

  const Pose2d& pose() const noexcept { return pose_; }
  bool lastMatched() const noexcept { return lastMatched_; }
  std::size_t matched() const noexcept { return matched_; }  ///< scans matched since `start`
  std::size_t scans() const noexcept { return scans_; }      ///< scans since `start`, the first included
  std::size_t retried() const noexcept { return retried_; }  ///< scans matched only by the wider retry

 private:
  std::unique_ptr<HallSurfaceMap> map_;
  ScanMatcher matcher_;
  Pose2d mount_;
  double retryWiden_ = 0.0;
  std::size_t retried_ = 0;
  Pose2d pose_{};
  bool started_ = false;
  bool lastMatched_ = false;
  std::size_t matched_ = 0;
  std::size_t scans_ = 0;
};

/// The track of `ScanOdometry` over `scans`: pose i from the prior `track[i - 1] (+) steps[i]`
/// with covariance `covariances[i]`; `track` starts at `start` and holds one pose per scan (the
/// shortest of the three inputs); steps[0] and covariances[0] are not used. Returns the number of
/// scans matched.
std::size_t scanMatchedTrack(const std::vector<LaserScan>& scans, const Pose2d& mount, const Pose2d& start,
                             const std::vector<Pose2d>& steps, const std::vector<Eigen::Matrix3d>& covariances,
                             std::vector<Pose2d>& track);

}  // namespace agv::mapping
