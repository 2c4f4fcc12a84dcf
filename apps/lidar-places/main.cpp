// agvnav-lidar-places: normal-histogram place recognition on a sequence of multi-beam lidar
// revolutions (KITTI or NCLT velodyne .bin files, VLP-16 raw packets or ROS 2 bags of them): signatures,
// key-signatures, loops, precision / recall against ground-truth positions (KITTI poses) and yaw errors. Figures on
// stdout, --json, --svg.
#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <map>
#include <string>

#include "agv/core/angle.hpp"
#include "agv/report/json.hpp"
#include "agv/report/text_file.hpp"
#include "places.hpp"

int main(int argc, char** argv) {
  agv::places::PlacesOptions options;
  std::string jsonPath;
  std::string svgPath;
  double minPrecision = -1.0;
  double minRecall = -1.0;
  bool verbose = false;
  CLI::App app{"agvnav-lidar-places: normal-histogram place signatures, key-signatures and loops on 3D lidar scans"};
  app.add_option("scans", options.files, "revolutions in driving order (.bin)")->check(CLI::ExistingFile);
  app.add_option("--sim", options.sim.sensor,
                 "run the simulated yard route instead of files: hdl64 or vlp16 (with the sensor's threshold set "
                 "and geometric verification for the options not given)")
      ->check(CLI::IsMember({"hdl64", "vlp16"}));
  app.add_option("--sim-calibration", options.sim.calibration,
                 "hdl64: factory calibration YAML (default: the shared HDL-64E S2.1 file)");
  app.add_option("--sim-step", options.sim.step, "[m] between simulated revolutions")->check(CLI::Range(0.1, 20.0));
  app.add_option("--sim-back", options.sim.back, "fraction of the lap driven back (opposite direction)")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--sim-again", options.sim.again, "fraction of the lap driven again (same direction)")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--sim-lateral", options.sim.lateral, "[m] lateral offset of the repeated passes")
      ->check(CLI::Range(0.0, 5.0));
  app.add_option("--sim-seed", options.sim.seed, "world and noise seed");
  app.add_flag("--sim-packets", options.sim.packets,
               "vlp16: run the simulated revolutions through VLP-16 packets (decoder, assembler, buildFromFirings)");
  const std::map<std::string, agv::places::Format> formats{{"kitti", agv::places::Format::Kitti},
                                                           {"nclt", agv::places::Format::Nclt},
                                                           {"vlp16", agv::places::Format::Vlp16Packets},
                                                           {"vlp16-bag", agv::places::Format::Vlp16Bag}};
  app.add_option("--format", options.format,
                 "kitti (float32 x y z r), nclt (velodyne_sync), vlp16 (raw 1206-byte VLP-16 payloads, concatenated) "
                 "or vlp16-bag (ROS 2 bag .db3 of velodyne_msgs/msg/VelodyneScan)")
      ->transform(CLI::CheckedTransformer(formats, CLI::ignore_case));
  app.add_option("--calibration", options.calibrationPath,
                 "vlp16: per-laser calibration, db.xml or velodyne_pointcloud YAML (default: the shared vlp16_db.yaml)")
      ->check(CLI::ExistingFile);
  app.add_option("--poses", options.posesPath, "KITTI poses file (frame = the number in each file name)");
  app.add_option("--radius", options.radius, "[m] a loop is true when its two positions are this close")
      ->check(CLI::PositiveNumber);
  app.add_option("--columns", options.columns, "range-image columns (0: 2000 KITTI, 1024 NCLT)")
      ->check(CLI::Range(0, 2048));
  app.add_option("--key-threshold", options.place.keyThreshold, "T_key (chi-square to the last key)");
  app.add_option("--chi2-threshold", options.place.chiSquareThreshold, "T_chi2");
  app.add_option("--sorensen-threshold", options.place.sorensenThreshold, "T_Sor");
  app.add_option("--orientation-check", options.place.maxOrientationCost,
                 "loop candidates need a relative orientation-signature cost <= this (0: off)")
      ->check(CLI::Range(0.0, 10.0));
  app.add_option("--loop-translation", options.place.maxLoopTranslation,
                 "[m] geometric verification: a loop candidate's profiles must align with a translation <= this "
                 "(0: off)")
      ->check(CLI::Range(0.0, 1000.0));
  app.add_option("--aligned-fraction", options.place.minAlignedFraction,
                 "geometric verification: share of the profile's bins paired after the alignment")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--skip-recent-keys", options.place.skipRecentKeys, "m: newest keys left out of the loop query");
  app.add_option("--laser-step", options.signature.normals.laserStep, "normal neighbours: lasers above/below")
      ->check(CLI::Range(1, 8));
  app.add_option("--firing-step", options.signature.normals.firingStep, "normal neighbours: firings before/after")
      ->check(CLI::Range(1, 64));
  app.add_option("--normal-min-range", options.signature.normals.minRange,
                 "[m] nearest point that gets a normal (thesis: 3; indoor recordings see less)")
      ->check(CLI::Range(0.1, 50.0));
  app.add_flag("--verbose", verbose, "print every revolution (default: only the loops and failures)");
  app.add_option("--json", jsonPath, "write the figures as JSON");
  app.add_option("--svg", svgPath, "write the key signatures and the loops as SVG");
  app.add_option("--min-precision", minPrecision, "exit 1 when the precision is below this (with poses)");
  app.add_option("--min-recall", minRecall, "exit 1 when the recall is below this (with poses)");
  CLI11_PARSE(app, argc, argv);
  if (options.sim.sensor.empty() == options.files.empty()) {
    std::fprintf(stderr, "agvnav-lidar-places: give either scan files or --sim\n");
    return 2;
  }
  // --sim: the sensor's set (docs/lidar-places.md) for each of its options not given.
  agv::places::SensorSet set;
  if (agv::places::simulatedSensorSet(options.sim.sensor, set)) {
    const auto unset = [&app](const char* name) { return app.count(name) == 0; };
    if (unset("--chi2-threshold")) {
      options.place.chiSquareThreshold = set.chiSquareThreshold;
    }
    if (unset("--sorensen-threshold")) {
      options.place.sorensenThreshold = set.sorensenThreshold;
    }
    if (unset("--laser-step")) {
      options.signature.normals.laserStep = set.laserStep;
    }
    if (unset("--loop-translation")) {
      options.place.maxLoopTranslation = set.maxLoopTranslation;
    }
    if (unset("--aligned-fraction")) {
      options.place.minAlignedFraction = set.minAlignedFraction;
    }
    std::printf(
        "simulated %s: T_chi2 %.2g, T_Sor %.3g, laser step %zu, geometric verification %.1f m / inlier share %.2f "
        "(the sensor's set where not given)\n",
        options.sim.sensor.c_str(), static_cast<double>(options.place.chiSquareThreshold),
        static_cast<double>(options.place.sorensenThreshold), options.signature.normals.laserStep,
        static_cast<double>(options.place.maxLoopTranslation), static_cast<double>(options.place.minAlignedFraction));
  }
  if (options.sim.sensor == "hdl64" && options.sim.calibration.empty()) {
    options.sim.calibration = std::string(AGVNAV_DEFAULT_DATA_DIR) + "/lidar3d/calibration/hdl64e_s2.1_sztaki.yaml";
  }

  if (agv::places::isPacketFormat(options.format) && options.calibrationPath.empty()) {
    options.calibrationPath = std::string(AGVNAV_DEFAULT_DATA_DIR) + "/lidar3d/calibration/vlp16_db.yaml";
  }
  if (!agv::places::isPacketFormat(options.format) && !options.calibrationPath.empty()) {
    std::fprintf(stderr, "agvnav-lidar-places: --calibration applies to --format vlp16 and vlp16-bag only\n");
    return 2;
  }

  agv::places::PlacesResult result;
  std::string error;
  if (!agv::places::runPlaces(options, result, error)) {
    std::fprintf(stderr, "agvnav-lidar-places: %s\n", error.c_str());
    return 2;
  }
  for (std::size_t i = 0; i < result.scans.size(); ++i) {
    const agv::places::ScanResult& s = result.scans[i];
    if (!verbose && !s.update.loop && s.status == agv::Status::Ok) {
      continue;  // long runs: the loops and the failures only
    }
    std::printf("scan %zu (%s): %zu points, %u normals, %s%s", i, s.file.c_str(), s.points, s.normals,
                agv::toString(s.status), s.update.isKey ? ", key" : "");
    if (s.update.loop) {
      std::printf(", loop with scan %u: chi2 %.3g sorensen %.3g", s.update.loopScan,
                  static_cast<double>(s.update.chiSquare), static_cast<double>(s.update.sorensen));
      if (s.hasTruth) {
        std::printf(" (%s, %.2f m)", s.loopTrue ? "true" : "FALSE", s.loopDistance);
      }
      if (s.update.hasYaw) {
        std::printf(", yaw %.2f deg (relative cost %.3f)", agv::rad2deg(static_cast<double>(s.update.yaw.yaw)),
                    static_cast<double>(s.update.yaw.relativeCost()));
      }
      if (s.update.hasAlignment) {
        std::printf(", aligned: yaw %.2f deg, x %.2f y %.2f m, paired %.2f",
                    agv::rad2deg(static_cast<double>(s.update.alignment.yaw)),
                    static_cast<double>(s.update.alignment.x), static_cast<double>(s.update.alignment.y),
                    static_cast<double>(s.update.alignment.matchedFraction()));
      }
      if (s.hasYawError) {
        std::printf(" (truth %.2f, error %.2f deg)", agv::rad2deg(s.yawTruth), agv::rad2deg(s.yawError));
      }
      if (s.hasTranslationError) {
        std::printf(" (translation error %.2f m)", s.translationError);
      }
    }
    if (s.hasStepYaw) {
      std::printf(", yaw from the previous %.2f deg", agv::rad2deg(s.stepYaw));
    }
    std::printf("\n");
  }
  std::printf("%zu revolutions in %.1f s; keys %zu; loops detected %zu", result.scans.size(), result.seconds,
              result.keys, result.summary.detected);
  if (!result.truth.empty()) {
    std::printf(", true %zu of %zu to find (radius %.1f m): precision %.3f recall %.3f", result.summary.truePositives,
                result.summary.positives, options.radius, result.summary.precision, result.summary.recall);
  }
  std::printf("\n");
  for (const agv::places::PrPoint& p : result.curve) {
    if (result.truth.empty()) {
      std::printf("  T_chi2 %.2e T_Sor %.4f: detected %zu\n", static_cast<double>(p.chiSquareThreshold),
                  static_cast<double>(p.sorensenThreshold), p.detected);
      continue;
    }
    std::printf("  T_chi2 %.2e T_Sor %.4f: detected %zu, true %zu, precision %.3f recall %.3f\n",
                static_cast<double>(p.chiSquareThreshold), static_cast<double>(p.sorensenThreshold), p.detected,
                p.truePositives, p.precision, p.recall);
  }
  if (agv::places::isPacketFormat(options.format)) {
    const agv::places::PacketStats& ps = result.packets;
    if (options.format == agv::places::Format::Vlp16Bag) {
      std::printf("VelodyneScan messages %zu, ", ps.messages);
    }
    std::printf(
        "packets %zu (refused %zu, blocks skipped %zu), returns %zu; revolutions assembled %zu, begun mid-turn "
        "(not run) %zu, records refused %zu\n",
        ps.packets, ps.refusedPackets, ps.skippedBlocks, ps.records, ps.revolutions, ps.incomplete, ps.refusedRecords);
  }
  if (result.truth.empty()) {
    std::printf("no ground-truth poses: no precision / recall or yaw errors\n");
  }
  if (result.stepYawCount > 0) {
    std::printf("yaw between consecutive revolutions over %zu pairs: mean |yaw| %.3f deg, max %.3f deg\n",
                result.stepYawCount, result.stepYawMeanAbsDeg, result.stepYawMaxAbsDeg);
  }
  if (result.yawCount > 0) {
    std::printf("yaw error over %zu loops: mean |e| %.3f deg, max %.3f deg\n", result.yawCount,
                result.yawErrorMeanAbsDeg, result.yawErrorMaxDeg);
    const auto line = [](const char* what, const agv::places::PlacesResult::YawStats& st) {
      std::printf("  %s: %zu loops, |e| median %.2f, 90%% %.2f, max %.2f deg, within 1 deg %.1f%%\n", what, st.count,
                  st.median, st.p90, st.max, 100.0 * st.within1);
    };
    line("same direction", result.yawSame);
    line("opposite direction", result.yawOpposite);
    line("signature yaw only", result.signatureYawAll);
  }
  if (result.translationCount > 0) {
    std::printf("loop translation error over %zu aligned loops: median %.3f m, max %.3f m\n", result.translationCount,
                result.translationErrorMedian, result.translationErrorMax);
  }
  if (!jsonPath.empty() && !agv::report::writeJsonFile(jsonPath, agv::places::placesJson(options, result), error)) {
    std::fprintf(stderr, "agvnav-lidar-places: %s\n", error.c_str());
    return 2;
  }
  if (!svgPath.empty() && !agv::report::writeTextFile(svgPath, agv::places::placesSvg(result), error)) {
    std::fprintf(stderr, "agvnav-lidar-places: %s\n", error.c_str());
    return 2;
  }
  if (!result.truth.empty() && (result.summary.precision < minPrecision || result.summary.recall < minRecall)) {
    std::fprintf(stderr, "agvnav-lidar-places: precision %.3f / recall %.3f below the required %.3f / %.3f\n",
                 result.summary.precision, result.summary.recall, minPrecision, minRecall);
    return 1;
  }
  return 0;
}
