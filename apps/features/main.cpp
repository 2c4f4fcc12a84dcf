// agvnav-features: FALKO keypoints on recorded 2D laser scans.
//   detect: keypoints of one scan of a log, written as SVG (points, keypoints, orientations).
//   eval:   repeatability (viewpoint, range noise, angular resampling) and BSC / CGH precision /
//           recall on the shared logs; tables on stdout, SVG curves, JSON with --json. With
//           --keypoints FILE it scores another detector's keypoints instead of running its own.
//   export: the scans eval uses (every variant), for another detector to process; optionally this
//           detector's keypoints in the format eval --keypoints reads, and the viewpoint pairs.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>
#include <vector>

#include "agv/datasets/carmen_log.hpp"
#include "agv/falko/falko_detector.hpp"
#include "agv/report/json.hpp"
#include "agv/report/text_file.hpp"
#include "eval.hpp"
#include "svg.hpp"

namespace {

/// Writes `text` to `path`; false after saying why on stderr.
bool writeFile(const std::string& path, const std::string& text) {
  std::string error;
  if (!agv::report::writeTextFile(path, text, error)) {
    std::fprintf(stderr, "agvnav-features: %s\n", error.c_str());
    return false;
  }
  return true;
}

struct Dataset {
  const char* name;
  const char* file;
};
const Dataset kDatasets[] = {
    {"intel", "intel/intel-lab.log.gz"}, {"fr079", "fr079/fr079.log.gz"}, {"mit-csail", "mit-csail/mit-cscail.log.gz"}};

/// Detector parameters from the command line: a named set, then single values on top of it.
struct FalkoCli {
  std::string set = "thesis";
  float neighA = 0.0F;
  float neighB = 0.0F;
  float beta = 0.0F;
  std::size_t gridSectors = 0;
  float maxScore = 0.0F;
  float nmsRadius = 0.0F;
  CLI::Option* neighAOpt = nullptr;
  CLI::Option* neighBOpt = nullptr;
  CLI::Option* betaOpt = nullptr;
  CLI::Option* sectorsOpt = nullptr;
  CLI::Option* maxScoreOpt = nullptr;
  CLI::Option* nmsRadiusOpt = nullptr;

