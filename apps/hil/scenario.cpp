#include "scenario.hpp"

#include <algorithm>
#include <cmath>
#include <random>

#include "agv/hal/plc_messages.hpp"
#include "agv/sim/path_follower.hpp"
#include "agv/sim/ray_caster.hpp"
#include "agv/sim/sim_clock.hpp"
#include "agv/sim/sim_plc.hpp"
#include "dead_reckoning.hpp"

namespace agv::hil {

double positionError(const Pose2d& estimate, const Pose2d& truth) noexcept {
  return std::hypot(estimate.x - truth.x, estimate.y - truth.y);
}

double headingError(const Pose2d& estimate, const Pose2d& truth) noexcept {
  return std::fabs(angleDiff(estimate.theta, truth.theta));
}

namespace {

/// One run of `path`: place the vehicle near the start, steer at rest, follow the path to its end
/// and stop; the navigation side integrates the encoders and publishes to the PLC peer.
RunResult runOne(const sim::RayCaster& caster, const sim::Path& path, int run, const ScenarioConfig& cfg,
                 std::uint64_t seed) {
  RunResult r;
  r.path = path.name;
  r.run = run;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);

  sim::SimVehicle vehicle(cfg.vehicle, seed ^ 0x9E3779B97F4A7C15ULL);
  sim::SimLaser laser(caster, cfg.laser, seed ^ 0xC2B2AE3D27D4EB4FULL);
  sim::SimPlcPeer plc;
  sim::SimClock clock;
  hal::EncoderSource& encoders = vehicle;
  hal::DriveControl& drive = vehicle;
  hal::LaserSource& laserSource = laser;
  hal::PlcLink& plcLink = plc;

  const Pose2d start{path.start.x + cfg.startPositionStdDev * normal(rng),
                     path.start.y + cfg.startPositionStdDev * normal(rng),
                     normalizeAngle(path.start.theta + cfg.startHeadingStdDev * normal(rng))};
  Timestamp t{};
  vehicle.reset(start, t);
  sim::PathFollowerParams fp;
  fp.wheelbase = cfg.estimate.kinematics.wheelbase;
  fp.steerOffset = cfg.estimate.kinematics.steerOffsetForward;
  sim::PathFollower follower(path, fp);

  // At rest: turn the steering to the first command, take the reference encoder sample.
  hal::DriveCommand first = follower.update(vehicle.truePose());
  first.speed = 0.0;
  static_cast<void>(drive.command(first));
  t = t + Duration::fromSeconds(1.0);
  vehicle.advanceTo(t);
  clock.set(t);
  hal::EncoderSample sample;
  hal::EncoderSample latest;
  bool have = false;
  while (encoders.read(sample) == Status::Ok) {
    latest = sample;
    have = true;
  }
  DeadReckoning withTruth(cfg.vehicle.truth);
  DeadReckoning withNominal(cfg.nominal.kinematics);
  DeadReckoning withEstimate(cfg.estimate.kinematics);
  if (!have) {
    return r;
  }
  withTruth.reset(vehicle.truePose(), latest);
  withNominal.reset(vehicle.truePose(), latest);
  withEstimate.reset(vehicle.truePose(), latest);

  static hal::LaserMeasurement scan;  // ~8.5 KiB, reused
  const Duration scanPeriod = laser.period();
  Timestamp nextScan = t;
  Pose2d laserPoseAtScanStart = vehicle.trueLaserPose();
  double reflectorSum = 0.0;
  double validSum = 0.0;
  r.minReflectorsPerScan = static_cast<std::size_t>(-1);
  const Timestamp tStart = t;
  const Timestamp deadline = t + Duration::fromSeconds(cfg.maxRunSeconds);
  std::uint16_t lastReflectors = 0;

