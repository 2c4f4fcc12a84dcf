#pragma once
/// @file keypoint_alignment.hpp
/// Laser egomotion between the two standstill scans of a calibration segment from FALKO keypoints,
/// for sites without reflectors: descriptor-based candidate matches, a bounded RANSAC over pairs of
/// candidates (deterministic generator) for the consensus, then the closed-form least squares of
/// `fitRigid2d` (the solver of the reflector alignment) on the consensus set, re-associated a few
/// times.
///
/// Precision: double for the motion and the fit (the calibration's noise floor is millimetres over
/// 10 m lever arms); the keypoints arrive as float (scan geometry) and are widened once.
/// Work: O(M N) descriptor distances to form the candidates, maxDraws length tests, then
/// O(maxHypotheses M K) for the consensus, M, N <= kMaxKeypoints, K <= kMaxKeypointCandidates.
/// About 20 kB of stack, no heap.

#include <cstddef>
#include <cstdint>

#include "agv/core/pose2.hpp"
#include "agv/core/span.hpp"
#include "agv/core/status.hpp"
#include "agv/falko/falko_descriptors.hpp"
#include "agv/falko/falko_keypoint.hpp"

namespace agv {

/// Largest number of candidate partners kept per keypoint of the second scan.
inline constexpr std::size_t kMaxKeypointCandidates = 16;

/// Which descriptor forms the candidate matches.
enum class KeypointDescriptor : std::uint8_t {
  Bsc,  ///< binary shape context, Hamming-like distance (0..128 cells)
  Cgh,  ///< circular Gaussian histogram, chi-square distance (0..1)
};

/// The keypoints of one scan and their descriptors (same order; the descriptor not selected by
/// KeypointAlignmentOptions::descriptor may be an empty span).
struct KeypointScanView {
  Span<const FalkoKeypoint> keypoints;
  Span<const BscDescriptor> bsc;
  Span<const CghDescriptor> cgh;
};

/// Matching and consensus settings.
struct KeypointAlignmentOptions {
  KeypointDescriptor descriptor = KeypointDescriptor::Bsc;
  /// Largest BSC distance of a candidate match [cells of 128]. Views of the same corner from
  /// metres apart differ by a few tens of cells (occlusions, beam density).
  std::uint32_t maxBscDistance = 40;
  /// Largest CGH distance of a candidate match (0 identical .. 1 disjoint).
  float maxCghDistance = 0.3F;
  /// Candidate partners kept per keypoint of the second scan, best descriptor first
  /// (1..kMaxKeypointCandidates). Corners of a building look alike (right angles), so the true
  /// partner is often not the best descriptor match: keep many.
  std::size_t candidatesPerKeypoint = 16;
  /// Only keypoints whose sub-beam refinement was accepted take part: an unrefined corner sits on
  /// the beam nearest to it, up to a beam spacing away (4 cm at 10 m with 0.25 deg), and which
  /// beam that is depends on the viewpoint.
  bool refinedOnly = true;
  /// A match is consistent with a motion when the mapped second keypoint lies within this distance
  /// of its partner [m]: a few times the keypoint position noise (about the range noise).
  double inlierGate = 0.08;
  /// Two candidates drawn for a hypothesis must be at least this far apart in the second scan [m]
  /// (a short base gives a poorly determined rotation).
  double minBaseline = 0.5;
  /// Fewest consistent matches accepted (at least 3: two define any motion).
  std::size_t minInliers = 4;
  /// Bound on pairs of candidate matches tried (a length comparison each); when all pairs are
  /// fewer, all are tried in order, else this many are drawn.
  int maxDraws = 100000;
  /// Bound on hypotheses scored (pairs whose lengths agree; an association pass each).
  int maxHypotheses = 2000;
  /// Seed of the deterministic generator drawing the pairs (same inputs, same result).
  std::uint64_t seed = 0x5DEECE66DULL;
  /// Re-association + least-squares passes on the consensus set (at least 1).
  int refinementPasses = 3;
  /// Hypotheses whose motion differs from the guess by more than these are discarded [m, rad];
  /// infinity (the default) accepts any motion. A guess from the nominal odometry resolves the
  /// symmetric rooms where two motions explain the corners equally well.
  double guessTranslationGate = 1.0e300;
  double guessRotationGate = 1.0e300;
};

/// The estimated motion and how well it is supported.
struct KeypointAlignment {
  /// Pose of the laser at the second scan expressed in its frame at the first one
  /// (a point q of the second scan lies at motion.transformPoint(q) in the first).
  Pose2d motion{};
  std::size_t candidates = 0;  ///< candidate matches formed from the descriptors
  std::size_t inliers = 0;     ///< matches consistent with the final motion (used in its fit)
  double rms = 0.0;            ///< RMS distance of the inliers after alignment [m]
  int hypotheses = 0;          ///< hypotheses evaluated
};

/// Aligns the keypoints of `second` onto those of `first` (sensor frames of the two scans).
/// `guess` is used only through the guess gates of the options.
/// Returns Ok; InvalidArgument for bad options or descriptor spans whose size differs from their
/// keypoints'; EmptyInput when a scan has no keypoint; CapacityExceeded above kMaxKeypoints
/// keypoints; NonFiniteInput for NaN/inf keypoints or guess; NotEnoughData when fewer than
/// minInliers consistent matches exist (too few corners, or corners that do not match).
/// `out` holds the best estimate found in every case (the guess when none).
Status alignKeypoints(const KeypointScanView& first, const KeypointScanView& second, const Pose2d& guess,
                      const KeypointAlignmentOptions& options, KeypointAlignment& out) noexcept;

}  // namespace agv
