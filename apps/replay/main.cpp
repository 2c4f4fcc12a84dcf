// agvnav-replay: the EKF localizer with a dynamic FALKO corner map replayed on a gmapping-corrected
// CARMEN log, compared with raw odometry and the log's corrected poses (relative pose error per
// metre of path, absolute trajectory error). Figures on stdout, --json, --svg of the trajectories.
#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "agv/datasets/carmen_log.hpp"
#include "agv/report/json.hpp"
#include "agv/report/text_file.hpp"
#include "replay.hpp"

namespace {

/// Writes `text` to `path`; false after saying why on stderr.
bool writeFile(const std::string& path, const std::string& text) {
  std::string error;
  if (!agv::report::writeTextFile(path, text, error)) {
    std::fprintf(stderr, "agvnav-replay: %s\n", error.c_str());
    return false;
  }
  return true;
}

/// The command line: files, the replay's options, the check.
struct ReplayCli {
  std::string logPath = std::string(AGVNAV_DEFAULT_DATA_DIR) + "/laser2d/fr079/freiburg-079-corrected.log.gz";
  std::string jsonPath;
  bool skipBadLines = false;
  std::string svgPath;
  agv::replay::ReplayOptions options = agv::replay::fr079Defaults();
  double expectOdometry = 0.0;
  double tolerance = 0.10;
  bool check = false;
};

/// The log, the outputs and the error segments.
void addFileOptions(CLI::App& app, ReplayCli& cli) {
  agv::replay::ReplayOptions& options = cli.options;
  app.add_option("log", cli.logPath, "gmapping-corrected CARMEN log (FLASER + ODOM), default fr079");
  app.add_option("--max-scans", options.maxScans, "replay only the first N scans (0: all)");
  app.add_option("--json", cli.jsonPath, "write the figures as JSON");
  app.add_flag("--skip-bad-lines", cli.skipBadLines,
               "replay a log with malformed lines without them (default: refuse it)");
  app.add_option("--svg", cli.svgPath, "write the trajectories as SVG");
  app.add_option("--segment", options.segmentLength, "[m] path length of the relative-error segments");
}

/// The localizer's, the map's and the detector's parameters.
void addLocalizerOptions(CLI::App& app, agv::replay::ReplayOptions& options) {
  app.add_option("--corner-sigma", options.localizer.laser.kindSigma[1], "[m] extra corner position noise");
  app.add_option("--range-max", options.localizer.laser.rangeMax, "[m] farthest keypoint used");
  app.add_option("--odo-trans-var", options.odometryNoise.translationVariancePerMetre, "[m^2/m]");
  app.add_option("--odo-rot-var-m", options.odometryNoise.rotationVariancePerMetre, "[rad^2/m]");
  app.add_option("--odo-rot-var-rad", options.odometryNoise.rotationVariancePerRadian, "[rad^2/rad]");
  app.add_option("--update-rate", options.map.updateRate, "map update rate");
  app.add_option("--gate", options.localizer.association.gate, "squared Mahalanobis gate");
  app.add_option("--min-support", options.localizer.association.minSupport,
                 "observations a cycle needs to correct an uncertain prior (1: off)");
  app.add_option("--support-sigma", options.localizer.association.supportSigma,
                 "[m] prior position sigma above which --min-support applies");
  app.add_option("--ambiguity", options.localizer.association.ambiguityMargin, "ambiguity margin (0: off)");
  app.add_flag("--field-support,!--no-field-support", options.localizer.association.fieldSupport,
               "static map with a likelihood field: --min-support applies in every cycle whose scan match was not "
               "fused, whatever the prior's sigma");
  app.add_option("--field-check-gate", options.localizer.association.fieldCheckGate,
                 "with a likelihood field: undo a landmark correction that makes the scan fit the field worse than "
                 "this 3-dof gate allows (0: off)");
  app.add_option("--max-position-sigma", options.localizer.health.maxPositionSigma,
                 "[m] covariance limit of a good cycle");
  app.add_option("--max-heading-sigma", options.localizer.health.maxHeadingSigma,
                 "[rad] covariance limit of a good cycle");
  app.add_option("--min-matched-fraction", options.localizer.health.minMatchedFraction,
                 "of the landmarks expected in view");
  app.add_option("--min-expected", options.localizer.health.minExpectedForCheck,
                 "landmarks expected before the match check runs");
  app.add_flag(
      "--no-occlusion", [&options](std::int64_t) { options.localizer.occlusion.enabled = false; },
      "count every landmark inside the range and angle limits as in view (no occlusion test)");
  app.add_option("--corner-detection-rate", options.localizer.health.detectionRate[1],
                 "probability that an expected corner is detected (the check counts expected detections)");
  app.add_option("--min-hits-confirmed", options.localizer.map.minHitsConfirmed,
                 "hits from which a dynamic landmark is expected and kept while occluded");
  app.add_option("--min-hits-to-correct", options.localizer.map.minHitsToCorrect,
                 "hits from which a dynamic landmark corrects the pose (tentative before)");
  app.add_option("--lost-after", options.localizer.health.lostAfterBadCycles,
                 "consecutive bad cycles that make it lost");
  app.add_option("--initial-hits", options.map.initialHits, "hit count of a new landmark");
  app.add_option("--max-hits", options.map.maxHits, "landmark hit-count cap");
  app.add_option("--insert-separation", options.localizer.map.insertSeparation, "[m]");
  app.add_option("--falko-max-score", options.falko.maxScore, "FALKO cornerness score limit");
  app.add_option("--falko-beta", options.falko.beta, "FALKO corner angle parameter");
}

/// The experiments and diagnostics: static map, trace, ground-truth odometry, mounting, no reset.
void addExperimentOptions(CLI::App& app, agv::replay::ReplayOptions& options) {
  app.add_flag("--static-map-from-truth", options.staticMapFromTruth,
               "localization case: static corner map built first from the corrected poses (optimistic)");
  app.add_option("--map-fraction", options.mapFraction,
                 "localize on the product's own maps: the first fraction of the scans (0..1) is the mapping run "
                 "(static corners + likelihood field), the rest is localized on them (0: off)");
  app.add_flag("!--no-scan-matching", options.scanMatching, "with --map-fraction: the corner map alone");
  app.add_option("--field-resolution", options.field.resolution, "[m] likelihood field cell size");
  app.add_flag("!--no-surface-map", options.surfaceMap,
               "map-less runs: no scan matching against the surface map of the earlier scans (corners alone)");
  app.add_option("--surface-max-range", options.surface.maxRange, "[m] farthest beam the surface map takes");
  app.add_flag("--surface-shift,!--no-surface-shift", options.surface.recentreByShift,
               "surface maps (and the laser odometry's) move by whole cells at a recentre, refilling only the "
               "uncovered strips, instead of a rebuild centred on the sensor");
  app.add_option_function<std::vector<double>>(
         "--surface-grid-offset",
         [&options](const std::vector<double>& xy) {
           options.surface.gridOffsetX = xy.at(0);
           options.surface.gridOffsetY = xy.at(1);
         },
         "[m] X Y: move the grid of the surface maps (and the laser odometry's) by this from centring on the "
         "sensor; a sub-cell offset draws another grid (a sensitivity check)")
      ->expected(2);
  app.add_option("--surface-new-distance", options.surface.newSurfaceDistance,
                 "[m] a beam farther than this from the surface map's surfaces is a new surface");
  app.add_option("--field-min-scans", options.fieldMinScans, "mapping scans a field surface cell needs");
  app.add_option("--match-inlier", options.localizer.scanMatch.inlierDistance, "[m] scan-match inlier distance");
  app.add_option("--match-max-rms", options.localizer.scanMatch.maxRmsResidual, "[m] scan-match RMS limit");
  app.add_option("--resync-after", options.localizer.scanMatch.resyncAfter,
                 "agreeing gated matches that resync (0: off)");
  app.add_option("--resync-max-rms", options.localizer.scanMatch.resyncMaxRms, "[m] RMS limit of a match that resyncs");
  app.add_option("--resync-min-inliers", options.localizer.scanMatch.resyncMinInliers,
                 "inliers a match needs to count for the resync (0: the matcher's minimum)");
  app.add_option("--on-route-distance", options.onRouteDistance,
                 "[m] a localized scan within this of a mapping scan is on the mapping run's route")
      ->check(CLI::PositiveNumber);
  app.add_flag("--map-changes,!--no-map-changes", options.mapChanges,
               "with --map-fraction: keep the surfaces the mapping run did not see and leave the scan points on them "
               "out of the match");
  app.add_flag("--surface-fallback,!--no-surface-fallback", options.surfaceFallback,
               "with --map-fraction: where the field cannot judge a scan (off the map), match it against a surface map "
               "of the localized scans, moving the estimate but not its covariance");
  app.add_flag("--adaptive-band", options.localizer.scanMatch.adaptiveBand,
               "scan matching: a final run in a band of 3 robust sigmas of the match's residuals");
  app.add_flag("!--no-field-relocalization", options.fieldRelocalization,
               "with --map-fraction: no search of the whole field when lost");
  app.add_option("--reloc-radius", options.relocRadius,
                 "[m] field relocalization: search radius around the estimate (0: whole field)");
  app.add_flag("--scan-odometry,!--no-scan-odometry", options.scanOdometry,
               "with --map-fraction: predict with the laser odometry (wheel steps corrected by scan matching; "
               "default on)");
  app.add_option("--scan-odometry-retry", options.scanOdometryRetry,
                 "a laser-odometry match refused over its window is tried again over a window this many times as "
                 "wide before the wheel step is taken (0: no retry)")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--cold-start", options.coldStart,
               "with --map-fraction: no pose at the start; the whole-field relocalization finds it");
  app.add_option("--reloc-confirmations", options.relocConfirmations,
                 "field relocalization: scans after the search that must confirm a candidate before the restart")
      ->check(CLI::PositiveNumber);
  app.add_option("--reloc-confirm-travel", options.relocalizer.confirmTravel,
                 "[m] field relocalization: the confirming scans must carry the candidate this far (or turn it "
                 "--reloc-confirm-turn) before the restart (0 with a zero turn: the scan count alone)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--reloc-confirm-turn", options.relocalizer.confirmTurn,
                 "[rad] field relocalization: or turn it this much")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--reloc-confirm-max-scans", options.relocalizer.confirmMaxScans,
                 "field relocalization: the restart after this many confirming scans whatever the motion")
      ->check(CLI::PositiveNumber);
  app.add_option("--reloc-confirm-sigmas", options.relocalizer.confirmSigmas,
                 "field relocalization: the confirmation window grows to this many standard deviations of the "
                 "odometry noise model over the carry (0: the fixed 0.25 m / 0.08 rad)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--widen-after", options.localizer.scanMatch.widenAfter,
                 "failed matches before the search widens (0: off)");
  app.add_option("--match-fit-scatter", options.localizer.scanMatch.fitScatter,
                 "a fused match's pose is known no better than this times its inliers' RMS residual (0: its "
                 "covariance alone; default 0.5)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--match-inflation", options.localizer.scanMatch.covarianceInflation,
                 "scan-match covariance inflation");
  app.add_option("--static-cluster-radius", options.staticClusterRadius, "[m] static corner clustering radius");
  app.add_option("--static-min-count", options.staticMinCount, "detections a static corner needs");
  app.add_option("--static-inlier-radius", options.staticInlierRadius,
                 "[m] static corners: sightings farther from the cluster's median are outliers (default 0: none)");
  app.add_option("--static-min-inlier-fraction", options.staticMinInlierFraction,
                 "static corners: share of a cluster's sightings that must be inliers (default 0)")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--static-max-scatter", options.staticMaxScatter,
                 "[m] static corners: largest scatter of the inliers per coordinate (default: no limit)");
  app.add_option("--trace", options.tracePath, "write one CSV line per scan (health, errors)");
  app.add_flag("--truth-odometry", options.truthOdometry,
               "diagnostic: predict with the ground-truth increments instead of the raw odometry");
  app.add_option("--laser-x", options.laserMounting.x,
                 "[m] laser position ahead of the robot centre (default: the log's PARAM robot_frontlaser_offset)")
      ->each([&options](const std::string&) { options.laserFromLog = false; });
  app.add_flag(
      "--no-reset", [&options](std::int64_t) { options.resetWhenLost = false; },
      "keep the latched lost state (no reinitialisation)");
}

