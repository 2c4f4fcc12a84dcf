#pragma once
/// @file ransac_association.hpp
/// Point association by RANSAC: two candidate pairs drawn at random (a deterministic, seeded
/// generator: same inputs, same answer) whose distances agree within `epsilon` give a rigid motion;
/// it is scored by the second points that land within `inlierGate` of a first point; the best
/// motion's inliers are made one-to-one and fitted (fitRigid2d), then re-associated and refitted.
///
/// Stops when the adaptive bound is reached (enough draws for `confidence` that one sample was all
/// inliers, given the best inlier fraction so far), when every second point is an inlier, or at
/// the work bounds `maxSamples` draws / `maxHypotheses` scored motions (then `budgetHit`).
/// Work: maxSamples draws of O(1), maxHypotheses scorings of O(n m).

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>

#include "agv/core/capacities.hpp"
#include "agv/core/span.hpp"
#include "agv/core/status.hpp"
#include "agv/loop/point_association.hpp"

namespace agv {

/// Sampling, scoring and bounds of the RANSAC association.
struct RansacParams {
  float inlierGate = 0.10F;              ///< [m] a mapped second point within this of a first point is an inlier
  float epsilon = 0.10F;                 ///< [m] the two pairs of a sample must have distances agreeing within this
  float minBaseline = 0.2F;              ///< [m] the two points of a sample at least this far apart (rotation)
  float confidence = 0.999F;             ///< probability that an all-inlier sample was drawn, for the adaptive stop
  std::uint32_t maxSamples = 20000;      ///< bound on draws
  std::uint32_t maxHypotheses = 2000;    ///< bound on motions scored
  std::size_t minPairs = 3;              ///< fewest inliers accepted (>= 3)
  int refinementPasses = 2;              ///< re-association + refit passes on the best motion
  std::uint64_t seed = 0x5EEDC0FFEEULL;  ///< generator seed
};

/// True when the distances are finite and > 0 (minBaseline >= 0), confidence in (0, 1), bounds
/// >= 1, minPairs >= 3 and passes in [0, 10].
bool isValid(const RansacParams& p) noexcept;

/// RANSAC matcher (holds the candidate table, ~16 kB).
class RansacMatcher {
 public:
  explicit RansacMatcher(const RansacParams& params = RansacParams{}) noexcept;

  /// Associates `second` with `first` [m], every combination a candidate pair. Returns Ok;
  /// InvalidArgument; EmptyInput; CapacityExceeded when a set exceeds kMaxLoopPoints;
  /// NonFiniteInput; NotEnoughData when the best motion has fewer than minPairs inliers;
  /// NotConverged when a work bound stopped it before the adaptive bound (out holds the best).
  Status match(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second, PointAssociation& out) noexcept;
  /// The same with the candidate pairs given (the samples are drawn from them).
  Status match(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second, Span<const PointPair> candidates,
               PointAssociation& out) noexcept;

  const RansacParams& params() const noexcept { return params_; }
  /// Replaces the parameters (checked at the next match: InvalidArgument when out of their domain).
  /// Use it instead of assigning a new matcher: a temporary of this size does not fit a small stack.
  void setParams(const RansacParams& params) noexcept { params_ = params; }
  /// Motions scored in the last call.
  std::uint32_t lastHypotheses() const noexcept { return hypotheses_; }

 private:
  Status run(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second, Span<const PointPair> candidates,
             PointAssociation& out) noexcept;

  RansacParams params_;
  std::uint32_t hypotheses_ = 0;
  CandidatePairs all_;
};

}  // namespace agv
