// agvnav-lidar-calibrate: per-laser intrinsic calibration (D_corr, theta, alpha; V_o, H_o on
// request) of a multi-beam lidar from scans of a planar target, the thesis' cost (mean squared
// distance of each target scan to its PCA plane) solved with Ceres. The scans come either from
// recordings of the sensor's data packets, one per placement (--recording), or from the
// simulator's calibration hall (9 distances x 5 tilts by default) with a factory file perturbed
// by known amounts as the truth; the program reports the plane residuals before / after (and, in
// the simulation, the errors against the truth and the noise floor), the conditioning and the wall
// time, and writes the calibrated intrinsics as velodyne_pointcloud YAML.
#include <CLI/CLI.hpp>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "agv/core/angle.hpp"
#include "agv/datasets/velodyne_calibration.hpp"
#include "agv/lidar_calibration/hall_scans.hpp"
#include "agv/lidar_calibration/intrinsic_calibration.hpp"
#include "agv/lidar_calibration/recording_scans.hpp"
#include "agv/report/json.hpp"
#include "agv/report/text_file.hpp"

namespace {

namespace lc = agv::lidar_calibration;
using agv::report::Json;

Json conditioningJson(const lc::ConditioningReport& c) {
  Json j;
  j["parameters"] = c.parameters;
  j["condition_number"] = c.conditionNumber;
  j["null_directions"] = c.nullDirections;
  Json smallest = Json::array();
  for (const lc::ConditionDirection& d : c.smallest) {
    smallest.push_back(Json{{"singular_value", d.singularValue}, {"gauge", d.gauge}, {"components", d.components}});
  }
  j["smallest"] = smallest;
  return j;
}

/// What a laser's report says in every run (refused or not): its outcome, evidence and correlation.
Json laserReportJson(const lc::LaserReport& l) {
  return Json{{"laser", l.laser},
              {"estimated", l.estimated},
              {"reason", l.reason},
              {"points", l.points},
              {"scans", l.scans},
              {"max_correlation", l.maxCorrelation},
              {"max_correlation_pair", l.maxCorrelationPair}};
}

/// A scan's target as segmented, with its plane rms at the start values.
Json scanReportJson(const lc::ScanReport& r, double rmsStart) {
  return Json{{"name", r.name},
              {"returns", r.returns},
              {"target_points", r.targetPoints},
              {"rms_start_m", rmsStart},
              {"extent_m", Json{r.extent.x(), r.extent.y()}}};
}

void printConditioning(const char* title, const lc::ConditioningReport& c) {
  std::printf("%s: %zu parameters, condition number %.3g (gauges fixed), %zu null directions besides the gauges\n",
              title, c.parameters, c.conditionNumber, c.nullDirections);
  for (const lc::ConditionDirection& d : c.smallest) {
    std::printf("  singular value %.3e%s%s: %s\n", d.singularValue, d.gauge.empty() ? "" : " gauge ", d.gauge.c_str(),
                d.components.c_str());
  }
}

/// Monte-Carlo statistics: the share beyond 3 sigma per parameter kind; z = error / sigma over all
/// runs (rms 1 if the sigma is honest); per laser the mean z over the runs (a bias in sigma units,
/// ~1/sqrt(runs) without one) and the spread of z about it (the noise part, ~1).
struct McStats {
  explicit McStats(std::size_t lasers)
      : zSum(lasers * agv::kLaserParamCount, 0.0),
        zSq(lasers * agv::kLaserParamCount, 0.0),
        zN(lasers * agv::kLaserParamCount, 0) {}
  std::vector<double> zSum;
  std::vector<double> zSq;
  std::vector<int> zN;
  std::array<std::size_t, agv::kLaserParamCount> beyondBy{};
  std::array<std::size_t, agv::kLaserParamCount> comparedBy{};
  std::size_t beyond = 0;
  std::size_t compared = 0;
  double worst = 0.0;

  void add(const lc::IntrinsicCalibrationResult& r, const lc::TruthComparison& c,
           const lc::IntrinsicCalibrationConfig& config) {
    beyond += c.beyondThreeSigma;
    compared += c.compared;
    worst = std::max(worst, c.maxSigmaRatio);
    for (int k = 0; k < agv::kLaserParamCount; ++k) {
      beyondBy[static_cast<std::size_t>(k)] += c.beyondByParam[static_cast<std::size_t>(k)];
      comparedBy[static_cast<std::size_t>(k)] += c.comparedByParam[static_cast<std::size_t>(k)];
    }
    for (const lc::LaserReport& l : r.lasers) {
      for (int k = 0; k < agv::kLaserParamCount; ++k) {
        const std::size_t i = l.laser * agv::kLaserParamCount + static_cast<std::size_t>(k);
        if (l.estimated && config.estimate[k] && l.sigma[k] > 0.0 && i < zN.size()) {
          const double z = c.error[l.laser][k] / l.sigma[k];
          zSum[i] += z;
          zSq[i] += z * z;
          ++zN[i];
        }
      }
    }
  }

