// agvnav-hil: the hardware-in-the-loop simulation, the library's main job.
//
// A simulated forklift (true kinematics, slip, quantised encoders) drives the reference paths of
// a simulated warehouse while a simulated navigation laser sweeps it; the navigation side reads
// the devices through the HAL and publishes its pose to an in-process PLC peer. The navigation
// side is the on-vehicle calibration routine (ATC closed form from reflector egomotion) followed
// by the localizer (EKF, agv/localization) with the calibrated parameters in three modes:
// reflectors against a surveyed map, a static FALKO corner map built by mapping runs, and the
// dynamic corner map; dead reckoning with the true, nominal and calibrated parameters is kept as
// a comparison (see docs/hil.md).
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "agv/calibration/calibration_routine.hpp"
#include "agv/calibration/sim_calibration_vehicle.hpp"
#include "agv/core/angle.hpp"
#include "agv/sim/ray_caster.hpp"
#include "agv/sim/world.hpp"
#include "scenario.hpp"
#include "svg_plots.hpp"

namespace {

constexpr double kPositionRequirement = 0.02;   // [m]
constexpr double kHeadingRequirementDeg = 0.1;  // [deg]

// Stages of the full HIL and whether this build runs them (a wired stage may still fail).
struct Stage {
  const char* key;
  const char* name;
  bool wired;
  bool failed = false;
};
Stage kStages[] = {
    {"calibration", "on-vehicle calibration routine (ATC + laser mount)", true},
    {"dead_reckoning", "dead reckoning (true, nominal, estimated parameters)", true},
    {"reflector_ekf", "EKF localization with reflectors only", true},
    {"static_falko_map", "EKF localization with a static FALKO map", true},
    {"dynamic_map", "EKF localization with the dynamic landmark map", true},
};

std::string jsonString(const std::string& s) {
  std::string o = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') {
      o += '\\';
      o += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", static_cast<unsigned>(c));
      o += buf;
    } else {
      o += c;
    }
  }
  return o + "\"";
}

void writeParams(std::FILE* f, const agv::TricycleParams& k, const agv::Pose2d& laser) {
  std::fprintf(
      f,
      "{\"wheelbase_m\": %.6f, \"drive_scale_m_per_tick\": %.9e, \"steer_offset_forward_deg\": %.6f, "
      "\"steer_offset_backward_deg\": %.6f, \"laser_x_m\": %.6f, \"laser_y_m\": %.6f, \"laser_theta_deg\": %.6f}",
      k.wheelbase, k.driveScale, agv::rad2deg(k.steerOffsetForward), agv::rad2deg(k.steerOffsetBackward), laser.x,
      laser.y, agv::rad2deg(laser.theta));
}

// Parameter errors (value - truth) in the units of writeParams.
void writeParamDiff(std::FILE* f, const agv::hil::NominalVehicle& v, const agv::sim::SimVehicleParams& truth) {
  const agv::TricycleParams& k = v.kinematics;
  const agv::TricycleParams& t = truth.truth;
  std::fprintf(f,
               "{\"drive_scale_m_per_tick\": %.9e, \"steer_offset_forward_deg\": %.6f, \"steer_offset_backward_deg\": "
               "%.6f, \"laser_x_m\": %.6f, \"laser_y_m\": %.6f, \"laser_theta_deg\": %.6f}",
               k.driveScale - t.driveScale, agv::rad2deg(k.steerOffsetForward - t.steerOffsetForward),
               agv::rad2deg(k.steerOffsetBackward - t.steerOffsetBackward), v.laserMount.x - truth.laserMount.x,
               v.laserMount.y - truth.laserMount.y,
               agv::rad2deg(agv::angleDiff(v.laserMount.theta, truth.laserMount.theta)));
}

bool meets(const agv::Pose2d& est, const agv::Pose2d& truth) {  // dead reckoning and localizer poses
  return agv::hil::positionError(est, truth) <= kPositionRequirement &&
         agv::rad2deg(agv::hil::headingError(est, truth)) <= kHeadingRequirementDeg;
}

