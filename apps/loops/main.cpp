// agvnav-loops: the FALKO thesis' loop-closure experiments (GLAROT + CG / AH / RANSAC, precision
// and recall versus N_min, offline and online) on the FLIRTLib logs, and online pose-graph mapping
// with Ceres on the gmapping-corrected logs (--pose-graph). Tables on stdout, progress on stderr,
// --json and --svg-dir for the figures (docs/loop-closure.md).
#include <CLI/CLI.hpp>

#include <cstdio>
#include <exception>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "agv/datasets/carmen_log.hpp"
#include "agv/report/json.hpp"
#include "agv/report/text_file.hpp"
#include "loops.hpp"
#include "pose_graph.hpp"

namespace {

// The FLIRTLib logs (VERTEX2 ground truth) and the corrected logs, relative to the data folder.
const std::map<std::string, std::string> kLoopLogs{{"intel", "laser2d/intel/intel-lab.log.gz"},
                                                   {"fr079", "laser2d/fr079/fr079.log.gz"},
                                                   {"mit-csail", "laser2d/mit-csail/mit-cscail.log.gz"}};
const std::map<std::string, std::string> kMappingLogs{{"fr079", "laser2d/fr079/freiburg-079-corrected.log.gz"},
                                                      {"intel", "laser2d/intel/intel-corrected.log.gz"},
                                                      {"aces", "laser2d/aces/aces-corrected.log.gz"}};

bool readLog(const std::string& path, agv::datasets::CarmenLog& log) {
  std::string error;
  std::fprintf(stderr, "agvnav-loops: reading %s\n", path.c_str());
  if (!agv::datasets::readCarmenLog(path, log, error)) {
    std::fprintf(stderr, "agvnav-loops: %s\n", error.c_str());
    return false;
  }
  if (log.scans.empty()) {
    std::fprintf(stderr, "agvnav-loops: %s: no laser scans (ROBOTLASER1 / FLASER lines) in the file\n", path.c_str());
    return false;
  }
  return true;
}

// A log's name in the output: its file name without the extensions.
std::string logName(const std::string& path) {
  std::string name = path.substr(path.find_last_of('/') == std::string::npos ? 0 : path.find_last_of('/') + 1);
  return name.substr(0, name.find('.'));
}

// (name, path) of each log: the named datasets under the data folder, or the files given instead.
std::vector<std::pair<std::string, std::string>> inputsOf(const std::vector<std::string>& names,
                                                          const std::map<std::string, std::string>& table,
                                                          const std::vector<std::string>& files,
                                                          const std::string& dataDir) {
  std::vector<std::pair<std::string, std::string>> inputs;
  if (!files.empty()) {
    for (const std::string& path : files) {
      inputs.emplace_back(logName(path), path);
    }
    return inputs;
  }
  for (const std::string& name : names) {
    inputs.emplace_back(name, dataDir + "/" + table.at(name));
  }
  return inputs;
}

void printCurves(const std::string& dataset, const char* mode, const agv::loops::ModeResult& r) {
  std::printf("\n%s %s: %zu scans queried, %zu with a loop in reference\n", dataset.c_str(), mode, r.scans, r.withLoop);
  std::printf("N_min");
  for (const char* m : agv::loops::kMethodNames) {
    std::printf(" | %-6s prec  recall acc", m);
  }
  std::printf("\n");
  for (std::size_t k = 0; k < r.curves[0].size(); ++k) {
    std::printf("%5zu", r.curves[0][k].minPairs);
    for (std::size_t m = 0; m < agv::loops::kMethods; ++m) {
      const agv::loops::PrPoint& p = r.curves[m][k];
      std::printf(" | %6s %5.3f %6.3f %4zu", "", p.precision, p.recall, p.accepted);
    }
    std::printf("\n");
  }
  for (std::size_t m = 0; m < agv::loops::kMethods; ++m) {
    const agv::loops::CurveSummary s = agv::loops::summarize(r.curves[m]);
    std::printf("%s %s %-6s: break-even %.3f at N_min %ld; recall at precision 1.0: %.3f (N_min %ld)\n",
                dataset.c_str(), mode, agv::loops::kMethodNames[m], s.breakEven, s.breakEvenMinPairs,
                s.recallAtPrecision1, s.recallAtPrecision1MinPairs);
  }
}

int run(int argc, char** argv) {
  std::string dataDir = AGVNAV_DEFAULT_DATA_DIR;
  std::vector<std::string> datasets{"intel", "fr079", "mit-csail"};
  std::string mode = "both";
  // The loop evaluation's features (docs/loop-closure.md, "What one run does"): FALKO with the
  // unrefined candidates kept, and the GLAROT signature of 128 spread beam endpoints. The pose
  // graph keeps its own (the thesis' keypoints and signature).
  agv::loops::ScanSelection selection;
  selection.falko.keepFarCorners = true;
  selection.glarotScanPoints = 128;
  agv::loops::EvalOptions eval;
  std::string jsonPath;
  std::string svgDir;
  bool poseGraph = false;
  bool skipLoops = false;
  std::vector<std::string> mapDatasets{"fr079", "intel", "aces"};
  agv::loops::MappingOptions mapping;

  std::vector<std::string> logFiles;
  std::vector<std::string> mapLogFiles;
  CLI::App app{
      "agvnav-loops: GLAROT loop closure (CG / AH / RANSAC) precision-recall on the FLIRTLib logs, "
      "and Ceres pose-graph mapping on the corrected logs"};
  app.add_option("--data-dir", dataDir, "folder holding laser2d/ (default: the build's AGVNAV_SHARED_DATA_DIR)");
  app.add_option("--datasets", datasets, "FLIRTLib logs to evaluate: intel, fr079, mit-csail")
      ->check(CLI::IsMember({"intel", "fr079", "mit-csail"}))
      ->delimiter(',');
  app.add_option("--log", logFiles, "FLIRTLib log files to evaluate instead of --datasets (named by file name)");
  app.add_option("--map-log", mapLogFiles, "corrected log files to map instead of --map-datasets");
  app.add_option("--mode", mode, "offline, online or both")->check(CLI::IsMember({"offline", "online", "both"}));
  app.add_option("--stride", selection.stride, "use every n-th scan")->check(CLI::Range(1, 1000));
  app.add_option("--max-scans", selection.maxScans, "use at most this many scans per log (0: all)");
  app.add_option("--candidates", eval.candidates, "GLAROT candidates per scan")->check(CLI::Range(1, 32));
  app.add_option("--revisit-distance", eval.revisitDistance,
                 "[m] a scan has a loop when an eligible reference scan was taken this close")
      ->check(CLI::PositiveNumber);
  app.add_flag("--verify,!--no-verify", eval.verify, "verify each association by the scans' agreement");
  app.add_option("--min-overlap", eval.minOverlap,
                 "verification: fewest fraction of each scan's points next to the other's endpoints")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--max-conflict", eval.maxConflict,
                 "verification: largest fraction of each scan's points in the other's free space")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--overlap-cell", eval.overlap.cell, "[m] grid cell of the verification's hit test")
      ->check(CLI::Range(0.01, 1.0));
  app.add_option("--dump-associations", eval.dumpPath,
                 "write every Ok association (and one line per scan) as CSV to this file (diagnosis)");
  app.add_option("--submap-scans", selection.submapScans,
                 "associate each scan's keypoints together with those of the previous n-1 scans, placed by odometry "
                 "(default 1: the scan's own)")
      ->check(CLI::Range(1, 50));
  app.add_option("--submap-points", selection.submapPoints,
                 "submaps: earlier scans' keypoints are added only while the set holds fewer than this many "
                 "(default 64, the capacity)")
      ->check(CLI::Range(1, 64));
  app.add_option("--submap-position-noise", selection.submapPositionVariancePerMetre,
                 "submaps: [m^2/m] position variance per metre of the simulated odometry placing them (default 0.01)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--submap-heading-noise", selection.submapHeadingVariancePerMetre,
                 "submaps: [rad^2/m] heading variance per metre of the simulated odometry (default 0.015)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--submap-noise-seed", selection.submapNoiseSeed,
                 "submaps: seed of the simulated odometry's noise (default 17)");
  app.add_flag("--submap-matched", selection.submapMatched,
               "submaps: place them by matching each scan against a surface map of the scans before it, "
               "the simulated odometry's step as the prior");
  app.add_option("--glarot-scan-points", selection.glarotScanPoints,
                 "GLAROT signature of this many beam endpoints spread over the scan (default 128); 0: of the "
                 "keypoints (thesis)")
      ->check(CLI::Range(0, 256));
  app.add_flag("--falko-keep-far,!--no-falko-keep-far", selection.falko.keepFarCorners,
               "FALKO keeps candidates whose walls meet away from the beam point, unrefined (thesis)");
  app.add_option("--falko-corner-ratio", selection.falko.minCornerResidualRatio,
                 "FALKO straight-wall rejection ratio (0: off, the thesis' detector)")
      ->check(CLI::Range(0.0, 1000.0));
  app.add_option("--falko-max-score", selection.falko.maxScore, "FALKO largest cornerness score")
      ->check(CLI::PositiveNumber);
  app.add_option("--falko-neigh-a", selection.falko.neighA, "FALKO neighbourhood radius at the sensor [m]")
      ->check(CLI::PositiveNumber);
  app.add_option("--falko-beta", selection.falko.beta, "FALKO triangle test beta")->check(CLI::PositiveNumber);
  app.add_option("--json", jsonPath, "write the figures as JSON");
  app.add_option("--svg-dir", svgDir, "write loops-<dataset>.svg (PR curves) and map-<dataset>.svg here");
  app.add_flag("--pose-graph", poseGraph, "also run online pose-graph mapping on the corrected logs");
  app.add_flag("--no-loops", skipLoops, "skip the precision-recall evaluation (with --pose-graph)");
  app.add_option("--map-datasets", mapDatasets, "corrected logs to map: fr079, intel, aces")
      ->check(CLI::IsMember({"fr079", "intel", "aces"}))
      ->delimiter(',');
  app.add_option("--map-min-pairs", mapping.minPairs, "N_min of the loops accepted for mapping")
      ->check(CLI::Range(3, 64));
  app.add_option("--map-max-scans", mapping.maxScans, "map at most this many scans per log (0: all)");
  app.add_flag(
      "!--map-raw-odometry", mapping.scanMatching,
      "mapping: build the graph on the raw odometry, without the scan-matching front end (the thesis' setting)");
  app.add_option("--map-submap", mapping.submapScans,
                 "keypoints of this many consecutive scans (placed by odometry) per loop query")
      ->check(CLI::Range(1, 50));
  app.add_option("--map-pair-window", mapping.window,
                 "[scans] a loop needs a consistent partner loop at most this many scans away")
      ->check(CLI::Range(1, 1000));
  app.add_flag("--map-trace", mapping.traceHypotheses, "print every loop hypothesis of the mapping on stderr");
  app.add_option("--map-candidates", mapping.candidates, "GLAROT candidates per scan for mapping")
      ->check(CLI::Range(1, 32));
  app.add_option("--map-min-overlap", mapping.minOverlap,
                 "fraction of a loop's scan points that must meet the reference scan's points")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--map-exclude-travel", mapping.excludeTravel, "[m] newest path not searched for loops")
      ->check(CLI::NonNegativeNumber);
  CLI11_PARSE(app, argc, argv);
  if (skipLoops && !poseGraph) {
    std::fprintf(stderr, "agvnav-loops: --no-loops without --pose-graph leaves nothing to do\n");
    return 2;
  }

