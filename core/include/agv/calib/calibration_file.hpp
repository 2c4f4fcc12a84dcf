#pragma once
/// @file calibration_file.hpp
/// Text format of a vehicle's calibration (what `agvnav-calibrate` writes and the localizer
/// loads), parsed from and written to caller-owned buffers (file access stays outside the core).
///
/// Format (`agvnav-calibration` version 2), one `key value [sigma]` record per line, fields
/// separated by spaces or tabs, LF or CRLF line ends, `#` starts a comment that runs to the end of
/// the line, blank lines ignored. Values in SI units (metres, radians); `sigma` is the optional
/// standard deviation of the value (same unit, >= 0; 0 or absent = not known):
///
///     agvnav-calibration 2
///     wheelbase                1.500000                  # L [m], from the drawing (not solved)
///     drive_scale              0.000500012  0.00000003   # s_w [m/tick]
///     steer_offset_forward     0.017455     0.00008      # alpha_F [rad] (+1.000 deg)
///     steer_offset_backward   -0.008727     0.00011      # alpha_B [rad] (-0.500 deg)
///     laser_x                  1.600100     0.0007       # laser pose in the vehicle frame [m]
///     laser_y                  0.399800     0.0009       # [m]
///     laser_theta              0.087266     0.0003       # [rad] (+5.000 deg)
///     end 7
///
/// - The first record is the header `agvnav-calibration 2`; every key above must appear once
///   (keys may come in any order), no other key is accepted.
/// - The last record is `end <count>`, count = the number of key records (7). Nothing but blank
///   lines and comments may follow it. A file that ends before it is refused as `Truncated`
///   (a cut inside the last value would otherwise load a wrong number), naming the line where
///   the text ends; a count that differs from the key lines read is refused (`Malformed`, or
///   `Truncated` when the `end` line itself is cut). The final LF may be missing.
/// - Ranges: 0.1 <= wheelbase <= 20 m; 0 < drive_scale <= 0.1 m/tick; |steer offsets| <= 0.5 rad;
///   |laser_x|, |laser_y| <= 50 m; |laser_theta| <= 2 pi (normalised to (-pi, pi] on reading). A
///   sigma is at most the width of its value's range (0.1 m/tick, 1 rad, 100 m, 4 pi rad).
/// - Numbers are decimal: optional sign, digits, optional fraction, optional exponent (`5e-4`).
///
/// Version 1 (header `agvnav-calibration 1`, no `end` record) is still read:
/// `CalibrationFileReport::version` tells the caller, who should warn that a cut inside its last
/// value cannot be detected (docs/calibration.md, "Calibration file"). `formatCalibrationFile`
/// writes version 2 only. A larger version is refused as `Unsupported`.

#include <cstddef>
#include <cstdint>

#include "agv/core/pose2.hpp"
#include "agv/core/result.hpp"
#include "agv/core/span.hpp"
#include "agv/core/status.hpp"
#include "agv/kinematics/tricycle.hpp"

namespace agv {

/// Standard deviations of the calibrated values; 0 = not known.
struct CalibrationSigmas {
  double driveScale = 0.0;           ///< [m/tick]
  double steerOffsetForward = 0.0;   ///< [rad]
  double steerOffsetBackward = 0.0;  ///< [rad]
  double laserX = 0.0;               ///< [m]
  double laserY = 0.0;               ///< [m]
  double laserTheta = 0.0;           ///< [rad]
};

/// A vehicle's calibration: odometry parameters and the laser's mounting pose.
struct VehicleCalibration {
  TricycleParams params{};     ///< L, s_w, alpha_F, alpha_B
  Pose2d laserPose{};          ///< laser frame in the vehicle (logical point) frame
  CalibrationSigmas sigmas{};  ///< uncertainty of the values (0 = not known)
};

/// The format version `formatCalibrationFile` writes (and the largest `parseCalibrationFile` reads).
inline constexpr std::uint32_t kCalibrationFileFormatVersion = 2;

/// Outcome details of `parseCalibrationFile`.
struct CalibrationFileReport {
  std::size_t errorLine = 0;     ///< 1-based line of the first error (0 when none or not line-bound)
  const char* key = nullptr;     ///< key concerned by the error (missing, duplicate, out of range), if any
  std::uint32_t version = 0;     ///< format version of the header (0: none read)
  std::size_t records = 0;       ///< key records read (up to the error)
  const char* detail = nullptr;  ///< what is wrong, when more than the status says (static text)
};

/// Parses `text` into `out`. All or nothing: `out` is only written on success. Errors:
/// `EmptyInput` (no header), `Malformed` (bad header, unknown key, bad number, wrong field count,
/// `end` count, a record after `end`; `report->errorLine`), `Truncated` (version 2 without its
/// `end` line, or cut inside its last line), `InvalidArgument` (a key given twice; `report->key`),
/// `OutOfRange` (a value or sigma outside its range; `report->key`), `NotFound` (a key missing;
/// `report->key`), `Unsupported` (a newer format version).
Status parseCalibrationFile(Span<const char> text, VehicleCalibration& out,
                            CalibrationFileReport* report = nullptr) noexcept;

/// Writes `calibration` in the format above (version 2, with its `end` line) into `out`, with comments giving the
/// angles in degrees. Values with 9 significant decimals (s_w with 12). Returns the number of characters written (no
/// terminating NUL); `Truncated` when `out` is too small, `OutOfRange` when a value is outside the range the parser
/// accepts (the file would not load).
Result<std::size_t> formatCalibrationFile(const VehicleCalibration& calibration, Span<char> out) noexcept;

}  // namespace agv
