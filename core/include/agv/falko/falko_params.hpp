#pragma once
/// @file falko_params.hpp
/// Parameters of the FALKO keypoint detector and of its BSC / CGH descriptors, with the defaults
/// of the FALKO thesis (Kallasi, Lodi Rizzini).

#include <cstddef>

#include "agv/core/status.hpp"

namespace agv {

/// FALKO detector parameters. Distances in metres, angles in radians.
struct FalkoParams {
  /// Neighbourhood radius r = a * exp(b * range) [m]: `a` is the radius of a candidate at the
  /// sensor. Thesis default 0.2 m.
  float neighA = 0.2F;
  /// Growth of the neighbourhood radius with range [1/m]; thesis default 0.07 (r = 0.40 m at 10 m).
  float neighB = 0.07F;
  /// When a*exp(b*range) reaches the range itself (very close points), the radius is clamped to
  /// this fraction of the range so that the neighbourhood never includes the sensor origin.
  float maxRadiusRangeRatio = 0.8F;
  /// Triangle test: the base (first to last neighbour) and the height of the candidate above that
  /// base must both be at least r / beta; rejects straight walls and tiny bumps. Thesis default 4.
  float beta = 4.0F;
  /// Minimum number of valid neighbours on each side (C_L before, C_R after the candidate in beam
  /// order). Thesis: 2.
  std::size_t minSidePoints = 2;
  /// Number of polar sectors s_n of the cornerness score (points of one straight side fall in one
  /// sector). Thesis default 16; must be in [4, 64].
  std::size_t gridSectors = 16;
  /// Largest accepted cornerness score: mean circular sector distance between the points of the
  /// same side (0 for two perfectly straight sides, about s_n / 4 for scattered points).
  float maxScore = 1.5F;
  /// Non-maxima suppression radius [m]: a candidate survives only if no better-scoring candidate
  /// lies within this distance. Thesis default 0.20 m.
  float nmsRadius = 0.20F;
  /// Sub-beam refinement: the corner is moved to the intersection of the two side lines when it is
  /// within this distance of the candidate beam point [m]; otherwise the beam point is kept.
  /// Thesis default 0.2 m.
  float subbeamMaxShift = 0.20F;
  /// What happens to a candidate whose two walls meet farther than subbeamMaxShift away. false
  /// (default): it is dropped (it guards against duplicates beside acute corners). true (thesis,
  /// falkolib): it is kept at its beam point, unrefined, after the refined corners, unless the beam
  /// point or the walls' meeting point lies within nmsRadius of an accepted corner. About 1.5-2x
  /// the keypoints on the FLIRTLib logs (docs/falko.md, "Unrefined candidates").
  bool keepFarCorners = false;
  /// Refinement passes 2 and 3 refit each side on the points within this factor times the
  /// neighbourhood radius of the estimated corner (more points at long range, where the
  /// neighbourhood holds only a few).
  float refineRadiusFactor = 2.5F;
  /// ... keeping only points within this distance of the previous pass's line of their side [m]
  /// (rejects other objects and the next wall); a few times the range noise of the sensor.
  float refineInlierDistance = 0.05F;
  /// Straight-wall rejection (addition to the thesis): the candidate is dropped when one line fits
  /// the refinement window with a squared residual at most this factor times that of the best
  /// two-line split. Range noise alone gives ratios near 1; a corner gives tens or more. 0 disables.
  float minCornerResidualRatio = 3.0F;
  /// Candidates closer than this to the sensor are not considered [m] (0: all valid readings).
  float minExtractionRange = 0.0F;
  /// Candidates farther than this are not considered [m] (their neighbourhood is sparse and the
  /// radius large). They are still neighbours of closer candidates.
  float maxExtractionRange = 30.0F;
};

/// True when every field of `p` lies in its documented domain (finite, positive where a size or
/// a radius, gridSectors in [4, 64], refineRadiusFactor >= 1, maxRadiusRangeRatio in (0, 1));
/// FalkoDetector::detect returns InvalidArgument otherwise. Lets a caller check a configuration
/// before the first scan.
bool isValid(const FalkoParams& p) noexcept;
/// The same as a status, as every parameter struct of the library reports it: `Ok` or
/// `InvalidArgument`.
inline Status validate(const FalkoParams& p) noexcept {
  return isValid(p) ? Status::Ok : Status::InvalidArgument;
}

/// The thesis defaults with the three values that the public reference implementation of FALKO
/// sets differently by default: neighA 0.1 m, beta 2.5, nmsRadius 0.1 m. For comparisons with
/// that implementation at equal parameters (its speed figures and repeatability are for these);
/// the reference's relative score threshold has no counterpart, so maxScore keeps its default.
inline FalkoParams falkoReferenceParams() noexcept {
  FalkoParams p;
  p.neighA = 0.1F;
  p.beta = 2.5F;
  p.nmsRadius = 0.1F;
  return p;
}

/// Descriptor parameters (BSC and CGH). The grid sizes are compile-time (kBscRings, kBscSectors,
/// kCghBins in falko_descriptors.hpp): 8 radial x 16 angular for BSC, 16 bins for CGH.
struct FalkoDescriptorParams {
  /// Radius of the disc around the keypoint whose scan points form both descriptors [m].
  /// Thesis default 0.5 m.
  float radius = 0.5F;
  /// Standard deviation of the Gaussian that spreads each point of the CGH over neighbouring
  /// angular bins [bins]. Thesis default 0.6.
  float cghSigmaBins = 0.6F;
};

}  // namespace agv
