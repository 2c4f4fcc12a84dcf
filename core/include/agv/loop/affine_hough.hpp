#pragma once
/// @file affine_hough.hpp
/// Point association by the Affine Hough transform: every candidate pair (a_i, b_j) is consistent
/// with a one-parameter family of rigid motions, t = a_i - R(theta) b_j for every theta, a helix
/// in [tx, ty, theta]; each pair votes along its helix in a bounded grid, and the cell with the
/// most votes (pairs) gives the motion. Its pairs, made one-to-one, are fitted (fitRigid2d), then
/// re-associated by nearest neighbour within `inlierGate` and refitted.
///
/// Memory is that of one theta slice, not of the grid: the slices are voted one after the other
/// (each pair's cell in the slice is kept so the votes can be taken back), the running maximum
/// over the slices being the answer. The thesis grid (+-5 m at 0.1 m, +-pi/2 at 0.04 rad) is
/// 100 x 100 x 79 cells, 1.6 MB of 16-bit counters dense; a slice is 100 x 100 x 2 bytes = 20 kB,
/// and the result is identical to the dense grid's (same cells and counts; on equal counts the
/// first in voting order wins: slices by increasing |theta|, then candidate order). Capacity: n_x * n_y <=
/// kMaxHoughCells (16384 with the defaults, 32 kB). Work: n_theta * K votes and as many take-backs for K candidate
/// pairs, bounded by `maxVotes`. Motions outside the grid (|t| > maxTranslation, |theta| > maxRotation) are not found.

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>

#include "agv/core/capacities.hpp"
#include "agv/core/span.hpp"
#include "agv/core/status.hpp"
#include "agv/loop/point_association.hpp"

namespace agv {

/// Grid and acceptance of the affine Hough association.
struct AffineHoughParams {
  float maxTranslation = 5.0F;     ///< [m] grid covers [-max, max) in x and y (thesis: 5 m)
  float translationStep = 0.1F;    ///< [m] cell size in x and y (thesis: 0.1 m)
  float maxRotation = 1.5707963F;  ///< [rad] slices cover [-max, max] (thesis: pi/2)
  float rotationStep = 0.04F;      ///< [rad] slice spacing (thesis: 0.04 rad); slices at k * step
  /// [m] re-association gate after the first fit (a few times the keypoint noise, and at least
  /// the error a half rotation step leaves at the sets' radius).
  float inlierGate = 0.15F;
  int refinementPasses = 2;  ///< re-association + refit passes (0: the cell's pairs only)
  /// Bound on votes cast (pairs x slices); when hit, the remaining slices are not voted and
  /// `budgetHit` is set. The default covers 64 x 64 pairs at the thesis grid (4096 x 79).
  std::uint32_t maxVotes = 400000;
  std::size_t minPairs = 3;  ///< fewest pairs accepted (>= 3)
};

/// True when the steps and bounds are finite and > 0, the slice fits kMaxHoughCells, there are at
/// most 4096 slices, passes in [0, 10], maxVotes >= 1 and minPairs >= 3.
bool isValid(const AffineHoughParams& p) noexcept;

/// Affine Hough matcher with its working storage (~57 kB: keep it static or a member).
class AffineHoughMatcher {
 public:
  explicit AffineHoughMatcher(const AffineHoughParams& params = AffineHoughParams{}) noexcept;

  /// Associates `second` with `first` [m], every combination a candidate pair. Returns Ok;
  /// InvalidArgument for parameters out of their domain; EmptyInput; CapacityExceeded when a set
  /// exceeds kMaxLoopPoints; NonFiniteInput; NotEnoughData when fewer than minPairs pairs support
  /// the best cell; NotConverged when the vote budget was hit (the best of the slices voted).
  Status match(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second, PointAssociation& out) noexcept;
  /// The same with the candidate pairs given. InvalidArgument also for a candidate outside its set.
  Status match(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second, Span<const PointPair> candidates,
               PointAssociation& out) noexcept;

  const AffineHoughParams& params() const noexcept { return params_; }
  /// Replaces the parameters (checked at the next match: InvalidArgument when out of their domain).
  /// Use it instead of assigning a new matcher: a temporary of this size does not fit a small stack.
  void setParams(const AffineHoughParams& params) noexcept { params_ = params; }
  /// Votes of the winning cell in the last call.
  std::uint32_t lastPeak() const noexcept { return peak_; }

 private:
  Status run(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second, Span<const PointPair> candidates,
             PointAssociation& out) noexcept;

  AffineHoughParams params_;
  std::uint32_t peak_ = 0;
  std::array<std::uint16_t, kMaxHoughCells> slice_{};
  std::array<std::uint16_t, CandidatePairs::kCapacity> cellOf_{};
  CandidatePairs all_;
};

}  // namespace agv
