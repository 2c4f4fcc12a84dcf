#include "scenario.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <random>

#include "agv/falko/falko_detector.hpp"
#include "agv/hal/plc_messages.hpp"
#include "agv/localization/localizer.hpp"
#include "agv/localization/sweep_motion.hpp"
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

const char* modeName(LocalizationMode mode) noexcept {
  switch (mode) {
    case LocalizationMode::Reflectors:
      return "reflectors";
    case LocalizationMode::Mapping:
      return "mapping";
    case LocalizationMode::StaticFalko:
      return "static_falko";
    case LocalizationMode::Dynamic:
      return "dynamic";
  }
  return "?";
}

Status buildSurveyedReflectorMap(const sim::World& world, double sigma, std::uint64_t seed, LandmarkMap& map) {
  map.clear();
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uint32_t id = 1;
  for (const sim::Circle& c : world.circles) {
    if (c.kind != sim::ObstacleKind::Reflector) {
      continue;
    }
    const double x = c.centre.x + sigma * normal(rng);
    const double y = c.centre.y + sigma * normal(rng);
    const Result<LandmarkIndex> r = map.addSurveyed(LandmarkKind::Reflector, x, y, sigma, id++);
    if (!r.ok()) {
      return r.status();
    }
  }
  map.setMode(MapMode::Static);
  return Status::Ok;
}

void CornerMapper::add(double x, double y) {
  Cluster* best = nullptr;
  double bestD2 = kMergeRadius * kMergeRadius;
  for (Cluster& c : clusters_) {
    const double n = static_cast<double>(c.n);
    const double dx = c.sx / n - x;
    const double dy = c.sy / n - y;
    if (dx * dx + dy * dy < bestD2) {
      bestD2 = dx * dx + dy * dy;
      best = &c;
    }
  }
  if (best == nullptr) {
    clusters_.push_back(Cluster{});
    best = &clusters_.back();
  }
  best->sx += x;
  best->sy += y;
  best->sxx += x * x;
  best->syy += y * y;
  ++best->n;
}

std::size_t CornerMapper::freeze(int minSightings, double maxScatter, LandmarkMap& frozen) const {
  frozen.clear();
  std::size_t count = 0;
  std::uint32_t id = 1;
  for (const Cluster& c : clusters_) {
    if (c.n < minSightings) {
      continue;
    }
    const double n = static_cast<double>(c.n);
    const double mx = c.sx / n;
    const double my = c.sy / n;
    // Scatter of the sightings: a true corner's apex is seen at one place from everywhere; a
    // pillar's or a pole's "corner" moves with the viewpoint.
    const double var = std::max(0.0, (c.sxx / n - mx * mx) + (c.syy / n - my * my)) / 2.0;
    if (std::sqrt(var) > maxScatter) {
      continue;
    }
    // The landmark's sigma: the scatter of one sighting (not of the mean: sightings from one
    // run share the pose error of the mapping localizer).
    if (frozen.addSurveyed(LandmarkKind::Corner, mx, my, std::sqrt(var), id++).ok()) {
      ++count;
    }
  }
  frozen.setMode(MapMode::Static);
  return count;
}

namespace {

/// The localizer side of the navigation: odometry increments from the encoder samples, point
/// observations (reflectors and/or FALKO corners) from the laser, motion-compensated to the end
/// of the sweep with the calibrated odometry, corrected against the map.
class Navigation {
 public:
  Navigation(const ScenarioConfig& cfg, LocalizationMode mode)
      : mode_(mode),
        odometry_(cfg.estimate.kinematics, noiseParams(cfg)),
        localizer_(std::make_unique<Localizer>(localizerParams(cfg, mode))),
        detector_(std::make_unique<FalkoDetector>()),
        keypoints_(std::make_unique<FalkoKeypoints>()),
        observations_(std::make_unique<ScanObservations>()),
        mount_(cfg.estimate.laserMount) {}

