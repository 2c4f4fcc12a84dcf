#pragma once
/// @file field_relocalizer.hpp
/// Global localization on a likelihood field: where on the whole map a scan fits, with no prior.
/// It is what brings a lost scan-matching localizer back (docs/localization.md, "Field
/// relocalization"): the tracking search is local (a window around the estimate), and once an
/// excursion off the map or odometry the model does not cover has carried the estimate metres
/// away, no local window finds the map again.
///
/// Method, in three stages, each bounded:
/// 1. **Coarse scoring** of every pose on a grid over the field: positions every `positionStep`
///    on the free side of the surfaces (at least `minClearance` from the nearest one: the vehicle
///    is not inside a wall), headings every `rotationStep` over the full turn. A pose scores
///    sum(max(0, 1 - |d_i| / band)) over at most `maxPoints` scan points spread evenly over the
///    scan, d_i the field's stored distance at the cell under point i, band = the field's
///    saturation distance (which the grid steps are chosen to stay within: a point at 10 m moves
///    0.17 m per half rotation step). A pose that can no longer beat the worst of the kept ones
///    is abandoned part-way. At most `maxPoses` poses are scored (`WorkBoundHit` beyond).
/// 2. **Refinement** of the `candidates` best coarse poses (kept apart by at least one grid step)
///    with the scan matcher in a window of one grid step around each.
/// 3. **Decision**: the refined match with the most points within `closeDistance` of a surface,
///    if it fits (inlier fraction and RMS) and no *distinct* refined match (`ambiguityDistance` /
///    `ambiguityAngle` away) comes within `ambiguityRatio` of that count: a corridor or a row of identical racks is
///    refused as `Ambiguous`, never guessed.
///
/// One answer is one scan's evidence: `confirm` checks the candidate on the next scans, carried by
/// the odometry, before a caller trusts it (a wrong relocalization is worse than none).
///
/// The search runs in one call (`localize`) or spread over calls with a work budget each
/// (`start`, then `advance` until it returns true): a vehicle's cycle cannot wait the 0.3-4 s a
/// whole-field search takes, so the pipeline advances it a slice per cycle. Both forms score the
/// same poses in the same order and give the same result.
///
/// Heap-free: the matcher's scratch, a copy of the scan, the candidate list and the refined
/// matches live inside the object (about 90 KB with 2048-beam scans).

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>

#include "agv/core/pose2.hpp"
#include "agv/core/status.hpp"
#include "agv/localization/likelihood_field.hpp"
#include "agv/localization/scan_matcher.hpp"

