#pragma once
/// @file localizer.hpp
/// The vehicle localizer: a `PoseEkf` driven by odometry increments and corrected once per laser
/// cycle by point observations associated (nearest neighbour, Mahalanobis-gated) with a
/// `LandmarkMap`, whose lifecycle it then runs. It keeps an odometry history so that a scan whose
/// timestamp lags the odometry is fused at its own time and the newer odometry re-applied
/// (docs/localization.md, "Latency"). Every cycle yields a `LocalizerHealth` for the PLC.
///
/// Heap-free; the object holds its history and per-cycle scratch inline (~32 KB): give it static
/// storage or allocate it once. Worst-case work per cycle is bounded by kMaxObservations,
/// kMaxOdometryHistory and the grid query bounds of `LandmarkMap`.

#include <Eigen/Core>
#include <cstdint>

#include "agv/core/capacities.hpp"
#include "agv/core/fixed_ring.hpp"
#include "agv/core/fixed_vector.hpp"
#include "agv/core/pose2.hpp"
#include "agv/core/status.hpp"
#include "agv/core/timestamp.hpp"
#include "agv/localization/chi_square.hpp"
#include "agv/localization/landmark_map.hpp"
#include "agv/localization/odometry.hpp"
#include "agv/localization/pose_ekf.hpp"
#include "agv/localization/scan_matcher.hpp"
#include "agv/scan/laser_scan.hpp"