  bool usesReflectors() const noexcept {
    return mode_ == LocalizationMode::Reflectors || mode_ == LocalizationMode::Mapping;
  }
  bool usesCorners() const noexcept { return mode_ != LocalizationMode::Reflectors; }

  /// Starts at the known pose `start` with `sample` as the odometry reference.
  void reset(const Pose2d& start, const hal::EncoderSample& sample, const Pose2d& deadReckoning) {
    odometry_.reset();
    static_cast<void>(odometry_.step(TricycleSample{sample.stamp, sample.driveTicks, sample.steeringAngle}));
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    cov(0, 0) = cov(1, 1) = 0.005 * 0.005;
    cov(2, 2) = deg2rad(0.05) * deg2rad(0.05);
    static_cast<void>(localizer_->reset(sample.stamp, start, cov));
    static_cast<void>(history_.add(sample.stamp, deadReckoning));
  }

  /// One encoder sample; `deadReckoning` is the calibrated odometry pose after it.
  void predict(const hal::EncoderSample& sample, const Pose2d& deadReckoning) {
    const Result<OdometryIncrement> inc =
        odometry_.step(TricycleSample{sample.stamp, sample.driveTicks, sample.steeringAngle});
    if (inc.ok()) {
      static_cast<void>(localizer_->predict(inc.value()));
    }
    static_cast<void>(history_.add(sample.stamp, deadReckoning));
  }

  /// One laser sweep. In Mapping mode the localizer corrects on the reflectors against `map`
  /// and the FALKO corners are accumulated into `cornerMap` at the corrected pose.
  const LocalizerHealth& correct(const hal::LaserMeasurement& m, LandmarkMap& map, CornerMapper* cornerMap) {
    ScanObservations& obs = *observations_;
    obs.points.clear();
    const SweepCompensation sweep(history_, m.scan, mount_);
    const Timestamp tRef = sweep.referenceStamp();
    obs.stamp = tRef;
    obs.kindsDetected = 0;
    if (usesReflectors() && m.hasReflectors) {
      obs.kindsDetected |= landmarkKindBit(LandmarkKind::Reflector);
      for (std::size_t i = 0; i < m.reflectors.size(); ++i) {
        const Pose2d::Vector2 p =
            sweep.atBearing(static_cast<double>(m.reflectors[i].x), static_cast<double>(m.reflectors[i].y));
        static_cast<void>(obs.points.push_back(PointObservation{p.x(), p.y(), LandmarkKind::Reflector}));
      }
    }
    keypointCount_ = 0;
    corners_.clear();
    if (usesCorners()) {
      keypoints_->clear();
      if (detector_->detect(m.scan, *keypoints_) == Status::Ok) {
        for (std::size_t i = 0; i < keypoints_->size(); ++i) {
          const FalkoKeypoint& k = (*keypoints_)[i];
          if (!k.refined) {
            continue;  // the apex of an unrefined keypoint is only the nearest beam point
          }
          ++keypointCount_;
          corners_.push_back(sweep.atBeam(k.beamIndex, static_cast<double>(k.x), static_cast<double>(k.y)));
        }
        if (mode_ != LocalizationMode::Mapping) {
          obs.kindsDetected |= landmarkKindBit(LandmarkKind::Corner);
          for (const Pose2d::Vector2& p : corners_) {
            static_cast<void>(obs.points.push_back(PointObservation{p.x(), p.y(), LandmarkKind::Corner}));
          }
        }
      }
    }
    const LocalizerHealth& h = localizer_->correct(obs, m.scan, map);
    if (mode_ == LocalizationMode::Mapping && cornerMap != nullptr && !localizer_->lost() &&
        !hasFlag(h.flags, LocalizerFlag::NoFix)) {
      // The corrected pose at the end of the sweep, from the newest one and the odometry between.
      const Pose2d poseRef =
          localizer_->pose() * between(history_.at(localizer_->stamp()).value(), history_.at(tRef).value());
      const Pose2d laserWorld = poseRef * mount_;
      for (const Pose2d::Vector2& p : corners_) {
        const Pose2d::Vector2 w = laserWorld.transformPoint(p);
        cornerMap->add(w.x(), w.y());
      }
    }
    return h;
  }

