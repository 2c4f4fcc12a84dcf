#include "calibrate_cli.hpp"

#include <CLI/CLI.hpp>
#include <cmath>
#include <string>
#include <vector>

#include "agv/calib/calibration_file.hpp"
#include "agv/calibration/calibration_routine.hpp"
#include "agv/calibration/calibration_session.hpp"
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

/// Everything the command line sets: the plan request and routine options it fills directly, and
/// the values given in drawing units (degrees) that become their fields once checked.
struct CalibrateArgs {
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
};

/// The vehicle's geometry, the plan's shape and the routine's driving options.
void addVehicleAndPlanOptions(CLI::App& app, CalibrateArgs& a) {
  app.add_option("--wheelbase", a.wheelbase, "L [m], from the drawing (default 1.5)")->check(CLI::PositiveNumber);
  app.add_option("--drive-scale", a.driveScale, "nominal s_w [m/tick] (default 1e-4)")->check(CLI::PositiveNumber);
  app.add_option("--laser-x", a.laserX, "nominal laser mount x [m] (default 1.6)");
  app.add_option("--laser-y", a.laserY, "nominal laser mount y [m] (default 0)");
  app.add_option("--laser-theta", a.laserThetaDeg, "nominal laser mount heading [deg] (default 0)");
  app.add_option("--steering-limit", a.steeringLimitDeg, "largest |steering| the vehicle accepts [deg] (default 85)")
      ->check(CLI::Range(1.0, 89.0));
  app.add_option("--steer-min", a.steerMinDeg, "smallest |steering| of the plan [deg] (default 18)")
      ->check(CLI::Range(1.0, 89.0));
  app.add_option("--steer-max", a.steerMaxDeg, "largest |steering| of the plan [deg] (default 50)")
      ->check(CLI::Range(1.0, 89.0));
  app.add_option("--segments", a.request.segmentsPerPhase,
                 "n_seg: steering angles, one segment each per phase (4 phases; default 6)")
      ->check(CLI::Range(1, static_cast<int>(kMaxCalibSegments / 4)));
  app.add_option("--beta", a.betaDeg, "rotation of each segment [deg] (default 180)")->check(CLI::Range(1.0, 359.0));
  app.add_option("--area", a.area, "free area XMIN YMIN XMAX YMAX [m] (default: open floor of the built-in warehouse)")
      ->expected(4);
  app.add_option("--start", a.start, "start pose X Y HEADING [m m deg] (default 10 12.5 0)")->expected(3);
  app.add_option("--clearance", a.request.clearance, "vehicle half width plus margin [m] (default 0.8)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--front", a.request.frontOverhang, "logical point to vehicle front [m] (default 2.0)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--speed", a.options.speed, "drive speed on the segments [m/s] (default 0.5)")
      ->check(CLI::Range(0.05, 2.0));
  app.add_option("--egomotion", a.egomotion, "egomotion source: reflectors (default) or keypoints (FALKO)")
      ->check(CLI::IsMember({"reflectors", "keypoints"}));
}

/// The output file and the simulated vehicle's options.
void addOutputAndSimulationOptions(CLI::App& app, CalibrateArgs& a) {
  app.add_option("--output,-o", a.output, "calibration file to write (default calibration.txt)");
  app.add_option("--world", a.worldFile, "simulated world file (docs/world-format.md); default: built-in warehouse");
  app.add_option("--seed", a.seed, "random seed of the simulated vehicle and laser (default 1)");
  app.add_option("--laser-resolution", a.laserResolutionDeg, "simulated laser beam spacing [deg] (default 0.25)")
      ->check(CLI::Range(0.1, 2.0));
  app.add_flag("--quiet,-q", a.quiet, "no progress lines");
}

/// True when every numeric option is a finite number.
bool allFinite(const CalibrateArgs& a) {
  const double numbers[] = {
      a.wheelbase,          a.driveScale,  a.laserX,  a.laserY,        a.laserThetaDeg,     a.steeringLimitDeg,
      a.steerMinDeg,        a.steerMaxDeg, a.betaDeg, a.options.speed, a.request.clearance, a.request.frontOverhang,
      a.laserResolutionDeg, a.area[0],     a.area[1], a.area[2],       a.area[3],           a.start[0],
      a.start[1],           a.start[2]};
  for (const double v : numbers) {
    if (!std::isfinite(v)) {
      return false;
    }
  }
  return true;
}