namespace agv {

/// One point detection in the laser frame.
struct PointObservation {
  double x = 0.0;  ///< [m], laser frame (x forward)
  double y = 0.0;  ///< [m], laser frame (y left)
  LandmarkKind kind = LandmarkKind::Reflector;
};

/// The detections of one scan.
struct ScanObservations {
  Timestamp stamp;  ///< acquisition time of the scan on the odometry's clock
  /// Kinds the detectors looked for in this scan (landmark kind bits); only landmarks of these
  /// kinds lose a hit when in view and not matched.
  std::uint8_t kindsDetected = kAllLandmarkKinds;
  FixedVector<PointObservation, kMaxObservations> points;
};

/// The laser as the localizer sees it.
struct LaserModel {
  Pose2d mounting{};              ///< calibrated laser pose l in the logical-point frame
  double rangeMin = 0.3;          ///< [m] closest valid detection
  double rangeMax = 30.0;         ///< [m] farthest valid detection
  double angleMin = -2.35619449;  ///< [rad] field of view start (-135 deg)
  double angleMax = 2.35619449;   ///< [rad] field of view end (+135 deg)
  double rangeSigma = 0.005;      ///< [m] range noise of a point detection
  double bearingSigma = 0.0005;   ///< [rad] bearing noise of a point detection (0.03 deg)
  /// Extra isotropic position noise per kind [m]: a reflector centre is well defined (0), a corner
  /// apex from FALKO's sub-beam refinement less so.
  double kindSigma[kLandmarkKindCount] = {0.0, 0.01};
  /// `Ok`, `NonFiniteInput`, or `InvalidArgument` (rangeMin negative or not below rangeMax,
  /// angleMin not below angleMax, a negative sigma).
  Status validate() const noexcept;
};

/// Association of observations with map landmarks.
struct AssociationParams {
  /// Squared-Mahalanobis gate for association and update (2 dof, 99 %).
  double gate = kChiSquare2Dof99;
  /// Largest association search radius [m] (bounds the work when the pose is uncertain).
  double maxSearchRadius = 1.0;
  /// Landmark variance assumed when sizing the search radius [m^2].
  double searchLandmarkVariance = 0.05 * 0.05;
  /// An observation whose second-best candidate is also inside the gate and within this much
  /// squared Mahalanobis distance of the best (a likelihood ratio below exp(margin/2) = 7.4) is
  /// ambiguous and not used. 0 disables the test.
  double ambiguityMargin = 4.0;
  /// Minimum support while uncertain: when the prior's position sigma (largest axis) exceeds
  /// `supportSigma` [m], the landmarks correct only when at least `minSupport` observations of the
  /// cycle can correct (matched to landmarks that may correct); otherwise they are held back
  /// (`SupportRejected`). A single observation cannot cross-check its own association, and with
  /// the gate as wide as an uncertain prior makes it, a wrong one moves the pose by up to 3 sigma
  /// (0.9 m from one corner on intel, docs/localization.md). A fused scan match is support enough.
  /// minSupport 1: off. 0.2 m: measured on the four corrected logs (docs/localization.md,
  /// "Minimum support").
  double supportSigma = 0.2;
  std::uint16_t minSupport = 2;
  /// Against a static map with a likelihood field (`correct` given one), minimum support applies
  /// whatever the prior's sigma in every cycle whose scan match was not fused: the field is the
  /// map's main observation, and while it cannot fix the pose (a room that changed since the
  /// mapping run, a scan off the map) the filter's covariance is checked by nothing, so a single
  /// corner associated with the wrong landmark keeps the estimate off by metres while it shrinks
  /// the covariance (fr079: docs/localization.md, "Field support and the field check"). A dynamic
  /// map's corners are its main observation and keep `supportSigma`. false: `supportSigma` alone.
  bool fieldSupport = true;
  /// Cross-check against the likelihood field: when `correct` is given a field and the scan's
  /// match was not fused, the landmarks' correction is undone (`FieldRejected`) when the scan fits
  /// the field worse at the corrected pose than at the prior by more than this gate allows. The
  /// matcher's robust cost (`ScanMatcher::costAt`) is read as a negative log-likelihood of the scan
  /// with the Huber threshold as the point sigma and the matcher's covariance inflation for the
  /// correlation of neighbouring points: undone when 2 x (cost after - cost before) / (huber^2 x
  /// inflation) exceeds the gate. A corner associated with the wrong landmark moves the pose off the
  /// surfaces the scan sees; a right one moves it onto them, or along a corridor, which the field
  /// cannot tell and does not refuse. Default: 3 dof, 99 %. 0 disables it.
  double fieldCheckGate = kChiSquare3Dof99;
  /// `Ok`, `NonFiniteInput`, or `InvalidArgument` (gate, search radius or variance not positive,
  /// negative margin, support sigma or field-check gate, minSupport zero).
  Status validate() const noexcept;
};

/// Which landmarks count as in view (and so are expected, or weakened when missed).
struct OcclusionParams {
  /// A landmark counts as "in view" (may lose a hit) only this far inside the range limits [m]...
  double viewRangeMargin = 0.5;
  /// ...and this far inside the angular limits [rad].
  double viewAngleMargin = 0.035;
  /// Occlusion (only when `correct` is given the scan's ranges): a landmark inside the view limits
  /// counts as in view only if a valid beam at its predicted bearing b measured at least
  /// r - tolerance, r its predicted range from the laser (`farthestReturnNear`). Otherwise a nearer
  /// object blocks the line of sight (or nothing returned there): the landmark is not expected, and
  /// not weakened once confirmed (`minHitsConfirmed`). tolerance = occlusionSigmas * sigma + occlusionKindDepth[kind]
  /// + r * angleIncrement, where sigma^2 = rangeSigma^2 + kindSigma^2 + landmark variance + the
  /// pose covariance projected on the ray (the standard deviation of measured minus predicted
  /// range when the landmark is visible), and r * angleIncrement allows for the beam nearest to the
  /// landmark hitting a surface that ends at it (a corner's side seen at >= 27 deg incidence).
  /// false: range and angle limits only (as without a scan).
  bool enabled = true;
  /// Sigma multiple of the occlusion tolerance (3: a visible landmark is taken for occluded with
  /// probability 0.13 % from noise alone).
  double sigmas = 3.0;
  /// How far in front of its point a landmark's own surface returns the beam [m], per kind: a
  /// reflector pole's radius (poles are 40..50 mm in radius; a flat reflector needs 0), a corner
  /// apex lies on the surface (0).
  double kindDepth[kLandmarkKindCount] = {0.05, 0.0};
  /// A landmark formed by two surfaces (a corner) is detectable only where both are seen: with the
  /// scan's ranges, a landmark of a kind with a support radius > 0 is *expected* by the
  /// matched/expected check only if at least `occlusionSupportPoints` valid scan points lie within
  /// that radius of its predicted position on each side of its bearing (`sideSupport`). A corner
  /// in the line of sight whose one face is turned away (seen from outside its outer quadrant), or
  /// a point where the beams find no surface at all, is still weakened (it is in view and cannot be
  /// matched from here) but not expected. Per kind [m]: reflectors 0 (off); corners 0.2 = FALKO's
  /// smallest neighbourhood radius (a = 0.2 m), whose sides need 2 points each.
  double supportRadius[kLandmarkKindCount] = {0.0, 0.2};
  std::size_t supportPoints = 2;
  /// `Ok`, `NonFiniteInput`, or `InvalidArgument` (a negative margin, sigma, depth or radius).
  Status validate() const noexcept;
};

/// The dynamic map's lifecycle: insertion, confirmation, correction.
struct MapLifecycleParams {
  /// No new landmark is inserted this close to an existing one of the same kind [m].
  double insertSeparation = 0.3;
  /// A dynamic landmark is *confirmed* once it has this many hits (surveyed landmarks always
  /// are). Only confirmed landmarks are expected by the matched/expected check and kept from the
  /// decrement while occluded: a corner seen once or twice may be a transient or a viewpoint
  /// artefact (an occlusion edge), its absence says nothing about the pose, and when it disappears
  /// behind something it is decremented as if in view.
  std::int16_t minHitsConfirmed = 3;
  /// A dynamic landmark corrects the pose only once it has this many hits (surveyed landmarks
  /// always do). Before that it is *tentative*: associated and gated like any other, matched
  /// (hits, position averaged at the update rate) but not fed to the filter. A corner inserted
  /// from this pose and re-observed from a few centimetres further on carries the same pose error
  /// and nearly the same detector error; used at once it pulls the heading toward its own
  /// insertion error (docs/localization.md, "Tentative landmarks"). 0 = every match corrects.
  std::int16_t minHitsToCorrect = 0;
  /// `Ok`, `NonFiniteInput`, or `InvalidArgument` (negative separation or hit counts).
  Status validate() const noexcept;
};

/// When a cycle is bad and when the localizer is lost.
struct LocalizerHealthParams {
  /// Fewer landmarks used than this: the cycle has no fix (flag NoFix).
  std::uint16_t minMatchesForFix = 2;
  /// Probability that the detector reports a landmark of each kind that is in view (and, for
  /// corners, seen on both sides): the matched/expected check counts expected *detections*, the sum
  /// of these over the expected landmarks. Reflectors 1 (a pole in the line of sight returns); FALKO
  /// corners 0.5 (re-detection rate from a moved viewpoint: 0.49 on fr079, docs/falko.md; the
  /// simulated warehouse gives 0.8), so a cycle with few corners in view is not judged on them.
  double detectionRate[kLandmarkKindCount] = {1.0, 0.5};
  /// The matched/expected check runs when at least this many detections are expected.
  std::uint16_t minExpectedForCheck = 3;
  /// A checked cycle is bad when fewer than max(minMatchesForFix, this fraction of the expected
  /// detections) landmarks were used.
  double minMatchedFraction = 0.3;
  /// The other side of the check, against a static map: of the observations of a kind, at least
  /// this fraction must be used (or tentative) when at least `minExpectedForCheck` of that kind were
  /// observed, else the cycle is bad. A surveyed reflector map holds every reflector, so reflectors
  /// seen and not matched mean the pose is wrong: it catches a vehicle carried away (kidnapped) to a
  /// place from where its old pose expected nothing, which the matched/expected check cannot see.
  /// Per kind: reflectors 0.3 (a stray reflective surface or two is tolerated), corners 0 (off:
  /// most FALKO corners are not in a map).
  double minObservedMatchedFraction[kLandmarkKindCount] = {0.3, 0.0};
  /// The same check against a likelihood field (a static map given to `correct` with the scan's
  /// points): a cycle whose field match is not fused is bad when, at the best pose of the tracking
  /// search (the filter's estimate and its window), fewer than this fraction of the sweep's points
  /// lie on a mapped surface (within `ScanMatchParams::inlierDistance`), counted when the sweep has
  /// at least `ScanMatchParams::minInliers` points. A mapping run covers the floor the vehicle
  /// drives, so a sweep that no pose near the estimate fits says the estimate is wrong: it catches
  /// the vehicle carried away at rest (kidnapped), whose covariance does not grow and whose old pose
  /// expects no landmark it could miss. A sweep matched against a fallback surface map is not
  /// judged (`correct` with a fallback: driving off the mapped floor was asked for; only its first
  /// sweeps, before the fallback has surfaces, are). 0 turns the check off.
  double minFieldInlierFraction = 0.25;
  /// Consecutive bad cycles that make the localizer lost (latched until `reset`).
  std::uint8_t lostAfterBadCycles = 3;
  /// Position (largest axis) and heading standard deviations beyond which a cycle is bad against
  /// a static map. Against a dynamic map they only raise `CovarianceLimit` (dead reckoning relative
  /// to the map the localizer builds itself: its absolute uncertainty grows by construction, and
  /// there is no reference to recover to).
  double maxPositionSigma = 0.10;  ///< [m]
  double maxHeadingSigma = 0.035;  ///< [rad] (2 deg)
  /// `Ok`, `NonFiniteInput`, or `InvalidArgument` (a rate or fraction outside [0, 1], a sigma limit
  /// not positive, `lostAfterBadCycles` or `minMatchesForFix` zero).
  Status validate() const noexcept;
};

/// Parameters of the localizer, one sub-struct per stage of a correction.
struct LocalizerParams {
  PoseEkfParams ekf{};
  LaserModel laser{};
  AssociationParams association{};
  OcclusionParams occlusion{};
  MapLifecycleParams map{};
  LocalizerHealthParams health{};
  /// Scan-to-map matching (used when `correct` is given a likelihood field and the scan's ranges).
  ScanMatchParams scanMatch{};
  /// Squared-Mahalanobis gate (3 dof) of a scan match against the prior; 99 %.
  double scanMatchGate = kChiSquare3Dof99;
  /// A scan stamped later than the newest odometry by more than this is refused.
  Duration maxScanLead = Duration::fromMilliseconds(100);

