#pragma once
/// @file velodyne_calibration.hpp
/// Readers of Velodyne per-laser calibration files into one `agv::LaserIntrinsics` table (host
/// code; docs/velodyne.md):
/// - the factory `db.xml` (boost serialization; `<distLSB_>` and per `<px>`: `id_`,
///   `rotCorrection_`, `vertCorrection_` [deg], `distCorrection_`, `vertOffsetCorrection_`,
///   `horizOffsetCorrection_` [cm]) — converted to m and rad here;
/// - the ROS YAML of velodyne_pointcloud (`lasers:` entries in block or flow style with
///   `laser_id`, `rot_correction`, `vert_correction` [rad], `dist_correction`,
///   `vert_offset_correction`, `horiz_offset_correction` [m]; optional `distance_resolution`,
///   `num_lasers`). Two-point and intensity fields are read past (not part of the thesis model).
/// Every laser id 0..n-1 must appear exactly once; numbers through `agv::report`'s parser.

#include <string>
#include <string_view>

#include "agv/lidar3d/laser_intrinsics.hpp"

namespace agv::datasets {

/// Parses a db.xml text. False with `error` naming the laser / field and the reason.
bool parseVelodyneDbXml(std::string_view text, LaserIntrinsics& out, std::string& error);
/// Parses a velodyne_pointcloud YAML text. False with `error`.
bool parseVelodyneYaml(std::string_view text, LaserIntrinsics& out, std::string& error);
/// Reads `path` and parses it as db.xml when it starts with `<` (after blanks), else as YAML.
bool readVelodyneCalibration(const std::string& path, LaserIntrinsics& out, std::string& error);

/// The table as velodyne_pointcloud YAML (`distance_resolution`, `num_lasers`, `lasers:` in block
/// style with the five thesis fields per laser, `two_pt_correction_available: false`; numbers
/// with 17 significant digits, so `parseVelodyneYaml` reads back the same doubles). `comment`
/// lines are written first as `# ...`.
std::string formatVelodyneYaml(const LaserIntrinsics& table, const std::string& comment = std::string());

}  // namespace agv::datasets