namespace agv {

/// Parameters of the field relocalization.
struct FieldRelocalizerParams {
  double positionStep = 0.25;  ///< [m] grid of candidate positions
  double rotationStep = 0.03;  ///< [rad] grid of candidate headings (1.7 deg)
  double minClearance = 0.15;  ///< [m] candidate positions at least this far from every surface
  std::size_t maxPoints = 48;  ///< scan points scored by the coarse stage
  std::uint32_t maxPoses = 16000000;
  /// Coarse poses refined (the best ones, at least one grid step apart); at most kMaxCandidates.
  std::size_t candidates = 12;
  /// A refined match must put this fraction of its points on the map, within this RMS [m].
  double minInlierFraction = 0.6;
  double maxRms = 0.06;
  /// [m] a refined match is ranked by its points this close to a surface (the inlier band of the
  /// matcher is wide enough that a wrong pose along the same walls keeps most of its inliers;
  /// the points that fit closely tell the poses apart).
  double closeDistance = 0.10;
  /// Ambiguous when a distinct match has at least this fraction of the best one's close points.
  double ambiguityRatio = 0.95;
  double ambiguityDistance = 0.5;  ///< [m]
  double ambiguityAngle = 0.17;    ///< [rad] (10 deg)
  /// `confirm`: the carried candidate and the scan's match agree within these (the odometry
  /// between two scans must fit in: a few centimetres and degrees per metre driven).
  double confirmDistance = 0.25;  ///< [m]
  double confirmAngle = 0.08;     ///< [rad]
  /// `confirmWindow`: when the caller gives the covariance of the carry (the odometry between the
  /// candidate's scan and this one), the window grows to this many of its standard deviations
  /// where that exceeds confirmDistance / confirmAngle: a log or vehicle whose scans lie a metre
  /// and 30 deg of odometry apart carries a right candidate farther than a fixed window allows.
  double confirmSigmas = 3.0;
  /// Upper bounds of that window (the confirmation's match search covers it).
  double confirmMaxDistance = 0.6;  ///< [m], at least confirmDistance
  double confirmMaxAngle = 0.3;     ///< [rad], at least confirmAngle
  /// The motion a candidate's confirmation must span (`FieldConfirmation`): the caller restarts
  /// from it only once its confirming scans carried it `confirmTravel` [m] (their odometry steps'
  /// lengths summed) or turned it `confirmTurn` [rad], or after `confirmMaxScans` confirming scans
  /// whatever the motion (a standing vehicle's view does not change: more scans add only time).
  /// Scans a few centimetres apart show the same view, so a twin that fits one fits the next as
  /// well; a new view refutes it. 0 (the default): no motion asked, the caller's count of scans
  /// alone. `agvnav-replay` asks 0.5 m / 0.5 rad (docs/localization.md, "Confirmation by motion").
  double confirmTravel = 0.0;
  double confirmTurn = 0.0;
  std::uint32_t confirmMaxScans = 8;
  /// The scan matcher of the refinement and the confirmation (its search window is set here).
  ScanMatchParams match{};
  /// `Ok`, `NonFiniteInput` or `InvalidArgument` (a non-positive step, distance or count, a
  /// fraction outside (0, 1], more candidates than kMaxCandidates, a negative confirmation
  /// travel or turn, confirmMaxScans zero, an invalid `match`).
  Status validate() const noexcept;
};

/// Why a relocalization ended as it did.
enum class FieldRelocOutcome : std::uint8_t {
  Found = 0,     ///< one pose fits, unambiguously (Status::Ok)
  InvalidInput,  ///< invalid parameters, non-finite mounting or region, field not built (see status)
  NoPoints,      ///< no finite scan point (EmptyInput)
  NoCandidate,   ///< no free position on the field, or no coarse pose scored above zero (NotFound)
  WeakSupport,   ///< no refined match fits well enough (NotEnoughData)
  Ambiguous,     ///< two distinct poses fit alike (Rejected)
  WorkBoundHit,  ///< the grid has more poses than maxPoses (NotConverged): coarsen the steps
};

/// Stable lower-case name of an outcome ("found", "weak_support", ...). Never null.
const char* toString(FieldRelocOutcome outcome) noexcept;

/// Where to search: the disc of `radius` around (x, y) [m], or the whole field when `radius` is 0.
struct RelocRegion {
  double x = 0.0;
  double y = 0.0;
  double radius = 0.0;
};

/// What one relocalization found; `pose` and `covariance` are meaningful only for Found.
struct FieldRelocResult {
  Status status = Status::NotFound;
  FieldRelocOutcome outcome = FieldRelocOutcome::NoCandidate;
  Pose2d pose{};  ///< the vehicle pose
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  std::uint32_t scored = 0;    ///< coarse poses scored (including those abandoned part-way)
  std::uint64_t visited = 0;   ///< grid poses visited (free or not): the coarse stage's work units
  std::uint16_t inliers = 0;   ///< of the best refined match
  std::uint16_t points = 0;    ///< of the best refined match
  double rmsResidual = 0.0;    ///< [m] of the best refined match
  std::uint16_t close = 0;     ///< points of the best match within closeDistance
  std::uint16_t runnerUp = 0;  ///< close points of the best distinct match (0: none)
};

/// The relocalizer (scratch only; holds no map).
class FieldRelocalizer {
 public:
  static constexpr std::size_t kMaxCandidates = 32;

  FieldRelocalizer() noexcept = default;
  explicit FieldRelocalizer(const FieldRelocalizerParams& params) noexcept : params_(params) {}
  FieldRelocalizer(const FieldRelocalizer&) = delete;
  FieldRelocalizer& operator=(const FieldRelocalizer&) = delete;

  /// Where on `field` the scan `points` (laser frame, in scan order) fits, through the laser
  /// mounting `laser` (laser pose in the vehicle frame). See the file comment.
  /// `region` bounds the positions tried (a caller that knows roughly where the vehicle went, e.g.
  /// dead reckoning since the loss, searches less and meets fewer look-alike places).
  FieldRelocResult localize(const MatchPoints& points, const Pose2d& laser, const LikelihoodFieldBase& field,
                            const RelocRegion& region = RelocRegion{}) noexcept;

  /// Begins the search of `localize` without running it: checks the input, copies the scan and
  /// lays out the grid (O(grid positions)). Ok: the search is under way (`advance` it). Any other
  /// status: it ended at once and `result()` says why (the outcomes of `localize`). `field` must
  /// stay alive and unchanged until the search ends or `cancel()`.
  Status start(const MatchPoints& points, const Pose2d& laser, const LikelihoodFieldBase& field,
               const RelocRegion& region = RelocRegion{}) noexcept;

  /// Advances the search begun by `start`: visits at most `budget` grid poses (at least one),
  /// scoring those at a free position;
  /// once all are scored, each call refines one candidate (one scan match), and the call after the
  /// last one decides. True when the search has ended (also when none is under way): `result()`
  /// then holds the answer. Bounded: O(budget x maxPoints), or one scan match.
  bool advance(std::uint32_t budget) noexcept;

  /// True between a successful `start` and the end of that search.
  bool searching() const noexcept { return stage_ == Stage::Coarse || stage_ == Stage::Refine; }

  /// The last search's answer (meaningful once it has ended).
  const FieldRelocResult& result() const noexcept { return result_; }

  /// Abandons the search under way (the result then says NoCandidate, NotFound).
  void cancel() noexcept;