  /// `Ok`, or the first sub-struct's refusal (`NonFiniteInput`, `InvalidArgument`): laser model
  /// (range and angle limits ordered, sigmas non-negative), association, occlusion, map,
  /// health, scan match (and a positive gate), and a non-negative scan lead. The localizer runs with whatever it is
  /// given; its owner checks this before (the navigation pipeline's `configure()` does).
  Status validate() const noexcept;
};

/// Bits of `LocalizerHealth::flags`.
enum class LocalizerFlag : std::uint32_t {
  NotInitialized = 1U << 0,        ///< no `reset` yet
  OdometryRejected = 1U << 1,      ///< an increment since the last cycle was refused (non-finite, out of order)
  ScanRejected = 1U << 2,          ///< the whole scan was refused (see ScanTooOld / ScanTooNew)
  ScanTooOld = 1U << 3,            ///< older than the odometry history or than the previous scan
  ScanTooNew = 1U << 4,            ///< later than the newest odometry by more than maxScanLead
  ObservationNonFinite = 1U << 5,  ///< some observation had NaN/inf coordinates
  ObservationOutOfView = 1U << 6,  ///< some observation lay outside the laser's range/field of view
  GateRejected = 1U << 7,          ///< some observation had map candidates, none within the gate
  DuplicateRejected = 1U << 8,     ///< two observations claimed one landmark; the worse was dropped
  UpdateRejected = 1U << 9,        ///< an associated observation failed the re-gate in the update
  NoFix = 1U << 10,                ///< fewer than minMatchesForFix landmarks used
  BadCycle = 1U << 11,             ///< too few of the expected landmarks matched, or covariance limit (static map)
  CovarianceLimit = 1U << 12,      ///< position or heading sigma beyond its limit (dynamic map: dead reckoning)
  MapInsertRefused = 1U << 13,     ///< the map was full; new landmarks were refused (counted)
  Lost = 1U << 14,                 ///< the pose is not trusted (latched until reset): stop the vehicle
  AmbiguityRejected = 1U << 15,    ///< an observation had two landmarks inside the gate, too close to tell
  OcclusionUnchecked = 1U << 16,   ///< ranges were given but unusable (`checkBeamGeometry`): no occlusion test
  ScanMatchRejected = 1U << 17,    ///< a likelihood field was given and its match not fused (see `ScanMatchHealth`)
  ScanMatchResync = 1U << 18,      ///< consistent refused matches reset the pose to the map (`resyncAfter`)
  SupportRejected = 1U << 19,      ///< uncertain prior, too few observations to correct: held back (`minSupport`)
  /// The field's match was not fused (off the map, typically) and the fallback field's match moved
  /// the estimate (`LocalizerHealth::fallbackMatch`); the covariance was left as dead reckoning made it.
  FallbackMatchFused = 1U << 20,
  /// The sweep contradicts the likelihood field at the estimate: its best match in the tracking
  /// window has fewer than `minFieldInlierFraction` of its points on a mapped surface (a bad cycle).
  FieldContradicted = 1U << 21,
  /// The landmarks' correction made the sweep fit the likelihood field worse than
  /// `AssociationParams::fieldCheckGate` allows: it was undone (`LocalizerHealth::rejectedField`).
  LandmarksContradictField = 1U << 22,
};

/// True when `flag` is set in `flags`.
constexpr bool hasFlag(std::uint32_t flags, LocalizerFlag flag) noexcept {
  return (flags & static_cast<std::uint32_t>(flag)) != 0U;
}

/// One observation kind's part of a correction (reflectors, corners), in the manner of PX4's
/// estimator aid-source status: an operator sees which kind is being fused and which gated out.
struct SourceHealth {
  std::uint16_t observed = 0;   ///< points of this kind in the scan
  std::uint16_t fused = 0;      ///< used in the update
  std::uint16_t tentative = 0;  ///< matched to a tentative landmark (not fused)
  std::uint16_t rejected = 0;   ///< gated out, ambiguous, duplicate, refused by the update or non-finite
  std::uint16_t unmatched = 0;  ///< no map candidate (outside the view limits included)
  double innovationRms = 0.0;   ///< [m] RMS of the fused innovations' norms (laser frame, at the prior)
  double maxTestRatio = 0.0;    ///< max d^2/gate over the fused (< 1)
  double meanTestRatio = 0.0;   ///< mean d^2/gate over the fused (~2/gate when consistent)
};

/// The scan-to-map match of one cycle (only when `correct` was given a likelihood field).
struct ScanMatchHealth {
  bool attempted = false;
  bool fused = false;                ///< passed the matcher and the gate, used in the update
  Status status = Status::NotFound;  ///< the matcher's status; `Rejected` when the gate refused it
  std::uint16_t points = 0;          ///< scan points matched (after thinning)
  std::uint16_t inliers = 0;         ///< of which on the map
  double rmsResidual = 0.0;          ///< [m] of the inliers
  double mahalanobis2 = 0.0;         ///< of the match against the prior (3 dof)
  double correction = 0.0;           ///< [m] position change of the update (or of the resync)
  /// Confirmations of the re-synchronisation hypothesis so far (`ScanMatchParams::resyncAfter`).
  std::uint8_t consecutiveGated = 0;
  /// A second match ran at the hypothesis carried by the odometry (the tracking match did not
  /// confirm it).
  bool hypothesisChecked = false;
  bool resynced = false;  ///< this cycle reset the pose to the match
  /// The gate refused the match and it was fused through the soft gate
  /// (`ScanMatchParams::softGate`; `fused` is set too).
  bool softGated = false;
  /// The search window was widened for recovery (`ScanMatchParams::widenAfter`).
  bool widened = false;
  double window = 0.0;  ///< [m] the larger translation half-width searched
  Pose2d pose{};        ///< where the matcher ended (diagnostic, whatever its status)
};

/// What one correction cycle did and how much it can be trusted.
struct LocalizerHealth {
  /// Ok; NotInitialized; Rejected (scan refused); Lost (latched).
  Status status = Status::Ok;
  std::uint32_t flags = 0;         ///< LocalizerFlag bits
  std::uint32_t cycle = 0;         ///< correction cycle number (1 = first)
  Timestamp stamp;                 ///< the scan's stamp
  std::uint16_t observations = 0;  ///< points in the scan
  std::uint16_t used = 0;          ///< landmarks used in the update
  std::uint16_t tentative = 0;     ///< matched to a tentative landmark (below minHitsToCorrect): not used
  std::uint16_t rejectedNonFinite = 0;
  std::uint16_t rejectedOutOfView = 0;
  std::uint16_t rejectedGate = 0;
  std::uint16_t rejectedDuplicate = 0;
  std::uint16_t rejectedUpdate = 0;
  std::uint16_t rejectedAmbiguous = 0;
  std::uint16_t rejectedSupport = 0;  ///< held back: too few to correct an uncertain prior (`minSupport`)
  std::uint16_t rejectedField = 0;    ///< fused, then undone: they contradicted the field (`fieldCheckGate`)
  std::uint16_t unmatched = 0;        ///< no map candidate at all (new landmark candidates)
  std::uint16_t expectedInView = 0;   ///< landmarks the check expects (see "Occlusion" in the docs)
  double expectedDetections = 0.0;    ///< their detectionRate summed: what the check compares with
  std::uint16_t occluded = 0;         ///< inside the limits, a nearer return blocks the line of sight
  std::uint16_t noReturn = 0;         ///< inside the limits, no valid beam at the bearing
  std::uint16_t unsupported = 0;      ///< in the line of sight, a corner not seen on both sides
  std::uint16_t inserted = 0;         ///< landmarks added to the map this cycle
  std::uint16_t insertRefused = 0;    ///< inserts the full map refused this cycle
  std::uint16_t deleted = 0;          ///< landmarks that died this cycle
  double maxTestRatio = 0.0;          ///< max d^2/gate over used observations (< 1)
  double meanTestRatio = 0.0;         ///< mean d^2/gate over used observations (~2/gate if consistent)
  /// How far this cycle's updates (scan match and landmarks) moved the pose at the scan's time:
  /// [m] and [rad]. What a PLC sees as a jump of the published pose.
  double correction = 0.0;
  double headingCorrection = 0.0;
  double positionSigma = 0.0;  ///< [m] largest axis of the position covariance
  double headingSigma = 0.0;   ///< [rad]
  /// The estimate at the scan's time after this cycle's updates (before the newer odometry is
  /// re-applied): where the scan was taken, e.g. to add it to a `SurfaceMap`. Meaningful when
  /// the cycle was not refused (`status` Ok).
  Pose2d scanPose{};
  std::uint8_t consecutiveBadCycles = 0;
  bool lost = false;
  /// Per observation kind, indexed by `LandmarkKind`.
  SourceHealth sources[kLandmarkKindCount] = {};
  ScanMatchHealth scanMatch{};
  /// The match against the fallback field (`correct` with a fallback): attempted when the
  /// likelihood field's match was not fused (nor resynced) and the fallback field is built.
  /// `fused`: it moved the estimate; `mahalanobis2` is against the odometry since the last fix,
  /// not against the filter.
  ScanMatchHealth fallbackMatch{};
};

class Localizer {
 public:
  explicit Localizer(const LocalizerParams& params = LocalizerParams{}) noexcept;
  Localizer(const Localizer&) = delete;
  Localizer& operator=(const Localizer&) = delete;