  if (!eval.dumpPath.empty()) {
    std::FILE* dump = std::fopen(eval.dumpPath.c_str(), "w");
    if (dump == nullptr) {
      std::fprintf(stderr, "agvnav-loops: cannot write %s\n", eval.dumpPath.c_str());
      return 2;
    }
    std::fprintf(dump,
                 "dataset,online,query,candidate,rank,method,pairs,rms,overlap,conflict,correct,has_loop,true_dist,"
                 "true_angle,query_keypoints,candidate_keypoints,error_m,error_rad,in_view\n");
    std::fclose(dump);
  }
  agv::report::Json doc = agv::report::Json::object();
  if (!skipLoops) {
    doc["loops"] = agv::report::Json::object();
    std::vector<std::vector<double>> timing(agv::loops::kMethods);
    for (const auto& [name, path] : inputsOf(datasets, kLoopLogs, logFiles, dataDir)) {
      agv::datasets::CarmenLog log;
      if (!readLog(path, log)) {
        return 2;
      }
      if (log.vertices.empty()) {
        std::fprintf(stderr,
                     "agvnav-loops: %s: no VERTEX2 lines: not a FLIRTLib log with ground truth (the corrected "
                     "logs go to --pose-graph)\n",
                     path.c_str());
        return 2;
      }
      agv::loops::ScanFeatures features;
      std::string error;
      if (!agv::loops::extractFeatures(log, selection, features, error)) {
        std::fprintf(stderr, "agvnav-loops: %s: %s\n", name.c_str(), error.c_str());
        return 2;
      }
      std::fprintf(stderr, "agvnav-loops: %s: %zu scans, %.2f keypoints per scan (%zu truncated to 64), %.3f ms\n",
                   name.c_str(), features.points.size(), features.meanKeypoints, features.truncated, features.detectMs);
      if (features.points.size() > agv::loops::kMaxDatabaseScans) {
        std::fprintf(stderr, "agvnav-loops: %s: %zu scans exceed the database capacity %zu; use --stride\n",
                     name.c_str(), features.points.size(), agv::loops::kMaxDatabaseScans);
        return 2;
      }
      agv::loops::ModeResult results[2];
      const char* modeNames[2] = {"offline", "online"};
      agv::report::Json modes = agv::report::Json::object();
      for (int k = 0; k < 2; ++k) {
        if (mode != "both" && mode != modeNames[k]) {
          continue;
        }
        std::fprintf(stderr, "agvnav-loops: %s: %s evaluation\n", name.c_str(), modeNames[k]);
        eval.dumpName = name;
        agv::loops::evaluate(features, k == 1, eval, results[k]);
        printCurves(name, modeNames[k], results[k]);
        agv::report::Json methods = agv::report::Json::object();
        for (std::size_t m = 0; m < agv::loops::kMethods; ++m) {
          agv::report::Json curve = agv::report::Json::array();
          for (const agv::loops::PrPoint& p : results[k].curves[m]) {
            curve.push_back({{"n_min", p.minPairs}, {"precision", p.precision}, {"recall", p.recall}});
          }
          methods[agv::loops::kMethodNames[m]] = curve;
          timing[m].insert(timing[m].end(), results[k].msPerScan[m].begin(), results[k].msPerScan[m].end());
        }
        modes[modeNames[k]] = methods;
      }
      doc["loops"][name] = modes;
      if (!svgDir.empty()) {
        const std::string svgPath = svgDir + "/loops-" + name + ".svg";
        if (!agv::report::writeTextFile(svgPath, agv::loops::prSvg(name, results[0], results[1]), error)) {
          std::fprintf(stderr, "agvnav-loops: %s\n", error.c_str());
          return 2;
        }
      }
    }
    doc["timing_ms"] = agv::report::Json::object();
    for (std::size_t m = 0; m < agv::loops::kMethods; ++m) {
      doc["timing_ms"][agv::loops::kMethodNames[m]] = agv::loops::timingJson(timing[m]);
    }
    std::printf("\nassociation time per scan (%zu candidates), ms:\n", eval.candidates);
    for (std::size_t m = 0; m < agv::loops::kMethods; ++m) {
      const agv::report::Json& t = doc["timing_ms"][agv::loops::kMethodNames[m]];
      std::printf("%-6s mean %.3f median %.3f p95 %.3f\n", agv::loops::kMethodNames[m], t["mean"].get<double>(),
                  t["median"].get<double>(), t["p95"].get<double>());
    }
  }

