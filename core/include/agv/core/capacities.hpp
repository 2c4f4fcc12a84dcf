#pragma once
/// @file capacities.hpp
/// Every compile-time capacity of the core, in one place.
///
/// Storage in `core/` is fixed-capacity; these numbers size it. A build may override any of them
/// with a compile definition of the same name (e.g. `-DAGV_MAX_SCAN_BEAMS=1081` for a smaller MCU),
/// and the values in force are those compiled into the library *and* the caller, so set them
/// project-wide (the CMake cache variables `AGVNAV_MAX_*` do that for consumers of `agv::core`).

#include <cstddef>

#ifndef AGV_MAX_SCAN_BEAMS
#define AGV_MAX_SCAN_BEAMS 2048
#endif
#ifndef AGV_MAX_KEYPOINTS
#define AGV_MAX_KEYPOINTS 256
#endif
#ifndef AGV_MAX_REFLECTORS
#define AGV_MAX_REFLECTORS 64
#endif
#ifndef AGV_MAX_OBSERVATIONS
#define AGV_MAX_OBSERVATIONS 128
#endif
#ifndef AGV_MAX_LANDMARKS
#define AGV_MAX_LANDMARKS 4096
#endif
#ifndef AGV_MAX_CALIB_SEGMENTS
#define AGV_MAX_CALIB_SEGMENTS 64
#endif
#ifndef AGV_MAX_ODOMETRY_HISTORY
#define AGV_MAX_ODOMETRY_HISTORY 128
#endif
#ifndef AGV_LANDMARK_GRID_BUCKETS
#define AGV_LANDMARK_GRID_BUCKETS 8192
#endif
#ifndef AGV_GLAROT_MAX_CELLS
#define AGV_GLAROT_MAX_CELLS 256
#endif
#ifndef AGV_GLAROT_MAX_RHO_BINS
#define AGV_GLAROT_MAX_RHO_BINS 64
#endif
#ifndef AGV_GLAROT_MAX_CANDIDATES
#define AGV_GLAROT_MAX_CANDIDATES 32
#endif
#ifndef AGV_MAX_LOOP_POINTS
#define AGV_MAX_LOOP_POINTS 64
#endif
#ifndef AGV_MAX_CG_VERTICES
#define AGV_MAX_CG_VERTICES 256
#endif
#ifndef AGV_MAX_HOUGH_CELLS
#define AGV_MAX_HOUGH_CELLS 16384
#endif
#ifndef AGV_MAX_LIDAR_LASERS
#define AGV_MAX_LIDAR_LASERS 128
#endif

namespace agv {

/// Beams in one 2D laser scan (a 360 deg scan at 0.25 deg has 1440; 2048 leaves head-room).
inline constexpr std::size_t kMaxScanBeams = AGV_MAX_SCAN_BEAMS;
/// FALKO keypoints kept per scan.
inline constexpr std::size_t kMaxKeypoints = AGV_MAX_KEYPOINTS;
/// Reflector detections one navigation laser reports per scan.
inline constexpr std::size_t kMaxReflectors = AGV_MAX_REFLECTORS;
/// Point observations (reflectors + keypoints) fed to one EKF correction.
inline constexpr std::size_t kMaxObservations = AGV_MAX_OBSERVATIONS;
/// Landmarks held by the landmark map.
inline constexpr std::size_t kMaxLandmarks = AGV_MAX_LANDMARKS;
/// Constant-steering path segments used by one calibration solve.
inline constexpr std::size_t kMaxCalibSegments = AGV_MAX_CALIB_SEGMENTS;

/// Odometry increments the localizer keeps for re-prediction after a late scan (at 100 Hz
/// encoders, 128 cover 1.28 s of scan latency).
inline constexpr std::size_t kMaxOdometryHistory = AGV_MAX_ODOMETRY_HISTORY;
/// Hash buckets of the landmark map's spatial grid (power of two; 2x kMaxLandmarks keeps chains short).
inline constexpr std::size_t kLandmarkGridBuckets = AGV_LANDMARK_GRID_BUCKETS;

/// Cells of one GLAROT signature (n_theta x n_rho; the default 8 x 32 fills it: 1 KiB of float).
inline constexpr std::size_t kGlarotMaxCells = AGV_GLAROT_MAX_CELLS;
/// Distance bins n_rho of one GLAROT signature.
inline constexpr std::size_t kGlarotMaxRhoBins = AGV_GLAROT_MAX_RHO_BINS;
/// Candidates one GLAROT database query returns at most (the thesis uses 10).
inline constexpr std::size_t kGlarotMaxCandidates = AGV_GLAROT_MAX_CANDIDATES;
/// Points of one set given to a loop-closure point association (keypoints of a scan, landmarks).
inline constexpr std::size_t kMaxLoopPoints = AGV_MAX_LOOP_POINTS;
/// Vertices (candidate pairs) of one correspondence graph; the adjacency is a V x V bit matrix.
inline constexpr std::size_t kMaxCgVertices = AGV_MAX_CG_VERTICES;
/// Cells of one translation slice (n_x x n_y) of the affine Hough accumulator.
inline constexpr std::size_t kMaxHoughCells = AGV_MAX_HOUGH_CELLS;
/// Lasers (beams) of one multi-beam lidar in a `LaserIntrinsics` table (HDL-64E 64, Ouster 128).
inline constexpr std::size_t kMaxLidarLasers = AGV_MAX_LIDAR_LASERS;

static_assert(kMaxScanBeams >= 16, "a scan needs at least 16 beams of capacity");
static_assert(kMaxKeypoints >= 1 && kMaxReflectors >= 1 && kMaxObservations >= 1, "capacities must be positive");
static_assert(kMaxLandmarks >= 1 && kMaxCalibSegments >= 2, "capacities must be positive");
static_assert(kMaxOdometryHistory >= 4, "the odometry history needs at least 4 entries");
static_assert(kLandmarkGridBuckets >= 16 && (kLandmarkGridBuckets & (kLandmarkGridBuckets - 1)) == 0,
              "landmark grid buckets must be a power of two");
static_assert(kGlarotMaxCells >= 8 && kGlarotMaxRhoBins >= 1 && kGlarotMaxRhoBins <= kGlarotMaxCells,
              "GLAROT capacities: at least 8 cells, rho bins within the cells");
static_assert(kGlarotMaxCandidates >= 1, "capacities must be positive");
static_assert(kMaxLoopPoints >= 3 && kMaxLoopPoints < 255, "loop points: at least 3, indices fit 8 bits");
static_assert(kMaxCgVertices >= 9 && kMaxCgVertices % 64 == 0 && kMaxCgVertices < 65535,
              "correspondence graph vertices: a multiple of 64 (bit-set words)");
static_assert(kMaxHoughCells >= 4, "capacities must be positive");
static_assert(kMaxLidarLasers >= 16 && kMaxLidarLasers <= 256, "lidar lasers: 16..256 (ids fit 8 bits)");

}  // namespace agv