  /// (Re-)initialises the pose at `stamp`, clears the history and the lost state.
  /// `InvalidArgument` for a non-finite pose or an invalid covariance (state unchanged).
  Status reset(Timestamp stamp, const Pose2d& pose, const Eigen::Matrix3d& covariance) noexcept;

  /// Predicts with one odometry increment ending at `inc.stamp` and records it in the history.
  /// Refused, state unchanged and flagged in the next health: `NotInitialized`, `NonFiniteInput`
  /// (invalid increment), `InvalidArgument` (stamp not after the newest one).
  Status predict(const OdometryIncrement& inc) noexcept;

  /// One laser cycle: rewinds to the scan's stamp through the history, associates the
  /// observations with `map`, corrects, maintains the map (Dynamic mode, good cycles only),
  /// re-applies the newer odometry and reports. Scans must come in stamp order.
  /// Without the scan's ranges a landmark is "in view" when inside the range and angle limits.
  const LocalizerHealth& correct(const ScanObservations& scan, LandmarkMap& map) noexcept;

  /// The same, with the ranges of the scan the observations came from (`beams`, in the same laser
  /// frame as the observations, i.e. at `scan.stamp`) for the occlusion test of "in view" (see
  /// `LocalizerParams::modelOcclusion`): a landmark hidden behind a nearer object is not expected
  /// by the matched/expected check, and a confirmed one is not weakened by the map lifecycle. An
  /// unusable `beams` (`checkBeamGeometry`) falls back to the limits and sets `OcclusionUnchecked`.
  const LocalizerHealth& correct(const ScanObservations& scan, const LaserScan& beams, LandmarkMap& map) noexcept;