  Json report(const lc::IntrinsicCalibrationConfig& config) const {
    Json byParam;
    for (int k = 0; k < agv::kLaserParamCount; ++k) {
      if (!config.estimate[k]) {
        continue;
      }
      double all = 0.0;
      double allN = 0.0;
      double meanSq = 0.0;
      double maxMean = 0.0;
      double spreadSq = 0.0;
      double lasersN = 0.0;
      for (std::size_t i = static_cast<std::size_t>(k); i < zN.size(); i += agv::kLaserParamCount) {
        if (zN[i] < 2) {
          continue;
        }
        const double n = zN[i];
        const double mean = zSum[i] / n;
        all += zSq[i];
        allN += n;
        meanSq += mean * mean;
        maxMean = std::max(maxMean, std::fabs(mean));
        spreadSq += (zSq[i] - n * mean * mean) / (n - 1.0);
        lasersN += 1.0;
      }
      const std::size_t ks = static_cast<std::size_t>(k);
      const double rmsZ = allN > 0.0 ? std::sqrt(all / allN) : 0.0;
      const double rmsMean = lasersN > 0.0 ? std::sqrt(meanSq / lasersN) : 0.0;
      const double spread = lasersN > 0.0 ? std::sqrt(spreadSq / lasersN) : 0.0;
      std::printf(
          "  %-7s %zu of %zu beyond 3 sigma (%.3f %%); z = error/sigma: rms %.3f; per laser mean z rms %.3f (max "
          "|%.3f|), spread %.3f\n",
          lc::laserParamName(k), beyondBy[ks], comparedBy[ks],
          comparedBy[ks] > 0 ? 100.0 * static_cast<double>(beyondBy[ks]) / static_cast<double>(comparedBy[ks]) : 0.0,
          rmsZ, rmsMean, maxMean, spread);
      Json sums = Json::array();
      Json squares = Json::array();
      Json counts = Json::array();
      for (std::size_t i = static_cast<std::size_t>(k); i < zN.size(); i += agv::kLaserParamCount) {
        sums.push_back(zSum[i]);
        squares.push_back(zSq[i]);
        counts.push_back(zN[i]);
      }
      byParam[lc::laserParamName(k)] = Json{{"compared", comparedBy[ks]},
                                            {"beyond_three_sigma", beyondBy[ks]},
                                            {"rms_z", rmsZ},
                                            {"rms_mean_z", rmsMean},
                                            {"max_abs_mean_z", maxMean},
                                            {"spread_z", spread},
                                            {"per_laser", Json{{"z_sum", sums}, {"z_sq", squares}, {"n", counts}}}};
    }
    return byParam;
  }
};

}  // namespace

