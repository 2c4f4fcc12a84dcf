#pragma once
/// @file trajectory_error.hpp
/// Error of an estimated trajectory against the ground truth of a recording: absolute (ATE) and
/// relative (per segment of path) position and heading errors. Used by agvnav-replay and
/// agvnav-loops. Host tool code (heap); not core.

#include <cstddef>
#include <vector>

#include "agv/core/pose2.hpp"

namespace agv {
namespace datasets {

/// Mean / median / RMS / max of a set of errors.
struct ErrorStats {
  std::size_t count = 0;
  double mean = 0.0;
  double median = 0.0;
  double rms = 0.0;
  double max = 0.0;
};

/// Relative pose error over segments of `segmentLength` of ground-truth path, starting at every scan.
struct RelativeError {
  ErrorStats position;  ///< [m] per segment
  ErrorStats heading;   ///< [rad] per segment
};

/// Absolute trajectory error (estimate and ground truth start at the same pose).
struct AbsoluteError {
  ErrorStats position;  ///< [m]
  ErrorStats heading;   ///< [rad]
};

/// Absolute error of the scans flagged in `select` (no alignment: both in the map's frame).
AbsoluteError absoluteErrorOf(const std::vector<Pose2d>& truth, const std::vector<Pose2d>& estimate,
                              const std::vector<bool>& select);

/// Relative error per segment of ground-truth path length `length`.
RelativeError relativeError(const std::vector<Pose2d>& truth, const std::vector<Pose2d>& estimate, double length);
/// Absolute error after aligning the first poses (estimate moved rigidly onto truth[0]).
AbsoluteError absoluteError(const std::vector<Pose2d>& truth, const std::vector<Pose2d>& estimate);

/// The statistics of `values` (taken by value: the median reorders them); all zero when empty.
ErrorStats errorStats(std::vector<double> values);

}  // namespace datasets
}  // namespace agv
