#pragma once
/// @file carmen_log.hpp
/// Reader of CARMEN / FLIRTLib text logs (plain or gzip): laser scans with their poses, odometry
/// and the pose-graph vertices used as ground truth. Host tool code (heap, files); not core.

#include <cstddef>
#include <string>
#include <vector>

#include "agv/core/pose2.hpp"
#include "agv/scan/laser_scan.hpp"

namespace agv {
namespace datasets {

/// One laser line (`ROBOTLASER1` or `FLASER`).
struct LogScan {
  std::size_t line = 0;         ///< 1-based line number in the file
  double timestamp = 0.0;       ///< [s] logger timestamp of the line
  float angleMin = 0.0F;        ///< [rad] angle of the first beam
  float angleIncrement = 0.0F;  ///< [rad]
  float maxRange = 0.0F;        ///< [m] readings at or above are invalid ("no return")
  std::vector<float> ranges;    ///< [m]
  Pose2d laserPose;             ///< laser pose written in the line (odometry or corrected frame)
  Pose2d robotPose;             ///< robot pose written in the line
  /// Ground-truth pose of the *laser* in the world: the VERTEX2 pose given just before the scan
  /// (FLIRTLib logs) composed with the laser offset of the line, or the corrected pose of a FLASER
  /// line (gmapping-corrected logs).
  Pose2d groundTruth;
  bool hasGroundTruth = false;
  long vertexId = -1;  ///< id of the VERTEX2 line that gave the ground truth (-1: none)

  /// Fills a core `LaserScan` (ranges beyond its capacity are dropped: returns false then).
  bool toLaserScan(LaserScan& scan) const;
};

/// One `ODOM` line.
struct LogOdometry {
  std::size_t line = 0;
  double timestamp = 0.0;  ///< [s]
  Pose2d pose;
  double tv = 0.0;  ///< [m/s]
  double rv = 0.0;  ///< [rad/s]
};

/// One `VERTEX2 id x y theta` line.
struct LogVertex {
  std::size_t line = 0;
  long id = 0;
  Pose2d pose;
};

/// A line that could not be used, with the reason.
struct LogIssue {
  std::size_t line = 0;
  std::string message;
};

/// Reader options.
struct CarmenReadOptions {
  /// Readings at or above this are "no return" [m]; the README of the shared logs says 50 m.
  float maxValidRange = 50.0F;
};

/// The content of one log.
struct CarmenLog {
  std::vector<LogScan> scans;
  std::vector<LogOdometry> odometry;
  std::vector<LogVertex> vertices;
  std::vector<LogIssue> issues;  ///< malformed lines (skipped), with their line number
  std::size_t lines = 0;         ///< lines read
  std::size_t ignoredLines = 0;  ///< comments, PARAM, EDGE2, NEFF and other records not used
  /// `PARAM robot_frontlaser_offset <m>`: the front laser's position ahead of the robot centre
  /// (0 when `frontLaserOffsetLine` is 0: the log does not say).
  double frontLaserOffset = 0.0;
  std::size_t frontLaserOffsetLine = 0;  ///< the line it was read from (0: none)
};

/// Parses log text (one record per line). Malformed lines are reported in `issues` and skipped.
CarmenLog parseCarmenLog(const std::string& text, const CarmenReadOptions& options = CarmenReadOptions{});

/// Reads a log file, gzip-compressed or plain (zlib reads both). Returns false and sets `error`
/// when the file cannot be opened or read; malformed lines are not errors (see `issues`).
bool readCarmenLog(const std::string& path, CarmenLog& log, std::string& error,
                   const CarmenReadOptions& options = CarmenReadOptions{});

/// Longest plausible step of the robot between two consecutive scans of a log, unless the time
/// between them allows more at `kMaxPlausibleSpeed` [m]: five times the longest step of the shared
/// corrected logs (1.8 m, mit-csail).
inline constexpr double kMaxPlausibleStep = 10.0;
/// [m/s] faster than any indoor robot or forklift.
inline constexpr double kMaxPlausibleSpeed = 20.0;

/// Whether `log` can be replayed or mapped as odometry + corrected poses: a gmapping-corrected CARMEN log (FLASER lines
/// with corrected poses, ODOM lines with the raw odometry), not a FLIRTLib log (ROBOTLASER1 + VERTEX2), with no robot
/// step beyond physics (`kMaxPlausibleStep` and `kMaxPlausibleSpeed`) between consecutive scans, in the corrected poses
/// or the raw odometry. False with `error` naming the line.
bool checkCorrectedLog(const CarmenLog& log, std::string& error);

/// Rebuilds the raw odometry increments of a corrected log: for scan i, inverse(corrected_{i-1})
/// composed with the last timestamped ODOM pose between FLASER_{i-1} and FLASER_i (zero if none).
/// `increments[0]` is zero. Returns the number of zero increments.
std::size_t odometryIncrements(const CarmenLog& log, std::size_t scans, std::vector<Pose2d>& increments);

}  // namespace datasets
}  // namespace agv
