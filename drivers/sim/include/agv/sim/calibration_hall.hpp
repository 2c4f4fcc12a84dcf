#pragma once
/// @file calibration_hall.hpp
/// The multi-beam lidar calibration hall of the simulator (host only; docs/lidar-calibration.md):
/// a hall (floor, side walls, back wall, ceiling) with a free-standing planar target wall and
/// clutter (pallets, a pillar), a sensor on a tripod placed at several distances in front of the
/// target with several head tilts (the thesis' protocol: 9 distances x 5 tilts), and a scan that
/// inverts the thesis' per-laser model: for every laser and firing the true intrinsics give the
/// ray (laser_ray.hpp), the ray is cast into the hall, and the return reports the raw range
/// D_ret = D - D_corr(true) plus Gaussian noise that the model maps back to the hit point.
///
/// World frame: the target's face is the plane x = 0 facing -x, centred on y = 0, on a stand above
/// the floor z = 0; placements stand at x = -distance.

#include <Eigen/Geometry>
#include <cstdint>
#include <random>
#include <vector>

#include "agv/lidar3d/laser_intrinsics.hpp"
#include "agv/lidar3d/laser_ray.hpp"
#include "agv/sim/multibeam_world.hpp"

namespace agv::sim {

/// The hall's dimensions [m].
struct CalibrationHallConfig {
  double targetWidth = 4.4;   ///< the thesis' planar wall
  double targetHeight = 3.5;  ///< [m] of the board
  double targetBottom = 0.2;  ///< [m] the board's lower edge above the floor (on a stand)
  double hallBehind = 26.0;   ///< back wall this far behind the target's face (placements up to 22 m)
  double hallFront = 6.0;     ///< front wall this far beyond the target's face
  double hallHalfWidth = 9.0;
  double hallHeight = 7.0;
  int pallets = 8;          ///< clutter boxes on the floor, beside the line of sight
  std::uint64_t seed = 19;  ///< clutter layout
};

/// The hall: its boxes (the ground is the world's z = 0) and which box is the target.
struct CalibrationHall {
  MultibeamWorld world;
  int targetSurface = -1;  ///< the `surface` value `MultibeamWorld::cast` reports for the target
  CalibrationHallConfig config;
};

/// Builds the hall.
CalibrationHall calibrationHall(const CalibrationHallConfig& config = CalibrationHallConfig{});

/// One placement of the sensor in front of the target.
struct HallPlacement {
  double distance = 10.0;  ///< [m] from the target's face to the sensor origin, along -x
  double tilt = 0.0;       ///< [rad] head pitched up (positive: the lower lasers rise onto the target)
  double yaw = 0.0;        ///< [rad] about the vertical (0: head azimuth 0 faces the target)
  double height = 1.2;     ///< [m] sensor origin above the floor
};

/// The thesis' protocol: `distances` evenly from `nearest` to `farthest` times `tilts` evenly
/// from `lowestTilt` to `highestTilt` (defaults 9 x 5: 3..22 m, 0..24 deg up).
std::vector<HallPlacement> hallProtocol(int distances = 9, double nearest = 3.0, double farthest = 22.0, int tilts = 5,
                                        double lowestTilt = 0.0, double highestTilt = 0.4188790205);

/// The sensor pose world <- sensor of a placement (REP-103 sensor frame, x toward the target).
Eigen::Isometry3d placementPose(const HallPlacement& placement);

/// The simulated sensor: the true per-laser intrinsics and the firing pattern.
struct ModelSensorConfig {
  std::size_t firings = 2083;  ///< per revolution (HDL-64E S2 at 10 Hz: 0.1728 deg steps)
  double rangeNoise = 0.02;    ///< [m] standard deviation of D_ret
  double maxRange = 120.0;     ///< [m] no return beyond
  bool quantize = true;        ///< D_ret rounded to the distance resolution (2 mm counts)
  double azimuthWindow = 0.0;  ///< [rad] > 0: fire only within +-window of phi = 0 (speed; 0 = full turn)
};

/// One revolution: raw returns and, per return, what the ray hit (0 ground, k + 1 box k).
struct ModelScan {
  std::vector<RawReturn> returns;
  std::vector<int> surface;
};

/// One revolution from `pose` (world <- sensor) with `truth` as the sensor's intrinsics: laser l
/// at head angle phi (firing f: phi = 2 pi (f + 0.5) / firings) casts its true ray; a hit at
/// D gives D_ret = D - D_corr + noise. Rays without a surface within maxRange give no return;
/// neither do returns whose D_ret would be <= 0.
void scanModel(const MultibeamWorld& world, const Eigen::Isometry3d& pose, const LaserIntrinsics& truth,
               const ModelSensorConfig& sensor, std::mt19937_64& rng, ModelScan& out);

/// The factory table `factory` with every laser's D_corr, theta and alpha moved by uniform random
/// amounts within +-the given bounds (V_o, H_o by +-vertHoriz) — a "true" unit to simulate. With
/// `zeroMeanAngles` the theta and alpha moves have zero mean over the lasers (the truth then keeps
/// the factory's common offsets, which a wall protocol cannot observe).
LaserIntrinsics perturbIntrinsics(const LaserIntrinsics& factory, double distCorrection, double theta, double alpha,
                                  double vertHoriz, std::mt19937_64& rng, bool zeroMeanAngles = false);

}  // namespace agv::sim
