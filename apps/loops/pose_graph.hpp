#pragma once
// Online pose-graph mapping on a gmapping-corrected CARMEN log: raw odometry rebuilt from the ODOM
// lines (datasets::odometryIncrements), corrected scan to scan by matching (the front end), loops
// found online by GLAROT + correspondence graph, screened against false loops (a gate from the
// odometry's accumulated uncertainty, then pairwise consistency of two loops within a few scans), a
// pose graph optimised with Ceres (Cauchy loss on the loop edges) after each batch of accepted
// loops, and a final residual check. The absolute trajectory error against the corrected poses,
// with the first pose fixed at the corrected one (docs/loop-closure.md, "Pose-graph mapping").
// Host tool code (heap, Ceres); not core.

#include <cstddef>
#include <string>
#include <vector>

#include "agv/core/pose2.hpp"
#include "agv/datasets/carmen_log.hpp"
#include "agv/report/json.hpp"

namespace agv {
namespace loops {

/// Settings of the online mapping (defaults: the documented runs).
struct MappingOptions {
  std::size_t maxScans = 0;  ///< 0: every scan of the log
  /// The front end: true, the odometry increments are replaced by scan-matched ones (each scan
  /// matched by the localizer's `ScanMatcher` against a surface map of the scans before it, the raw
  /// step as the prior, the odometry edge sigmas below as its search window; a refused match keeps
  /// the raw step); they place the submaps and form the odometry edges and the gates. false: the raw
  /// odometry (the thesis' setting). docs/loop-closure.md, "Pose-graph mapping".
  bool scanMatching = true;
  std::size_t candidates = 10;  ///< GLAROT candidates per scan
  /// Keypoints of this many scans (the scan and the ones before it, placed by odometry) form the
  /// set a scan's signature and associations use; 1: the scan's own keypoints (the thesis).
  std::size_t submapScans = 1;
  std::size_t minPairs = 3;  ///< N_min: CG pairs a loop needs
  double maxRms = 0.10;      ///< [m] largest RMS residual of the CG fit
  /// Geometric check of a loop: at least this fraction of the query scan's points, moved by the
  /// loop's transform, fall within about `overlapCell` of the reference scan's points.
  double minOverlap = 0.5;
  double overlapCell = 0.10;   ///< [m]
  double excludeTravel = 5.0;  ///< [m] the newest path of this length is not searched for loops
  // Odometry edge standard deviations: constant plus a part per metre travelled / per radian turned.
  double odoSigmaXY = 0.02;           ///< [m]
  double odoSigmaXYPerM = 0.10;       ///< [m/m]
  double odoSigmaTheta = 0.01;        ///< [rad]
  double odoSigmaThetaPerM = 0.05;    ///< [rad/m]
  double odoSigmaThetaPerRad = 0.05;  ///< [rad/rad]
  // Loop edge standard deviations (whitened residuals go through a Cauchy loss of scale 1).
  double loopSigmaXY = 0.10;      ///< [m]
  double loopSigmaTheta = 0.035;  ///< [rad]
  // Gate 1: a loop's relative pose must agree with the current estimate within 3 sigma, sigma
  // growing with the odometry path driven from the reference scan to the query scan.
  double gateXY = 0.30;         ///< [m] sigma at zero distance
  double gateXYPerM = 0.15;     ///< [m/m]
  double gateTheta = 0.10;      ///< [rad]
  double gateThetaPerM = 0.07;  ///< [rad/m]
  // Gate 2: a loop is accepted only with a partner loop from another query scan at most `window`
  // scans away whose implied pose of the robot agrees with the odometry between the two scans,
  // within a tolerance that grows with the path between them.
  std::size_t window = 30;
  double pairXY = 0.30;            ///< [m]
  double pairTheta = 0.087;        ///< [rad] (5 deg)
  double pairXYPerM = 0.05;        ///< [m/m] of odometry path between the two scans
  double pairThetaPerM = 0.02;     ///< [rad/m]
  std::size_t optimiseEvery = 25;  ///< [scans] at most one optimisation this often (if loops were added)
  bool traceHypotheses = false;    ///< one stderr line per loop hypothesis (pairs, overlap, truth check)
  double chi2Final = 11.34;        ///< final check: whitened squared residual above this drops the loop (chi2(3) 99 %)
};

/// One loop edge: pose of robot `to` in the frame of robot `from`.
struct LoopEdge {
  std::size_t from = 0;
  std::size_t to = 0;
  Pose2d relative{};
  std::size_t pairs = 0;
  bool wrong = false;  ///< disagrees with the corrected poses by more than 0.5 m or 10 deg
};

struct MappingResult {
  std::size_t scans = 0;
  std::size_t zeroIncrements = 0;  ///< scans with no timestamped ODOM line since the previous one
  double laserX = 0.0;             ///< [m] laser ahead of the robot centre (log PARAM)
  std::vector<Pose2d> truth;       ///< corrected robot poses
  std::vector<Pose2d> odometry;    ///< raw odometry chained from truth[0]
  bool scanMatching = false;       ///< the front end was scan matching (else frontEnd = odometry)
  std::size_t scansMatched = 0;    ///< scans the front end's matcher accepted
  std::vector<Pose2d> frontEnd;    ///< the front end's poses from truth[0]: what the graph starts from
  std::vector<Pose2d> optimised;   ///< pose graph, first pose fixed at truth[0]
  std::vector<LoopEdge> loops;     ///< accepted, in the final graph
  std::size_t hypotheses = 0;      ///< CG loops with at least minPairs pairs
  std::size_t loopsAccepted = 0;
  std::size_t loopsRejected = 0;  ///< gate 1 + gate 2 + final check
  std::size_t rejectedGate = 0;
  std::size_t rejectedUnpaired = 0;
  std::size_t rejectedFinal = 0;
  std::size_t acceptedWrong = 0;
  std::size_t hypothesesWrong = 0;  ///< hypotheses the corrected poses call wrong
  std::size_t optimisations = 0;
  double odometryAteM = 0.0;  ///< RMS position error of the raw odometry
  double frontEndAteM = 0.0;
  double optimisedAteM = 0.0;
  double odometryAteDeg = 0.0;  ///< RMS heading error
  double frontEndAteDeg = 0.0;
  double optimisedAteDeg = 0.0;
  double seconds = 0.0;
};

/// Maps `log` online; false with `error` (not a corrected log, no scans, too many scans).
bool mapOnline(const datasets::CarmenLog& log, const MappingOptions& options, MappingResult& result,
               std::string& error);

/// The JSON object of issue 17 plus counts.
report::Json mappingJson(const MappingResult& r);

/// The maps side by side: scan points at the raw odometry poses, at the front end's when it
/// matched scans, and at the optimised poses.
std::string mapSvg(const std::string& dataset, const datasets::CarmenLog& log, const MappingResult& r);

}  // namespace loops
}  // namespace agv
