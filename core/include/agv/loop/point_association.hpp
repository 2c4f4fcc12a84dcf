#pragma once
/// @file point_association.hpp
/// What the loop-closure point associations (correspondence graph, affine Hough, RANSAC) return:
/// one-to-one pairs between two point sets and the rigid transform they support.
///
/// Convention (that of `fitRigid2d`): `first` is the reference set (a database scan, the map),
/// `second` the set being placed (the current scan); `transform` maps second onto first,
/// first[pair.first] ~ transform.transformPoint(second[pair.second]). For two scans it is the pose
/// of the second sensor in the frame of the first.

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>

#include "agv/core/capacities.hpp"
#include "agv/core/fixed_vector.hpp"
#include "agv/core/pose2.hpp"
#include "agv/core/span.hpp"

namespace agv {

/// One association: index into the first set and index into the second set.
struct PointPair {
  std::uint16_t first = 0;
  std::uint16_t second = 0;
};

/// Candidate pairs given to a method (e.g. filtered by a descriptor distance), at most one per
/// (first, second) combination: kMaxLoopPoints^2 of them.
using CandidatePairs = FixedVector<PointPair, kMaxLoopPoints * kMaxLoopPoints>;

/// The result of one association.
struct PointAssociation {
  /// One-to-one pairs (no index of either set twice), the support of `transform`.
  FixedVector<PointPair, kMaxLoopPoints> pairs;
  /// Least-squares rigid transform of the pairs (fitRigid2d); identity when fewer than 3 pairs.
  Pose2d transform{};
  /// RMS distance [m] between first[pair.first] and transform(second[pair.second]).
  double rms = 0.0;
  /// Work spent, in the unit of the method's bound: branch-and-bound nodes (correspondence
  /// graph), votes (affine Hough), drawn samples (RANSAC).
  std::uint32_t work = 0;
  /// True when the method stopped at its work bound (its answer is then the best found so far).
  bool budgetHit = false;
};

/// Every (first, second) combination of two sets of sizes nFirst, nSecond, row by row.
/// CapacityExceeded (nothing written, `out` cleared) when a size exceeds kMaxLoopPoints.
Status allCandidatePairs(std::size_t nFirst, std::size_t nSecond, IVector<PointPair>& out) noexcept;

}  // namespace agv