  /// The same, first matching `beams` against `field` (a likelihood field of the surfaces of a
  /// mapping run, `ScanMatcher`) from the prior at the scan's time: a match that passes the
  /// matcher's checks and `scanMatchGate` corrects the pose (`LocalizerHealth::scanMatch`) before
  /// the landmarks are associated; otherwise `ScanMatchRejected` is flagged and the cycle goes on
  /// with the landmarks alone. A fused match is a fix: the cycle is not bad for lack of landmarks.
  const LocalizerHealth& correct(const ScanObservations& scan, const LaserScan& beams, LandmarkMap& map,
                                 const LikelihoodFieldBase& field) noexcept;

  /// The same with the scan's points for the match given de-skewed (`points`, laser frame at
  /// `scan.stamp`; `beams` still serve the occlusion test): for a scan taken while moving.
  const LocalizerHealth& correct(const ScanObservations& scan, const LaserScan& beams, const MatchPoints& points,
                                 LandmarkMap& map, const LikelihoodFieldBase& field) noexcept;

  /// The same, with a fallback for the scans whose match against the mapping run's field is not
  /// fused (off the map: rooms it never saw, a lane end): `fallbackPoints` (laser frame at
  /// `scan.stamp`, e.g. the beams within a `SurfaceMap`'s range) are matched against `fallback`, a
  /// field of the localizer's own recent surfaces placed with its estimates (a `SurfaceMap`), with
  /// `surfaceMapMatching(params().scanMatch)`. The fallback has no authority over the map's frame:
  /// its prior uncertainty is the odometry's since the last fused match of either field (the
  /// search covers at least the recovery window, `recoveryTranslation` / `recoveryRotation`: the
  /// odometry's worst steps exceed its model), a match outside `scanMatchGate` against that
  /// uncertainty is refused (no soft gate, no re-synchronisation), and a match inside it moves only
  /// the estimate: the covariance keeps growing as dead reckoning makes it, so the covariance
  /// limits and the lost logic see the vehicle off the map as it is. What it gains is a mean that
  /// follows the surfaces instead of the odometry's drift, so that the map's field finds the
  /// vehicle again inside its tracking window on re-entry.
  const LocalizerHealth& correct(const ScanObservations& scan, const LaserScan& beams, const MatchPoints& points,
                                 LandmarkMap& map, const LikelihoodFieldBase& field, const MatchPoints& fallbackPoints,
                                 const LikelihoodFieldBase& fallback) noexcept;

