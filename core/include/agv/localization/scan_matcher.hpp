#pragma once
/// @file scan_matcher.hpp
/// Scan-to-map matching against a `LikelihoodFieldBase`: the pose at which the scan's points lie
/// on the mapped surfaces, found by robust Gauss-Newton from a prior pose, with the covariance
/// the alignment supports. It is the localizer's second observation next to point landmarks
/// (docs/localization.md, "Scan matching"): a corridor constrains the pose across it and not
/// along it, and the covariance says so, so the EKF takes from each scan only what it can tell.
///
/// Model: scan point p_i (laser frame) maps to world point q_i(x) = x ⊕ l ⊕ p_i for the vehicle
/// pose x and the laser mounting l; residual r_i = D(q_i), D the field's signed distance. Points farther
/// than `inlierDistance` from every surface (or outside the field) are not on the map and weigh 0;
/// the others weigh by Huber's function with threshold `huber`.
///
/// Covariance: sigma^2 (J^T W J)^-1 x `covarianceInflation`, with sigma^2 the weighted residual
/// variance (floored at `sigmaFloor`^2). Neighbouring points on one wall share the wall's map
/// error, so they are not independent measurements: the points are thinned to `pointSpacing`
/// apart (two cells of the default field) and the inflation covers the correlation left.
///
/// Heap-free; the matcher holds its point scratch inline (kMaxScanBeams points, 16 KB). Work per
/// call: at most kMaxScanBeams points x `maxIterations` field samples, plus the coarse search's
/// `maxSearchPoses` x points.

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <limits>

#include "agv/core/capacities.hpp"
#include "agv/core/fixed_vector.hpp"
#include "agv/core/pose2.hpp"
#include "agv/core/status.hpp"
#include "agv/localization/likelihood_field.hpp"
#include "agv/scan/laser_scan.hpp"