  /// Whether the scan `points` taken at `carried` (a candidate carried to this scan by the
  /// odometry) matches the field within confirmDistance / confirmAngle of it, with the fit
  /// `localize` demands. True with `refined` set to the match.
  bool confirm(const MatchPoints& points, const Pose2d& laser, const Pose2d& carried, const LikelihoodFieldBase& field,
               Pose2d& refined) noexcept;

  /// The same within `confirmWindow(carryCovariance)`: `carryCovariance` is the covariance of the
  /// odometry that carried the candidate (x, y, theta; any frame: the window takes the largest
  /// position variance). False for a non-finite or negative covariance.
  bool confirm(const MatchPoints& points, const Pose2d& laser, const Pose2d& carried, const LikelihoodFieldBase& field,
               const Eigen::Matrix3d& carryCovariance, Pose2d& refined) noexcept;

  /// The confirmation window for a carry of covariance `carryCovariance`: per axis the larger of
  /// confirmDistance (confirmAngle) and confirmSigmas standard deviations, at most
  /// confirmMaxDistance (confirmMaxAngle); x = y = the position bound. A zero covariance gives the
  /// fixed window; a non-finite or negative one gives a zero window (nothing agrees).
  SearchWindow confirmWindow(const Eigen::Matrix3d& carryCovariance) const noexcept;

  /// Whether `pose` lies within `window` of `carried` (position distance, heading difference).
  static bool withinWindow(const Pose2d& pose, const Pose2d& carried, const SearchWindow& window) noexcept;

  const FieldRelocalizerParams& params() const noexcept { return params_; }

 private:
  struct Candidate {
    Pose2d pose{};
    double score = 0.0;
  };
  /// Keeps `c` among the best, at least one grid step apart from the others kept.
  void offer(const Candidate& c) noexcept;
  /// Whether a refined match fits as `localize` demands.
  bool fits(const ScanMatchResult& m) const noexcept;
  /// Points of `points` (laser frame) within closeDistance of a surface at vehicle pose `x`.
  std::uint16_t closePoints(const MatchPoints& points, const Pose2d& laser, const Pose2d& x,
                            const LikelihoodFieldBase& field) const noexcept;

  enum class Stage : std::uint8_t { Idle, Coarse, Refine, Done };
  /// Whether (x, y) is a candidate position (in the region, minClearance from every surface).
  bool candidatePosition(double x, double y) const noexcept;
  /// The field's stored distance at (x, y); false outside the field.
  bool cellDistance(double x, double y, double& d) const noexcept;
  /// Rotates the coarse points to heading index it_.
  void rotate() noexcept;
  void end(Status status, FieldRelocOutcome outcome) noexcept;
  void decide() noexcept;

  FieldRelocalizerParams params_{};
  ScanMatcher matcher_{};
  MatchPoints coarse_;                      // vehicle frame, at most maxPoints
  MatchPoint rotated_[kMaxScanBeams] = {};  // coarse_ rotated to the heading being scored
  Candidate best_[kMaxCandidates] = {};
  std::size_t kept_ = 0;
  // The search under way (start / advance).
  Stage stage_ = Stage::Idle;
  const LikelihoodFieldBase* field_ = nullptr;
  Pose2d laser_{};
  RelocRegion region_{};
  MatchPoints scan_;  // laser frame: the refinement matches the whole scan
  double x0_ = 0.0;
  double y0_ = 0.0;
  std::uint64_t nx_ = 0;
  std::uint64_t ny_ = 0;
  std::uint64_t nt_ = 0;
  std::uint64_t it_ = 0;  // next pose: heading it_, position (ix_, iy_)
  std::uint64_t ix_ = 0;
  std::uint64_t iy_ = 0;
  double theta_ = 0.0;  // heading it_ [rad]
  std::uint32_t scored_ = 0;
  std::uint64_t visited_ = 0;
  std::size_t refinedCount_ = 0;
  ScanMatchResult refined_[kMaxCandidates] = {};
  std::uint16_t close_[kMaxCandidates] = {};
  FieldRelocResult result_{};
};

/// A candidate's confirmation in progress: how many scans confirmed it (`FieldRelocalizer::confirm`
/// returned true) and the odometry they spanned, judged against the caller's minimum count and
/// `FieldRelocalizerParams::confirmTravel` / `confirmTurn` / `confirmMaxScans`.
class FieldConfirmation {
 public:
  /// A new candidate: nothing confirmed yet.
  void restart() noexcept { *this = FieldConfirmation{}; }
  /// One more scan confirmed the candidate, carried to it by the odometry `step` (from the scan
  /// before; a non-finite step counts as no motion).
  void add(const Pose2d& step) noexcept;
  /// At least `minScans` confirming scans, and the motion `params` asks for or its
  /// `confirmMaxScans` of them.
  bool complete(std::uint32_t minScans, const FieldRelocalizerParams& params) const noexcept;
  std::uint32_t scans() const noexcept { return scans_; }
  double travel() const noexcept { return travel_; }  ///< [m] the confirming steps' lengths summed
  double turn() const noexcept { return turn_; }      ///< [rad] their absolute rotations summed

 private:
  std::uint32_t scans_ = 0;
  double travel_ = 0.0;
  double turn_ = 0.0;
};

}  // namespace agv