  /// Newest pose estimate (at `stamp()`), its covariance and time.
  const Pose2d& pose() const noexcept { return ekf_.pose(); }
  const Eigen::Matrix3d& covariance() const noexcept { return ekf_.covariance(); }
  Timestamp stamp() const noexcept;
  bool initialized() const noexcept { return initialized_; }
  bool lost() const noexcept { return lost_; }
  const LocalizerHealth& health() const noexcept { return health_; }
  const LocalizerParams& params() const noexcept { return params_; }

 private:
  struct HistoryEntry {
    Timestamp stamp;
    Pose2d delta{};  // increment ending at stamp
    Eigen::Matrix3d deltaCov = Eigen::Matrix3d::Zero();
    Pose2d pose{};  // posterior after it
    Eigen::Matrix3d cov = Eigen::Matrix3d::Identity();
    Pose2d odo{};  // dead-reckoned pose after it (increments composed since construction)
    Eigen::Matrix3d odoCov = Eigen::Matrix3d::Zero();  // sum of the increments' covariances so far
  };
  enum class Assoc : std::uint8_t {
    None,
    Matched,
    NonFinite,
    OutOfView,
    Gate,
    Duplicate,
    Ambiguous,
    Used,
    Tentative,
    UpdateRejected,
    Unsupported,
    FieldRejected
  };
  struct Scratch {
    Eigen::Matrix2d R = Eigen::Matrix2d::Zero();  // sensor noise, laser frame
    double d2 = 0.0;
    LandmarkIndex landmark = kNoLandmark;
    Assoc state = Assoc::None;
    double ratio = 0.0;        // d^2 / gate of the fused update
    double innovation2 = 0.0;  // |innovation|^2 of the fused update [m^2]
  };
  /// Where a scan falls in the odometry history (see `rewindToScan`).
  struct Rewind {
    std::size_t k = 0;   // the history entry at or before the scan
    bool split = false;  // the scan lies inside increment k + 1 (at fraction f)
    double f = 0.0;
    Pose2d part{};  // the part of increment k + 1 before the scan
  };

