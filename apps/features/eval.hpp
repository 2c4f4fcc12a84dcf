#pragma once
// Keypoint evaluation on the shared logs: repeatability versus viewpoint, range noise and angular
// resampling; BSC / CGH precision and recall on scan pairs with ground truth.

#include <cstddef>
#include <cstdint>
#include <iosfwd>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "agv/datasets/carmen_log.hpp"
#include "agv/falko/falko_descriptors.hpp"
#include "agv/falko/falko_detector.hpp"
#include "agv/report/json.hpp"

namespace agv {
namespace features {

/// Evaluation settings (defaults: the full run of the tool).
struct EvalOptions {
  std::size_t maxScans = 0;                                   ///< 0: every scan of the log
  double pairMaxDistance = 1.0;                               ///< [m] scan pairs closer than this (ground truth)
  std::vector<double> viewpointLevels{0.25, 0.5, 0.75, 1.0};  ///< [m] upper bounds of the distance bins
  std::size_t pairsPerScan = 4;                               ///< at most one partner per distance bin and scan
  double matchDistance = 0.10;                                ///< [m] a keypoint is repeated if one lies this close
  double visibilityTolerance = 0.30;                          ///< [m] the other scan must see the point this close
  std::vector<double> noiseLevels{0.01, 0.03, 0.05, 0.1, 0.2, 0.3};  ///< [m] sigma of range noise
  std::vector<int> resampleLevels{-4, -2, 2};  ///< <0: keep every k-th beam; >0: k-times oversampling
  std::uint32_t seed = 1;
  FalkoParams falko;
  FalkoDescriptorParams descriptors;
};

/// Precision / recall of nearest-neighbour descriptor matching at one distance threshold.
struct PrPoint {
  double threshold = 0.0;
  double precision = 0.0;
  double recall = 0.0;
};

/// Results for one dataset.
struct DatasetResult {
  std::string name;
  std::size_t scans = 0;
  double keypointsPerScan = 0.0;
  /// test name ("viewpoint", "noise", "sampling") -> level label -> repeatability in [0, 1]
  std::map<std::string, std::map<std::string, double>> repeatability;
  /// test -> level -> number of keypoints evaluated (visible in the other scan)
  std::map<std::string, std::map<std::string, std::size_t>> samples;
  std::vector<PrPoint> bsc;
  std::vector<PrPoint> cgh;
  std::size_t pairs = 0;
};

/// One set of scans the evaluation detects keypoints on: the clean scans of the log ("clean"), each
/// range-noise level ("noise-<sigma>", e.g. "noise-0.03") and each resampling factor
/// ("sampling-<label>", e.g. "sampling-x1/2"). Every scan of a variant is made from the clean scan
/// of the same index by `makeVariant`, deterministically (the noise seed depends on the index).
struct ScanVariant {
  std::string name;   ///< as above; the key of the keypoint and scan files
  std::string test;   ///< "" (clean), "noise" or "sampling": the test in the results
  std::string level;  ///< the level in the results ("0.03", "x1/2"); "" for clean
  std::size_t levelIndex = 0;
};

/// The variants of a run: clean first, then noise and resampling levels in option order.
std::vector<ScanVariant> scanVariants(const EvalOptions& options);

/// The scan of `variant` made from clean scan number `scanIndex`.
void makeVariant(const ScanVariant& variant, std::size_t scanIndex, const LaserScan& clean, const EvalOptions& options,
                 LaserScan& out);

/// A viewpoint scan pair: clean scans i < j whose ground-truth laser poses are `distance` apart,
/// in distance bin `bin` (index into EvalOptions::viewpointLevels).
struct ScanPair {
  std::size_t i = 0;
  std::size_t j = 0;
  double distance = 0.0;
  std::size_t bin = 0;
};

/// The viewpoint pairs of a sequence of ground-truth poses: for each scan, the later scans (at most
/// 2000 ahead) within pairMaxDistance, at most one per distance bin and pairsPerScan in all.
std::vector<ScanPair> viewpointPairs(const std::vector<Pose2d>& poses, const EvalOptions& options);

/// Keypoints of another detector, to score with this evaluation: dataset -> variant -> scan index ->
/// keypoints (only x and y are used; sensor frame, metres).
using KeypointTable = std::map<std::string, std::map<std::string, std::map<std::size_t, std::vector<FalkoKeypoint>>>>;

/// Reads a keypoint file: one line per scan, `<dataset> <variant> <scan> <k> <x_1> <y_1> ... <x_k> <y_k>`
/// (whitespace separated, scan indices from 0, k may be 0); blank lines and lines starting with '#'
/// are skipped. Strict: the first malformed line (missing or extra values, a non-finite
/// coordinate, a negative count, a scan listed twice) fails the read with its line number.
bool readKeypointTable(std::istream& in, KeypointTable& table, std::string& error);

/// One line of the keypoint file format above (coordinates with 9 significant digits: exact floats).
std::string keypointLine(const std::string& dataset, const std::string& variant, std::size_t scan,
                         const std::vector<FalkoKeypoint>& keypoints);

/// One line of the scan file `export` writes: `<dataset> <variant> <scan> <angle_min>
/// <angle_increment> <range_min> <range_max> <n> <range_0> ... <range_{n-1}>` ([rad], [m]; 9
/// significant digits, exact floats; invalid readings as they are: e.g. inf, or the log's
/// "no return" value, which lies at or above range_max).
std::string scanLine(const std::string& dataset, const std::string& variant, std::size_t scan, const LaserScan& s);

/// Runs every test on one log. Returns false (and `error`) if the log cannot be read or holds no
/// scan with ground truth.
///
/// With `external`, the keypoints are taken from it instead of the detector: it must hold every
/// variant of `scanVariants` for dataset `name`, each with a line for every scan (and nothing
/// else), or the run fails naming what is missing. The repeatability is then scored exactly as for
/// the detector's keypoints; the descriptor curves are left empty (they need this describer's
/// keypoint orientation).
bool evaluateLog(const std::string& name, const std::string& path, const EvalOptions& options, DatasetResult& result,
                 std::string& error, const KeypointTable* external = nullptr);

/// What `exportLog` writes; a null stream is skipped.
struct ExportStreams {
  std::ostream* scans = nullptr;      ///< every scan of every variant (`scanLine`)
  std::ostream* keypoints = nullptr;  ///< this detector's keypoints of every scan (`keypointLine`)
  std::ostream* pairs = nullptr;      ///< `<dataset> <i> <j> <distance> <bin level>` per viewpoint pair
};

/// Writes the scans the evaluation of one log uses (same selection as `evaluateLog`), for another
/// detector to process, and optionally this detector's keypoints and the viewpoint pairs.
bool exportLog(const std::string& name, const std::string& path, const EvalOptions& options, const ExportStreams& out,
               std::string& error);

/// JSON of the results: {"repeatability": {dataset: {test: {level: value}}},
/// "keypoints_per_scan": {dataset: value}, "scans": {...}, "descriptors": {...},
/// "falko_params": {...}} (the detector parameters of the run). When the keypoints were read from a
/// file (`keypointsFile` not empty), "keypoints_file": path replaces "falko_params".
report::Json resultsToJson(const std::vector<DatasetResult>& results, const FalkoParams& params = FalkoParams{},
                           const std::string& keypointsFile = std::string());

/// The detector parameters a run used, one line (for logs and table headers).
std::string paramsLine(const FalkoParams& params);

/// Human-readable tables.
std::string resultsToTables(const std::vector<DatasetResult>& results);

/// Resamples a scan angularly: factor < 0 keeps every |factor|-th beam, factor > 1 inserts
/// factor - 1 interpolated beams between neighbours (linear in range, invalid when either
/// neighbour is invalid or they differ by more than 0.1 m).
void resampleScan(const LaserScan& in, int factor, LaserScan& out);

/// Adds Gaussian noise of `sigma` metres to every valid range.
void addRangeNoise(LaserScan& scan, double sigma, std::uint32_t seed);

}  // namespace features
}  // namespace agv