  while (t < deadline) {
    const hal::DriveCommand cmd = follower.update(vehicle.truePose());
    if (drive.command(cmd) != Status::Ok) {
      break;
    }
    const Pose2d before = vehicle.truePose();
    t = t + cfg.controlPeriod;
    vehicle.advanceTo(t);
    clock.set(t);
    r.distance += positionError(vehicle.truePose(), before);

    while (encoders.read(sample) == Status::Ok) {
      withTruth.update(sample);
      withNominal.update(sample);
      withEstimate.update(sample);
      hal::PoseReport report;
      report.stamp = sample.stamp;
      report.pose = withEstimate.pose();
      report.health.mode = hal::NavMode::Localizing;
      report.health.visibleReflectors = lastReflectors;
      static_cast<void>(plcLink.publish(report));
    }
    // Laser sweeps: the pose is interpolated between the control steps around the sweep (the
    // sweep ends one beam before the next starts; the pose difference is sub-millimetre).
    if (t >= nextScan + scanPeriod) {
      const Pose2d laserPoseNow = vehicle.trueLaserPose();
      if (laser.capture(laserPoseAtScanStart, laserPoseNow, nextScan) == Status::Ok &&
          laserSource.read(scan) == Status::Ok) {
        ++r.scans;
        lastReflectors = static_cast<std::uint16_t>(scan.reflectors.size());
        reflectorSum += static_cast<double>(scan.reflectors.size());
        r.minReflectorsPerScan = std::min(r.minReflectorsPerScan, scan.reflectors.size());
        std::size_t valid = 0;
        for (std::size_t i = 0; i < scan.scan.size(); ++i) {
          valid += scan.scan.isValid(i) ? 1U : 0U;
        }
        validSum += static_cast<double>(valid) / static_cast<double>(std::max<std::size_t>(1, scan.scan.size()));
      }
      laserPoseAtScanStart = laserPoseNow;
      nextScan = t;
    }
    r.history.push_back(
        TrajectorySample{r.distance, vehicle.truePose(), withTruth.pose(), withNominal.pose(), withEstimate.pose()});
    if (follower.finished() && drive.isStandstill()) {
      r.finished = true;
      break;
    }
  }
  r.simSeconds = (t - tStart).seconds();
  r.finalTruth = vehicle.truePose();
  r.finalWithTruth = withTruth.pose();
  r.finalWithNominal = withNominal.pose();
  r.plcReports = plc.reports().size();
  r.finalWithEstimate = plc.reports().empty() ? withEstimate.pose() : plc.reports().back().pose;
  if (r.scans > 0) {
    r.meanReflectorsPerScan = reflectorSum / static_cast<double>(r.scans);
    r.meanValidBeamFraction = validSum / static_cast<double>(r.scans);
  } else {
    r.minReflectorsPerScan = 0;
  }
  return r;
}

}  // namespace

bool runScenario(const sim::World& world, const ScenarioConfig& config,
                 const std::function<void(const RunResult&, int index, int total)>& progress,
                 std::vector<RunResult>* results, std::string* error) {
  if (world.paths.empty()) {
    *error = "the world has no path to drive";
    return false;
  }
  const Status laserStatus = config.laser.validate();
  if (laserStatus != Status::Ok) {
    *error = std::string("laser parameters: ") + toString(laserStatus);
    return false;
  }
  if (config.runsPerPath < 1) {
    *error = "runs per path must be >= 1";
    return false;
  }
  const sim::RayCaster caster(world, 1.0);
  const int total = static_cast<int>(world.paths.size()) * config.runsPerPath;
  int index = 0;
  for (std::size_t p = 0; p < world.paths.size(); ++p) {
    for (int run = 1; run <= config.runsPerPath; ++run) {
      const std::uint64_t runIndex = static_cast<std::uint64_t>(static_cast<unsigned>(run));
      const std::uint64_t seed = config.seed * 1000003U + p * 1000U + runIndex;
      results->push_back(runOne(caster, world.paths[p], run, config, seed));
      ++index;
      if (progress) {
        progress(results->back(), index, total);
      }
    }
  }
  return true;
}

}  // namespace agv::hil
