#pragma once
/// @file falko_detector.hpp
/// FALKO (Fast Adaptive Laser Keypoint Orientation-invariant) corner detector.

#include <array>
#include <cstddef>

#include "agv/core/capacities.hpp"
#include "agv/core/fixed_vector.hpp"
#include "agv/core/status.hpp"
#include "agv/falko/falko_keypoint.hpp"
#include "agv/falko/falko_params.hpp"
#include "agv/falko/scan_points.hpp"
#include "agv/scan/laser_scan.hpp"

namespace agv {

/// Keypoints of one scan.
using FalkoKeypoints = FixedVector<FalkoKeypoint, kMaxKeypoints>;

/// Detects corners in 2D laser scans.
///
/// For every valid beam (the candidate) the detector takes the valid points within the radius
/// r = a * exp(b * range) in an angular window, splits them into the side before (C_L) and after
/// (C_R) the candidate in beam order, rejects the candidate unless each side has `minSidePoints`
/// and the triangle first-neighbour / candidate / last-neighbour has base and height >= r / beta,
/// then scores it: the side points are binned into s_n polar sectors around the candidate, aligned
/// to the corner orientation, and the score is the mean circular sector distance between points of
/// the same side (0 for two straight sides). Candidates with score <= maxScore are refined:
/// go through a greedy non-maxima suppression, best score first: a candidate within nmsRadius of
/// an accepted corner is suppressed, otherwise it is refined: the points within refineRadiusFactor * r are split in two
/// in beam order where two fitted lines leave the least residual, the lines are intersected (accepted within
/// subbeamMaxShift of the beam point; one line fitting almost as well drops the candidate), and the
/// fit is repeated twice on the points near each line. A candidate whose lines meet farther away
/// is dropped, or with FalkoParams::keepFarCorners kept at its beam point, unrefined (thesis),
/// after the refined corners, unless the beam point or the meeting point lies within nmsRadius of
/// an accepted corner.
/// A candidate whose refinement is rejected suppresses nothing; one that refines to within
/// nmsRadius of an accepted corner is dropped. The orientation is
/// the mean of the directions from the corner to the centroids of its two sides.
///
/// Work per scan is bounded by beams x (window size), with the window bounded by the scan length;
/// the object holds all its buffers (about 190 kB with 2048 beams), so keep it static on an MCU.
/// No heap, no exceptions.
class FalkoDetector {
 public:
  /// `params` are copied; values outside their domain make `detect` return `InvalidArgument`.
  explicit FalkoDetector(const FalkoParams& params = FalkoParams{}) noexcept;

  const FalkoParams& params() const noexcept { return params_; }

  /// Finds the keypoints of `scan` and appends them to `out` after clearing it, in beam order.
  /// Returns Ok; `CapacityExceeded` when `out` could not take every keypoint (the first ones in
  /// beam order are kept, the rest counted in `out.refusedCount()`); `InvalidArgument` for bad
  /// parameters or scan geometry. An empty or all-invalid scan gives Ok and no keypoints.
  /// The scan's points stay available through `points()` for the descriptors.
  Status detect(const LaserScan& scan, IVector<FalkoKeypoint>& out) noexcept;

  /// Same on an already converted scan `pts`.
  Status detect(const ScanPoints& pts, IVector<FalkoKeypoint>& out) noexcept;

  /// Points of the last scan given to `detect(const LaserScan&, ...)`.
  const ScanPoints& points() const noexcept { return points_; }

  /// Number of candidates that passed the side, triangle and score tests in the last call
  /// (before non-maxima suppression); for diagnostics.
  std::size_t lastCandidateCount() const noexcept { return candidateCount_; }

  /// Entries of the score histogram buffer: up to 2 interleaved copies of 64 sectors.
  static constexpr std::size_t kHistSize = std::size_t{2} * 64U;

 private:
  struct Side {
    std::size_t count = 0;
    float sumX = 0.0F;
    float sumY = 0.0F;
  };
  /// Gathers the neighbours of beam i into left/right buffers (coordinates relative to the
  /// candidate) from the beams at most kLeft before and kRight after it (the offsets of the
  /// farthest neighbours); returns false when a side has too few points.
  bool gather(const ScanPoints& pts, std::size_t i, float radius, std::size_t kLeft, std::size_t kRight, Side& left,
              Side& right) noexcept;
  /// One side of gather: the points within sqrt(r2) of beam i among the k beams in direction dir
  /// (-1: before, +1: after), nearest first, relative to the candidate, written to (xs, ys).
  static Side gatherSide(const ScanPoints& pts, std::size_t i, int dir, std::size_t k, float r2, float* xs,
                         float* ys) noexcept;
  float scoreOf(const Side& left, const Side& right, float c, float s) noexcept;
  /// What the sub-beam refinement made of a candidate.
  enum class RefineOutcome {
    Accepted,   ///< kp holds the corner (refined, or the beam point when no lines fit)
    Rejected,   ///< one line explains the points around the candidate: a wall, dropped
    FarCorner,  ///< the two walls meet farther than subbeamMaxShift away; (kp.x, kp.y) = that point
  };
  /// Sub-beam refinement and orientation of candidate i.
  /// (sideX, sideY): sum of the side centroids relative to the candidate (orientation fallback).
  RefineOutcome refine(const ScanPoints& pts, std::size_t i, float sideX, float sideY, FalkoKeypoint& kp) noexcept;

