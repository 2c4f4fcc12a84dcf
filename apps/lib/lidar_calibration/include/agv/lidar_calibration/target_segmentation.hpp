#pragma once
/// @file target_segmentation.hpp
/// Finding the planar calibration target in one multi-beam scan (host code;
/// docs/lidar-calibration.md). The target is not the only thing in view (floor, hall walls,
/// clutter), so: sequential RANSAC planes (hypotheses scored on a sample, inliers on all points);
/// per plane the largest connected region of its inliers on an in-plane grid; regions whose
/// in-plane extents fit the target's size (not the floor, not a hall wall, not a pillar) are
/// candidates; each is refined (PCA refit, re-selection within the region's cells with a threshold
/// from the residuals' median absolute deviation, a few times, leaving out points that also lie
/// on one of the other large planes found: where the target meets the floor, the floor's points
/// on the line of intersection lie in the target's plane); the largest candidate that still fits
/// and is planar within `maxRms` (a pallet is not) is the target.

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace agv::lidar_calibration {

/// Segmentation parameters (SI).
struct TargetSegmentationConfig {
  double targetWidth = 4.4;       ///< [m] larger side of the target
  double targetHeight = 3.5;      ///< [m] smaller side
  double extentTolerance = 1.25;  ///< the refined target may extend up to this factor times a side
  /// The RANSAC region of a candidate may extend up to this factor times a side (at the RANSAC
  /// threshold it can hold the floor's ring whose radius is the target's distance).
  double candidateTolerance = 1.6;
  double minExtentFraction =
      0.3;               ///< the region's extents must reach this fraction of the sides (a pillar is no target)
  double maxRms = 0.08;  ///< [m] a refined target region is planar within this (a pallet's faces are not)
  double ransacThreshold = 0.15;  ///< [m] inlier distance of the RANSAC hypotheses (miscalibration allowed)
  double minThreshold = 0.04;     ///< [m] floor of the refinement threshold
  double madFactor = 4.0;         ///< refinement threshold = max(minThreshold, madFactor * 1.4826 * MAD)
  double regionCell = 0.5;        ///< [m] in-plane grid of the connected region
  int iterations = 300;           ///< RANSAC hypotheses per plane
  int sample = 3000;              ///< points scoring a hypothesis
  int maxPlanes = 8;              ///< planes tried before giving up
  int refinements = 4;            ///< PCA refit / re-selection rounds
  std::size_t minPoints = 50;     ///< a target region needs this many points
  double maxRange = 60.0;         ///< [m] points farther from the sensor are not used
  std::uint64_t seed = 1;         ///< RANSAC random stream
};

/// A plane n . x = d with unit normal n.
struct Plane {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitX();
  double offset = 0.0;
};

/// Two orthonormal vectors spanning the plane with unit normal `n` (the first horizontal unless n
/// is nearly vertical): in-plane coordinates, and the tangent space of the normal.
Eigen::Matrix<double, 3, 2> planeAxes(const Eigen::Vector3d& n);

/// PCA plane of `points[indices]` (all when `indices` is null): through the centroid, normal =
/// the covariance's smallest eigenvector; `meanSquared` = the smallest eigenvalue = the mean
/// squared distance of the points to the plane (the thesis' cost of one scan). Needs 3 points.
Plane pcaPlane(const std::vector<Eigen::Vector3d>& points, const std::vector<std::size_t>* indices,
               double* meanSquared = nullptr);

/// The target's points in one scan.
struct TargetSegment {
  std::vector<std::size_t> indices;                  ///< into the scan's points, ascending
  Plane plane;                                       ///< PCA plane of the indices
  double rms = 0.0;                                  ///< [m] root mean squared distance to it
  Eigen::Vector2d extent = Eigen::Vector2d::Zero();  ///< [m] in-plane extents (larger first)
  int planesTried = 0;                               ///< RANSAC planes examined
};

/// Segments the target in `points` (sensor frame). False with `error` naming the reason (no point,
/// a non-finite point, no plane region of the target's size).
bool segmentTarget(const std::vector<Eigen::Vector3d>& points, const TargetSegmentationConfig& config,
                   TargetSegment& out, std::string& error);

}  // namespace agv::lidar_calibration
