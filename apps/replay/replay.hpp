#pragma once
// Replay of the localizer on a gmapping-corrected CARMEN log (FLASER scans, ODOM lines): raw
// odometry rebuilt from the ODOM lines, the EKF localizer with a dynamic FALKO corner map, and
// both compared with the corrected poses (docs/localization.md, "Real data: fr079").
// Host tool code (heap, files); not core.

#include <cstddef>
#include <limits>
#include <string>
#include <vector>

#include "agv/core/pose2.hpp"
#include "agv/datasets/carmen_log.hpp"
#include "agv/datasets/trajectory_error.hpp"
#include "agv/falko/falko_params.hpp"
#include "agv/localization/field_relocalizer.hpp"
#include "agv/localization/likelihood_field.hpp"
#include "agv/localization/localizer.hpp"
#include "agv/localization/map_changes.hpp"
#include "agv/localization/odometry.hpp"
#include "agv/localization/surface_map.hpp"
#include "agv/mapping/scan_odometry.hpp"
#include "agv/report/json.hpp"

namespace agv {
namespace replay {

// The trajectory error figures of a replay (agv/datasets/trajectory_error.hpp).
using datasets::AbsoluteError;
using datasets::ErrorStats;
using datasets::RelativeError;

/// The field relocalization's parameters of `agvnav-replay`: the core's defaults with a
/// confirmation that spans 0.5 m or 0.5 rad of the log's motion (`ReplayOptions::relocalizer`).
inline FieldRelocalizerParams replayRelocalizerParams() {
  FieldRelocalizerParams p;
  p.confirmTravel = 0.5;
  p.confirmTurn = 0.5;
  return p;
}

/// Settings of one replay (defaults: the fr079 run documented in docs/localization.md).
struct ReplayOptions {
  std::size_t maxScans = 0;    ///< 0: every scan of the log
  double segmentLength = 1.0;  ///< [m] ground-truth path length of the relative-error segments
  /// The laser in the robot frame. With `laserFromLog` (the default) its x is the log's
  /// `PARAM robot_frontlaser_offset` (0 when the log has none: fr079 says -0.04, the other shared
  /// logs 0); `--laser-x` sets it and clears `laserFromLog`.
  Pose2d laserMounting{};
  bool laserFromLog = true;
  /// Odometry noise of the unicycle input (variances grow with distance and rotation).
  UnicycleNoiseParams odometryNoise{};
  /// With `mapFraction`: replace `odometryNoise` by the model fitted on the mapping run (the
  /// prediction's steps against the corrected poses, `fitOdometryNoise`), as a commissioning would
  /// measure a vehicle's odometry. On by default since 2026-12-07, with `scanOdometry`
  /// (docs/localization.md, "Laser odometry as the prediction"); map-less runs have no mapping run
  /// to fit on and keep `odometryNoise`.
  bool fitOdometryNoise = true;
  /// With `mapFraction`: laser odometry as the prediction input (`mapping::ScanOdometry`). Each
  /// scan's wheel step is corrected by matching the scan against the surfaces of the scans before
  /// it (from the log's first scan on, so causal), searched over `scanOdometryWindow`; the
  /// localizer, the relocalization's carry and the odometry noise fit then use those steps. The
  /// raw odometry figures stay the wheels'. On by default since 2026-12-07 (docs/localization.md,
  /// "Laser odometry as the prediction": intel's on-map RMS from 5.5 m to 0.10 m); map-less runs
  /// (no mapping run) keep the wheel steps.
  bool scanOdometry = true;
  /// The search window of each laser-odometry match: the wheel step's sigmas (the pose graph's
  /// odometry edges by default).
  mapping::StepSigmas scanOdometryWindow{};
  /// A laser-odometry match refused over `scanOdometryWindow` is tried again over a window this
  /// many times as wide before the wheel step is taken (`mapping::ScanOdometry`; 0: no retry).
  /// The wheel step of a refused match is as wrong as the wheels (intel: 9.4 deg in one turn), and
  /// the prediction's noise model, fitted to the laser steps, does not expect it; 2 since
  /// 2026-12-07 (docs/localization.md, "Laser odometry: the wider retry").
  double scanOdometryRetry = 2.0;
  LocalizerParams localizer{};
  LandmarkMapParams map{};
  FalkoParams falko{};
  /// Reinitialise the localizer at its own estimate when it declares itself lost (the map is
  /// kept); counted in the result. Off: the latched lost state ends the corrections.
  bool resetWhenLost = true;
  /// Initial pose standard deviations [m, rad] around the first corrected pose.
  double initialSigmaXY = 0.01;
  double initialSigmaTheta = 0.01;
  /// Diagnostic: feed the localizer the ground-truth increments instead of the raw odometry
  /// (isolates the error the landmarks add).
  bool truthOdometry = false;
  /// Localization case instead of the dynamic map: a static corner map is built first from every
  /// scan's keypoints placed with the corrected poses (clusters within `staticClusterRadius`
  /// seen at least `staticMinCount` times), then the localizer runs on it in Static mode. The map
  /// shares the ground truth the result is compared with: an optimistic bound.
  bool staticMapFromTruth = false;
  double staticClusterRadius = 0.10;  ///< [m]
  std::size_t staticMinCount = 5;
  double staticSigma = 0.02;  ///< [m] declared sigma of the static corners
  /// Outlier rejection of the static corners (`mapping::CornerFreezeParams`): sightings farther
  /// than `staticInlierRadius` [m] from the cluster's median are left out (0: none), a cluster
  /// whose inliers are fewer than `staticMinInlierFraction` of its sightings is refused, and one
  /// whose inliers scatter more than `staticMaxScatter` [m] per coordinate.
  double staticInlierRadius = 0.0;
  double staticMinInlierFraction = 0.0;
  double staticMaxScatter = std::numeric_limits<double>::infinity();
  /// Localization on the product's own maps, the honest case: when in (0, 1), the first
  /// `mapFraction` of the scans is the *mapping run*: its corners (clustered as above) become a
  /// static corner map and its scan points a likelihood field (`field`), both placed with the
  /// corrected poses; the localizer then starts at the corrected pose of the first scan after it
  /// and localizes the rest of the log on those maps, with scan-to-map matching, in Static mode.
  /// The errors are measured on that rest only, absolute in the map's frame. 0: off.
  double mapFraction = 0.0;
  LikelihoodFieldParams field{};
  /// A field cell becomes a surface only when scan points of at least this many mapping scans fall
  /// in it (a person walking through the mapping run leaves no wall behind).
  std::size_t fieldMinScans = 2;
  /// Scan-to-map matching on the field (with `mapFraction`); off: the corner map alone.
  bool scanMatching = true;
  double onMapFraction = 0.5;    ///< see `ReplayResult::onMap`
  double onRouteDistance = 1.0;  ///< [m] see `ReplayResult::onRoute`
  /// With the field: when the localizer is lost, search the whole field for the scan
  /// (`FieldRelocalizer`), confirm the candidate on `relocConfirmations` further scans carried by
  /// the odometry that span the motion `relocalizer` asks (`FieldConfirmation`), then restart the
  /// localizer there. Off: the lost localizer is restarted at its own estimate (`resetWhenLost`).
  bool fieldRelocalization = true;
  /// The core's defaults, except the confirmation's motion: 0.5 m or 0.5 rad (the core asks none,
  /// for a vehicle that stands while lost). A log's robot keeps driving: on fr079 (0.65 split) two
  /// scans 0.1 m apart confirmed a 90-degree twin 2.8 m away, which 0.5 m of new views refuse,
  /// while mit-csail's scans, up to 1.3 m apart, span it in two (docs/localization.md,
  /// "Confirmation by motion").
  FieldRelocalizerParams relocalizer = replayRelocalizerParams();
  /// Two scans at least, as the vehicle's pipeline. Three (`--reloc-confirmations 3`) also refused
  /// fr079's twin but kept mit-csail lost far longer (median on-map RMS 1.87 -> 3.64 m).
  std::uint32_t relocConfirmations = 2;
  double relocConfirmDistance() const { return relocalizer.confirmDistance; }
  double relocConfirmAngle() const { return relocalizer.confirmAngle; }
  /// [m] the search covers a disc around the dead-reckoned estimate: 3 standard deviations of its
  /// position covariance (which grows with the distance driven since the loss), at least this
  /// radius; 0: the whole field.
  double relocRadius = 3.0;
  /// With `mapFraction` and `fieldRelocalization`: no hint at the start. The localizer is not given
  /// the corrected pose of the first localized scan; it starts with no pose and the field
  /// relocalization searches the whole field (there is no estimate to centre a disc on) on every
  /// scan until a candidate is confirmed, as a vehicle powered up without a set-pose does. The
  /// scans before that restart have no pose and are left out of the error figures
  /// (`ReplayResult::coldStartScans`).
  bool coldStart = false;
  /// Map-less runs (no `mapFraction`, no `staticMapFromTruth`): scan-to-map matching against a
  /// `SurfaceMap`, the likelihood field of the localizer's own earlier scans, next to the dynamic
  /// corner map. Off: the corners alone.
  bool surfaceMap = true;
  SurfaceMapParams surface{};
  /// Runs on a mapping run's field (`mapFraction`): keep the surfaces the mapping run did not see
  /// (found at fused matches, `MapChangeDetector`) and leave the scan points on them out of the
  /// match, as the vehicle's pipeline does (`ObservationParams::mapChanges`).
  bool mapChanges = false;
  MapChangeParams changes{};
  /// Runs on a mapping run's field: a `SurfaceMap` of the localized scans (with `surface`'s
  /// parameters) as the field's fallback, matched when the field cannot judge a scan (off the
  /// map), moving the estimate but not shrinking its covariance (`Localizer::correct` with a
  /// fallback). Cleared at every restart (relocalization, re-synchronisation).
  bool surfaceFallback = false;
  /// When not empty, one CSV line per scan (health and errors) is written here.
  std::string tracePath;
};

/// Defaults for the fr079 run (see the docs for the derivation).
ReplayOptions fr079Defaults();

/// Everything measured by one replay.
struct ReplayResult {
  std::string log;
  std::size_t scans = 0;
  double pathLength = 0.0;         ///< [m] of the ground truth
  double duration = 0.0;           ///< [s]
  std::size_t zeroIncrements = 0;  ///< scans with no timestamped ODOM line since the previous scan
  std::vector<Pose2d> truth;       ///< corrected robot poses
  std::vector<Pose2d> odometry;    ///< raw odometry track (chained increments from truth[0])
  std::vector<Pose2d> localizer;   ///< localizer estimates at the scan times
  RelativeError odometryRelative;
  RelativeError localizerRelative;
  AbsoluteError odometryAbsolute;
  AbsoluteError localizerAbsolute;
  // Localizer statistics.
  std::size_t keypoints = 0;  ///< FALKO keypoints given to the localizer
  std::size_t used = 0;       ///< observations used in updates
  std::size_t fixCycles = 0;  ///< cycles with at least minMatchesForFix used
  std::size_t rejectedGate = 0;
  std::size_t rejectedAmbiguous = 0;
  std::size_t rejectedDuplicate = 0;
  std::size_t rejectedUpdate = 0;
  /// Landmark observations fused, then undone: their correction contradicted the likelihood field
  /// (`AssociationParams::fieldCheckGate`).
  std::size_t rejectedField = 0;
  std::size_t badCycles = 0;
  std::size_t fieldContradicted = 0;  ///< bad cycles whose sweep fit no pose near the estimate on the field
  double laserX = 0.0;                ///< [m] the laser offset used
  std::size_t laserXLine = 0;         ///< the log line it came from (0: the options)
  std::size_t lostEvents = 0;         ///< times the localizer declared itself lost
  std::size_t mapRestarts = 0;        ///< of which the dynamic map was dropped and rebuilt (`resetWhenLost`)
  std::size_t expected = 0;           ///< landmarks expected in view, summed over the cycles
  std::size_t occluded = 0;  ///< inside the view limits but hidden (or no valid return), summed over the cycles
  std::size_t mapSize = 0;   ///< landmarks at the end
  std::size_t mapInserted = 0;
  std::size_t mapDeleted = 0;
  bool staticMap = false;
  // Localization on a map from a mapping run (`mapFraction`).
  std::size_t mappingScans = 0;   ///< scans of the mapping run (not localized)
  std::size_t staticCorners = 0;  ///< corners of the static map
  std::size_t fieldSurfaceCells = 0;
  bool surfaceMap = false;               ///< a map-less run matched against its `SurfaceMap`
  std::size_t surfaceAdded = 0;          ///< surface pieces the map took
  bool surfaceShift = false;             ///< surface maps recentred by shift (`recentreByShift`)
  double gridOffsetX = 0.0;              ///< [m] the surface maps' grid offset (`gridOffsetX`)
  double gridOffsetY = 0.0;              ///< [m] (`gridOffsetY`)
  double fieldWidth = 0.0;               ///< [m]
  double fieldHeight = 0.0;              ///< [m]
  std::size_t matchAttempts = 0;         ///< scans matched against the field
  std::size_t matchFused = 0;            ///< matches used in the update
  std::size_t matchGated = 0;            ///< refused by the gate against the prior
  std::size_t matchRefused = 0;          ///< refused by the matcher (too few inliers, unobservable, ...)
  bool mapChanges = false;               ///< the changes since the mapping run were kept (`mapChanges`)
  std::size_t changePieces = 0;          ///< surface pieces the change map took
  std::size_t changedPointsDropped = 0;  ///< scan points left out of the matches as lying on changes
  bool surfaceFallback = false;          ///< the field's fallback surface map ran (`surfaceFallback`)
  std::size_t fallbackAttempts = 0;      ///< scans the field could not judge, matched against it
  std::size_t fallbackFused = 0;         ///< of which moved the estimate
  std::size_t fallbackPieces = 0;        ///< surface pieces it took
  std::size_t fallbackClears = 0;        ///< times it was dropped at a restart
  double fitScatter = 0.0;               ///< `ScanMatchParams::fitScatter` of the run
  std::size_t matchResyncs = 0;          ///< resets of the filter to a confirmed hypothesis (`resyncAfter`)
  std::size_t resyncWrong = 0;           ///< of which more than 0.3 m / 5 deg from the corrected pose
  std::size_t lostCycles = 0;            ///< cycles whose health said lost
  bool scanOdometry = false;             ///< the prediction's steps were the laser odometry's
  std::size_t scanOdometryMatched = 0;   ///< scans of the log the laser odometry matched
  std::size_t scanOdometryScans = 0;     ///< of the scans it saw (the mapping run's included)
  double scanOdometryRetry = 0.0;        ///< its retry's widening (`scanOdometryRetry`; 0: none)
  std::size_t scanOdometryRetried = 0;   ///< of the matched, found only by the wider retry
  RelativeError scanOdometryRelative;    ///< its steps against the corrected poses, localized scans
  UnicycleNoiseParams odometryNoise{};   ///< the model used (fitted on the mapping run, or given)
  std::size_t odometryNoiseSteps = 0;    ///< mapping-run steps it was fitted on (0: given, not fitted)
  // Field relocalization (`ReplayOptions::fieldRelocalization`).
  std::size_t relocSearches = 0;     ///< scans searched on the whole field
  std::size_t relocFound = 0;        ///< searches that found one pose
  std::size_t relocAmbiguous = 0;    ///< searches refused as ambiguous
  std::size_t relocWeak = 0;         ///< searches with no candidate that fits
  std::size_t relocConfirmed = 0;    ///< candidates confirmed: the localizer restarted there
  std::size_t relocUnconfirmed = 0;  ///< candidates the next scans did not confirm
  std::size_t relocWrong = 0;        ///< confirmed restarts more than 0.3 m / 5 deg from the corrected pose
  double relocSeconds = 0.0;         ///< wall time spent in the searches
  // Start with no hint (`ReplayOptions::coldStart`). The trajectories, masks and error figures
  // then cover the scans from the first restart on, the odometry chained from its corrected pose.
  bool coldStart = false;
  bool coldStartFound = false;     ///< a candidate was confirmed before the log ended
  std::size_t coldStartScans = 0;  ///< localized scans before the first restart (all of them when not found)
  double coldStartSeconds = 0.0;   ///< [s] log time from the first localized scan to that restart
  double coldStartPath = 0.0;      ///< [m] corrected path driven until then
  bool coldStartWrong = false;     ///< the first restart is more than 0.3 m / 5 deg from the corrected pose
  /// Per localized scan: on the map, i.e. at least `onMapFraction` of its points (thinned as the
  /// matcher thins them) lie within the matcher's inlier distance of the field's surfaces at the
  /// *true* pose. What a map-based localizer can be asked to hold; off the map it dead-reckons.
  std::vector<bool> onMap;
  std::size_t onMapScans = 0;
  AbsoluteError localizerOnMap;  ///< absolute error over the on-map scans
  AbsoluteError odometryOnMap;
  /// Per localized scan: on the mapping run's route, i.e. its true position within
  /// `onRouteDistance` of a mapping scan's true position (any heading). A stricter subset of
  /// where a map-based localizer can be asked to hold: where the mapping run drove, as a natural
  /// navigation product is taught its routes, rather than wherever the scan overlaps the map (a
  /// room seen through its door from the corridor is on the map, not on the route).
  std::vector<bool> onRoute;
  std::size_t onRouteScans = 0;
  double onRouteDistance = 0.0;    ///< [m] the distance used
  AbsoluteError localizerOnRoute;  ///< absolute error over the on-route scans
  AbsoluteError odometryOnRoute;
  std::size_t noFixCycles = 0;  ///< cycles without a fix (no landmark and no match)
  double meanTestRatio = 0.0;   ///< over cycles with used observations
  double seconds = 0.0;         ///< wall time of the replay loop
};

/// The unicycle noise model of the odometry increments `inc[i]` of scans [begin, end) against
/// the corrected poses: per step, the odometry's error in the frame it ends in, e = inc^-1 ⊕
/// truth increment; the heading variance fitted as a * |turn| + b * distance (turn and distance of
/// the corrected step: the odometry's own carry its error and would bias the fit) and the position
/// variance per axis as c * distance (non-negative least squares on the squared errors, each with
/// an intercept: the corrected poses' own per-step scatter, fitted and left out). The fit cannot resolve less than that
/// scatter: where the model's variance at the mean step (position; heading) is below its intercept, the model is
/// scaled up to it. Steps with no motion, and steps whose error exceeds 1 m or 0.5 rad (a corrected pose that jumped,
/// not odometry), are left out. `fallback` when fewer than 20 steps remain. `steps` receives the number of steps used.
UnicycleNoiseParams fitOdometryNoise(const datasets::CarmenLog& log, const std::vector<Pose2d>& inc, std::size_t begin,
                                     std::size_t end, const UnicycleNoiseParams& fallback, std::size_t& steps);

/// Replays `log`; false with `error` when the log has no usable scans.
bool replayLog(const datasets::CarmenLog& log, const ReplayOptions& options, ReplayResult& result, std::string& error);

/// Human-readable summary.
std::string resultText(const ReplayResult& r);
/// JSON object of the figures (no trajectories).
report::Json resultJson(const ReplayResult& r);
/// SVG of the three trajectories (ground truth, raw odometry, localizer).
std::string trajectorySvg(const ReplayResult& r);

}  // namespace replay
}  // namespace agv