/// The checked values, in SI units, into the routine options and the plan request.
void applyArgs(CalibrateArgs& a) {
  a.options.nominal = TricycleParams{a.wheelbase, a.driveScale, 0.0, 0.0};
  a.options.nominalLaser = Pose2d{a.laserX, a.laserY, deg2rad(a.laserThetaDeg)};
  a.options.egomotion = a.egomotion == "keypoints" ? EgomotionSource::Keypoints : EgomotionSource::Reflectors;
  a.request.wheelbase = a.wheelbase;
  a.request.steeringLimit = deg2rad(a.steeringLimitDeg);
  a.request.minSteering = deg2rad(a.steerMinDeg);
  a.request.maxSteering = deg2rad(a.steerMaxDeg);
  a.request.rotation = deg2rad(a.betaDeg);
  a.request.area = FreeArea{a.area[0], a.area[1], a.area[2], a.area[3]};
  a.request.start = Pose2d{a.start[0], a.start[1], deg2rad(a.start[2])};
}

/// The built-in warehouse or `worldFile`; false after saying why on `err`.
bool loadWorld(const std::string& worldFile, sim::World& world, std::FILE* err) {
  sim::WorldParseError perr;
  const Status ws = worldFile.empty() ? sim::parseWorld(sim::defaultWorldText(), world, perr)
                                      : sim::loadWorldFile(worldFile, world, perr);
  if (ws != Status::Ok) {
    std::fprintf(err, "agvnav-calibrate: world %s: line %d: %s (%s)\n",
                 worldFile.empty() ? "(built-in)" : worldFile.c_str(), perr.line, perr.message.c_str(), toString(ws));
    return false;
  }
  return true;
}

void printPlan(std::FILE* out, const CalibrateArgs& a, const CalibrationPlan& plan) {
  const PlanRequest& request = a.request;
  std::fprintf(out,
               "plan: %zu segments (%d steering angles %.1f..%.1f deg x left/right x forward/backward), beta %.0f "
               "deg, start (%.2f, %.2f, %.1f deg), free area [%.2f, %.2f] x [%.2f, %.2f] m\n",
               plan.segments.size(), request.segmentsPerPhase, a.steerMinDeg, a.steerMaxDeg, a.betaDeg, request.start.x,
               request.start.y, a.start[2], request.area.xMin, request.area.xMax, request.area.yMin, request.area.yMax);
  std::fprintf(out, "egomotion from %s; vehicle: simulated (world %s, encoders over CANopen)\n", a.egomotion.c_str(),
               a.worldFile.empty() ? "built-in warehouse" : a.worldFile.c_str());
  std::fflush(out);
}

/// What was driven and measured: segments, alignment, the CAN counters, both observability reports.
void printData(std::FILE* out, const CalibrateArgs& a, const CalibrationOutcome& r, const sim::CanBusCounters& c) {
  std::fprintf(out,
               "data: %d segments driven, %d used, %d rejected, %s of driving; alignment %.1f %s per segment, "
               "rms %.2f mm\n",
               r.segmentsDriven, r.segmentsUsed, r.segmentsRejected, minutes(r.seconds).c_str(), r.meanMatches,
               a.options.egomotion == EgomotionSource::Keypoints ? "keypoint inliers" : "reflector pairs",
               1e3 * r.meanAlignmentRms);
  std::fprintf(out, "encoders: %llu CAN frames decoded, %llu samples, %llu mismatches, %llu withheld\n",
               static_cast<unsigned long long>(c.framesDecoded()), static_cast<unsigned long long>(c.samples),
               static_cast<unsigned long long>(c.sampleMismatches), static_cast<unsigned long long>(c.samplesWithheld));
  printReport(out, "STC", r.stc.report);
  printReport(out, "ATC", r.result.report);
}

/// The table nominal / STC / ATC / written value / 1-sigma / simulated truth / error.
void printComparison(std::FILE* out, const CalibrateArgs& a, const CalibrationOutcome& r, const VehicleCalibration& cal,
                     const sim::SimVehicleParams& truth) {
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
  const TricycleParams& best = cal.params;
  const Pose2d& bestLaser = cal.laserPose;
  row("s_w [m/tick]", 1.0, a.driveScale, r.stc.params.driveScale, r.result.params.driveScale, best.driveScale,
      cal.sigmas.driveScale, truth.truth.driveScale, fe);
  row("alpha_F [deg]", d, 0.0, r.stc.params.steerOffsetForward, r.result.params.steerOffsetForward,
      best.steerOffsetForward, cal.sigmas.steerOffsetForward, truth.truth.steerOffsetForward, ff);
  row("alpha_B [deg]", d, 0.0, r.stc.params.steerOffsetBackward, r.result.params.steerOffsetBackward,
      best.steerOffsetBackward, cal.sigmas.steerOffsetBackward, truth.truth.steerOffsetBackward, ff);
  row("laser x [m]", 1.0, a.laserX, r.stc.laserPose.x, r.result.laserPose.x, bestLaser.x, cal.sigmas.laserX,
      truth.laserMount.x, ff);
  row("laser y [m]", 1.0, a.laserY, r.stc.laserPose.y, r.result.laserPose.y, bestLaser.y, cal.sigmas.laserY,
      truth.laserMount.y, ff);
  row("laser th [deg]", d, deg2rad(a.laserThetaDeg), r.stc.laserPose.theta, r.result.laserPose.theta, bestLaser.theta,
      cal.sigmas.laserTheta, truth.laserMount.theta, ff);
}

