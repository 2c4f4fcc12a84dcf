#pragma once
/// @file normal_signature.hpp
/// The normal-histogram place signature of one revolution (Muhammad 2012, ch. 5): the histogram
/// of the z component of the beam-arrangement normals (beam_normals.hpp) in 101 bins over
/// [-1, 1], normalised to sum 1, and its two distances.
///
/// Bin b holds n.z in [-1 + (b - 0.5) 0.02, -1 + (b + 0.5) 0.02): the bins are centred on
/// -1, -0.98, ..., 0, ..., 1, so a wall (n.z = 0) falls in bin 50 and a floor (n.z = 1) in bin
/// 100. n.z does not change when the sensor turns about its vertical axis: the signature is yaw
/// invariant (up to the azimuth binning of the range image).
///
/// Distances, for normalised P, Q (sum 1 each):
/// - chi-square D = sum_b (P_b - Q_b)^2 / (P_b + Q_b + 1), in [0, 1]: 0 for identical histograms,
///   at most half the L1 distance, so at most 1 (each term is d^2 / (P + Q + 1) <= d^2 / (d + 1)
///   <= d / 2 with d = |P - Q| <= 1; reached by disjoint one-bin histograms);
/// - Sorensen D = sum_b |P_b - Q_b| / sum_b (P_b + Q_b), in [0, 1]: 0 identical, 1 disjoint.
/// Both are symmetric. Two empty signatures are at distance 0 from each other.
///
/// Precision: float. Work: computeNormalSignature O(rows * columns) beamNormal calls; each
/// distance 101 terms.

#include <array>
#include <cstddef>
#include <cstdint>

#include "agv/core/status.hpp"
#include "agv/lidar3d/beam_normals.hpp"
#include "agv/lidar3d/range_image.hpp"

namespace agv {

/// Bins of the normal histogram (thesis: 101 over [-1, 1]).
inline constexpr std::size_t kNormalSignatureBins = 101;

/// How many points were skipped and why (see NormalSkip).
struct NormalCounts {
  std::uint32_t normals = 0;           ///< normals counted in the histogram
  std::uint32_t outOfRange = 0;        ///< no return or outside [minRange, maxRange]
  std::uint32_t missingNeighbour = 0;  ///< a neighbour outside the image or without return
  std::uint32_t neighbourTooFar = 0;   ///< depth jump
  std::uint32_t degenerate = 0;        ///< parallel differences
  std::uint32_t belowMinimum = 0;      ///< normals found but not used: fewer than minNormals
};

/// The signature of one revolution.
struct NormalSignature {
  std::array<float, kNormalSignatureBins> bins{};  ///< sums to 1 when counts.normals > 0, all zero otherwise
  NormalCounts counts{};
  bool empty() const noexcept { return counts.normals == 0; }
};

/// Normals and the smallest number of them a signature needs.
struct NormalSignatureParams {
  BeamNormalParams normals{};
  /// Fewer normals than this give NotEnoughData (a revolution seeing almost nothing is no place).
  std::uint32_t minNormals = 100;
};

/// The bin of a normal's z component (values outside [-1, 1] are clamped).
std::size_t normalBin(float nz) noexcept;

/// Computes the signature of `image` into `out`. Ok; InvalidArgument for parameters out of their
/// domain or an image with no more than 2 * firingStep columns; EmptyInput when the image holds
/// no valid cell; NotEnoughData when fewer than minNormals normals were found. On every failure
/// `out.bins` is all zero (an empty signature) and `out.counts` says what was seen (on NotEnoughData
/// the normals found are in `counts.belowMinimum`, `counts.normals` is 0).
Status computeNormalSignature(const RangeImageBase& image, const NormalSignatureParams& params,
                              NormalSignature& out) noexcept;

/// Chi-square distance sum (P - Q)^2 / (P + Q + 1), in [0, 1] for normalised signatures.
float chiSquareDistance(const NormalSignature& a, const NormalSignature& b) noexcept;

/// Sorensen distance sum |P - Q| / sum (P + Q), in [0, 1]; 0 when both are empty.
float sorensenDistance(const NormalSignature& a, const NormalSignature& b) noexcept;

}  // namespace agv
