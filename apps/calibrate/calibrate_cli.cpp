#include "calibrate_cli.hpp"

#include <CLI/CLI.hpp>
#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include "agv/calib/calibration_file.hpp"
#include "agv/calibration/calibration_routine.hpp"
#include "agv/calibration/sim_calibration_vehicle.hpp"
#include "agv/core/angle.hpp"
#include "agv/sim/ray_caster.hpp"
#include "agv/sim/world.hpp"

namespace agv::calibration {
namespace {

const char* yesNo(bool b) noexcept {
  return b ? "yes" : "NO";
}

/// Seconds as "12m05s".
std::string minutes(double s) {
  char buf[32];
  const long total = std::lround(s < 0.0 ? 0.0 : s);
  std::snprintf(buf, sizeof buf, "%ldm%02lds", total / 60, total % 60);
  return buf;
}

void printReport(std::FILE* out, const char* name, const CalibrationReport& r) {
  std::fprintf(out, "observability (%s): %s%s%s\n", name, toString(r.status),
               r.failed == CalibCondition::None ? "" : ", failed condition: ",
               r.failed == CalibCondition::None ? "" : toString(r.failed));
  std::fprintf(out, "  segments %zu (forward %zu, backward %zu)\n", r.segmentCount, r.forwardCount, r.backwardCount);
  std::fprintf(out, "  steering diversity: all %s, forward %s, backward %s; laser rotation %s, translation %s\n",
               yesNo(r.steeringDiverse), yesNo(r.forwardSteeringDiverse), yesNo(r.backwardSteeringDiverse),
               yesNo(r.laserRotationObserved), yesNo(r.laserTranslationObserved));
  std::fprintf(out, "  condition numbers: STC %.1f, forward %.1f, backward %.1f, laser %.1f\n", r.conditionStc,
               r.conditionForward, r.conditionBackward, r.conditionLaser);
  std::fprintf(out, "  fit: rotation rms %.2f mdeg, translation rms %.2f mm, ATC multiplier %.3g\n",
               1e3 * rad2deg(r.rotationRms), 1e3 * r.translationRms, r.lambda);
}

}  // namespace

int calibrateMain(int argc, const char* const* argv, std::FILE* out, std::FILE* err) {
  CLI::App app{
      "agvnav-calibrate: on-vehicle calibration (driving scale, steering offsets, laser mount) by driving "
      "half circles and measuring them with the laser; runs on the simulated vehicle"};
  PlanRequest request;
  RoutineOptions options;
  double wheelbase = 1.5;
  double driveScale = 1.0e-4;
  double laserX = 1.6;
  double laserY = 0.0;
  double laserThetaDeg = 0.0;
  double steeringLimitDeg = 85.0;
  double steerMinDeg = 18.0;
  double steerMaxDeg = 50.0;
  double betaDeg = 180.0;
  std::vector<double> area{request.area.xMin, request.area.yMin, request.area.xMax, request.area.yMax};
  std::vector<double> start{request.start.x, request.start.y, 0.0};
  std::string egomotion = "reflectors";
  std::string output = "calibration.txt";
  std::string worldFile;
  std::uint64_t seed = 1;
  double laserResolutionDeg = 0.25;
  bool quiet = false;
  app.add_option("--wheelbase", wheelbase, "L [m], from the drawing (default 1.5)")->check(CLI::PositiveNumber);
  app.add_option("--drive-scale", driveScale, "nominal s_w [m/tick] (default 1e-4)")->check(CLI::PositiveNumber);
  app.add_option("--laser-x", laserX, "nominal laser mount x [m] (default 1.6)");
  app.add_option("--laser-y", laserY, "nominal laser mount y [m] (default 0)");
  app.add_option("--laser-theta", laserThetaDeg, "nominal laser mount heading [deg] (default 0)");
  app.add_option("--steering-limit", steeringLimitDeg, "largest |steering| the vehicle accepts [deg] (default 85)")
      ->check(CLI::Range(1.0, 89.0));
  app.add_option("--steer-min", steerMinDeg, "smallest |steering| of the plan [deg] (default 18)")
      ->check(CLI::Range(1.0, 89.0));
  app.add_option("--steer-max", steerMaxDeg, "largest |steering| of the plan [deg] (default 50)")
      ->check(CLI::Range(1.0, 89.0));
  app.add_option("--segments", request.segmentsPerPhase,
                 "n_seg: steering angles, one segment each per phase (4 phases; default 6)")
      ->check(CLI::Range(1, static_cast<int>(kMaxCalibSegments / 4)));
  app.add_option("--beta", betaDeg, "rotation of each segment [deg] (default 180)")->check(CLI::Range(1.0, 359.0));
  app.add_option("--area", area, "free area XMIN YMIN XMAX YMAX [m] (default: open floor of the built-in warehouse)")
      ->expected(4);
  app.add_option("--start", start, "start pose X Y HEADING [m m deg] (default 10 12.5 0)")->expected(3);
  app.add_option("--clearance", request.clearance, "vehicle half width plus margin [m] (default 0.8)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--front", request.frontOverhang, "logical point to vehicle front [m] (default 2.0)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--speed", options.speed, "drive speed on the segments [m/s] (default 0.5)")
      ->check(CLI::Range(0.05, 2.0));
  app.add_option("--egomotion", egomotion, "egomotion source: reflectors (default) or keypoints (FALKO)")
      ->check(CLI::IsMember({"reflectors", "keypoints"}));
  app.add_option("--output,-o", output, "calibration file to write (default calibration.txt)");
  app.add_option("--world", worldFile, "simulated world file (docs/world-format.md); default: built-in warehouse");
  app.add_option("--seed", seed, "random seed of the simulated vehicle and laser (default 1)");
  app.add_option("--laser-resolution", laserResolutionDeg, "simulated laser beam spacing [deg] (default 0.25)")
      ->check(CLI::Range(0.1, 2.0));
  app.add_flag("--quiet,-q", quiet, "no progress lines");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) {
      std::fprintf(out, "%s", app.help().c_str());
      return 0;
    }
    std::fprintf(err, "agvnav-calibrate: %s\n", e.what());
    return 2;
  }

  const double numbers[] = {
      wheelbase,          driveScale,  laserX,  laserY,        laserThetaDeg,     steeringLimitDeg,
      steerMinDeg,        steerMaxDeg, betaDeg, options.speed, request.clearance, request.frontOverhang,
      laserResolutionDeg, area[0],     area[1], area[2],       area[3],           start[0],
      start[1],           start[2]};
  for (const double v : numbers) {
    if (!std::isfinite(v)) {
      std::fprintf(err, "agvnav-calibrate: every numeric option must be a finite number\n");
      return 2;
    }
  }
  options.nominal = TricycleParams{wheelbase, driveScale, 0.0, 0.0};
  options.nominalLaser = Pose2d{laserX, laserY, deg2rad(laserThetaDeg)};
  options.egomotion = egomotion == "keypoints" ? EgomotionSource::Keypoints : EgomotionSource::Reflectors;
  request.wheelbase = wheelbase;
  request.steeringLimit = deg2rad(steeringLimitDeg);
  request.minSteering = deg2rad(steerMinDeg);
  request.maxSteering = deg2rad(steerMaxDeg);
  request.rotation = deg2rad(betaDeg);
  request.area = FreeArea{area[0], area[1], area[2], area[3]};
  request.start = Pose2d{start[0], start[1], deg2rad(start[2])};

  CalibrationPlan plan;
  std::string planError;
  if (planCalibration(request, plan, planError) != Status::Ok) {
    std::fprintf(err, "agvnav-calibrate: plan refused: %s\n", planError.c_str());
    return 2;
  }

  sim::World world;
  sim::WorldParseError perr;
  const Status ws = worldFile.empty() ? sim::parseWorld(sim::defaultWorldText(), world, perr)
                                      : sim::loadWorldFile(worldFile, world, perr);
  if (ws != Status::Ok) {
    std::fprintf(err, "agvnav-calibrate: world %s: line %d: %s (%s)\n",
                 worldFile.empty() ? "(built-in)" : worldFile.c_str(), perr.line, perr.message.c_str(), toString(ws));
    return 2;
  }
  const sim::RayCaster caster(world, 1.0);
  const sim::SimVehicleParams truth;
  sim::SimLaserParams laserParams;
  laserParams.angularResolution = deg2rad(laserResolutionDeg);
  // The encoders reach the routine as CAN frames through the vehicle's CANopen decoder.
  const sim::SimCanEncodersParams can = sim::defaultSimCanEncoders(1U << 14U);
  SimCalibrationVehicle vehicle(caster, truth, laserParams, seed, request.start, &can);
  if (vehicle.status() != Status::Ok) {
    std::fprintf(err, "agvnav-calibrate: simulated laser or CAN parameters refused (%s)\n", toString(vehicle.status()));
    return 2;
  }
  options.deceleration = truth.acceleration;

  std::fprintf(out,
               "plan: %zu segments (%d steering angles %.1f..%.1f deg x left/right x forward/backward), beta %.0f "
               "deg, start (%.2f, %.2f, %.1f deg), free area [%.2f, %.2f] x [%.2f, %.2f] m\n",
               plan.segments.size(), request.segmentsPerPhase, steerMinDeg, steerMaxDeg, betaDeg, request.start.x,
               request.start.y, start[2], request.area.xMin, request.area.xMax, request.area.yMin, request.area.yMax);
  std::fprintf(out, "egomotion from %s; vehicle: simulated (world %s, encoders over CANopen)\n", egomotion.c_str(),
               worldFile.empty() ? "built-in warehouse" : worldFile.c_str());
  std::fflush(out);
  const auto progress = [&](const RoutineProgress& p) {
    if (quiet) {
      return;
    }
    const PlannedSegment& s = plan.segments[static_cast<std::size_t>(p.segment - 1)];
    std::fprintf(out, "segment %2d of %d  %-14s %+6.1f deg  elapsed %s  remaining ~%s\n", p.segment, p.total,
                 phaseName(s.phase), rad2deg(s.steering), minutes(p.elapsed).c_str(), minutes(p.remaining).c_str());
    std::fflush(out);
  };
  const CalibrationOutcome r = runCalibrationRoutine(vehicle, plan, options, progress);
  std::fprintf(out,
               "data: %d segments driven, %d used, %d rejected, %s of driving; alignment %.1f %s per segment, "
               "rms %.2f mm\n",
               r.segmentsDriven, r.segmentsUsed, r.segmentsRejected, minutes(r.seconds).c_str(), r.meanMatches,
               options.egomotion == EgomotionSource::Keypoints ? "keypoint inliers" : "reflector pairs",
               1e3 * r.meanAlignmentRms);
  const sim::CanBusCounters c = vehicle.canCounters();
  std::fprintf(out, "encoders: %llu CAN frames decoded, %llu samples, %llu mismatches, %llu withheld\n",
               static_cast<unsigned long long>(c.framesDecoded()), static_cast<unsigned long long>(c.samples),
               static_cast<unsigned long long>(c.sampleMismatches), static_cast<unsigned long long>(c.samplesWithheld));
  printReport(out, "STC", r.stc.report);
  printReport(out, "ATC", r.result.report);
  if (r.status != Status::Ok) {
    std::fprintf(err, "agvnav-calibrate: calibration failed: %s; no file written\n", r.message.c_str());
    return 1;
  }
  const bool refined = r.refinedStatus == Status::Ok;
  const TricycleParams& best = refined ? r.refined.params : r.result.params;
  const Pose2d& bestLaser = refined ? r.refined.laserPose : r.result.laserPose;
  VehicleCalibration cal;
  cal.params = best;
  cal.laserPose = bestLaser;
  // A posteriori scale of the refinement's covariance: when the residuals are larger than its noise
  // model says (cost per degree of freedom above 1: wheel slip, keypoint noise), the sigmas grow by
  // sqrt(cost / dof); they never shrink below the model's.
  const double dof = 3.0 * r.segmentsUsed - static_cast<double>(kCalibParamCount);
  const double varianceFactor = dof > 0.0 ? std::fmax(1.0, r.refined.finalCost / dof) : 1.0;
  if (refined) {
    const auto sd = [&](int i) { return std::sqrt(varianceFactor * r.refined.covariance(i, i)); };
    cal.sigmas = CalibrationSigmas{sd(kParamDriveScale), sd(kParamOffsetForward), sd(kParamOffsetBackward),
                                   sd(kParamLaserX),     sd(kParamLaserY),        sd(kParamLaserTheta)};
  }
  std::fprintf(out, "refinement: %s (%d iterations, cost %.1f -> %.1f, %.0f degrees of freedom, sigma scale %.2f)\n",
               toString(r.refinedStatus), r.refined.iterations, r.refined.initialCost, r.refined.finalCost, dof,
               std::sqrt(varianceFactor));
  std::fprintf(out, "  %-16s %13s %13s %13s %13s %11s %13s %11s\n", "", "nominal", "STC", "ATC", "refined", "1-sigma",
               "sim. truth", "error");
  const auto row = [&](const char* name, double scale, double nom, double stc, double atc, double ref, double sigma,
                       double tru, const char* fmt) {
    std::fprintf(out, fmt, name, scale * nom, scale * stc, scale * atc, scale * ref, scale * sigma, scale * tru,
                 scale * (ref - tru));
  };
  const char* fe = "  %-16s %13.6e %13.6e %13.6e %13.6e %11.2e %13.6e %+11.2e\n";
  const char* ff = "  %-16s %13.4f %13.4f %13.4f %13.4f %11.4f %13.4f %+11.4f\n";
  const double d = rad2deg(1.0);
  row("s_w [m/tick]", 1.0, driveScale, r.stc.params.driveScale, r.result.params.driveScale, best.driveScale,
      cal.sigmas.driveScale, truth.truth.driveScale, fe);
  row("alpha_F [deg]", d, 0.0, r.stc.params.steerOffsetForward, r.result.params.steerOffsetForward,
      best.steerOffsetForward, cal.sigmas.steerOffsetForward, truth.truth.steerOffsetForward, ff);
  row("alpha_B [deg]", d, 0.0, r.stc.params.steerOffsetBackward, r.result.params.steerOffsetBackward,
      best.steerOffsetBackward, cal.sigmas.steerOffsetBackward, truth.truth.steerOffsetBackward, ff);
  row("laser x [m]", 1.0, laserX, r.stc.laserPose.x, r.result.laserPose.x, bestLaser.x, cal.sigmas.laserX,
      truth.laserMount.x, ff);
  row("laser y [m]", 1.0, laserY, r.stc.laserPose.y, r.result.laserPose.y, bestLaser.y, cal.sigmas.laserY,
      truth.laserMount.y, ff);
  row("laser th [deg]", d, deg2rad(laserThetaDeg), r.stc.laserPose.theta, r.result.laserPose.theta, bestLaser.theta,
      cal.sigmas.laserTheta, truth.laserMount.theta, ff);

  std::vector<char> text(4096);
  const Result<std::size_t> n = formatCalibrationFile(cal, Span<char>(text.data(), text.size()));
  if (!n.ok()) {
    std::fprintf(err, "agvnav-calibrate: cannot format the calibration (%s)\n", toString(n.status()));
    return 1;
  }
  std::ofstream file(output, std::ios::binary);
  file.write(text.data(), static_cast<std::streamsize>(n.value()));
  file.close();
  if (!file) {
    std::fprintf(err, "agvnav-calibrate: cannot write %s\n", output.c_str());
    return 2;
  }
  std::fprintf(out, "wrote %s (%s values%s)\n", output.c_str(), refined ? "refined" : "ATC closed-form",
               refined ? " with 1-sigma" : "");
  return 0;
}

}  // namespace agv::calibration
