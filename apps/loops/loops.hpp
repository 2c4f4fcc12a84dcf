#pragma once
// agvnav-loops: the loop-closure experiments of the FALKO thesis (chapter 4) on the FLIRTLib logs
// (VERTEX2 ground truth): FALKO keypoints and a GLAROT signature per scan, 10 GLAROT candidates per
// scan, each associated by correspondence graph (cg), affine Hough (ah) and RANSAC (ransac);
// precision and recall versus N_min, offline and online (docs/loop-closure.md, "agvnav-loops").
// Host tool code (heap, files); not core.

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "agv/core/pose2.hpp"
#include "agv/datasets/carmen_log.hpp"
#include "agv/falko/falko_params.hpp"
#include "agv/loop/glarot.hpp"
#include "agv/loop/scan_overlap.hpp"
#include "agv/report/json.hpp"
#include "agv/scan/laser_scan.hpp"

namespace agv {
namespace loops {

/// The three association methods, in the order of every array below.
inline constexpr std::size_t kMethods = 3;
inline constexpr std::array<const char*, kMethods> kMethodNames{"cg", "ah", "ransac"};

/// Scans one GLAROT database holds here (the largest shared log, fr079 corrected, has 4791).
inline constexpr std::size_t kMaxDatabaseScans = 8192;

/// FALKO keypoints (sensor frame, at most kMaxLoopPoints) and the GLAROT signature of each scan,
/// with the ground-truth pose of the sensor.
struct ScanFeatures {
  std::vector<std::vector<Eigen::Vector2f>> points;
  std::vector<LaserScan> scans;  ///< the readings, for the verification (agv/loop/scan_overlap.hpp)
  std::vector<GlarotSignature> signatures;
  std::vector<Pose2d> truth;         ///< ground-truth sensor pose (laser frame in the world)
  std::vector<std::size_t> logScan;  ///< index of the scan in the log
  std::size_t truncated = 0;         ///< scans with more than kMaxLoopPoints keypoints (the rest dropped)
  double meanKeypoints = 0.0;        ///< before truncation
  double detectMs = 0.0;             ///< mean FALKO + GLAROT time per scan
};

/// Which scans of a log to use.
struct ScanSelection {
  std::size_t stride = 1;    ///< every stride-th scan with ground truth
  std::size_t maxScans = 0;  ///< 0: all
  FalkoParams falko{};
  GlarotParams glarot{};
  /// 0: the GLAROT signature of the FALKO keypoints (thesis). n > 0: of n beam endpoints spread
  /// evenly over the scan's valid readings instead (the association stays on the keypoints).
  std::size_t glarotScanPoints = 0;
  /// Submaps: a scan's association set is its own keypoints plus, newest first, those of up to
  /// `submapScans` - 1 earlier selected scans (placed in its frame by odometry, see below), taken only while the set
  /// holds fewer than `submapPoints` points (a scan rich in corners stays alone; one with few borrows from its
  /// predecessors). 1: the scan's own keypoints (the thesis). The signature and the verification stay the scan's own.
  std::size_t submapScans = 1;
  std::size_t submapPoints = kMaxLoopPoints;
  /// The FLIRTLib logs carry no odometry (their pose fields repeat the VERTEX2 ground truth, data
  /// README): the submaps are placed by a simulated odometry instead, the ground-truth increments
  /// between selected scans with zero-mean Gaussian noise of these variances per metre travelled
  /// (the defaults: about intel's raw odometry, the worst of the shared logs, 0.12 m and 5.6 deg
  /// of drift per metre), seeded.
  double submapPositionVariancePerMetre = 0.01;  ///< [m^2/m]
  double submapHeadingVariancePerMetre = 0.015;  ///< [rad^2/m]
  std::uint64_t submapNoiseSeed = 17;
  /// Place the submaps by scan matching instead of by that odometry alone: each selected scan is
  /// matched (`ScanMatcher`, the odometry's step as the prior with its variances as the search
  /// window) against a `SurfaceMap` of the scans before it, and the matched pose is the one the
  /// submap uses; a scan the matcher refuses keeps the odometry's step. What a vehicle with a laser
  /// does between two places (docs/loop-closure.md, "Submaps placed by scan matching").
  bool submapMatched = false;
};

/// Adds `points` (keypoints in another scan's sensor frame) to `submap` (this scan's frame),
/// each moved by `toThis` (that frame's pose in this one) and left out when within `mergeRadius`
/// of a point already there, until `submap` holds `limit` points (at most kMaxLoopPoints): call it
/// for the scan's own points first, then for the earlier scans', newest first.
void addSubmapPoints(const std::vector<Eigen::Vector2f>& points, const Pose2d& toThis, float mergeRadius,
                     std::size_t limit, std::vector<Eigen::Vector2f>& submap);

/// Detects the features of the selected scans that carry ground truth (`LogScan::groundTruth`).
/// False with `error` when no scan is usable.
bool extractFeatures(const datasets::CarmenLog& log, const ScanSelection& selection, ScanFeatures& out,
                     std::string& error);

/// Settings of the precision-recall evaluation.
struct EvalOptions {
  std::size_t candidates = 10;  ///< GLAROT candidates per scan (thesis: 10)
  // A loop is correct when the candidate's ground-truth pose composed with the estimated transform
  // is within these of the query's ground-truth pose (thesis: 0.50 m, 10 deg).
  double correctDistance = 0.50;              ///< [m]
  double correctAngle = 0.17453292519943295;  ///< [rad]
  // Online: earlier scans only, leaving out the recent ones whose pose relative to the query is
  // within these (walking back from the previous scan until one is outside; issue 17).
  double onlineSkipX = 0.20;      ///< [m]
  double onlineSkipY = 0.20;      ///< [m]
  double onlineSkipTheta = 0.35;  ///< [rad]
  // The recall's reference: a scan "has a loop" when one of its eligible reference scans was taken
  // within these of its ground-truth pose (the overlap a correct association needs).
  double revisitDistance = 1.0;               ///< [m]
  double revisitAngle = 0.52359877559829882;  ///< [rad] (30 deg)
  std::size_t maxMinPairs = 20;               ///< N_min from 0 to this
  // Verification of an association by the scans (agv/loop/scan_overlap.hpp): a candidate's
  // association counts only when at least minOverlap of each scan's points, placed by its
  // transform, land next to the other's endpoints, and at most maxConflict of them land in the
  // other's free space. verify = false: the thesis' acceptance by N_min alone. The two thresholds
  // were chosen on fr079 online alone (docs/loop-closure.md, "Thresholds").
  bool verify = true;
  double minOverlap = 0.6;
  double maxConflict = 0.03;
  ScanOverlapParams overlap{};
  /// When not empty: every Ok association (all candidates, methods) as one CSV line here.
  std::string dumpPath;
  std::string dumpName;  ///< dataset name in the dump
};

/// The best candidate of one scan for one method: most associated pairs (ties: lower rms, then
/// the nearer GLAROT candidate). pairs = 0 when no candidate gave an association (status not Ok).
struct BestLoop {
  std::size_t pairs = 0;
  bool correct = false;
  std::size_t candidate = 0;  ///< reference scan (index in ScanFeatures)
  Pose2d transform{};         ///< query sensor pose in the candidate's sensor frame
  double overlap = 0.0;       ///< smaller hit fraction of the two scans (minOverlap)
  double conflict = 0.0;      ///< larger conflict fraction of the two scans (maxConflict)
};

/// One point of a precision-recall curve.
struct PrPoint {
  std::size_t minPairs = 0;
  std::size_t accepted = 0;  ///< scans whose best loop has at least minPairs pairs
  std::size_t correct = 0;   ///< of which correct
  std::size_t recalled = 0;  ///< correct ones among the scans that have a loop
  double precision = 1.0;    ///< correct / accepted (1 when nothing is accepted)
  double recall = 0.0;       ///< recalled / scans that have a loop
};

/// The evaluation of one log in one mode.
struct ModeResult {
  std::size_t scans = 0;                             ///< queried scans
  std::size_t withLoop = 0;                          ///< of which have a loop (the recall's denominator)
  std::vector<bool> hasLoop;                         ///< per queried scan
  std::array<std::vector<BestLoop>, kMethods> best;  ///< per method, per queried scan
  std::array<std::vector<PrPoint>, kMethods> curves;
  std::array<std::vector<double>, kMethods> msPerScan;  ///< association time of the candidates of one scan
  std::vector<double> glarotMsPerScan;                  ///< candidate search time per scan
};

/// Runs one mode (offline: every other scan is a reference; online: earlier scans only).
void evaluate(const ScanFeatures& features, bool online, const EvalOptions& options, ModeResult& out);

/// Precision and recall for N_min = 0..options.maxMinPairs from the best loops.
std::vector<PrPoint> prCurve(const std::vector<BestLoop>& best, const std::vector<bool>& hasLoop,
                             std::size_t maxMinPairs);

/// Break-even (the first N_min where precision reaches recall after being below it at N_min - 1;
/// -1 if the curve does not cross, e.g. precision above recall from N_min = 0) and the largest recall at
/// precision 1.0 with at least one accepted loop (0 when none), with its N_min (-1 if none).
struct CurveSummary {
  long breakEvenMinPairs = -1;
  double breakEven = 0.0;  ///< mean of precision and recall at that N_min
  double recallAtPrecision1 = 0.0;
  long recallAtPrecision1MinPairs = -1;
};
CurveSummary summarize(const std::vector<PrPoint>& curve);

/// Mean, median and 95th percentile.
report::Json timingJson(std::vector<double> values);

/// One SVG of the precision-recall curves of one dataset (both modes, three methods).
std::string prSvg(const std::string& dataset, const ModeResult& offline, const ModeResult& online);

}  // namespace loops
}  // namespace agv
