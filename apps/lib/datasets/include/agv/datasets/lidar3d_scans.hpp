#pragma once
/// @file lidar3d_scans.hpp
/// Readers of the multi-beam lidar recordings in ../shared/data/lidar3d (host tool code: heap,
/// files; not core): KITTI velodyne `.bin` revolutions (rings recovered from the azimuth
/// wrap-arounds), NCLT `velodyne_sync` `.bin` revolutions (laser ids mapped to elevation order),
/// and KITTI ground-truth poses.

#include <Eigen/Core>
#include <cstddef>
#include <string>
#include <vector>

#include "agv/lidar3d/range_image.hpp"

namespace agv {
namespace datasets {

/// One revolution as ring-ordered Cartesian points (sensor frame, z up) and the rows it spans.
struct Revolution {
  std::vector<RingPoint> points;
  std::size_t rings = 0;  ///< 1 + the largest ring
};

/// Reads a KITTI velodyne file (float32 x, y, z, reflectance per point). The points are stored ring
/// by ring, top to bottom, each ring starting at the front and turning counter-clockwise; the ring
/// index grows when the azimuth atan2(-y, -x) jumps down by more than pi (and falls back when it
/// jumps up), as in the data README. False with `error` when the file cannot be read or its size is
/// not a multiple of 16 bytes.
bool readKittiVelodyne(const std::string& path, Revolution& out, std::string& error);

/// Reads an NCLT velodyne_sync file (uint16 x, y, z as v * 0.005 - 100 m, uint8 intensity, uint8
/// laser id). The rows are the laser ids ranked by their mean elevation in this file (HDL-32E ids
/// are interleaved in elevation). The coordinates are kept as stored: in the shared file z points
/// up (the lasers' mean elevations span -34..+1 deg; most points lie at z in [-2, 0) m). False
/// with `error` on a bad file.
bool readNcltVelodyne(const std::string& path, Revolution& out, std::string& error);

/// Per-laser angles of a Velodyne calibration YAML (ros-drivers/velodyne format: a `lasers:` list
/// with `laser_id`, `rot_correction` [rad], `vert_correction` [rad] per entry), indexed by laser
/// id. False with `error` when a laser lacks a field, an id repeats or the ids are not 0..n-1.
bool readVelodyneCalibration(const std::string& path, std::vector<double>& elevation,
                             std::vector<double>& azimuthOffset, std::string& error);

/// KITTI ground-truth poses (one 3 x 4 [R | t] row-major per line, left-camera frame: x right,
/// y down, z forward). False with `error` naming the line on a malformed line.
bool readKittiPoses(const std::string& path, std::vector<Eigen::Matrix<double, 3, 4>>& out, std::string& error);

/// The yaw [rad] of the lidar at pose b relative to pose a (counter-clockwise about the up axis,
/// in (-pi, pi]): the camera's y axis points down, so a lidar yaw psi is a camera rotation of -psi
/// about y; psi = -atan2(R(0, 2), R(2, 2)) of R = Ra^T Rb.
double kittiRelativeYaw(const Eigen::Matrix<double, 3, 4>& a, const Eigen::Matrix<double, 3, 4>& b);

/// The ground-plane position (x, z of the camera) of a KITTI pose [m].
Eigen::Vector2d kittiPosition(const Eigen::Matrix<double, 3, 4>& pose);

}  // namespace datasets
}  // namespace agv
