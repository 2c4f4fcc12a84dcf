#pragma once
/// @file profile_alignment.hpp
/// A coarse 2D alignment of two revolutions from their orientation signatures (an addition to the
/// thesis): the 360 mean ranges of one beam are a horizontal range profile, bin k a point at
/// azimuth (k + 0.5) deg. Starting from the signature's relative yaw (`relativeYaw`), the profile
/// of b is aligned to that of a by point-to-line ICP with projective association: a point of b,
/// moved into a's frame by the current estimate, is paired with the point of a in the bins of its
/// azimuth (+-`searchBins`, the nearest), and the distance along the normal of a's profile there
/// (from a's neighbouring bins) is minimised over (x, y, yaw) by Gauss-Newton with Cauchy weights;
/// the pairing gate shrinks from `startGate` to `endGate`.
///
/// What it gives beyond the signature's yaw: the translation between the two revolutions (b's
/// position in a's frame), and a yaw that accounts for it (the mean-range signature of a beam
/// changes with the translation: its best shift is off by up to a few degrees at 5 m); and a
/// geometric verification of a loop candidate: the share of b's bins that found a partner within
/// `endGate` at the end (`matchedFraction`), of them those within `inlierResidual` of a's profile
/// (`inlierFraction`), and their residual.
///
/// Convention: p_a = R(yaw) p_b + t, i.e. yaw as in `relativeYaw` (b turned counter-clockwise by
/// yaw relative to a) and t = (x, y) the position of b's sensor in a's frame.
///
/// Precision: float points, double normal equations. Work: at most `maxIterations` x 360 x
/// (2 searchBins + 1) pairings and one atan2 per bin and iteration; no allocation.

#include <cstdint>

#include "agv/core/result.hpp"
#include "agv/lidar3d/orientation_signature.hpp"

namespace agv {

/// Alignment parameters (defaults: the simulated yard routes, docs/lidar-places.md).
struct ProfileAlignParams {
  std::uint16_t maxIterations = 30;  ///< Gauss-Newton steps at most
  std::uint16_t searchBins = 2;      ///< pairing: a's bins within +-this of the point's azimuth
  float startGate = 4.0F;            ///< [m] pairing gate of the first step
  float endGate = 0.3F;              ///< [m] pairing gate of the last steps (and of matchedFraction)
  float gateDecay = 0.8F;            ///< gate of step i = max(endGate, startGate * gateDecay^i)
  float cauchyScale = 0.1F;          ///< [m] robust weight 1 / (1 + (r / s)^2), s = max(this, gate / 2)
  /// a's bin has a normal (is a pairing partner) when both neighbouring bins are valid and within
  /// this fraction of its range from it (no depth jump between them).
  float maxNeighbourRatio = 0.15F;
  std::uint16_t minPairs = 20;  ///< fewer pairs in a step: NotEnoughData
  /// A matched bin is an inlier when its point-to-line residual at the result is at most this [m]
  /// (a few times the noise of a bin's mean range; a wrong pose spreads the residuals over the gate).
  float inlierResidual = 0.1F;
};

/// True when the parameters are in their domain.
bool isValid(const ProfileAlignParams& p) noexcept;

/// The alignment of b's profile to a's.
struct ProfileAlignment {
  float yaw = 0.0F;              ///< [rad] in (-pi, pi], as relativeYaw
  float x = 0.0F;                ///< [m] b's sensor position in a's frame
  float y = 0.0F;                ///< [m]
  std::uint16_t matched = 0;     ///< b's bins paired within endGate at the result
  std::uint16_t bins = 0;        ///< b's valid bins
  std::uint16_t inliers = 0;     ///< of the matched, those within inlierResidual of a's profile
  float rms = 0.0F;              ///< [m] point-to-line residual of the matched bins
  std::uint16_t iterations = 0;  ///< steps done
  bool converged = false;        ///< the last step moved less than 2 mm and 0.01 deg
  /// How well the translation is determined: the smaller eigenvalue of sum w n n^T over the matched
  /// bins' normals n (weights w), divided by sum w: 0..0.5; near 0 when the matched surfaces are all
  /// parallel (a straight road or aisle: the shift along it is not observed).
  float translationObservability = 0.0F;
  float translation() const noexcept;       ///< [m] |(x, y)|
  float matchedFraction() const noexcept {  ///< matched / bins (0 when no bins)
    return bins > 0 ? static_cast<float>(matched) / static_cast<float>(bins) : 0.0F;
  }
  float inlierFraction() const noexcept {  ///< inliers / bins (0 when no bins)
    return bins > 0 ? static_cast<float>(inliers) / static_cast<float>(bins) : 0.0F;
  }
};

/// Aligns b's profile to a's from `initialYaw` [rad] (e.g. relativeYaw(a, b).yaw) and zero
/// translation. InvalidArgument (params, non-finite yaw); NotEnoughData (an empty signature, or
/// fewer than minPairs pairs in a step, or a singular step).
Result<ProfileAlignment> alignProfiles(const OrientationSignature& a, const OrientationSignature& b, float initialYaw,
                                       const ProfileAlignParams& params = ProfileAlignParams{}) noexcept;

}  // namespace agv