  void associate(const ScanObservations& scan, const LandmarkMap& map) noexcept;
  void orderMatches(const ScanObservations& scan) noexcept;  // sorts the matches into order_
  enum class Visibility : std::uint8_t { OutOfLimits, Occluded, NoReturn, InViewUnsupported, InView };
  struct ViewCount {
    std::size_t inView = 0;
    std::size_t occluded = 0;
    std::size_t noReturn = 0;
    std::size_t unsupported = 0;
    double detections = 0.0;
  };
  // Stages of one correction (correctWith), in order.
  /// The fallback field of a correction and the points matched against it.
  struct Fallback {
    const LikelihoodFieldBase* field = nullptr;
    const MatchPoints* points = nullptr;
  };
  const LocalizerHealth& correctWith(const ScanObservations& scan, const LaserScan* beams, LandmarkMap& map,
                                     const LikelihoodFieldBase* field, const MatchPoints* points,
                                     Fallback fallback) noexcept;
  /// The fallback's match (see the `correct` overload with a fallback), after the field's match
  /// was not fused; health_.fallbackMatch.
  void matchFallback(const Rewind& at, const Fallback& fallback) noexcept;
  /// Scan-to-map match at the rewound prior (of `points` when given, else of `beams`), fused when
  /// it passes (health_.scanMatch).
  void matchScan(const Rewind& at, const LaserScan& beams, const MatchPoints* points,
                 const LikelihoodFieldBase& field) noexcept;
  /// Re-synchronisation after a match that was not fused (`m`, taken at the prior `before`, the
  /// scan at history position `at`): starts, confirms (if needed with a second match at the
  /// hypothesis) or drops the hypothesis, and resets the filter to it after `resyncAfter`
  /// confirmations.
  void resync(const ScanMatchResult& m, const Pose2d& before, const Rewind& at, const LaserScan& beams,
              const MatchPoints* points, const LikelihoodFieldBase& field) noexcept;
  /// The dead-reckoned pose and the summed increment covariance at the scan instant `at`.
  void odometryAt(const Rewind& at, Pose2d& odo, Eigen::Matrix3d& odoCov) const noexcept;
  /// Latency: moves the filter to the scan's time inside the history. False (health filled) when
  /// the scan is refused.
  bool rewindToScan(const ScanObservations& scan, Rewind& at) noexcept;
  /// The matched observations fused one by one, most certain first, each gated again.
  void fuseMatches(const ScanObservations& scan, const LandmarkMap& map) noexcept;
  /// The field cross-check of the landmarks' correction (`fieldCheckGate`): back to `before`
  /// when the sweep fits the field worse at the corrected pose.
  void checkAgainstField(const PoseEkf& before, const ScanObservations& scan, const LaserScan& beams,
                         const MatchPoints* points, const LikelihoodFieldBase& field) noexcept;
  /// Counts per outcome and per kind, and the flags they raise.
  void tallyObservations(const ScanObservations& scan) noexcept;
  /// Matched vs expected, and the covariance limits against a static map: true for a bad cycle
  /// (counted towards lost).
  bool judgeCycle(MapMode mode) noexcept;
  /// Stores the corrected state at the scan's time and re-applies the newer odometry.
  void storeAndReplay(const Rewind& at) noexcept;
  void maintainMap(const ScanObservations& scan, const LaserScan* beams, LandmarkMap& map) noexcept;
  /// Counts the landmarks of `kinds` in view from the current state; with `mutableMap`, weakens
  /// those in view and not matched this cycle.
  ViewCount countInView(std::uint8_t kinds, const LandmarkMap& map, const LaserScan* beams,
                        LandmarkMap* mutableMap) const noexcept;
  Visibility visibility(const Pose2d& laserWorld, const Landmark& lm, const LaserScan* beams) const noexcept;
  void finishHealth() noexcept;