namespace agv {

/// One scan point in the laser frame [m] (float: a laser's noise is far above float resolution).
struct MatchPoint {
  float x = 0.0F;
  float y = 0.0F;
};
/// The points of one scan, for scans that must be de-skewed first (each beam moved to the sensor
/// frame at one instant with the motion during the sweep, `SweepCompensation::atBeam`).
using MatchPoints = FixedVector<MatchPoint, kMaxScanBeams>;

/// The valid beams of `scan` (`LaserScan::isValid`) no farther than `maxRange` [m], as points in
/// the laser frame in beam order, into `out` (cleared first). No motion correction: the points of
/// a scan taken at rest, or whose sweep has been de-skewed already.
void scanToMatchPoints(const LaserScan& scan, MatchPoints& out,
                       double maxRange = std::numeric_limits<double>::infinity()) noexcept;

/// Parameters of the scan matcher.
struct ScanMatchParams {
  std::uint8_t maxIterations = 20;  ///< Gauss-Newton iterations at most
  /// [m] scan points closer than this to the previous point kept are skipped (decorrelation and
  /// bounded work); 0 keeps every valid beam.
  double pointSpacing = 0.10;
  /// [m] points farther than this from the nearest surface are outliers (weight 0). Must not
  /// exceed the field's maxDistance (the field cannot tell farther distances apart).
  double inlierDistance = 0.30;
  double huber = 0.05;  ///< [m] Huber threshold of the residual weights
  /// After convergence, one more Gauss-Newton run in a band of 3 robust sigmas of this match's
  /// own residuals (1.4826 x their median; at least 3 `sigmaFloor`): points on surfaces that
  /// moved or were never mapped, which the wide band keeps, stop biasing the pose. The result
  /// (pose, covariance) is that run's when it converges with `minInliers`; the checks on the
  /// fit (`minInlierFraction`, `maxRmsResidual`) and the covariance are the wide band's. Off by
  /// default: measured as an option (docs/localization.md, "Adaptive band").
  bool adaptiveBand = false;
  /// Fewer inliers than this (absolute, and as a fraction of the points) refuse the match.
  std::size_t minInliers = 30;
  double minInlierFraction = 0.40;
  /// [m] a converged match whose inliers fit worse than this (RMS) is refused (`IllConditioned`):
  /// a scan that overlaps the map only in part finds accidental inliers inside the band, spread
  /// uniformly (RMS inlierDistance / sqrt(3) = 17 cm at 0.3 m), where a true alignment leaves
  /// the range noise and the map's own error (median 5..7 cm, 90th percentile 8..12 cm on the
  /// real logs, docs/localization.md). The limit admits most true alignments; the localizer's
  /// gate backs it up, and only `resyncMaxRms` lets a match past the gate.
  double maxRmsResidual = 0.10;
  /// [m] floor of the residual standard deviation used for the covariance (map quantisation at
  /// 5 cm cells, res / sqrt(12) = 1.4 cm, plus range noise).
  double sigmaFloor = 0.02;
  /// Multiplier of the covariance for the correlation of neighbouring points (see the file
  /// comment); docs/localization.md gives the NEES it yields on real logs.
  double covarianceInflation = 4.0;
  /// Fit scatter (used by the localizer): the covariance above says how well the points fit the
  /// map, and shrinks with their number; a map that is off where the scan looks (surfaces that
  /// moved, a mapping run's own pose error) moves every point the same way, and no number of
  /// points averages that out. The pose of a match is then known no better than its inliers fit:
  /// the localizer adds (fitScatter x rmsResidual)^2 to each position variance and
  /// (fitScatter x rmsResidual / lever)^2 to the heading variance of the match it fuses
  /// (`ScanMatchResult::lever`). 0 (the default): the covariance alone, as on a vehicle whose map
  /// was surveyed with it; the real-log replay uses 0.5 (docs/localization.md, "Fit scatter").
  /// The re-synchronisation's hypothesis keeps its own scatter (`resyncMatchSigma*`).
  double fitScatter = 0.0;
  /// Convergence: stop when a step is below both [m] and [rad] (a tenth of the 2 cm / 0.1 deg
  /// requirement), or when no step along the Gauss-Newton direction (halved up to 5 times) lowers
  /// the robust cost.
  double stepTranslation = 2e-3;
  double stepRotation = 1.7e-4;
  /// [m], [rad]: a match that moved the pose farther than this (or than the search window, when
  /// larger) from the prior is refused (the basin of a truncated field is about `inlierDistance`;
  /// beyond it a match is a guess).
  double maxCorrection = 0.5;
  double maxRotation = 0.2;
  /// Coarse search before the refinement, when the prior is uncertain (the basin of the truncated
  /// field is about `inlierDistance` in position and a few degrees in heading): with the prior's
  /// covariance, every pose on a grid over +-`searchSigmas` standard deviations (capped at
  /// `maxSearchTranslation` and `maxSearchRotation`) in steps of `searchStepTranslation` and
  /// `searchStepRotation` is scored with the robust cost, and the refinement starts from the best.
  /// Skipped when the window is within one step each way. Work: at most `maxSearchPoses` poses x
  /// the points (the steps grow to keep to it).
  double searchSigmas = 3.0;
  double maxSearchTranslation = 0.6;   ///< [m]
  double maxSearchRotation = 0.35;     ///< [rad] (20 deg)
  double searchStepTranslation = 0.1;  ///< [m]
  double searchStepRotation = 0.01;    ///< [rad] (a point at 10 m moves 10 cm)
  std::size_t maxSearchPoses = 20000;
  /// Re-synchronisation (used by the localizer): a match the gate refuses means the prior and the
  /// map disagree. One such match may be wrong, so it only starts a hypothesis: a pose filter of
  /// its own, at the match with its covariance, carried to each later scan by the odometry with
  /// the odometry's noise model (not by the main filter, whose corrections are no motion). A later
  /// match confirms it when it passes the hypothesis' gate (`LocalizerParams::scanMatchGate`, the
  /// vehicle has moved by what odometry says within what odometry can be wrong by, and the map
  /// keeps placing it there); it is then fused into the hypothesis. When the tracking match,
  /// searched around the main filter's estimate, does not confirm it, a second match is run at the
  /// hypothesis over the window of its covariance (so a cycle runs the matcher at most twice).
  /// `resyncAfter` matches in a row (the first included) mean the prior is wrong (a slip the
  /// odometry model did not cover): the main filter is reset to the hypothesis. A scan the
  /// matcher cannot use (too few points, off the map), or a match at the hypothesis that passes
  /// its gate but fits worse than `resyncMaxRms`, carries the hypothesis on without counting; a
  /// good match elsewhere replaces it; a match at the hypothesis that fails its gate ends it.
  /// 0 disables it. Three, because a wrong match that repeats three times while the vehicle moves
  /// is a map that is locally ambiguous, which the gate cannot tell either.
  std::uint8_t resyncAfter = 3;
  /// [m], [rad] 1-sigma scatter of a real match around the true pose beyond its covariance (the
  /// covariance says how well the points fit the map, not how well the map fits the world), added
  /// to each match the hypothesis takes: the matcher's median error against the corrected poses
  /// of the real logs is 3-6 cm and 0.2-0.5 deg (docs/localization.md, "Scan matching on real
  /// logs").
  double resyncMatchSigma = 0.04;
  double resyncMatchSigmaAngle = 0.008;
  /// [m] a match bypasses the gate only through the resync, and only when its inliers fit at
  /// least this well (RMS): far stricter than `maxRmsResidual`, which the gate backs up.
  double resyncMaxRms = 0.06;
  /// A match counts for the re-synchronisation only with at least this many inliers: a match
  /// that overrules the filter needs more support than one the filter agrees with. 0 (the
  /// default): `minInliers`, as for tracking.
  std::size_t resyncMinInliers = 0;
  /// Soft gate (used by the localizer): a match the gate refuses that fits within `resyncMaxRms`
  /// is fused with the innovation covariance scaled up to just inside the gate instead of being
  /// dropped, so it moves the pose by the gated correction times gate / d^2: a few of the
  /// filter's own sigmas per cycle at most, never a jump. For a map with no authority over the
  /// filter (a `SurfaceMap`, `surfaceMapMatching`), whose matches must not reset it but which
  /// may tell a filter that became overconfident (odometry errors its model does not cover) where
  /// it drifts. Off by default: against a surveyed map the re-synchronisation decides.
  bool softGate = false;
  /// Recovery (used by the localizer): the prior's covariance bounds the search, so a filter that
  /// has drifted while believing itself (refused matches and wrong corner fixes shrink the
  /// covariance while the pose walks off) can no longer find the map. After `widenAfter` cycles in
  /// a row whose match was refused or gated, the search window is widened: doubled per further
  /// such cycle from `recoveryTranslation` / `recoveryRotation` up to `maxRecoveryTranslation` /
  /// `maxRecoveryRotation` (beyond the tracking caps above). The work stays bounded by
  /// `maxSearchPoses`; a match found this way is fused only through the gate or the
  /// re-synchronisation above (three agreeing matches), never on its own. 0 disables it.
  std::uint8_t widenAfter = 2;
  double recoveryTranslation = 0.3;     ///< [m] half-width of the first widened window
  double recoveryRotation = 0.1;        ///< [rad]
  double maxRecoveryTranslation = 2.0;  ///< [m]
  double maxRecoveryRotation = 0.6;     ///< [rad] (34 deg)
  /// `Ok`, `NonFiniteInput`, or `InvalidArgument` (zero iterations, a negative spacing,
  /// non-positive distances, sigma, inflation, step bounds or agreement bounds, a fraction outside
  /// [0, 1], a negative fit scatter).
  Status validate() const noexcept;
};

/// Half-widths of the coarse search around the prior [m, m, rad] (0: no search on that axis).
struct SearchWindow {
  double x = 0.0;
  double y = 0.0;
  double theta = 0.0;
};

/// The outcome of one match.
struct ScanMatchResult {
  /// Ok; EmptyInput (no valid beam); NotInitialized (field not built); NotEnoughData (too few
  /// inliers); Unobservable (the inliers do not constrain all three dof); NotConverged;
  /// IllConditioned (the inliers fit worse than maxRmsResidual);
  /// OutOfRange (moved beyond maxCorrection / maxRotation); NonFiniteInput (prior or mounting).
  Status status = Status::EmptyInput;
  std::uint8_t iterations = 0;
  std::uint16_t points = 0;                                  ///< scan points used (after thinning)
  std::uint16_t inliers = 0;                                 ///< within inlierDistance at the end
  std::uint32_t searched = 0;                                ///< poses scored by the coarse search (0: none)
  Pose2d pose{};                                             ///< vehicle pose (world frame)
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();  ///< of `pose` [m^2, rad^2]
  double rmsResidual = 0.0;                                  ///< [m] over the inliers at the end
  /// [m] RMS distance of the points used from the vehicle origin (the heading's lever arm for
  /// `ScanMatchParams::fitScatter`); computed only when that is above 0, else 0.
  double lever = 0.0;
};

/// The matcher (scratch only; holds no map).
class ScanMatcher {
 public:
  ScanMatcher() noexcept = default;
  explicit ScanMatcher(const ScanMatchParams& params) noexcept : params_(params) {}
  ScanMatcher(const ScanMatcher&) = delete;
  ScanMatcher& operator=(const ScanMatcher&) = delete;