  void addTo(CLI::App* cmd) {
    cmd->add_option("--params", set,
                    "detector parameter set: thesis (the FALKO thesis defaults) or reference (the public reference "
                    "implementation's defaults: a 0.1 m, beta 2.5, NMS 0.1 m)")
        ->check(CLI::IsMember({"thesis", "reference"}));
    neighAOpt = cmd->add_option("--neigh-a", neighA, "[m] neighbourhood radius at the sensor, a (overrides --params)")
                    ->check(CLI::PositiveNumber);
    neighBOpt =
        cmd->add_option("--neigh-b", neighB, "[1/m] growth of the radius with range, b")->check(CLI::NonNegativeNumber);
    betaOpt = cmd->add_option("--beta", beta, "triangle test ratio beta")->check(CLI::PositiveNumber);
    sectorsOpt = cmd->add_option("--sectors", gridSectors, "cornerness score sectors s_n")->check(CLI::Range(4, 64));
    maxScoreOpt =
        cmd->add_option("--max-score", maxScore, "largest accepted cornerness score")->check(CLI::NonNegativeNumber);
    nmsRadiusOpt =
        cmd->add_option("--nms-radius", nmsRadius, "[m] non-maxima suppression radius")->check(CLI::NonNegativeNumber);
  }
  /// The parameters asked for; false (with a message) when they are out of their domain.
  bool resolve(agv::FalkoParams& p) const {
    p = set == "reference" ? agv::falkoReferenceParams() : agv::FalkoParams{};
    p.neighA = *neighAOpt ? neighA : p.neighA;
    p.neighB = *neighBOpt ? neighB : p.neighB;
    p.beta = *betaOpt ? beta : p.beta;
    p.gridSectors = *sectorsOpt ? gridSectors : p.gridSectors;
    p.maxScore = *maxScoreOpt ? maxScore : p.maxScore;
    p.nmsRadius = *nmsRadiusOpt ? nmsRadius : p.nmsRadius;
    if (!agv::isValid(p)) {
      std::fprintf(stderr, "agvnav-features: invalid detector parameters (%s)\n", agv::features::paramsLine(p).c_str());
      return false;
    }
    return true;
  }
};

int runDetect(const std::string& logPath, std::size_t index, const std::string& svgPath,
              const agv::FalkoParams& params) {
  agv::datasets::CarmenLog log;
  std::string err;
  if (!agv::datasets::readCarmenLog(logPath, log, err)) {
    std::fprintf(stderr, "agvnav-features: %s\n", err.c_str());
    return 1;
  }
  for (const auto& issue : log.issues) {
    std::fprintf(stderr, "%s:%zu: %s (skipped)\n", logPath.c_str(), issue.line, issue.message.c_str());
  }
  if (index >= log.scans.size()) {
    std::fprintf(stderr, "agvnav-features: scan %zu out of range (%zu scans)\n", index, log.scans.size());
    return 1;
  }
  auto scan = std::make_unique<agv::LaserScan>();
  if (!log.scans[index].toLaserScan(*scan)) {
    std::fprintf(stderr, "agvnav-features: scan %zu has more beams than the capacity\n", index);
  }
  auto detector = std::make_unique<agv::FalkoDetector>(params);
  auto kps = std::make_unique<agv::FalkoKeypoints>();
  std::printf("%s\n", agv::features::paramsLine(params).c_str());
  const agv::Status st = detector->detect(*scan, *kps);
  std::printf("scan %zu (line %zu): %zu beams, %zu valid, %zu keypoints (%s)\n", index, log.scans[index].line,
              scan->size(), detector->points().validCount(), kps->size(), agv::toString(st));
  for (const auto& k : *kps) {
    std::printf("  beam %4u  x %8.3f  y %8.3f  orientation %7.3f  radius %.3f  score %.3f%s\n", k.beamIndex,
                static_cast<double>(k.x), static_cast<double>(k.y), static_cast<double>(k.orientation),
                static_cast<double>(k.radius), static_cast<double>(k.score), k.refined ? "" : "  (not refined)");
  }
  const std::vector<agv::FalkoKeypoint> v(kps->begin(), kps->end());
  if (!writeFile(svgPath, agv::features::scanSvg(*scan, v))) {
    return 1;
  }
  return 0;
}

/// The datasets named on the command line (all when none), with their log paths; false when a
/// name is unknown.
bool selectDatasets(const std::vector<std::string>& names, const std::string& dataDir,
                    std::vector<std::pair<std::string, std::string>>& out) {
  for (const std::string& n : names) {
    const bool known =
        std::any_of(std::begin(kDatasets), std::end(kDatasets), [&](const Dataset& d) { return n == d.name; });
    if (!known) {
      std::fprintf(stderr, "agvnav-features: unknown dataset %s (intel, fr079, mit-csail)\n", n.c_str());
      return false;
    }
  }
  for (const Dataset& d : kDatasets) {
    if (names.empty() || std::find(names.begin(), names.end(), d.name) != names.end()) {
      out.emplace_back(d.name, dataDir + "/laser2d/" + d.file);
    }
  }
  return true;
}

int runExport(const std::vector<std::pair<std::string, std::string>>& sets, const agv::features::EvalOptions& options,
              const std::string& scansPath, const std::string& kpPath, const std::string& pairsPath) {
  std::ofstream files[3];
  agv::features::ExportStreams out;
  // Opens `path` (when given) as files[f] and points `stream` at it; false when it cannot be written.
  auto open = [&](std::size_t f, const std::string& path, std::ostream*& stream) {
    if (path.empty()) {
      return true;
    }
    files[f].open(path);
    if (!files[f]) {
      std::fprintf(stderr, "agvnav-features: cannot write %s\n", path.c_str());
      return false;
    }
    stream = &files[f];
    return true;
  };
  if (!open(0, scansPath, out.scans) || !open(1, kpPath, out.keypoints) || !open(2, pairsPath, out.pairs)) {
    return 1;
  }
  if (out.scans == nullptr && out.keypoints == nullptr && out.pairs == nullptr) {
    std::fprintf(stderr, "agvnav-features: export needs --scans, --keypoints or --pairs\n");
    return 2;
  }
  if (out.scans != nullptr) {
    *out.scans << "# <dataset> <variant> <scan> <angle_min> <angle_increment> <range_min> <range_max> <n> <ranges>\n";
  }
  if (out.keypoints != nullptr) {
    *out.keypoints << "# <dataset> <variant> <scan> <k> <x_1> <y_1> ... <x_k> <y_k>  ("
                   << agv::features::paramsLine(options.falko) << ")\n";
  }
  if (out.pairs != nullptr) {
    *out.pairs << "# <dataset> <scan i> <scan j> <ground-truth distance [m]> <viewpoint bin>\n";
  }
  for (const auto& set : sets) {
    std::string err;
    if (!agv::features::exportLog(set.first, set.second, options, out, err)) {
      std::fprintf(stderr, "agvnav-features: %s\n", err.c_str());
      return 1;
    }
    std::printf("%s: exported\n", set.first.c_str());
  }
  return 0;
}

/// The command line: the three subcommands and what they set.
struct FeaturesCli {
  CLI::App* detect = nullptr;
  CLI::App* eval = nullptr;
  CLI::App* exportCmd = nullptr;
  // detect
  std::string logPath;
  std::size_t index = 0;
  std::string svgPath = "scan.svg";
  FalkoCli detectParams;
  // eval and export
  std::string dataDir = AGVNAV_DEFAULT_DATA_DIR;
  std::vector<std::string> names;
  agv::features::EvalOptions options;
  std::string jsonPath;
  std::string svgDir;
  std::string keypointsIn;
  FalkoCli evalParams;
  std::string exportScans;
  std::string exportKeypoints;
  std::string exportPairs;
  FalkoCli exportParams;
};

void addDetectCommand(CLI::App& app, FeaturesCli& cli) {
  CLI::App* detect = app.add_subcommand("detect", "keypoints of one scan of a log, as SVG");
  detect->add_option("log", cli.logPath, "CARMEN / FLIRTLib log (.log or .log.gz)")->required();
  detect->add_option("-s,--scan", cli.index, "index of the scan in the log (0-based)");
  detect->add_option("-o,--svg", cli.svgPath, "SVG output file");
  cli.detectParams.addTo(detect);
  cli.detect = detect;
}

void addEvalCommand(CLI::App& app, FeaturesCli& cli) {
  CLI::App* eval = app.add_subcommand("eval", "repeatability and descriptor matching on the shared logs");
  eval->add_option("--data", cli.dataDir, "folder holding laser2d/");
  eval->add_option("--datasets", cli.names, "subset of intel, fr079, mit-csail (default: all)");
  eval->add_option("--max-scans", cli.options.maxScans, "scans per dataset (0: all)");
  eval->add_option("--json", cli.jsonPath, "write the results as JSON");
  eval->add_option("--svg-dir", cli.svgDir, "write repeatability curves (SVG) into this folder");
  eval->add_option("--match-distance", cli.options.matchDistance, "[m] repeated keypoint tolerance");
  eval->add_option("--keypoints", cli.keypointsIn,
                   "score the keypoints in this file (another detector's, see export) instead of detecting")
      ->check(CLI::ExistingFile);
  cli.evalParams.addTo(eval);
  cli.eval = eval;
}

void addExportCommand(CLI::App& app, FeaturesCli& cli) {
  CLI::App* exportCmd =
      app.add_subcommand("export", "the scans eval uses, for another detector; this detector's keypoints; the pairs");
  exportCmd->add_option("--data", cli.dataDir, "folder holding laser2d/");
  exportCmd->add_option("--datasets", cli.names, "subset of intel, fr079, mit-csail (default: all)");
  exportCmd->add_option("--max-scans", cli.options.maxScans, "scans per dataset (0: all)");
  exportCmd->add_option("--scans", cli.exportScans, "write every scan of every variant here");
  exportCmd->add_option("--keypoints", cli.exportKeypoints,
                        "write this detector's keypoints here (eval --keypoints format)");
  exportCmd->add_option("--pairs", cli.exportPairs, "write the viewpoint scan pairs here");
  cli.exportParams.addTo(exportCmd);
  cli.exportCmd = exportCmd;
}

/// The results as tables on stdout, JSON and SVG curves when asked; the exit code.
int reportEval(const FeaturesCli& cli, const std::vector<agv::features::DatasetResult>& results) {
  std::fputs(agv::features::resultsToTables(results).c_str(), stdout);
  std::string error;
  if (!cli.jsonPath.empty() &&
      !agv::report::writeJsonFile(cli.jsonPath,
                                  agv::features::resultsToJson(results, cli.options.falko, cli.keypointsIn), error)) {
    std::fprintf(stderr, "agvnav-features: %s\n", error.c_str());
    return 1;
  }
  if (!cli.svgDir.empty()) {
    for (const char* test : {"viewpoint", "noise", "sampling"}) {
      const std::string p = cli.svgDir + "/repeatability_" + test + ".svg";
      if (!writeFile(p, agv::features::curveSvg(results, test))) {
        return 1;
      }
    }
  }
  return 0;
}

/// eval: the detector's (or the --keypoints file's) keypoints scored on every dataset of `sets`.
int runEval(const FeaturesCli& cli, const std::vector<std::pair<std::string, std::string>>& sets) {
  agv::features::KeypointTable external;
  if (!cli.keypointsIn.empty()) {
    std::ifstream in(cli.keypointsIn);
    std::string err;
    if (!in || !agv::features::readKeypointTable(in, external, err)) {
      std::fprintf(stderr, "agvnav-features: %s: %s\n", cli.keypointsIn.c_str(), in ? err.c_str() : "cannot read");
      return 1;
    }
    std::printf("keypoints from %s (the detector is not run)\n", cli.keypointsIn.c_str());
  } else {
    std::printf("%s\n", agv::features::paramsLine(cli.options.falko).c_str());
  }
  std::vector<agv::features::DatasetResult> results;
  for (const auto& set : sets) {
    agv::features::DatasetResult r;
    std::string err;
    if (!agv::features::evaluateLog(set.first, set.second, cli.options, r, err,
                                    cli.keypointsIn.empty() ? nullptr : &external)) {
      std::fprintf(stderr, "agvnav-features: %s\n", err.c_str());
      return 1;
    }
    results.push_back(std::move(r));
  }
  return reportEval(cli, results);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"FALKO keypoints on recorded 2D laser scans"};
  app.require_subcommand(1);
  FeaturesCli cli;
  addDetectCommand(app, cli);
  addEvalCommand(app, cli);
  addExportCommand(app, cli);
  CLI11_PARSE(app, argc, argv);

  if (*cli.detect) {
    agv::FalkoParams params;
    if (!cli.detectParams.resolve(params)) {
      return 2;
    }
    return runDetect(cli.logPath, cli.index, cli.svgPath, params);
  }
  std::vector<std::pair<std::string, std::string>> sets;
  if (!selectDatasets(cli.names, cli.dataDir, sets)) {
    return 2;
  }
  if (*cli.exportCmd) {
    if (!cli.exportParams.resolve(cli.options.falko)) {
      return 2;
    }
    return runExport(sets, cli.options, cli.exportScans, cli.exportKeypoints, cli.exportPairs);
  }
  if (!cli.evalParams.resolve(cli.options.falko)) {
    return 2;
  }
  return runEval(cli, sets);
}