void writeLocalizerRun(std::FILE* f, const agv::hil::RunResult& r) {
  std::fprintf(f,
               "    {\"mode\": \"%s\", \"path\": %s, \"run\": %d, \"final_position_error_m\": %.6f, "
               "\"final_heading_error_deg\": %.6f, \"distance_m\": %.3f, \"finished\": %s, \"lost\": %s, "
               "\"landmarks_used_per_scan\": %.2f, \"scans_without_fix\": %zu, \"keypoints_per_scan\": %.2f}",
               agv::hil::modeName(r.mode), jsonString(r.path).c_str(), r.run,
               agv::hil::positionError(r.finalLocalized, r.finalTruth),
               agv::rad2deg(agv::hil::headingError(r.finalLocalized, r.finalTruth)), r.distance,
               r.finished ? "true" : "false", r.localizerLost ? "true" : "false", r.meanUsedPerScan, r.scansWithoutFix,
               r.meanKeypointsPerScan);
}

// The calibration stage's outcome and the encoder frames its routine exchanged over CAN.
struct HilCalibration : agv::calibration::CalibrationOutcome {
  agv::sim::CanBusCounters can;
};

// A localizer run meets the requirement when it reached the operation point, the pose sent to
// the PLC is within 2 cm / 0.1 deg and the localizer is not lost (a lost localizer stops the
// vehicle through the PLC interlock, whatever its last pose).
bool runMeets(const agv::hil::RunResult& r) {
  return r.finished && !r.localizerLost && meets(r.finalLocalized, r.finalTruth);
}

// The encoder frames of the whole session (calibration routine and every run), decoded by the
// vehicle's CANopen decoder: the only way the encoder samples reach the navigation.
agv::sim::CanBusCounters canTotals(const HilCalibration& calib, const std::vector<agv::hil::RunResult>& runs,
                                   const std::vector<agv::hil::RunResult>& mappingRuns) {
  agv::sim::CanBusCounters c = calib.can;
  for (const std::vector<agv::hil::RunResult>* set : {&runs, &mappingRuns}) {
    for (const agv::hil::RunResult& r : *set) {
      c += r.can;
    }
  }
  return c;
}

void writeCanJson(std::FILE* f, const agv::hil::ScenarioConfig& cfg, const agv::sim::CanBusCounters& c) {
  std::fprintf(f, "  \"can_encoders\": {\"drive_node\": %u, \"steering_node\": %u, \"sync\": %s",
               unsigned{cfg.can.bus.drive.nodeId}, unsigned{cfg.can.bus.steering.nodeId},
               cfg.can.bus.syncPeriod.ns > 0 ? "true" : "false");
  const std::pair<const char*, std::uint64_t> fields[] = {{"frames_decoded", c.framesDecoded()},
                                                          {"drive_pdos", c.drivePositions},
                                                          {"steering_pdos", c.steeringPositions},
                                                          {"heartbeats", c.heartbeats},
                                                          {"frames_to_nodes", c.framesToNodes},
                                                          {"frames_dropped", c.framesDropped},
                                                          {"malformed", c.malformed},
                                                          {"measurements", c.measurements},
                                                          {"samples_decoded", c.samples},
                                                          {"sample_mismatches", c.sampleMismatches},
                                                          {"samples_withheld", c.samplesWithheld},
                                                          {"drive_counter_wraps", c.driveCounterWraps}};
  for (const auto& [key, value] : fields) {
    std::fprintf(f, ", \"%s\": %" PRIu64, key, value);
  }
  std::fprintf(f, "},\n");
}