  LocalizerParams params_{};
  PoseEkf ekf_{};
  bool initialized_ = false;
  bool lost_ = false;
  std::uint8_t badCycles_ = 0;
  std::uint8_t gatedRun_ = 0;
  /// Cycles in a row whose scan match was attempted and not fused (widens the search).
  std::uint8_t failedRun_ = 0;
  std::uint32_t cycle_ = 0;
  std::uint32_t pendingFlags_ = 0;
  Timestamp lastScanStamp_{};
  bool haveScan_ = false;
  /// Oldest first; never empty once initialised (reset() stores the initial state).
  FixedRing<HistoryEntry, kMaxOdometryHistory> history_;
  Scratch scratch_[kMaxObservations];
  std::uint16_t order_[kMaxObservations] = {};
  ScanMatcher matcher_{};
  /// Dead reckoning since construction (increments composed, their covariances summed): the
  /// odometry between any two instants of the history, free of the filter's corrections.
  Pose2d odo_{};
  Eigen::Matrix3d odoCov_ = Eigen::Matrix3d::Zero();
  /// The re-synchronisation hypothesis (`ScanMatchParams::resyncAfter`): a filter of its own,
  /// started at a gate-refused match, carried by the odometry and updated by the matches that
  /// confirm it; `hypOdo_` / `hypOdoCov_` is the odometry at its last scan. `gatedRun_` counts the
  /// matches it holds.
  PoseEkf hyp_{};
  Pose2d hypOdo_{};
  Eigen::Matrix3d hypOdoCov_ = Eigen::Matrix3d::Zero();
  /// The summed odometry covariance at the last scan a match (either field) fixed, or at reset:
  /// the fallback's uncertainty is what the odometry added since.
  Eigen::Matrix3d fixOdoCov_ = Eigen::Matrix3d::Zero();
  LocalizerHealth health_{};
};

}  // namespace agv