  const Localizer& localizer() const noexcept { return *localizer_; }
  std::size_t keypointCount() const noexcept { return keypointCount_; }

 private:
  static TricycleNoiseParams noiseParams(const ScenarioConfig& cfg) {
    TricycleNoiseParams n;
    // Encoder samples per laser correction (100 Hz encoders, 12.5 Hz sweeps by default).
    n.samplesPerCorrection = std::max(1.0, cfg.laser.scanRate > 0.0 ? 100.0 / cfg.laser.scanRate : 1.0);
    return n;
  }
  static LocalizerParams localizerParams(const ScenarioConfig& cfg, LocalizationMode mode) {
    LocalizerParams p;
    p.laser.mounting = cfg.estimate.laserMount;  // calibrated, never the true mount
    p.laser.rangeMin = std::max(0.3, cfg.laser.rangeMin);
    p.laser.rangeMax = std::min(cfg.laser.rangeMax, cfg.laser.reflectorMaxRange);
    p.laser.angleMin = -0.5 * cfg.laser.fieldOfView;
    p.laser.angleMax = 0.5 * cfg.laser.fieldOfView;
    // The laser reports reflector centres with isotropic noise (1 cm per coordinate by default):
    // mostly a per-kind term on top of the default range/bearing model.
    p.laser.kindSigma[static_cast<std::size_t>(LandmarkKind::Reflector)] =
        std::sqrt(std::max(0.0, cfg.laser.reflectorNoiseStdDev * cfg.laser.reflectorNoiseStdDev - 0.005 * 0.005));
    // The matched/expected check runs with the library defaults in every mode: `correct` gets the
    // sweep's ranges, so landmarks hidden behind pallets and racks are not expected.
    // Dynamic map from an empty start: a corner corrects the pose only after 10 matches (about
    // 1.3 s of travel at the warehouse's 0.8 re-detection rate), when its position is an average
    // over several viewpoints rather than one detection taken from the pose it would correct.
    if (mode == LocalizationMode::Dynamic) {
      p.minHitsToCorrect = cfg.dynamicMinHitsToCorrect;
    }
    return p;
  }

  LocalizationMode mode_;
  TricycleOdometry odometry_;
  std::unique_ptr<Localizer> localizer_;
  std::unique_ptr<FalkoDetector> detector_;
  std::unique_ptr<FalkoKeypoints> keypoints_;
  std::unique_ptr<ScanObservations> observations_;
  Pose2d mount_;
  MotionHistory history_;
  std::size_t keypointCount_ = 0;
  std::vector<Pose2d::Vector2> corners_;
};

/// Publishes the localizer's newest pose to the PLC peer.
void publish(const Localizer& loc, std::uint16_t visibleReflectors, hal::PlcLink& plc) {
  hal::PoseReport report;
  report.stamp = loc.stamp();
  report.pose = loc.pose();
  report.covariance = loc.covariance();
  report.health.mode = loc.lost() ? hal::NavMode::Lost : hal::NavMode::Localizing;
  report.health.lastStatus = loc.health().status;
  report.health.matchedLandmarks = loc.health().used;
  report.health.visibleReflectors = visibleReflectors;
  static_cast<void>(plc.publish(report));
}

/// One run of `path`: place the vehicle near the start, steer at rest, follow the path to its end
/// and stop; the navigation side integrates the encoders and publishes to the PLC peer.
RunResult runOne(const sim::RayCaster& caster, const sim::Path& path, int run, const ScenarioConfig& cfg,
                 LocalizationMode mode, LandmarkMap& map, CornerMapper* cornerMap, std::uint64_t seed) {
  RunResult r;
  r.path = path.name;
  r.run = run;
  r.mode = mode;
  if (mode == LocalizationMode::Dynamic) {
    map.clear();
    map.setMode(MapMode::Dynamic);
  }
  Navigation nav(cfg, mode);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);

