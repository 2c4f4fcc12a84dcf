#pragma once
/// @file sweep_motion.hpp
/// Motion of the sensor during a laser sweep. A scanner takes its beams one after the other
/// (beam 0 at `LaserScan::stamp`, the last one `sweepDuration` later), so on a moving vehicle every
/// point of a sweep is seen from a different pose: at 1 m/s and a 40 ms sweep the ends of a sweep
/// are 4 cm apart, and a turn at 0.5 rad/s rotates the sensor by 1.1 deg (10 cm at 5 m).
/// `MotionHistory` keeps the vehicle's recent dead-reckoning poses; `SweepCompensation` expresses a
/// point seen at any instant of a sweep in the sensor frame at the end of the sweep, the frame the
/// observations of that sweep are then stamped with.
///
/// Dead reckoning is the right source: only the motion within a sweep (tens of milliseconds) is
/// used, where odometry drift is far below the range noise; a localizer correction in the middle of
/// a sweep must not bend it.

#include <cstddef>

#include "agv/core/capacities.hpp"
#include "agv/core/fixed_ring.hpp"
#include "agv/core/pose2.hpp"
#include "agv/core/result.hpp"
#include "agv/core/status.hpp"
#include "agv/core/timestamp.hpp"
#include "agv/scan/laser_scan.hpp"

namespace agv {

/// The vehicle's dead-reckoning poses of the recent past (fixed capacity, no heap): poses older
/// than `maxAge` before the newest one are dropped (the two newest are always kept), and when the
/// capacity is full the oldest pose makes room. At 100 Hz encoders the default 0.5 s keeps 51
/// poses; the capacity of 128 (`kMaxOdometryHistory`) still covers 128 ms at 1 kHz.
class MotionHistory {
 public:
  static constexpr std::size_t kCapacity = kMaxOdometryHistory;

  /// `maxAge`: how far back from the newest pose the history reaches (default 0.5 s).
  explicit MotionHistory(Duration maxAge = Duration::fromSeconds(0.5)) noexcept : maxAge_(maxAge) {}

  /// Appends the pose at `stamp`. Refused, history unchanged: `NonFiniteInput` for a non-finite
  /// pose, `InvalidArgument` for a stamp not after the newest one.
  Status add(Timestamp stamp, const Pose2d& pose) noexcept;

  /// Forgets every pose.
  void clear() noexcept { samples_.clear(); }

  /// Number of poses held.
  std::size_t size() const noexcept { return samples_.size(); }
  /// True when no pose is held.
  bool empty() const noexcept { return samples_.empty(); }
  /// Oldest stamp held; precondition `!empty()` (checked in debug builds).
  Timestamp oldest() const noexcept { return samples_.front().stamp; }
  /// Newest stamp held; precondition `!empty()` (checked in debug builds).
  Timestamp newest() const noexcept { return samples_.back().stamp; }

  /// The pose at `t`: linear between the two stored poses around it (position, and heading along
  /// the shorter arc); the oldest / newest pose for a `t` outside the stored interval.
  /// `NotEnoughData` when the history is empty.
  Result<Pose2d> at(Timestamp t) const noexcept;

 private:
  struct Sample {
    Timestamp stamp;
    Pose2d pose;
  };

  Duration maxAge_;
  FixedRing<Sample, kCapacity> samples_;  ///< oldest first; stamps strictly increase
};

/// Moves the points of one sweep into the sensor frame at the end of the sweep
/// (`referenceStamp()`), with the motion `history` recorded. `mount` is the sensor's pose in the
/// frame whose poses the history holds (the vehicle frame: `LaserModel::mounting`). With an empty
/// history, or one that does not move during the sweep, the points are left as they are.
class SweepCompensation {
 public:
  /// For the sweep of `scan`: beam 0 at `scan.stamp`, beam n-1 at `scan.stamp +
  /// scan.sweepDuration`, the beams in between evenly spaced in time. `history` is kept by
  /// reference and must outlive this object and not change while it is used (one sweep); `scan`
  /// is read here only.
  SweepCompensation(const MotionHistory& history, const LaserScan& scan, const Pose2d& mount) noexcept;

  /// End of the sweep: the stamp of the compensated observations.
  Timestamp referenceStamp() const noexcept { return reference_; }

  /// Fraction of the sweep [0, 1] at which the beam towards the sensor-frame point (x, y) was taken
  /// (its bearing from angle_min, turning the scan's way, over the angle of the last beam;
  /// clamped).
  double fractionOf(double x, double y) const noexcept;

  /// The point (x, y) seen at sweep fraction `f` (clamped to [0, 1]), in the sensor frame at the
  /// end of the sweep.
  Pose2d::Vector2 atFraction(double f, double x, double y) const noexcept;

  /// The point seen by beam `beam` (e.g. a keypoint's beam index).
  Pose2d::Vector2 atBeam(std::size_t beam, double x, double y) const noexcept;

  /// The point seen along its own bearing (e.g. a reflector the sensor reports as a point).
  Pose2d::Vector2 atBearing(double x, double y) const noexcept { return atFraction(fractionOf(x, y), x, y); }

  /// The point (x, y) seen at time `t`, in the sensor frame at `referenceStamp()`: for sensors
  /// that stamp each measurement themselves (a NAV350 stamps every reflector). This needs no
  /// sweep duration: a scan of zero duration (a NAV350 reply, stamped at reception) has its
  /// reference at `LaserScan::stamp`. `t` may lie outside the history's interval (its end poses
  /// hold there). With an empty history the point is left as it is.
  Pose2d::Vector2 atStamp(Timestamp t, double x, double y) const noexcept;

 private:
  const MotionHistory& history_;
  Pose2d mount_;
  Timestamp start_;
  Timestamp reference_;
  double sweepSeconds_ = 0.0;
  double angleMin_ = 0.0;
  double lastBeamAngle_ = 0.0;  ///< angle of beam n-1 from beam 0 [rad]
  double lastBeam_ = 0.0;       ///< n - 1
  Pose2d referencePose_;        ///< sensor pose at the end of the sweep (history frame)
  bool haveReference_ = false;  ///< referencePose_ is known (the history is not empty)
  bool moves_ = false;          ///< ... and the sensor moved between the first beam and the end
};

}  // namespace agv