void addCheckOptions(CLI::App& app, ReplayCli& cli) {
  app.add_option("--expect-odometry", cli.expectOdometry,
                 "[m] expected mean per-metre position error of raw odometry; with --check");
  app.add_option("--tolerance", cli.tolerance, "relative tolerance of --expect-odometry");
  app.add_flag("--check", cli.check,
               "exit 2 unless the odometry figure matches --expect-odometry and the localizer beats odometry");
}

/// --check: the odometry figure as expected and the localizer below it; 0 or 2.
int checkResult(const ReplayCli& cli, const agv::replay::ReplayResult& r) {
  const double odo = r.odometryRelative.position.mean;
  const bool odoOk =
      cli.expectOdometry > 0.0 && std::fabs(odo - cli.expectOdometry) <= cli.tolerance * cli.expectOdometry;
  const bool locOk =
      r.localizerRelative.position.mean < odo && r.localizerRelative.heading.mean < r.odometryRelative.heading.mean;
  std::printf("check: odometry %.4f m/m vs expected %.4f (+-%.0f %%): %s; localizer below odometry: %s\n", odo,
              cli.expectOdometry, cli.tolerance * 100.0, odoOk ? "ok" : "FAIL", locOk ? "ok" : "FAIL");
  return odoOk && locOk ? 0 : 2;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"EKF localizer with a dynamic FALKO map replayed on a corrected CARMEN log"};
  ReplayCli cli;
  addFileOptions(app, cli);
  addLocalizerOptions(app, cli.options);
  addExperimentOptions(app, cli.options);
  addCheckOptions(app, cli);
  app.add_flag("--fit-odometry-noise,!--no-fit-odometry-noise", cli.options.fitOdometryNoise,
               "with --map-fraction: fit the odometry noise model on the mapping run (replaces --odo-*; default on)");
  CLI11_PARSE(app, argc, argv);

  agv::datasets::CarmenLog log;
  std::string err;
  if (!agv::datasets::readCarmenLog(cli.logPath, log, err)) {
    std::fprintf(stderr, "agvnav-replay: %s\n", err.c_str());
    return 1;
  }
  for (const auto& issue : log.issues) {
    std::fprintf(stderr, "%s:%zu: %s%s\n", cli.logPath.c_str(), issue.line, issue.message.c_str(),
                 cli.skipBadLines ? " (skipped)" : "");
  }
  if (!log.issues.empty() && !cli.skipBadLines) {
    std::fprintf(stderr, "agvnav-replay: %s: %zu malformed line(s) refused (--skip-bad-lines to replay without them)\n",
                 cli.logPath.c_str(), log.issues.size());
    return 2;
  }
  agv::replay::ReplayResult r;
  r.log = cli.logPath.substr(cli.logPath.find_last_of('/') + 1);
  if (!agv::replay::replayLog(log, cli.options, r, err)) {
    std::fprintf(stderr, "agvnav-replay: %s\n", err.c_str());
    return 1;
  }
  std::fputs(agv::replay::resultText(r).c_str(), stdout);
  if (!cli.jsonPath.empty() && !writeFile(cli.jsonPath, agv::report::dumpJson(agv::replay::resultJson(r)))) {
    return 1;
  }
  if (!cli.svgPath.empty() && !writeFile(cli.svgPath, agv::replay::trajectorySvg(r))) {
    return 1;
  }
  return cli.check ? checkResult(cli, r) : 0;
}
