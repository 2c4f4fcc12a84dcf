#pragma once
/// @file multibeam_world.hpp
/// A 3D world for the multi-beam lidar simulation (host only): a flat ground and oriented boxes
/// (buildings, rack rows, walls, ramps and tilted panels), a ray caster, a multi-beam sensor with
/// per-laser elevations and azimuth offsets (the factory calibration's vert_correction and
/// rot_correction), and a route that revisits places, some in the opposite direction.

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <random>
#include <vector>

#include "agv/core/pose2.hpp"
#include "agv/lidar3d/range_image.hpp"

namespace agv::sim {

/// An oriented box: centre, half extents along its own axes, rotation world <- box.
struct Box3 {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  Eigen::Vector3d half = Eigen::Vector3d::Ones();
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
};

/// The ground z = 0 and the boxes.
struct MultibeamWorld {
  std::vector<Box3> boxes;
  /// Distance along the unit ray (origin, dir) to the nearest surface, or maxRange when none is
  /// nearer; `candidates` (indices into boxes) limits the boxes tested (all when null). When
  /// `surface` is given it receives what was hit: -1 nothing, 0 the ground, k + 1 box k.
  double cast(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double maxRange,
              const std::vector<std::size_t>* candidates = nullptr, int* surface = nullptr) const;
};

/// A multi-beam lidar: one entry per laser (hardware order), firings per revolution, noise.
struct MultibeamSensor {
  std::vector<double> elevation;      ///< [rad] per laser, positive up
  std::vector<double> azimuthOffset;  ///< [rad] per laser (rot_correction), added to the firing azimuth
  std::size_t firings = 2000;         ///< per revolution
  double height = 1.73;               ///< [m] above the ground (KITTI's HDL-64E)
  double rangeNoise = 0.02;           ///< [m] standard deviation (HDL-64E spec: < 2 cm)
  double maxRange = 120.0;            ///< [m]
};

/// A VLP-16: elevations -15..+15 deg in its interleaved laser order, 1800 firings, 3 cm noise, 1.0 m high.
MultibeamSensor vlp16Sensor();

/// One revolution from a sensor at `pose` (x, y, yaw on the ground): Cartesian points in the
/// sensor frame (z up) with their ring = the laser's rank in elevation order; rays without a
/// surface within maxRange give no point.
void scanRevolution(const MultibeamWorld& world, const MultibeamSensor& sensor, const Pose2d& pose,
                    std::mt19937_64& rng, std::vector<RingPoint>& out);

/// One pose of the route with the travelled distance.
struct RoutePose {
  Pose2d pose;
  double travel = 0.0;  ///< [m]
  int lap = 0;          ///< 0: first pass; 1: back in the opposite direction; 2: again in the first direction
};

/// The yard: a rectangular road of width x height metres around a block, lined on both sides
/// with seeded random buildings, rack rows, walls, ramps, embankments and tilted panels.
MultibeamWorld yardWorld(double width, double height, std::uint64_t seed);

/// The route on the yard's road: a full lap counter-clockwise; then back clockwise over the first
/// `backFraction` of the lap (the opposite direction); then counter-clockwise again over the first
/// `againFraction`; a revolution every `step` metres, with a lateral offset of up to `lateral`
/// metres on the repeated passes.
std::vector<RoutePose> yardRoute(double width, double height, double step, double backFraction, double againFraction,
                                 double lateral);

}  // namespace agv::sim
