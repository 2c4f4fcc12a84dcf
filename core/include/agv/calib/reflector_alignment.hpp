#pragma once
/// @file reflector_alignment.hpp
/// Laser egomotion between two standstill observations of a reflector field: rigid 2D alignment
/// by nearest-neighbour association (mutual, gated) and the closed-form least-squares rotation
/// and translation, iterated until the association settles. Gives the s^k of a calibration
/// segment from the reflector sets the navigation laser reports at its two ends.
///
/// Precision: double. The result feeds the calibration, whose noise floor is millimetres over
/// 10 m lever arms; the centroid sums of up to kMaxReflectors points stay exact enough in double
/// while float would add ~1e-6 rad of rounding per pass.

#include <Eigen/Core>
#include <cstddef>

#include "agv/core/pose2.hpp"
#include "agv/core/span.hpp"
#include "agv/core/status.hpp"

namespace agv {

/// Association and iteration settings.
struct ReflectorAlignmentOptions {
  /// Largest distance [m] between a reflector of the first set and a reflector of the second set
  /// (mapped through the current estimate) for them to be paired while converging. It must cover
  /// the error of the initial guess at the reflectors' range, and stay below half the smallest
  /// reflector spacing.
  double associationGate = 0.5;
  /// Gate [m] of the final passes, once the estimate has converged: pairs farther apart are
  /// outliers (spurious reflections, reflectors seen in one set only).
  double finalGate = 0.05;
  /// Fewest pairs accepted (at least 2).
  std::size_t minMatches = 3;
  /// Bound on association + solve passes in each of the two phases.
  int maxIterations = 30;
  /// The iteration stops when the estimate moves less than this [m at 1 m lever, rad].
  double convergence = 1e-10;
};

/// The estimated motion and how well it is supported.
struct ReflectorAlignment {
  /// Pose of the laser at the second observation expressed in its frame at the first one
  /// (a point q seen in the second set lies at motion.transformPoint(q) in the first).
  Pose2d motion{};
  std::size_t matches = 0;  ///< pairs used in the final solve
  double rms = 0.0;         ///< RMS distance of those pairs after alignment [m]
  int iterations = 0;       ///< passes done, both phases
};

/// Aligns `second` onto `first` (reflector positions in the laser frame at each observation [m]),
/// starting from `guess` (e.g. the motion the nominal odometry and laser pose predict).
/// Returns Ok; EmptyInput when a set is empty; CapacityExceeded when a set has more than
/// kMaxReflectors points; NonFiniteInput for NaN/inf points or guess; InvalidArgument for bad
/// options; NotEnoughData when fewer than minMatches pairs remain; NotConverged when the
/// iteration bound is hit. `out` is filled with the last estimate in every case.
Status alignReflectors(Span<const Eigen::Vector2d> first, Span<const Eigen::Vector2d> second, const Pose2d& guess,
                       const ReflectorAlignmentOptions& options, ReflectorAlignment& out) noexcept;

}  // namespace agv
