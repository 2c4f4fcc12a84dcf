#pragma once
/// @file glarot.hpp
/// GLAROT: the rotation-invariant GLARE signature of a set of 2D points (FALKO keypoints of a
/// scan), for place recognition.
///
/// Every pair of points votes into an n_theta x n_rho accumulator at (the direction of the segment
/// joining them modulo pi, its length); each vote is spread by a Gaussian over the adjacent cells
/// (+-1 in both directions, theta circular) and the accumulator is normalised to sum 1, so that
/// sets of different sizes compare. A rotation of the sensor by phi adds phi to every segment
/// direction: the signature turns by a circular shift of phi / (pi / n_theta) cells along theta.
/// The shifted L1 distance SL1 (the minimum of the L1 distance over the n_theta circular shifts)
/// is therefore rotation-invariant, and the shift that attains it estimates the rotation modulo pi.
/// Translation changes no segment: the signature is translation-invariant.
///
/// Precision: float (scan geometry; a signature is 1 KiB with the defaults).
/// Work: computeGlarot O(n^2) pairs, n <= kMaxKeypoints (6 expf, 1 atan2, 1 sqrt per pair);
/// glarotDistance O(n_theta^2 n_rho) (2048 absolute differences with the defaults).

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>

#include "agv/core/capacities.hpp"
#include "agv/core/result.hpp"
#include "agv/core/span.hpp"
#include "agv/core/status.hpp"
#include "agv/falko/falko_keypoint.hpp"

namespace agv {

/// Accumulator shape and spreading. Sizes are run-time values within the compile-time capacities
/// (n_theta * n_rho <= kGlarotMaxCells, n_rho <= kGlarotMaxRhoBins).
struct GlarotParams {
  /// n_theta: direction bins over [0, pi) (thesis: 8, i.e. 22.5 deg; the rotation estimate has
  /// this resolution).
  std::size_t thetaBins = 8;
  /// n_rho: distance bins over [0, maxDistance). 32 bins of 0.5 m: GLARE's choice of cells about
  /// as wide as the keypoint repeatability allows, indoor rooms and corridors resolved.
  std::size_t rhoBins = 32;
  /// [m] pairs at this distance or farther are not counted (GLARE bounds rho; two corners 16 m
  /// apart are seldom both seen from two poses of a loop).
  float maxDistance = 16.0F;
  /// Standard deviation of the Gaussian spreading along theta [cells]; the vote goes to the cell
  /// of the pair and its two neighbours, weights renormalised to sum 1.
  float sigmaTheta = 0.5F;
  /// Standard deviation of the Gaussian spreading along rho [cells] (neighbours outside
  /// [0, n_rho) get nothing; the weights of the others are renormalised).
  float sigmaRho = 0.5F;
};

/// True when `p` lies in its domain: thetaBins >= 2, rhoBins >= 1, thetaBins * rhoBins <=
/// kGlarotMaxCells, rhoBins <= kGlarotMaxRhoBins, maxDistance and both sigmas finite and > 0.
bool isValid(const GlarotParams& p) noexcept;

/// The signature of one point set.
struct GlarotSignature {
  std::uint16_t thetaBins = 0;    ///< n_theta of the parameters it was computed with
  std::uint16_t rhoBins = 0;      ///< n_rho
  std::uint32_t pairs = 0;        ///< pairs counted (closer than maxDistance)
  std::uint32_t pairsBeyond = 0;  ///< pairs not counted because they were maxDistance or more apart
  /// Theta-major accumulator: cells[t * rhoBins + r]; sums to 1 when pairs > 0, all zero otherwise.
  std::array<float, kGlarotMaxCells> cells{};

  /// Number of live cells (thetaBins * rhoBins).
  std::size_t size() const noexcept { return static_cast<std::size_t>(thetaBins) * rhoBins; }
};

/// Computes the signature of `points` [m]. Returns Ok; InvalidArgument for parameters out of
/// their domain (out left empty, 0 x 0); CapacityExceeded for more than kMaxKeypoints points;
/// NonFiniteInput when a coordinate is NaN or infinite; EmptyInput for no point and NotEnoughData
/// when no pair is counted (one point, or all pairs beyond maxDistance). In the last two cases
/// and on the capacity and NaN refusals `out` is the all-zero signature of the right shape (a
/// valid database entry, at SL1 distance 1 from every non-empty signature).
Status computeGlarot(Span<const Eigen::Vector2f> points, const GlarotParams& params, GlarotSignature& out) noexcept;

/// The same for FALKO keypoints (their x, y in the sensor frame).
Status computeGlarot(Span<const FalkoKeypoint> keypoints, const GlarotParams& params, GlarotSignature& out) noexcept;

/// SL1 and the shift that attains it.
struct GlarotMatch {
  /// min over s of sum_{t,r} |a[(t - s) mod n_theta][r] - b[t][r]|; 0 (identical) .. 2 (disjoint).
  float distance = 0.0F;
  /// The s attaining it (the smallest on ties): `b` looks like `a` turned counter-clockwise by
  /// s * pi / n_theta, modulo pi. See glarotRotation.
  std::uint16_t shift = 0;
};

/// SL1 distance between two signatures. InvalidArgument when their shapes differ or are empty.
Result<GlarotMatch> glarotDistance(const GlarotSignature& a, const GlarotSignature& b) noexcept;

/// L1 distance of `b` to `a` shifted by `shift` cells (the term SL1 minimises); -1 when the shapes
/// differ or shift >= n_theta.
float glarotShiftedL1(const GlarotSignature& a, const GlarotSignature& b, std::size_t shift) noexcept;

/// The rotation [rad] a shift stands for, in (-pi/2, pi/2] (the signature cannot tell phi from
/// phi + pi: segment directions are taken modulo pi).
float glarotRotation(std::size_t shift, std::size_t thetaBins) noexcept;

}  // namespace agv