  // The stages of detect, in order.
  /// Neighbourhood radius (radius_) and beam window (window_, 0 for beams that are no candidate)
  /// of every beam.
  void radiiAndWindows(const ScanPoints& pts) noexcept;
  /// Early rejection of every beam by the triangle test, which needs only the first (front) and
  /// last (back) neighbours, found from the window edges inwards; most beams (walls) stop here.
  /// Marks every beam not a candidate in score_; lists the survivors in order_ with their side
  /// extents packed in window_ (kLeft << 16 | kRight). Returns the number of survivors.
  std::size_t rejectEarly(const ScanPoints& pts) noexcept;
  /// Early rejection of the beams [begin, end) one at a time; survivors appended to order_ after
  /// the first `survivors`. Returns the new number of survivors.
  std::size_t rejectOneByOne(const ScanPoints& pts, std::size_t begin, std::size_t end, float invBeta,
                             std::size_t survivors) noexcept;
  /// Early rejection of the beams in groups of four in lockstep (falko_detail::farthestWithin4),
  /// one at a time in the groups where a window reaches a scan end; survivors listed in order_.
  /// `next`: the first beam not handled (fewer than four left). Returns the number of survivors.
  std::size_t rejectInFours(const ScanPoints& pts, float invBeta, std::size_t& next) noexcept;
  /// Sides, orientation and score of the survivors; the candidates (score <= maxScore) get their
  /// score in score_ and their side sums in sideX_/sideY_. Returns the number of candidates.
  std::size_t scoreSurvivors(const ScanPoints& pts, std::size_t survivors) noexcept;
  /// Lists the candidates among the n beams in order_, best score first (ties to the lower beam
  /// index); returns their number.
  std::size_t candidatesByScore(std::size_t n) noexcept;
  /// Greedy non-maxima suppression of the first `candidates` of order_: a candidate whose beam
  /// point lies within nmsRadius of an accepted corner is suppressed; otherwise it is refined, and
  /// accepted unless the refinement rejects it or it lands within nmsRadius of an accepted corner.
  /// A rejected candidate suppresses nothing, so the next best candidate of the same corner gets
  /// its turn. Candidates whose walls meet farther than subbeamMaxShift away are dropped, or with
  /// keepFarCorners set aside and accepted afterwards at their beam point, unrefined, unless that
  /// point or the meeting point lies within nmsRadius of an accepted corner.
  /// O(candidates x accepted). Returns the number accepted (in cands_).
  std::size_t suppressAndRefine(const ScanPoints& pts, std::size_t candidates) noexcept;
  /// True when (x, y) lies within sqrt(nms2) of one of the first `kept` accepted corners.
  bool nearAccepted(float x, float y, std::size_t kept, float nms2) const noexcept;
  /// Appends the `kept` accepted corners to `out` in beam order.
  Status emitInBeamOrder(std::size_t kept, IVector<FalkoKeypoint>& out) noexcept;

  FalkoParams params_;
  ScanPoints points_;
  std::array<float, kMaxScanBeams> leftX_{};
  std::array<float, kMaxScanBeams> leftY_{};
  std::array<float, kMaxScanBeams> rightX_{};
  std::array<float, kMaxScanBeams> rightY_{};
  std::array<float, kMaxScanBeams> score_{};           ///< per beam; +inf when not a candidate
  std::array<float, kMaxScanBeams> radius_{};          ///< per beam neighbourhood radius
  std::array<std::uint32_t, kMaxScanBeams> window_{};  ///< per beam window in beams, 0: no candidate
  std::array<float, kMaxScanBeams> sideX_{};           ///< per beam sum of the side centroids (relative)
  std::array<float, kMaxScanBeams> sideY_{};
  std::array<std::uint32_t, kMaxScanBeams> order_{};  ///< candidates by score
  std::array<FalkoKeypoint, kMaxScanBeams> cands_{};  ///< accepted keypoints
  std::array<std::uint32_t, kHistSize> hist_{};       ///< score histograms (interleaved copies), zero between uses
  std::size_t candidateCount_ = 0;
};

}  // namespace agv