  /// Aligns `scan` (ranges in the laser frame, taken at vehicle pose ~`prior`) with `field` through
  /// the laser mounting `laser` (laser pose in the vehicle frame). The scan is treated as taken at
  /// one instant (de-skew it before if the vehicle moves during the sweep).
  ScanMatchResult match(const LaserScan& scan, const Pose2d& laser, const Pose2d& prior,
                        const LikelihoodFieldBase& field) noexcept;

  /// The same with the prior's covariance: first the coarse search over the window it spans (see
  /// `searchSigmas`), then the refinement from the best pose found. `NonFiniteInput` for a
  /// non-finite covariance.
  ScanMatchResult match(const LaserScan& scan, const Pose2d& laser, const Pose2d& prior,
                        const Eigen::Matrix3d& priorCovariance, const LikelihoodFieldBase& field) noexcept;

  /// The same with the scan given as points in the laser frame (already de-skewed, in scan order
  /// for the thinning; non-finite points are skipped).
  ScanMatchResult match(const MatchPoints& points, const Pose2d& laser, const Pose2d& prior,
                        const Eigen::Matrix3d& priorCovariance, const LikelihoodFieldBase& field) noexcept;

  /// The same with an explicit search window (not capped by `maxSearchTranslation` /
  /// `maxSearchRotation`; the work is still bounded by `maxSearchPoses`): the recovery search.
  /// A match may move the pose as far as the window reaches.
  ScanMatchResult match(const LaserScan& scan, const Pose2d& laser, const Pose2d& prior, const SearchWindow& window,
                        const LikelihoodFieldBase& field) noexcept;
  ScanMatchResult match(const MatchPoints& points, const Pose2d& laser, const Pose2d& prior, const SearchWindow& window,
                        const LikelihoodFieldBase& field) noexcept;