/// Writes `cal` as the calibration file `output` (atomically, the old file kept as `.bak`); the
/// exit code (0, or 2 after saying why).
int writeCalibration(const VehicleCalibration& cal, const std::string& output, std::FILE* err) {
  std::string error;
  if (writeCalibrationFile(output, cal, error) != Status::Ok) {
    std::fprintf(err, "agvnav-calibrate: %s\n", error.c_str());
    return 2;
  }
  return 0;
}

/// The refinement's figures, the comparison table and the calibration file; the exit code.
int reportAndWrite(std::FILE* out, std::FILE* err, const CalibrateArgs& a, const CalibrationOutcome& r,
                   const sim::SimVehicleParams& truth) {
  const bool refined = r.refinedStatus == Status::Ok;
  const double dof = 3.0 * r.segmentsUsed - static_cast<double>(kCalibParamCount);
  const double varianceFactor = refinementVarianceFactor(r);
  const VehicleCalibration cal = calibrationToWrite(r);
  std::fprintf(out, "refinement: %s (%d iterations, cost %.1f -> %.1f, %.0f degrees of freedom, sigma scale %.2f)\n",
               toString(r.refinedStatus), r.refined.iterations, r.refined.initialCost, r.refined.finalCost, dof,
               std::sqrt(varianceFactor));
  printComparison(out, a, r, cal, truth);
  const int code = writeCalibration(cal, a.output, err);
  if (code != 0) {
    return code;
  }
  std::fprintf(out, "wrote %s (%s values%s)\n", a.output.c_str(), refined ? "refined" : "ATC closed-form",
               refined ? " with 1-sigma" : "");
  return 0;
}

/// The routine on the simulated vehicle in `world`, then the report and the file; the exit code.
int calibrateSimulated(std::FILE* out, std::FILE* err, CalibrateArgs& a, const CalibrationPlan& plan,
                       const sim::World& world) {
  const sim::RayCaster caster(world, 1.0);
  const sim::SimVehicleParams truth;
  sim::SimLaserParams laserParams;
  laserParams.angularResolution = deg2rad(a.laserResolutionDeg);
  // The encoders reach the routine as CAN frames through the vehicle's CANopen decoder.
  const sim::SimCanEncodersParams can = sim::defaultSimCanEncoders(1U << 14U);
  SimCalibrationVehicle vehicle(caster, truth, laserParams, a.seed, a.request.start, &can);
  if (vehicle.status() != Status::Ok) {
    std::fprintf(err, "agvnav-calibrate: simulated laser or CAN parameters refused (%s)\n", toString(vehicle.status()));
    return 2;
  }
  a.options.deceleration = truth.acceleration;
  printPlan(out, a, plan);
  const auto progress = [&](const RoutineProgress& p) {
    if (a.quiet) {
      return;
    }
    const PlannedSegment& s = plan.segments[static_cast<std::size_t>(p.segment - 1)];
    std::fprintf(out, "segment %2d of %d  %-14s %+6.1f deg  elapsed %s  remaining ~%s\n", p.segment, p.total,
                 phaseName(s.phase), rad2deg(s.steering), minutes(p.elapsed).c_str(), minutes(p.remaining).c_str());
    std::fflush(out);
  };
  const CalibrationOutcome r = runCalibrationRoutine(vehicle, plan, a.options, progress);
  printData(out, a, r, vehicle.canCounters());
  if (r.status != Status::Ok) {
    std::fprintf(err, "agvnav-calibrate: calibration failed: %s; no file written\n", r.message.c_str());
    return 1;
  }
  return reportAndWrite(out, err, a, r, truth);
}

}  // namespace

int calibrateMain(int argc, const char* const* argv, std::FILE* out, std::FILE* err) {
  CLI::App app{
      "agvnav-calibrate: on-vehicle calibration (driving scale, steering offsets, laser mount) by driving "
      "half circles and measuring them with the laser; runs on the simulated vehicle"};
  CalibrateArgs a;
  addVehicleAndPlanOptions(app, a);
  addOutputAndSimulationOptions(app, a);
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
  if (!allFinite(a)) {
    std::fprintf(err, "agvnav-calibrate: every numeric option must be a finite number\n");
    return 2;
  }
  applyArgs(a);

  CalibrationPlan plan;
  std::string planError;
  if (planCalibration(a.request, plan, planError) != Status::Ok) {
    std::fprintf(err, "agvnav-calibrate: plan refused: %s\n", planError.c_str());
    return 2;
  }
  sim::World world;
  if (!loadWorld(a.worldFile, world, err)) {
    return 2;
  }
  return calibrateSimulated(out, err, a, plan, world);
}

}  // namespace agv::calibration