  if (poseGraph) {
    doc["pose_graph"] = agv::report::Json::object();
    for (const auto& [name, path] : inputsOf(mapDatasets, kMappingLogs, mapLogFiles, dataDir)) {
      agv::datasets::CarmenLog log;
      if (!readLog(path, log)) {
        return 2;
      }
      agv::loops::MappingResult r;
      std::string error;
      std::fprintf(stderr, "agvnav-loops: %s: online pose-graph mapping\n", name.c_str());
      if (!agv::loops::mapOnline(log, mapping, r, error)) {
        std::fprintf(stderr, "agvnav-loops: %s: %s\n", name.c_str(), error.c_str());
        return 2;
      }
      std::printf(
          "\npose graph %s: %zu scans (%zu matched by the front end), %zu loops accepted, %zu rejected (%zu of "
          "the accepted wrong by the corrected poses); ATE position RMS raw odometry %.3f m -> front end %.3f m -> "
          "optimised %.3f m, heading RMS %.2f -> %.2f -> %.2f deg\n",
          name.c_str(), r.scans, r.scansMatched, r.loopsAccepted, r.loopsRejected, r.acceptedWrong, r.odometryAteM,
          r.frontEndAteM, r.optimisedAteM, r.odometryAteDeg, r.frontEndAteDeg, r.optimisedAteDeg);
      doc["pose_graph"][name] = agv::loops::mappingJson(r);
      if (!svgDir.empty()) {
        const std::string svgPath = svgDir + "/map-" + name + ".svg";
        if (!agv::report::writeTextFile(svgPath, agv::loops::mapSvg(name, log, r), error)) {
          std::fprintf(stderr, "agvnav-loops: %s\n", error.c_str());
          return 2;
        }
      }
    }
  }

  if (!jsonPath.empty()) {
    std::string error;
    if (!agv::report::writeJsonFile(jsonPath, doc, error)) {
      std::fprintf(stderr, "agvnav-loops: %s\n", error.c_str());
      return 2;
    }
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "agvnav-loops: error: %s\n", e.what());
    return 2;
  }
}