  sim::SimVehicle vehicle(cfg.vehicle, seed ^ 0x9E3779B97F4A7C15ULL);
  sim::SimLaser laser(caster, cfg.laser, seed ^ 0xC2B2AE3D27D4EB4FULL);
  sim::SimPlcPeer plc;
  sim::SimClock clock;
  sim::CanEncoderSource canEncoders(vehicle, cfg.can);  // encoder samples only through CAN frames
  hal::EncoderSource& encoders = canEncoders;
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
  nav.reset(vehicle.truePose(), latest, withEstimate.pose());
  double usedSum = 0.0;
  double keypointSum = 0.0;

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
      nav.predict(sample, withEstimate.pose());
      publish(nav.localizer(), lastReflectors, plcLink);
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
        const LocalizerHealth& h = nav.correct(scan, map, cornerMap);
        usedSum += static_cast<double>(h.used);
        keypointSum += static_cast<double>(nav.keypointCount());
        r.scansWithoutFix += hasFlag(h.flags, LocalizerFlag::NoFix) ? 1U : 0U;
        publish(nav.localizer(), lastReflectors, plcLink);
      }
      laserPoseAtScanStart = laserPoseNow;
      nextScan = t;
    }
    r.history.push_back(TrajectorySample{r.distance, vehicle.truePose(), withTruth.pose(), withNominal.pose(),
                                         withEstimate.pose(), nav.localizer().pose()});
    if (follower.finished() && drive.isStandstill()) {
      r.finished = true;
      break;
    }
  }
  r.simSeconds = (t - tStart).seconds();
  r.finalTruth = vehicle.truePose();
  r.can = canEncoders.counters();
  r.finalWithTruth = withTruth.pose();
  r.finalWithNominal = withNominal.pose();
  r.plcReports = plc.reports().size();
  r.finalWithEstimate = withEstimate.pose();
  r.finalLocalized = plc.reports().empty() ? nav.localizer().pose() : plc.reports().back().pose;
  r.localizerLost = nav.localizer().lost();
  if (r.scans > 0) {
    r.meanUsedPerScan = usedSum / static_cast<double>(r.scans);
    r.meanKeypointsPerScan = keypointSum / static_cast<double>(r.scans);
    r.meanReflectorsPerScan = reflectorSum / static_cast<double>(r.scans);
    r.meanValidBeamFraction = validSum / static_cast<double>(r.scans);
  } else {
    r.minReflectorsPerScan = 0;
  }
  return r;
}

}  // namespace

bool runScenario(const sim::World& world, const ScenarioConfig& config, LocalizationMode mode, LandmarkMap& map,
                 CornerMapper* cornerMap, const std::vector<std::size_t>& pathIndices, int runsPerPath,
                 std::uint64_t seedSalt, const std::function<void(const RunResult&, int index, int total)>& progress,
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
  if (sim::validateSimCanEncoders(config.can) != Status::Ok) {
    *error = "encoder CAN bus parameters refused by the decoder";
    return false;
  }
  if (runsPerPath < 1) {
    *error = "runs per path must be >= 1";
    return false;
  }
  const sim::RayCaster caster(world, 1.0);
  std::vector<std::size_t> paths = pathIndices;
  if (paths.empty()) {
    for (std::size_t p = 0; p < world.paths.size(); ++p) {
      paths.push_back(p);
    }
  }
  const int total = static_cast<int>(paths.size()) * runsPerPath;
  int index = 0;
  for (const std::size_t p : paths) {
    if (p >= world.paths.size()) {
      *error = "path index out of range";
      return false;
    }
    for (int run = 1; run <= runsPerPath; ++run) {
      const std::uint64_t runIndex = static_cast<std::uint64_t>(static_cast<unsigned>(run));
      const std::uint64_t seed = (config.seed + seedSalt) * 1000003U + p * 1000U + runIndex;
      results->push_back(runOne(caster, world.paths[p], run, config, mode, map, cornerMap, seed));
      ++index;
      if (progress) {
        progress(results->back(), index, total);
      }
    }
  }
  return true;
}

}  // namespace agv::hil