  /// The robust cost (the refinement's objective: Huber's cost of each thinned point's field
  /// distance, an outlier at the cost of `inlierDistance`) of `scan` taken at vehicle pose `x`
  /// through the laser mounting `laser`. It compares poses for one scan: the lower, the better the
  /// scan lies on the map. NaN when the scan has no point, or an input is not finite or the field
  /// not built.
  double costAt(const LaserScan& scan, const Pose2d& laser, const Pose2d& x, const LikelihoodFieldBase& field) noexcept;
  double costAt(const MatchPoints& points, const Pose2d& laser, const Pose2d& x,
                const LikelihoodFieldBase& field) noexcept;

  /// The tracking window of a prior covariance: +-`searchSigmas` standard deviations per axis,
  /// capped at `maxSearchTranslation` and `maxSearchRotation` (zero for a non-finite covariance).
  SearchWindow searchWindow(const Eigen::Matrix3d& priorCovariance) const noexcept;

  const ScanMatchParams& params() const noexcept { return params_; }
  void setParams(const ScanMatchParams& params) noexcept { params_ = params; }

 private:
  /// Finite prior, mounting and covariance, and a built field; false with `result` saying why.
  bool checkInput(const Pose2d& laser, const Pose2d& prior, const Eigen::Matrix3d& priorCovariance,
                  const LikelihoodFieldBase& field, ScanMatchResult& result) const noexcept;
  /// The scan's points in the vehicle frame, thinned; false (status set) when there are none.
  bool collectPoints(const LaserScan& scan, const Pose2d& laser, ScanMatchResult& result) noexcept;
  bool collectPoints(const MatchPoints& points, const Pose2d& laser, ScanMatchResult& result) noexcept;
  /// Appends a vehicle-frame point unless within pointSpacing of the last one kept.
  void keepPoint(const Eigen::Vector2d& p) noexcept;
  /// `costAt` for either scan type.
  template <typename Scan>
  double costOf(const Scan& scan, const Pose2d& laser, const Pose2d& x, const LikelihoodFieldBase& field) noexcept;
  /// The explicit-window match of either scan type (`LaserScan` or `MatchPoints`).
  template <typename Scan>
  ScanMatchResult matchInWindow(const Scan& scan, const Pose2d& laser, const Pose2d& prior, const SearchWindow& window,
                                const LikelihoodFieldBase& field) noexcept;
  /// Search and refinement once the points are collected.
  ScanMatchResult searchAndRefine(const Pose2d& prior, const SearchWindow& window, const LikelihoodFieldBase& field,
                                  ScanMatchResult result) noexcept;
  /// `inlierDistance`, capped at the field's saturation distance.
  double effectiveInlierDistance(const LikelihoodFieldBase& field) const noexcept;
  /// Robust cost of the points at pose `x` (the refinement's objective, without derivatives).
  /// Every point adds a non-negative term, so the sum is abandoned once it reaches `bound`: the
  /// value returned is then a partial sum at least `bound` (the search only asks whether a pose
  /// beats the best so far, and gets the same answer).
  double cost(const Pose2d& x, const LikelihoodFieldBase& field,
              double bound = std::numeric_limits<double>::infinity()) const noexcept;
  /// The coarse search around `prior` over +-(wx, wy, wt); the best pose (prior when no better).
  Pose2d search(const Pose2d& prior, double wx, double wy, double wt, const LikelihoodFieldBase& field,
                std::uint32_t& scored) const noexcept;
  /// Gauss-Newton from `start`; `prior` and `allowed` for the maxCorrection check.
  ScanMatchResult refine(const Pose2d& prior, const Pose2d& start, double allowedTranslation, double allowedRotation,
                         const LikelihoodFieldBase& field) noexcept;

  /// The band of the final run: 3 robust sigmas of the inliers' residuals at `x`.
  double residualBand(const Pose2d& x, const LikelihoodFieldBase& field, double inlierDistance) noexcept;

  ScanMatchParams params_{};
  MatchPoints points_;                             // vehicle frame, thinned
  FixedVector<float, kMaxScanBeams> residuals_{};  // |residual| of the inliers, for the band
};

}  // namespace agv