int main(int argc, char** argv) {
  std::string factoryPath;
  std::string truthPath;
  std::string outputPath;
  std::string jsonPath;
  double perturbDist = 0.05;
  double perturbThetaDeg = 0.3;
  double perturbAlphaDeg = 0.5;
  double perturbOffsets = 0.0;
  int distances = 9;
  int tilts = 5;
  double nearest = 3.0;
  double farthest = 22.0;
  double minTiltDeg = 0.0;
  double maxTiltDeg = 24.0;
  double windowDeg = 0.0;
  bool noQuantize = false;
  bool estimateOffsets = false;
  bool quiet = false;
  int monteCarlo = 0;
  int monteCarloFirst = 0;
  std::uint64_t seed = 1;
  lc::HallScansConfig sim;
  lc::IntrinsicCalibrationConfig config;
  std::vector<std::string> recordings;
  lc::RecordingScanOptions recordingOptions;
  std::string writeRecordingsDir;

  CLI::App app{"agvnav-lidar-calibrate: per-laser intrinsics of a multi-beam lidar from planar-target scans (Ceres)"};
  app.add_option("--factory", factoryPath,
                 "factory / start intrinsics (db.xml or YAML; default: the shared HDL-64E S2.1 SZTAKI file)")
      ->check(CLI::ExistingFile);
  app.add_option("--recording", recordings,
                 "recorded data packets of one placement of the sensor in front of the target (pcap, ROS 2 bag of "
                 "VelodyneScan, or bare 1206-byte payloads); repeat per placement. Calibrates from these instead of "
                 "the simulated hall")
      ->check(CLI::ExistingFile);
  app.add_option("--port", recordingOptions.port, "pcap recordings: UDP port of the data packets");
  app.add_option("--revolutions", recordingOptions.maxRevolutions,
                 "recordings: whole revolutions used per recording, each one scan (0: all)");
  app.add_option("--target-width", config.segmentation.targetWidth, "[m] the planar target's larger side")
      ->check(CLI::Range(0.2, 50.0));
  app.add_option("--target-height", config.segmentation.targetHeight, "[m] the planar target's smaller side")
      ->check(CLI::Range(0.2, 50.0));
  app.add_option(
      "--write-recordings", writeRecordingsDir,
      "simulation: also write each simulated placement as a recording of data packets (DIR/placement-NN.bin; "
      "HDL-32E / HDL-64E tables)");
  app.add_option("--truth", truthPath, "simulated unit's intrinsics (default: the factory file perturbed)")
      ->check(CLI::ExistingFile);
  app.add_option("--perturb-dist", perturbDist, "[m] truth = factory D_corr + uniform(+-this)")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--perturb-theta", perturbThetaDeg, "[deg] theta perturbation bound")->check(CLI::Range(0.0, 5.0));
  app.add_option("--perturb-alpha", perturbAlphaDeg, "[deg] alpha perturbation bound")->check(CLI::Range(0.0, 5.0));
  app.add_option("--perturb-offsets", perturbOffsets, "[m] V_o and H_o perturbation bound")
      ->check(CLI::Range(0.0, 0.5));
  app.add_option("--noise", sim.sensor.rangeNoise, "[m] range noise (standard deviation)")->check(CLI::Range(0.0, 1.0));
  app.add_flag("--no-quantize", noQuantize, "keep the simulated ranges continuous (no 2 mm counts)");
  app.add_option("--firings", sim.sensor.firings, "firings per revolution")->check(CLI::Range(36, 20000));
  app.add_option("--azimuth-window", windowDeg, "[deg] fire only within +-this of the target (0: full turn)")
      ->check(CLI::Range(0.0, 180.0));
  app.add_option("--distances", distances, "placements: number of distances")->check(CLI::Range(1, 50));
  app.add_option("--nearest", nearest, "[m] nearest placement")->check(CLI::Range(2.0, 25.0));
  app.add_option("--farthest", farthest, "[m] farthest placement")->check(CLI::Range(2.0, 25.0));
  app.add_option("--tilts", tilts, "placements: number of head tilts")->check(CLI::Range(1, 20));
  app.add_option("--min-tilt", minTiltDeg, "[deg] lowest head tilt (up)")->check(CLI::Range(-30.0, 40.0));
  app.add_option("--max-tilt", maxTiltDeg, "[deg] highest head tilt (up)")->check(CLI::Range(-30.0, 40.0));
  app.add_flag("--estimate-offsets", estimateOffsets, "also estimate V_o and H_o");
  const std::map<std::string, lc::PlaneResidual> residuals{{"orthogonal", lc::PlaneResidual::Orthogonal},
                                                           {"beam", lc::PlaneResidual::AlongBeam}};
  app.add_option("--residual", config.residual,
                 "orthogonal: the thesis' plane distance; beam: the range error along the beam (unbiased)")
      ->transform(CLI::CheckedTransformer(residuals, CLI::ignore_case));
  bool noBiasCorrection = false;
  app.add_flag("--no-bias-correction", noBiasCorrection,
               "orthogonal residual: report the thesis' minimum itself (its noise bias not removed)");
  app.add_option("--bias-correction-steps", config.noiseBiasSteps,
                 "Gauss-Newton steps of the noise-bias correction (1: its first-order bias)")
      ->check(CLI::Range(1, 10));
  bool freeMeanTheta = false;
  app.add_flag("--free-mean-theta", freeMeanTheta, "do not hold the mean theta at the factory values (near-gauge)");
  app.add_option("--passes", config.passes, "segment + solve rounds")->check(CLI::Range(1, 5));
  app.add_option("--threads", config.threads, "Ceres threads")->check(CLI::Range(1, 2));
  app.add_option("--max-correlation", config.maxCorrelation,
                 "hold a laser two of whose parameters correlate beyond this")
      ->check(CLI::Range(0.5, 1.0));
  app.add_option("--seed", seed, "perturbation and noise seed");
  app.add_option("--monte-carlo", monteCarlo, "repeat with this many noise seeds; report the errors against sigma")
      ->check(CLI::Range(0, 1000));
  app.add_option("--monte-carlo-first", monteCarloFirst,
                 "index of the first Monte-Carlo run (noise seed = seed + 1000 + index): split a Monte-Carlo over "
                 "processes; the JSON's per-laser z sums add up")
      ->check(CLI::Range(0, 100000));
  app.add_option("--output", outputPath, "write the calibrated intrinsics (velodyne_pointcloud YAML)");
  app.add_option("--json", jsonPath, "write the figures as JSON");
  app.add_flag("--quiet", quiet, "no progress lines");
  CLI11_PARSE(app, argc, argv);
  if (factoryPath.empty()) {
    factoryPath = std::string(AGVNAV_DEFAULT_DATA_DIR) + "/lidar3d/calibration/hdl64e_s2.1_sztaki.yaml";
  }
  const bool simulated = recordings.empty();
  if (!simulated && (!truthPath.empty() || !writeRecordingsDir.empty() || monteCarlo > 0)) {
    std::fprintf(stderr,
                 "agvnav-lidar-calibrate: --truth, --write-recordings and --monte-carlo need the simulation "
                 "(no --recording)\n");
    return 2;
  }
  if (config.segmentation.targetHeight > config.segmentation.targetWidth) {
    std::fprintf(stderr,
                 "agvnav-lidar-calibrate: --target-height above --target-width (the width is the larger side)\n");
    return 2;
  }
  if (farthest < nearest) {
    std::fprintf(stderr, "agvnav-lidar-calibrate: --farthest below --nearest\n");
    return 2;
  }

  std::string error;
  static agv::LaserIntrinsics factory;
  static agv::LaserIntrinsics truth;
  if (!agv::datasets::readVelodyneCalibration(factoryPath, factory, error)) {
    std::fprintf(stderr, "agvnav-lidar-calibrate: %s\n", error.c_str());
    return 2;
  }
  std::mt19937_64 rng(seed);
  if (!truthPath.empty()) {
    if (!agv::datasets::readVelodyneCalibration(truthPath, truth, error)) {
      std::fprintf(stderr, "agvnav-lidar-calibrate: %s\n", error.c_str());
      return 2;
    }
  } else {
    truth = agv::sim::perturbIntrinsics(factory, perturbDist, agv::deg2rad(perturbThetaDeg),
                                        agv::deg2rad(perturbAlphaDeg), perturbOffsets, rng);
  }
  if (truth.size() != factory.size()) {
    std::fprintf(stderr, "agvnav-lidar-calibrate: the truth has %zu lasers, the factory file %zu\n", truth.size(),
                 factory.size());
    return 2;
  }
  sim.placements =
      agv::sim::hallProtocol(distances, nearest, farthest, tilts, agv::deg2rad(minTiltDeg), agv::deg2rad(maxTiltDeg));
  sim.sensor.quantize = !noQuantize;
  sim.sensor.azimuthWindow = agv::deg2rad(windowDeg);
  sim.seed = seed;
  config.holdMeanTheta = !freeMeanTheta;
  config.correctNoiseBias = !noBiasCorrection;
  config.estimate.vertOffset = estimateOffsets;
  config.estimate.horizOffset = estimateOffsets;
  if (!quiet) {
    config.progress = [](const std::string& line) { std::printf("  %s\n", line.c_str()); };
  }
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<lc::CalibrationScan> scans;
  Json recordingJson = Json::array();
  if (simulated) {
    std::printf(
        "agvnav-lidar-calibrate: %zu lasers (%s), %zu placements (%d distances %.1f..%.1f m x %d tilts %.0f..%.0f "
        "deg), noise %.3f m, truth = factory + D_corr +-%.3f m, theta +-%.2f deg, alpha +-%.2f deg, V_o/H_o +-%.3f m\n",
        factory.size(), factoryPath.c_str(), sim.placements.size(), distances, nearest, farthest, tilts, minTiltDeg,
        maxTiltDeg, sim.sensor.rangeNoise, perturbDist, perturbThetaDeg, perturbAlphaDeg, perturbOffsets);
    scans = lc::simulateHallScans(sim, truth);
  } else {
    std::printf("agvnav-lidar-calibrate: %zu lasers (%s), %zu recordings, target %.2f x %.2f m\n", factory.size(),
                factoryPath.c_str(), recordings.size(), config.segmentation.targetWidth,
                config.segmentation.targetHeight);
    for (const std::string& path : recordings) {
      lc::RecordingStats rs;
      if (!lc::readRecordingScans(path, factory, recordingOptions, scans, rs, error)) {
        std::fprintf(stderr, "agvnav-lidar-calibrate: %s\n", error.c_str());
        return 2;
      }
      std::printf(
          "%s: %s, %zu packets (%zu refused, %zu blocks skipped), %zu revolutions (%zu partial), %zu used, "
          "%zu returns\n",
          path.c_str(), rs.container.c_str(), rs.packets, rs.refusedPackets, rs.skippedBlocks, rs.revolutions,
          rs.partial, rs.used, rs.returns);
      recordingJson.push_back(Json{{"path", path},
                                   {"container", rs.container},
                                   {"packets", rs.packets},
                                   {"refused_packets", rs.refusedPackets},
                                   {"skipped_blocks", rs.skippedBlocks},
                                   {"revolutions", rs.revolutions},
                                   {"partial_revolutions", rs.partial},
                                   {"scans", rs.used},
                                   {"returns", rs.returns}});
    }
  }
  const double simSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::size_t returns = 0;
  for (const lc::CalibrationScan& s : scans) {
    returns += s.returns.size();
  }
  std::printf("%s %zu scans, %zu returns in %.2f s\n", simulated ? "simulated" : "read", scans.size(), returns,
              simSeconds);
  // --write-recordings: each simulated placement as HDL packets, read back through the recording
  // path and compared with the simulated returns (what a later --recording run will calibrate on).
  Json written;
  if (!writeRecordingsDir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(writeRecordingsDir, ec);
    double rounding = 0.0;
    std::size_t differ = 0;
    Json files = Json::array();
    for (std::size_t s = 0; s < scans.size(); ++s) {
      char name[48];
      std::snprintf(name, sizeof name, "placement-%02zu.bin", s);
      const std::string path = writeRecordingsDir + "/" + name;
      double r = 0.0;
      std::vector<lc::CalibrationScan> back;
      lc::RecordingStats rs;
      if (!lc::writeRecording(path, scans[s], truth, r, error) ||
          !lc::readRecordingScans(path, truth, lc::RecordingScanOptions{}, back, rs, error)) {
        std::fprintf(stderr, "agvnav-lidar-calibrate: %s\n", error.c_str());
        return 2;
      }
      rounding = std::max(rounding, r);
      const std::vector<agv::RawReturn>& a = scans[s].returns;
      const std::vector<agv::RawReturn>& b = back.front().returns;
      differ += a.size() > b.size() ? a.size() - b.size() : b.size() - a.size();
      for (std::size_t i = 0; i < a.size() && i < b.size(); ++i) {
        differ += a[i].laser != b[i].laser || a[i].range != b[i].range || std::fabs(a[i].phi - b[i].phi) > r + 1e-12
                      ? 1U
                      : 0U;
      }
      files.push_back(path);
    }
    std::printf(
        "wrote %zu recordings to %s (head angle rounded to the packets' 0.01 deg: at most %.4f deg); read back: %s\n",
        scans.size(), writeRecordingsDir.c_str(), agv::rad2deg(rounding),
        differ == 0 ? "the same returns" : "DIFFERENT returns");
    written = Json{{"files", files}, {"max_azimuth_rounding_rad", rounding}, {"read_back_equal", differ == 0}};
    if (differ != 0) {
      std::fprintf(stderr, "agvnav-lidar-calibrate: %zu returns of the written recordings read back differently\n",
                   differ);
      return 2;
    }
  }

  lc::IntrinsicCalibrationResult result;
  const auto t1 = std::chrono::steady_clock::now();
  const bool ok = lc::calibrateIntrinsics(scans, factory, config, result, error);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
  Json doc;
  doc["program"] = "agvnav-lidar-calibrate";
  doc["factory"] = factoryPath;
  doc["lasers"] = factory.size();
  doc["input"] = simulated ? "simulation" : "recordings";
  if (simulated) {
    doc["placements"] = sim.placements.size();
    doc["noise_m"] = sim.sensor.rangeNoise;
  } else {
    doc["recordings"] = recordingJson;
    doc["target_m"] = Json{config.segmentation.targetWidth, config.segmentation.targetHeight};
  }
  doc["scan_count"] = scans.size();
  if (!written.is_null()) {
    doc["written_recordings"] = written;
  }
  doc["residual"] = config.residual == lc::PlaneResidual::AlongBeam ? "beam" : "orthogonal";
  doc["returns"] = returns;
  doc["ok"] = ok;
  if (!ok) {
    std::fprintf(stderr, "agvnav-lidar-calibrate: %s\n", error.c_str());
    doc["error"] = error;
  }
  printConditioning("conditioning at the factory values", result.startConditioning);
  Json lasers = Json::array();
  std::size_t held = 0;
  for (const lc::LaserReport& l : result.lasers) {
    if (!l.estimated) {
      ++held;
      std::printf("laser %2zu held at the start values: %s\n", l.laser, l.reason.c_str());
    }
  }
  if (!ok) {
    // The plane residual of each scan's target with the start values (the scans segmented before the refusal).
    std::vector<std::vector<std::size_t>> found;
    for (const lc::ScanReport& r : result.scans) {
      found.push_back(r.targets);
    }
    const std::vector<double> rmsStart = result.scans.size() == scans.size()
                                             ? lc::planeResiduals(scans, found, factory)
                                             : std::vector<double>(result.scans.size(), 0.0);
    Json scanJson = Json::array();
    if (!result.scans.empty()) {
      std::printf("\n%-40s %8s %10s %16s\n", "scan", "points", "rms start", "target extent");
    }
    for (std::size_t s = 0; s < result.scans.size(); ++s) {
      const lc::ScanReport& r = result.scans[s];
      std::printf("%-40s %8zu %10.5f %7.2f x %-7.2f\n", r.name.c_str(), r.targetPoints, rmsStart[s], r.extent.x(),
                  r.extent.y());
      scanJson.push_back(scanReportJson(r, rmsStart[s]));
    }
    doc["scans"] = scanJson;
    doc["conditioning_start"] = conditioningJson(result.startConditioning);
    for (const lc::LaserReport& l : result.lasers) {
      lasers.push_back(laserReportJson(l));
    }
    doc["laser_reports"] = lasers;
    if (!jsonPath.empty() && !agv::report::writeJsonFile(jsonPath, doc, error)) {
      std::fprintf(stderr, "agvnav-lidar-calibrate: %s\n", error.c_str());
    }
    return 3;
  }
  // Noise floor: the truth's own plane residual on the same target points (simulation only; for a
  // recording the table's "err" columns are the change from the start values).
  std::vector<std::vector<std::size_t>> targets;
  for (const lc::ScanReport& s : result.scans) {
    targets.push_back(s.targets);
  }
  std::vector<double> floor(result.scans.size(), 0.0);
  lc::TruthComparison cmp;
  if (simulated) {
    floor = lc::planeResiduals(scans, targets, truth);
    cmp = lc::compareWithTruth(result, truth, config);
  } else {
    for (const lc::LaserReport& l : result.lasers) {
      cmp.error.resize(std::max(cmp.error.size(), l.laser + 1),
                       Eigen::Matrix<double, agv::kLaserParamCount, 1>::Zero());
      cmp.error[l.laser] = agv::toVector(l.estimate) - agv::toVector(l.start);
    }
  }

  std::printf("\n%-22s %8s %10s %10s %10s %8s\n", "scan", "points", "rms start", "rms final",
              simulated ? "rms truth" : "", simulated ? "final/truth" : "");
  Json scanJson = Json::array();
  double worstRatio = 0.0;
  for (std::size_t s = 0; s < result.scans.size(); ++s) {
    const lc::ScanReport& r = result.scans[s];
    const double ratio = floor[s] > 0.0 ? r.rmsFinal / floor[s] : 0.0;
    worstRatio = std::max(worstRatio, ratio);
    std::printf("%-22s %8zu %10.5f %10.5f %10.5f %8.4f\n", r.name.c_str(), r.targetPoints, r.rmsStart, r.rmsFinal,
                floor[s], ratio);
    Json sj = scanReportJson(r, r.rmsStart);
    sj["rms_final_m"] = r.rmsFinal;
    if (simulated) {
      sj["rms_truth_m"] = floor[s];
    }
    scanJson.push_back(sj);
  }
  const char* errHead = simulated ? "err" : "chg";  // against the truth / from the start values
  std::printf("\n%5s %7s %10s %6s [mm] %10s %5s [mdeg] %10s %5s [mdeg] %6s\n", "laser", "points", "D_corr", errHead,
              "theta[deg]", errHead, "alpha[deg]", errHead, "corr");
  for (const lc::LaserReport& l : result.lasers) {
    const auto& e = cmp.error[l.laser];
    std::printf("%5zu %7zu %10.5f %5.2f+-%-4.2f %10.4f %5.1f+-%-4.1f %10.4f %5.1f+-%-4.1f %6.3f%s\n", l.laser, l.points,
                l.estimate.distCorrection, e[agv::kDistCorrection] * 1e3, l.sigma[agv::kDistCorrection] * 1e3,
                agv::rad2deg(l.estimate.theta), agv::rad2deg(e[agv::kTheta]) * 1e3,
                agv::rad2deg(l.sigma[agv::kTheta]) * 1e3, agv::rad2deg(l.estimate.alpha),
                agv::rad2deg(e[agv::kAlpha]) * 1e3, agv::rad2deg(l.sigma[agv::kAlpha]) * 1e3, l.maxCorrelation,
                l.estimated ? "" : "  held");
    Json lj = laserReportJson(l);
    Json est;
    Json sig;
    Json err;
    for (int k = 0; k < agv::kLaserParamCount; ++k) {
      est[lc::laserParamName(k)] = agv::toVector(l.estimate)[k];
      sig[lc::laserParamName(k)] = l.sigma[k];
      err[lc::laserParamName(k)] = e[k];
    }
    lj["estimate"] = est;
    lj["sigma"] = sig;
    lj[simulated ? "error_vs_truth" : "change_from_start"] = err;
    lasers.push_back(lj);
  }
  printConditioning("\nconditioning at the solution", result.conditioning);
  Json errJson;
  if (simulated) {
    std::printf(
        "\nerrors against the truth (%zu lasers estimated, %zu held; held common offsets removed: alpha %.4f deg, "
        "theta %.4f deg):\n",
        result.lasersEstimated, held, agv::rad2deg(cmp.commonAlpha), agv::rad2deg(cmp.commonTheta));
    for (int k = 0; k < agv::kLaserParamCount; ++k) {
      if (!config.estimate[k]) {
        continue;
      }
      const bool angle = k == agv::kTheta || k == agv::kAlpha;
      const double f = angle ? agv::rad2deg(1.0) * 1e3 : 1e3;
      std::printf("  %-7s start max %8.3f, final max %8.4f rms %8.4f %s\n", lc::laserParamName(k),
                  cmp.maxAbsStart[k] * f, cmp.maxAbs[k] * f, cmp.rms[k] * f, angle ? "mdeg" : "mm");
      errJson[lc::laserParamName(k)] =
          Json{{"start_max", cmp.maxAbsStart[k]}, {"final_max", cmp.maxAbs[k]}, {"final_rms", cmp.rms[k]}};
    }
    std::printf("  |error| / sigma: max %.2f, %zu of %zu beyond 3 sigma\n", cmp.maxSigmaRatio, cmp.beyondThreeSigma,
                cmp.compared);
  } else {
    std::printf("\n%zu lasers estimated, %zu held\n", result.lasersEstimated, held);
  }
  if (result.noiseBias.applied) {
    std::printf(
        "noise-bias correction of the thesis' minimum (range sigma %.5f m, %d Gauss-Newton steps): largest change "
        "D_corr %.3f mm, theta %.2f mdeg, alpha %.2f mdeg; thesis cost there %.6e m^2 (minimum %.6e)\n",
        result.noiseBias.rangeSigma, result.noiseBias.iterations, result.noiseBias.step[agv::kDistCorrection] * 1e3,
        agv::rad2deg(result.noiseBias.step[agv::kTheta]) * 1e3, agv::rad2deg(result.noiseBias.step[agv::kAlpha]) * 1e3,
        result.costCalibrated, result.costFinal);
  }
  std::printf(
      "cost (sum over scans of the mean squared plane distance): start %.6e, final %.6e m^2 (PCA planes), "
      "%.6e m^2 (Ceres' planes), planes within %.2e rad",
      result.costStart, result.costFinal, result.costFinalJoint, result.maxPlaneAngle);
  if (simulated) {
    std::printf("; worst scan rms final / truth %.4f", worstRatio);
  }
  std::printf("\n");
  std::printf("residual sigma %.5f m; %d iterations; wall time %.2f s (segmentation %.2f, solve %.2f, analysis %.2f)\n",
              result.noiseSigma, result.iterations, wall, result.secondsSegmentation, result.secondsSolve,
              result.secondsAnalysis);
  doc["cost_start_m2"] = result.costStart;
  doc["cost_final_m2"] = result.costFinal;
  doc["cost_final_joint_m2"] = result.costFinalJoint;
  doc["max_plane_angle_rad"] = result.maxPlaneAngle;
  if (simulated) {
    doc["worst_rms_final_over_truth"] = worstRatio;
  }
  doc["noise_sigma_m"] = result.noiseSigma;
  doc["range_sigma_m"] = result.rangeSigma;
  doc["cost_calibrated_m2"] = result.costCalibrated;
  {
    Json step;
    for (int k = 0; k < agv::kLaserParamCount; ++k) {
      step[lc::laserParamName(k)] = result.noiseBias.step[k];
    }
    doc["noise_bias_correction"] = Json{{"applied", result.noiseBias.applied},
                                        {"iterations", result.noiseBias.iterations},
                                        {"range_sigma_m", result.noiseBias.rangeSigma},
                                        {"largest_change", step}};
  }
  doc["iterations"] = result.iterations;
  doc["wall_time_s"] = wall;
  doc["seconds"] = Json{{simulated ? "simulation" : "reading", simSeconds},
                        {"segmentation", result.secondsSegmentation},
                        {"solve", result.secondsSolve},
                        {"analysis", result.secondsAnalysis}};
  doc["lasers_estimated"] = result.lasersEstimated;
  doc["lasers_held"] = held;
  if (simulated) {
    doc["errors_vs_truth"] = errJson;
    doc["common_alpha_offset_rad"] = cmp.commonAlpha;
    doc["common_theta_offset_rad"] = cmp.commonTheta;
    doc["max_error_over_sigma"] = cmp.maxSigmaRatio;
    doc["beyond_three_sigma"] = cmp.beyondThreeSigma;
  }
  doc["conditioning_start"] = conditioningJson(result.startConditioning);
  doc["conditioning"] = conditioningJson(result.conditioning);
  doc["scans"] = scanJson;
  doc["laser_reports"] = lasers;

  // Monte-Carlo: the same truth, new noise; errors against each run's sigma.
  if (monteCarlo > 0) {
    lc::IntrinsicCalibrationConfig mc = config;
    mc.progress = nullptr;
    McStats calibrated(factory.size());
    McStats minimum(factory.size());  // the thesis' minimum itself (when the correction moved it)
    bool corrected = false;
    double seconds = 0.0;
    int failed = 0;
    for (int run = 0; run < monteCarlo; ++run) {
      lc::HallScansConfig s = sim;
      s.seed = seed + 1000U + static_cast<std::uint64_t>(monteCarloFirst + run);
      lc::IntrinsicCalibrationResult r;
      std::string e;
      const auto tr = std::chrono::steady_clock::now();
      if (!lc::calibrateIntrinsics(lc::simulateHallScans(s, truth), factory, mc, r, e)) {
        ++failed;
        std::printf("  monte-carlo %d: refused: %s\n", run, e.c_str());
        continue;
      }
      seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - tr).count();
      const lc::TruthComparison c = lc::compareWithTruth(r, truth, mc);
      calibrated.add(r, c, mc);
      corrected = corrected || r.noiseBias.applied;
      lc::IntrinsicCalibrationResult m = r;
      for (lc::LaserReport& l : m.lasers) {
        l.estimate = l.minimum;
      }
      const lc::TruthComparison cm = lc::compareWithTruth(m, truth, mc);
      minimum.add(m, cm, mc);
      if (!quiet) {
        std::printf(
            "  monte-carlo %d: max |error|/sigma %.2f, %zu of %zu beyond 3 sigma (thesis' minimum: %.2f, %zu)\n", run,
            c.maxSigmaRatio, c.beyondThreeSigma, c.compared, cm.maxSigmaRatio, cm.beyondThreeSigma);
      }
    }
    std::printf(
        "monte-carlo: %d runs (%d failed), %zu of %zu parameter errors beyond 3 sigma (%.3f %%), worst %.2f "
        "sigma, mean calibration time %.2f s\n",
        monteCarlo, failed, calibrated.beyond, calibrated.compared,
        calibrated.compared > 0
            ? 100.0 * static_cast<double>(calibrated.beyond) / static_cast<double>(calibrated.compared)
            : 0.0,
        calibrated.worst, monteCarlo > failed ? seconds / (monteCarlo - failed) : 0.0);
    Json mcJson{{"runs", monteCarlo},
                {"first", monteCarloFirst},
                {"failed", failed},
                {"compared", calibrated.compared},
                {"beyond_three_sigma", calibrated.beyond},
                {"worst_sigma", calibrated.worst},
                {"mean_seconds", seconds / std::max(1, monteCarlo - failed)},
                {"by_param", calibrated.report(mc)}};
    if (corrected) {
      std::printf(
          "monte-carlo, the thesis' minimum without the noise-bias correction (same runs and sigmas): %zu of %zu "
          "beyond 3 sigma (%.3f %%), worst %.2f sigma\n",
          minimum.beyond, minimum.compared,
          minimum.compared > 0 ? 100.0 * static_cast<double>(minimum.beyond) / static_cast<double>(minimum.compared)
                               : 0.0,
          minimum.worst);
      mcJson["thesis_minimum"] = Json{{"compared", minimum.compared},
                                      {"beyond_three_sigma", minimum.beyond},
                                      {"worst_sigma", minimum.worst},
                                      {"by_param", minimum.report(mc)}};
    }
    doc["monte_carlo"] = mcJson;
  }
  if (!outputPath.empty()) {
    const std::string text = agv::datasets::formatVelodyneYaml(
        result.calibrated, "agvnav-lidar-calibrate: calibrated from " + std::to_string(scans.size()) +
                               " planar-target scans, start " + factoryPath);
    if (!agv::report::writeTextFile(outputPath, text, error)) {
      std::fprintf(stderr, "agvnav-lidar-calibrate: %s\n", error.c_str());
      return 2;
    }
    // Round trip: the file read back by the project's reader gives the same table.
    static agv::LaserIntrinsics back;
    bool same =
        agv::datasets::readVelodyneCalibration(outputPath, back, error) && back.size() == result.calibrated.size();
    for (std::size_t l = 0; same && l < back.size(); ++l) {
      same = agv::toVector(back.params(l)) == agv::toVector(result.calibrated.params(l));
    }
    std::printf("wrote %s (read back: %s)\n", outputPath.c_str(), same ? "the same table" : "DIFFERENT");
    doc["output"] = Json{{"path", outputPath}, {"read_back_equal", same}};
    if (!same) {
      std::fprintf(stderr, "agvnav-lidar-calibrate: %s does not read back as written\n", outputPath.c_str());
      return 2;
    }
  }
  if (!jsonPath.empty() && !agv::report::writeJsonFile(jsonPath, doc, error)) {
    std::fprintf(stderr, "agvnav-lidar-calibrate: %s\n", error.c_str());
    return 2;
  }
  return 0;
}