bool writeJson(const std::string& file, const agv::hil::ScenarioConfig& cfg, const HilCalibration& calib,
               const std::string& calibStatus, const std::vector<agv::hil::RunResult>& runs,
               const std::vector<agv::hil::RunResult>& mappingRuns, std::size_t mapCorners, bool requirementMet) {
  std::FILE* f = std::fopen(file.c_str(), "w");
  if (f == nullptr) {
    return false;
  }
  std::fprintf(f, "{\n  \"calibration\": {\n    \"truth\": ");
  writeParams(f, cfg.vehicle.truth, cfg.vehicle.laserMount);
  std::fprintf(f, ",\n    \"estimate\": ");
  writeParams(f, cfg.estimate.kinematics, cfg.estimate.laserMount);
  std::fprintf(f, ",\n    \"nominal\": ");
  writeParams(f, cfg.nominal.kinematics, cfg.nominal.laserMount);
  std::fprintf(f, ",\n    \"estimate_error\": ");
  writeParamDiff(f, cfg.estimate, cfg.vehicle);
  std::fprintf(f, ",\n    \"nominal_error\": ");
  writeParamDiff(f, cfg.nominal, cfg.vehicle);
  std::fprintf(f, ",\n    \"estimate_source\": \"%s\",\n    \"status\": %s,\n    \"segments_used\": %d\n  },\n",
               calib.status == agv::Status::Ok ? "calibration_atc" : "nominal", jsonString(calibStatus).c_str(),
               calib.segmentsUsed);
  std::fprintf(f, "  \"requirement\": {\"position_m\": %.3f, \"heading_deg\": %.3f},\n", kPositionRequirement,
               kHeadingRequirementDeg);
  writeCanJson(f, cfg, canTotals(calib, runs, mappingRuns));
  std::fprintf(f, "  \"stages\": {");
  bool firstStage = true;
  for (const Stage& s : kStages) {
    std::fprintf(f, "%s\"%s\": \"%s\"", firstStage ? "" : ", ", s.key,
                 s.failed ? "failed" : (s.wired ? "run" : "not wired"));
    firstStage = false;
  }
  std::fprintf(f, "},\n  \"runs\": [\n");
  bool first = true;
  for (const agv::hil::RunResult& r : runs) {
    std::fprintf(f, "%s", first ? "" : ",\n");
    writeLocalizerRun(f, r);
    first = false;
  }
  for (const agv::hil::RunResult& r : runs) {
    if (r.mode != agv::hil::LocalizationMode::Reflectors) {
      continue;  // the vehicle runs of every mode repeat these (same seeds): one comparison set
    }
    struct Entry {
      const char* params;
      const agv::Pose2d* pose;
    };
    const Entry entries[3] = {
        {"truth", &r.finalWithTruth}, {"nominal", &r.finalWithNominal}, {"estimate", &r.finalWithEstimate}};
    for (const Entry& e : entries) {
      std::fprintf(f,
                   "%s    {\"mode\": \"dead_reckoning\", \"parameters\": \"%s\", \"path\": %s, \"run\": %d, "
                   "\"final_position_error_m\": %.6f, \"final_heading_error_deg\": %.6f, \"distance_m\": %.3f, "
                   "\"finished\": %s}",
                   first ? "" : ",\n", e.params, jsonString(r.path).c_str(), r.run,
                   agv::hil::positionError(*e.pose, r.finalTruth),
                   agv::rad2deg(agv::hil::headingError(*e.pose, r.finalTruth)), r.distance,
                   r.finished ? "true" : "false");
      first = false;
    }
  }
  std::fprintf(f, "\n  ],\n  \"static_falko_mapping\": {\"frozen_corners\": %zu, \"runs\": [\n", mapCorners);
  first = true;
  for (const agv::hil::RunResult& r : mappingRuns) {
    std::fprintf(f, "%s", first ? "" : ",\n");
    writeLocalizerRun(f, r);
    first = false;
  }
  std::fprintf(f, "\n  ]},\n  \"requirement_met\": %s\n}\n", requirementMet ? "true" : "false");
  return std::fclose(f) == 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"agvnav-hil: hardware-in-the-loop simulation of a tricycle forklift AGV in a warehouse"};
  std::string worldFile;
  std::string jsonFile;
  std::string svgDir;
  int runs = 6;
  bool shortScenario = false;
  bool printWorld = false;
  std::uint64_t seed = 1;
  app.add_option("--world", worldFile, "world file (docs/world-format.md); default: the built-in warehouse")
      ->check(CLI::ExistingFile);
  app.add_option("--json", jsonFile, "write a JSON summary to FILE");
  app.add_option("--svg", svgDir, "write map.svg and error.svg into DIR (created if missing)");
  app.add_option("--runs", runs, "runs per path (default 6)")->check(CLI::Range(1, 1000));
  app.add_option("--seed", seed, "random seed of the simulation (default 1)");
  app.add_flag("--short", shortScenario,
               "test-size scenario: 1 run per path, 1 deg laser resolution, 3 calibration steering angles");
  app.add_flag("--print-world", printWorld, "print the built-in world file and exit");
  int minHitsToCorrect = agv::hil::ScenarioConfig{}.dynamicMinHitsToCorrect;
  app.add_option("--min-hits-to-correct", minHitsToCorrect,
                 "dynamic mode: matches before a new corner corrects the pose (0 = at once)")
      ->check(CLI::Range(0, 20));
  bool canSync = false;
  app.add_flag("--can-sync", canSync,
               "encoders send synchronous TPDOs on the vehicle's SYNC (every encoder period) instead of cyclic ones");
  CLI11_PARSE(app, argc, argv);

  if (printWorld) {
    const std::string_view text = agv::sim::defaultWorldText();
    std::fwrite(text.data(), 1, text.size(), stdout);
    return 0;
  }

  agv::sim::World world;
  agv::sim::WorldParseError perr;
  const agv::Status ws = worldFile.empty() ? agv::sim::parseWorld(agv::sim::defaultWorldText(), world, perr)
                                           : agv::sim::loadWorldFile(worldFile, world, perr);
  if (ws != agv::Status::Ok) {
    std::fprintf(stderr, "agvnav-hil: world %s: line %d: %s (%s)\n",
                 worldFile.empty() ? "(built-in)" : worldFile.c_str(), perr.line, perr.message.c_str(),
                 agv::toString(ws));
    return 2;
  }

  agv::hil::ScenarioConfig cfg;
  cfg.runsPerPath = shortScenario && app.count("--runs") == 0 ? 1 : runs;
  cfg.seed = seed;
  cfg.dynamicMinHitsToCorrect = static_cast<std::int16_t>(minHitsToCorrect);
  if (canSync) {
    cfg.can.bus.syncPeriod = cfg.vehicle.encoderPeriod;
  }
  if (shortScenario) {
    cfg.laser.angularResolution = agv::deg2rad(1.0);
  }

  // Stage 1: the on-vehicle calibration routine against the simulated vehicle.
  const agv::sim::RayCaster caster(world, 1.0);
  agv::calibration::PlanRequest request;
  if (!worldFile.empty()) {
    request.start = world.paths.empty() ? agv::Pose2d{} : world.paths.front().start;
  }
  agv::sim::Point2 lo;
  agv::sim::Point2 hi;
  world.bounds(&lo, &hi);
  request.area = agv::calibration::FreeArea{lo.x, lo.y, hi.x, hi.y};  // the hall; paths keep clear of obstacles
  request.wheelbase = cfg.nominal.kinematics.wheelbase;
  request.segmentsPerPhase = shortScenario ? 3 : 5;  // steering 18/34/50 or 18/26/34/42/50 deg
  agv::calibration::CalibrationPlan plan;
  std::string planError;
  HilCalibration calib;
  if (agv::calibration::planCalibration(request, plan, planError) != agv::Status::Ok) {
    calib.status = agv::Status::OutOfRange;
    calib.message = planError;
  } else {
    std::printf("calibration routine: %zu half-circle segments (steering +-", plan.segments.size());
    for (std::size_t k = 0; k < plan.segments.size(); k += 4) {
      std::printf("%s%.0f", k == 0 ? "" : "/", agv::rad2deg(plan.segments[k].steering));
    }
    std::printf(" deg, forward and backward) from (%.1f, %.1f)...\n", request.start.x, request.start.y);
    std::fflush(stdout);
    // Encoder samples only through CAN frames, as in the runs.
    agv::calibration::SimCalibrationVehicle simVehicle(caster, cfg.vehicle, cfg.laser, cfg.seed, request.start,
                                                       &cfg.can);
    agv::calibration::RoutineOptions routine;
    routine.nominal = cfg.nominal.kinematics;
    routine.nominalLaser = cfg.nominal.laserMount;
    routine.deceleration = cfg.vehicle.acceleration;
    routine.controlPeriod = cfg.controlPeriod;
    static_cast<agv::calibration::CalibrationOutcome&>(calib) =
        agv::calibration::runCalibrationRoutine(simVehicle, plan, routine, {});
    calib.can = simVehicle.canCounters();
  }
  std::string calibStatus = agv::toString(calib.status);
  if (calib.status == agv::Status::Ok) {
    cfg.estimate.kinematics = calib.result.params;
    cfg.estimate.laserMount = calib.result.laserPose;
  } else {
    calibStatus = calib.message;
    cfg.estimate = cfg.nominal;
    kStages[0].failed = true;
  }

  std::printf("agvnav-hil: world %s: %zu obstacle edges, %zu cylinders (%zu reflectors), %zu paths\n",
              worldFile.empty() ? "(built-in warehouse)" : worldFile.c_str(), world.segments.size(),
              world.circles.size(), world.reflectorCount(), world.paths.size());
  std::printf("stages:\n");
  for (const Stage& s : kStages) {
    std::printf("  %-52s %s\n", s.name,
                s.failed ? "FAILED (nominal parameters used)" : (s.wired ? "RUN" : "NOT WIRED YET (skipped)"));
  }
  const agv::TricycleParams& tk = cfg.vehicle.truth;
  const agv::TricycleParams& nk = cfg.nominal.kinematics;
  const agv::TricycleParams& ek = cfg.estimate.kinematics;
  if (calib.status == agv::Status::Ok) {
    std::printf(
        "calibration: %d of %d segments used, %.0f s of driving, reflector alignment rms %.1f mm, "
        "condition numbers fwd %.1f / bwd %.1f / laser %.1f\n",
        calib.segmentsUsed, calib.segmentsDriven, calib.seconds, 1000.0 * calib.meanAlignmentRms,
        calib.result.report.conditionForward, calib.result.report.conditionBackward,
        calib.result.report.conditionLaser);
  } else {
    std::printf("calibration FAILED (%s): the estimate is the nominal drawing value\n", calibStatus.c_str());
  }
  const agv::Pose2d& tl = cfg.vehicle.laserMount;
  const agv::Pose2d& nl = cfg.nominal.laserMount;
  const agv::Pose2d& el = cfg.estimate.laserMount;
  std::printf("  %-20s %14s %14s %14s %14s\n", "", "truth", "nominal", "estimate", "est - truth");
  std::printf("  %-20s %14.6e %14.6e %14.6e %14.2e\n", "s_w [m/tick]", tk.driveScale, nk.driveScale, ek.driveScale,
              ek.driveScale - tk.driveScale);
  std::printf("  %-20s %14.4f %14.4f %14.4f %14.4f\n", "alpha_F [deg]", agv::rad2deg(tk.steerOffsetForward),
              agv::rad2deg(nk.steerOffsetForward), agv::rad2deg(ek.steerOffsetForward),
              agv::rad2deg(ek.steerOffsetForward - tk.steerOffsetForward));
  std::printf("  %-20s %14.4f %14.4f %14.4f %14.4f\n", "alpha_B [deg]", agv::rad2deg(tk.steerOffsetBackward),
              agv::rad2deg(nk.steerOffsetBackward), agv::rad2deg(ek.steerOffsetBackward),
              agv::rad2deg(ek.steerOffsetBackward - tk.steerOffsetBackward));
  std::printf("  %-20s %14.4f %14.4f %14.4f %14.4f\n", "laser x [m]", tl.x, nl.x, el.x, el.x - tl.x);
  std::printf("  %-20s %14.4f %14.4f %14.4f %14.4f\n", "laser y [m]", tl.y, nl.y, el.y, el.y - tl.y);
  std::printf("  %-20s %14.4f %14.4f %14.4f %14.4f\n", "laser theta [deg]", agv::rad2deg(tl.theta),
              agv::rad2deg(nl.theta), agv::rad2deg(el.theta), agv::rad2deg(agv::angleDiff(el.theta, tl.theta)));
  std::printf("laser: %zu beams over %.0f deg at %.1f Hz, reflectors up to %.0f m\n", cfg.laser.beamCount(),
              agv::rad2deg(cfg.laser.fieldOfView), cfg.laser.scanRate, cfg.laser.reflectorMaxRange);
  std::printf("runs: %d per path; final pose error at the operation point (end of path) vs %.0f cm / %.1f deg\n",
              cfg.runsPerPath, kPositionRequirement * 100.0, kHeadingRequirementDeg);
  std::fflush(stdout);

  // Stage 2: the localizer in the loop, mode after mode. The runs of every mode use the same
  // seeds, so the vehicle, its slip and the laser noise repeat: the modes differ only in what the
  // localizer is fed.
  using agv::hil::LocalizationMode;
  using agv::hil::RunResult;
  const auto progress = [](const RunResult& r, int index, int total) {
    std::printf(
        "[%2d/%2d] %-12s %-4s run %d: %5.2f m in %5.1f s%s | localizer %6.1f mm %6.3f deg%s (%.1f landmarks/scan, "
        "%zu without fix) | DR estimated %6.1f mm %6.3f deg | DR true %5.1f mm | reflectors/scan %.1f (min %zu)\n",
        index, total, agv::hil::modeName(r.mode), r.path.c_str(), r.run, r.distance, r.simSeconds,
        r.finished ? "" : " (NOT FINISHED)", 1000.0 * agv::hil::positionError(r.finalLocalized, r.finalTruth),
        agv::rad2deg(agv::hil::headingError(r.finalLocalized, r.finalTruth)), r.localizerLost ? " LOST" : "",
        r.meanUsedPerScan, r.scansWithoutFix, 1000.0 * agv::hil::positionError(r.finalWithEstimate, r.finalTruth),
        agv::rad2deg(agv::hil::headingError(r.finalWithEstimate, r.finalTruth)),
        1000.0 * agv::hil::positionError(r.finalWithTruth, r.finalTruth), r.meanReflectorsPerScan,
        r.minReflectorsPerScan);
    std::fflush(stdout);
  };
  std::vector<RunResult> results;
  std::vector<RunResult> mappingResults;
  std::string error;
  // The surveyed reflector map: the poles as a surveyor measured them (1 mm per coordinate).
  constexpr double kSurveySigma = 0.001;  // [m]
  auto reflectorMap = std::make_unique<agv::LandmarkMap>();
  if (agv::hil::buildSurveyedReflectorMap(world, kSurveySigma, seed ^ 0x5EEDU, *reflectorMap) != agv::Status::Ok) {
    std::fprintf(stderr, "agvnav-hil: the world's reflectors do not fit the landmark map\n");
    return 2;
  }
  std::printf("mode reflectors: surveyed map of %zu reflectors (survey noise %.0f mm), static\n", reflectorMap->size(),
              1000.0 * kSurveySigma);
  if (!agv::hil::runScenario(world, cfg, LocalizationMode::Reflectors, *reflectorMap, nullptr, {}, cfg.runsPerPath, 0,
                             progress, &results, &error)) {
    std::fprintf(stderr, "agvnav-hil: %s\n", error.c_str());
    return 2;
  }
  // Static FALKO map: one mapping run per path (other seeds) localizing on the surveyed
  // reflectors while the FALKO corners are accumulated at the localizer's pose; the corners seen
  // at least kMinMapHits times are then frozen and used alone.
  constexpr int kMinMapHits = 5;
  constexpr double kMaxCornerScatter = 0.015;  // [m] per coordinate
  agv::hil::CornerMapper mapper;
  std::printf(
      "mode static_falko: mapping runs (localizing on the surveyed reflectors, FALKO corners accumulated "
      "at the localizer's pose), 1 per path\n");
  if (!agv::hil::runScenario(world, cfg, LocalizationMode::Mapping, *reflectorMap, &mapper, {}, 1, 0xA11CEU, progress,
                             &mappingResults, &error)) {
    std::fprintf(stderr, "agvnav-hil: %s\n", error.c_str());
    return 2;
  }
  auto falkoMap = std::make_unique<agv::LandmarkMap>();
  const std::size_t mapCorners = mapper.freeze(kMinMapHits, kMaxCornerScatter, *falkoMap);
  std::printf(
      "mode static_falko: %zu of %zu corner clusters frozen (seen >= %d times, scatter <= %.0f mm), static, corners "
      "only\n",
      mapCorners, mapper.clusters(), kMinMapHits, 1000.0 * kMaxCornerScatter);
  if (!agv::hil::runScenario(world, cfg, LocalizationMode::StaticFalko, *falkoMap, nullptr, {}, cfg.runsPerPath, 0,
                             progress, &results, &error)) {
    std::fprintf(stderr, "agvnav-hil: %s\n", error.c_str());
    return 2;
  }
  // Dynamic map: FALKO corners only, no prior map, on the path into the block storage (P4 in the
  // built-in warehouse; the last path of a custom world).
  std::size_t dynamicPath = world.paths.size() - 1;
  for (std::size_t p = 0; p < world.paths.size(); ++p) {
    if (world.paths[p].name == "P4") {
      dynamicPath = p;
    }
  }
  auto dynamicMap = std::make_unique<agv::LandmarkMap>();
  std::printf("mode dynamic: FALKO corners only, empty map at the start, path %s\n",
              world.paths[dynamicPath].name.c_str());
  if (!agv::hil::runScenario(world, cfg, LocalizationMode::Dynamic, *dynamicMap, nullptr, {dynamicPath},
                             cfg.runsPerPath, 0, progress, &results, &error)) {
    std::fprintf(stderr, "agvnav-hil: %s\n", error.c_str());
    return 2;
  }

  // Summary per path and parameter set: maximum final errors over the runs.
  bool allFinished = true;
  bool localizerMeets = true;
  int truthMeetCount = 0;
  int estimateMeetCount = 0;
  int drRuns = 0;
  std::printf("dead reckoning (comparison), max over runs: %-4s %22s %22s %22s\n", "path", "DR true params",
              "DR nominal params", "DR estimated params");
  for (const agv::sim::Path& p : world.paths) {
    double maxP[3] = {0.0, 0.0, 0.0};
    double maxH[3] = {0.0, 0.0, 0.0};
    for (const RunResult& r : results) {
      if (r.path != p.name || r.mode != LocalizationMode::Reflectors) {
        continue;
      }
      const agv::Pose2d* finals[3] = {&r.finalWithTruth, &r.finalWithNominal, &r.finalWithEstimate};
      for (int k = 0; k < 3; ++k) {
        maxP[k] = std::max(maxP[k], agv::hil::positionError(*finals[k], r.finalTruth));
        maxH[k] = std::max(maxH[k], agv::hil::headingError(*finals[k], r.finalTruth));
      }
    }
    std::printf("                                            %-4s", p.name.c_str());
    for (int k = 0; k < 3; ++k) {
      std::printf(" %9.1f mm %7.3f deg", 1000.0 * maxP[k], agv::rad2deg(maxH[k]));
    }
    std::printf("\n");
  }
  std::printf("localizer (pose sent to the PLC): %-12s %-4s %s\n", "mode", "path",
              "position max / rms [mm], heading max / rms [deg], runs within requirement");
  for (const LocalizationMode mode :
       {LocalizationMode::Reflectors, LocalizationMode::StaticFalko, LocalizationMode::Dynamic}) {
    for (const agv::sim::Path& p : world.paths) {
      double maxP = 0.0;
      double maxH = 0.0;
      double sumP2 = 0.0;
      double sumH2 = 0.0;
      int n = 0;
      int met = 0;
      for (const RunResult& r : results) {
        if (r.path != p.name || r.mode != mode) {
          continue;
        }
        const double e = agv::hil::positionError(r.finalLocalized, r.finalTruth);
        const double h = agv::rad2deg(agv::hil::headingError(r.finalLocalized, r.finalTruth));
        maxP = std::max(maxP, e);
        maxH = std::max(maxH, h);
        sumP2 += e * e;
        sumH2 += h * h;
        ++n;
        met += runMeets(r) ? 1 : 0;
      }
      if (n == 0) {
        continue;
      }
      std::printf("                                  %-12s %-4s %6.1f / %6.1f mm   %6.3f / %6.3f deg   %d of %d\n",
                  agv::hil::modeName(mode), p.name.c_str(), 1000.0 * maxP,
                  1000.0 * std::sqrt(sumP2 / static_cast<double>(n)), maxH, std::sqrt(sumH2 / static_cast<double>(n)),
                  met, n);
    }
  }
  int localizerRuns = 0;
  int localizerMeetCount = 0;
  for (const RunResult& r : results) {
    allFinished = allFinished && r.finished;
    localizerMeets = localizerMeets && runMeets(r);
    ++localizerRuns;
    localizerMeetCount += runMeets(r) ? 1 : 0;
    if (r.mode == LocalizationMode::Reflectors) {
      ++drRuns;
      truthMeetCount += meets(r.finalWithTruth, r.finalTruth) ? 1 : 0;
      estimateMeetCount += meets(r.finalWithEstimate, r.finalTruth) ? 1 : 0;
    }
  }
  const bool requirementMet = allFinished && localizerMeets;
  std::printf(
      "%.0f cm / %.1f deg met by dead reckoning with the true parameters in %d of %d runs, with the "
      "estimated parameters in %d\n",
      kPositionRequirement * 100.0, kHeadingRequirementDeg, truthMeetCount, drRuns, estimateMeetCount);
  const agv::sim::CanBusCounters can = canTotals(calib, results, mappingResults);
  std::printf("encoders over CAN (CiA 402 drive node %u, CiA 406 steering node %u%s): %" PRIu64
              " frames decoded (%" PRIu64 " drive positions, %" PRIu64 " steering positions, %" PRIu64
              " heartbeats), %" PRIu64 " samples, %" PRIu64 " drive counter wraps, %" PRIu64
              " samples differing from the measurement sent\n",
              unsigned{cfg.can.bus.drive.nodeId}, unsigned{cfg.can.bus.steering.nodeId},
              cfg.can.bus.syncPeriod.ns > 0 ? ", SYNC" : "", can.framesDecoded(), can.drivePositions,
              can.steeringPositions, can.heartbeats, can.samples, can.driveCounterWraps, can.sampleMismatches);
  std::printf("requirement (pose sent to the PLC by the localizer, every run of every mode): %s (%d of %d runs)\n",
              requirementMet ? "MET" : "NOT MET", localizerMeetCount, localizerRuns);

  int rc = requirementMet ? 0 : 1;
  if (!allFinished) {
    std::fprintf(stderr, "agvnav-hil: a run did not reach the end of its path\n");
    rc = 3;
  }
  if (!svgDir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(svgDir, ec);
    const std::string map = svgDir + "/map.svg";
    const std::string err = svgDir + "/error.svg";
    if (ec || !agv::hil::writeMapSvg(map, world, results) ||
        !agv::hil::writeErrorSvg(err, results, kPositionRequirement)) {
      std::fprintf(stderr, "agvnav-hil: cannot write the plots into %s\n", svgDir.c_str());
      return 2;
    }
    std::printf("plots: %s, %s\n", map.c_str(), err.c_str());
  }
  if (!jsonFile.empty()) {
    if (!writeJson(jsonFile, cfg, calib, calibStatus, results, mappingResults, mapCorners, requirementMet)) {
      std::fprintf(stderr, "agvnav-hil: cannot write %s\n", jsonFile.c_str());
      return 2;
    }
    std::printf("summary: %s\n", jsonFile.c_str());
  }
  return rc;
}
