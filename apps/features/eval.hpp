#pragma once
// Keypoint evaluation on the shared logs: repeatability versus viewpoint, range noise and angular
// resampling; BSC / CGH precision and recall on scan pairs with ground truth.

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "agv/datasets/carmen_log.hpp"
#include "agv/falko/falko_descriptors.hpp"
#include "agv/falko/falko_detector.hpp"

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

/// Runs every test on one log. Returns false (and `error`) if the log cannot be read or holds no
/// scan with ground truth.
bool evaluateLog(const std::string& name, const std::string& path, const EvalOptions& options, DatasetResult& result,
                 std::string& error);

/// JSON of the results: {"repeatability": {dataset: {test: {level: value}}},
/// "keypoints_per_scan": {dataset: value}, "scans": {...}, "descriptors": {...},
/// "falko_params": {...}} (the detector parameters of the run).
std::string resultsToJson(const std::vector<DatasetResult>& results, const FalkoParams& params = FalkoParams{});

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
