#include "scenario.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <mutex>
#include <random>
#include <thread>
#include <utility>

#include "agv/hal/plc_messages.hpp"
#include "agv/localization/localizer.hpp"
#include "agv/nav/pipeline.hpp"
#include "agv/sim/path_follower.hpp"
#include "agv/sim/ray_caster.hpp"
#include "agv/sim/sim_clock.hpp"
#include "agv/sim/sim_plc.hpp"
#include "dead_reckoning.hpp"
#include "reloc_oracle.hpp"

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
    case LocalizationMode::Natural:
      return "natural";
  }
  return "?";
}

sim::SimVehicleParams floorVehicle() {
  sim::SimVehicleParams v;
  v.accelSlip = 0.01;
  v.turnSlip = 0.01;
  v.steerBacklash = deg2rad(0.3);
  return v;
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

namespace {

/// The encoder source the pipeline reads, tapped: every sample it hands out is also kept for the
/// dead-reckoning comparisons of the run (true, nominal and calibrated parameters).
class EncoderTap final : public hal::EncoderSource {
 public:
  explicit EncoderTap(hal::EncoderSource& source) : source_(source) {}
  Status read(hal::EncoderSample& out) noexcept override {
    const Status s = source_.read(out);
    if (s == Status::Ok) {
      taken_.push_back(out);
    }
    return s;
  }
  Status health() const noexcept override { return source_.health(); }
  /// The samples handed out since the last call, oldest first.
  std::vector<hal::EncoderSample> take() { return std::exchange(taken_, {}); }

 private:
  hal::EncoderSource& source_;
  std::vector<hal::EncoderSample> taken_;
};

/// The navigation pipeline's parameters for `mode` (docs/hil.md, "Localization modes"): the
/// calibrated vehicle, never the truth.
nav::PipelineParams pipelineParams(const ScenarioConfig& cfg, LocalizationMode mode) {
  nav::PipelineParams p;
  p.kinematics = cfg.estimate.kinematics;
  // Encoder samples per laser correction (100 Hz encoders, 12.5 Hz sweeps by default).
  p.odometryNoise.samplesPerCorrection = std::max(1.0, cfg.laser.scanRate > 0.0 ? 100.0 / cfg.laser.scanRate : 1.0);
  // The systematic errors the floor and drive train add after calibration (what an integrator
  // sets from the vehicle's data sheet): the steering bias of half the backlash and the encoder
  // drift, the distance bias of the radius change and the traction slip at the drive's ramp.
  const double halfBacklash = 0.5 * cfg.vehicle.steerBacklash;
  p.odometryNoise.steeringBiasSigma =
      std::sqrt(halfBacklash * halfBacklash + cfg.floor.steerDriftStdDev * cfg.floor.steerDriftStdDev);
  const double rampSlip = cfg.vehicle.accelSlip * cfg.vehicle.acceleration;
  p.odometryNoise.scaleBiasSigma =
      std::sqrt(cfg.floor.radiusChangeStdDev * cfg.floor.radiusChangeStdDev + rampSlip * rampSlip);
  LocalizerParams& l = p.localizer;
  l.laser.mounting = cfg.estimate.laserMount;  // calibrated, never the true mount
  l.laser.rangeMin = std::max(0.3, cfg.laser.rangeMin);
  l.laser.rangeMax = std::min(cfg.laser.rangeMax, cfg.laser.reflectorMaxRange);
  l.laser.angleMin = -0.5 * cfg.laser.fieldOfView;
  l.laser.angleMax = 0.5 * cfg.laser.fieldOfView;
  // The laser reports reflector centres with isotropic noise (1 cm per coordinate by default):
  // mostly a per-kind term on top of the default range/bearing model.
  l.laser.kindSigma[static_cast<std::size_t>(LandmarkKind::Reflector)] =
      std::sqrt(std::max(0.0, cfg.laser.reflectorNoiseStdDev * cfg.laser.reflectorNoiseStdDev - 0.005 * 0.005));
  // The matched/expected check runs with the library defaults in every mode: `correct` gets the
  // sweep's ranges, so landmarks hidden behind pallets and racks are not expected.
  // Dynamic map from an empty start: a corner corrects the pose only after 10 matches (about
  // 1.3 s of travel at the warehouse's 0.8 re-detection rate), when its position is an average
  // over several viewpoints rather than one detection taken from the pose it would correct.
  if (mode == LocalizationMode::Dynamic) {
    l.map.minHitsToCorrect = cfg.dynamicMinHitsToCorrect;
  }
  const bool reflectors = mode == LocalizationMode::Reflectors || mode == LocalizationMode::Mapping;
  p.observations.reflectors = reflectors;
  p.observations.corners = !reflectors;
  p.observations.detectCorners = mode == LocalizationMode::Mapping;  // collected, not corrected with
  p.observations.collectScanPoints = mode == LocalizationMode::Mapping;
  p.observations.surfaceMap =
      (mode == LocalizationMode::Dynamic || mode == LocalizationMode::StaticFalko) && cfg.cornerModesSurfaceMap;
  p.observations.mapChanges = mode == LocalizationMode::Natural && cfg.mapChanges;
  p.observations.surfaceFallback = mode == LocalizationMode::Natural && cfg.surfaceFallback;
  l.scanMatch.adaptiveBand = cfg.adaptiveBand;
  // The vehicle is placed at the path start to within a few millimetres (startPositionStdDev).
  p.setPosePositionStdDev = 0.005;
  p.setPoseHeadingStdDev = deg2rad(0.05);
  p.publishPeriod = cfg.controlPeriod;  // one report per control step
  return p;
}

/// The laser's world pose at the reference instant of the sweep just corrected with (mapping
/// runs): `NotFound` while the localizer is lost, the sweep gave no fix or corrected nothing.
Result<Pose2d> correctedLaserPose(const nav::Pipeline& pipeline) {
  const Localizer& loc = pipeline.localizer();
  if (!pipeline.lastCycle().corrected || loc.lost() || hasFlag(loc.health().flags, LocalizerFlag::NoFix)) {
    return Status::NotFound;
  }
  const Result<Pose2d> pose = pipeline.poseAt(pipeline.lastCycle().sweepReference);
  if (!pose.ok()) {
    return pose.status();
  }
  return pose.value() * loc.params().laser.mounting;
}

/// Mapping runs: the corners of the sweep just corrected with, in the world frame at the corrected
/// pose (at the end of the sweep), into `cornerMap`.
void collectCorners(const nav::Pipeline& pipeline, mapping::CornerMapper& cornerMap) {
  const Result<Pose2d> laserWorld = correctedLaserPose(pipeline);
  if (!laserWorld.ok()) {
    return;
  }
  for (const Pose2d::Vector2& p : pipeline.sweepCorners()) {
    cornerMap.add(laserWorld.value().transformPoint(p));
  }
}

/// Mapping runs: the points of the sweep just corrected with, in the world frame at the corrected
/// pose, into `surfaces`.
void collectSurfaces(const nav::Pipeline& pipeline, mapping::SurfaceMapper& surfaces) {
  const Result<Pose2d> laserWorld = correctedLaserPose(pipeline);
  if (!laserWorld.ok()) {
    return;
  }
  surfaces.beginScan();
  for (const MatchPoint& p : pipeline.sweepPoints()) {
    surfaces.add(laserWorld.value().transformPoint(Pose2d::Vector2(static_cast<double>(p.x), static_cast<double>(p.y))),
                 laserWorld.value().translation());
  }
}

/// One run of `path`: place the vehicle near the start, steer at rest, set the pose through the
/// PLC, follow the path to its end and stop. The navigation is the vehicle's pipeline on the
/// simulated devices (encoders through CAN frames, laser, PLC peer, clock).
RunResult runOne(const sim::RayCaster& caster, const std::string& name, const std::vector<const sim::Path*>& legs,
                 int run, const ScenarioConfig& cfg, LocalizationMode mode, LandmarkMap& map, const RunMaps& maps,
                 std::uint64_t seed) {
  RunResult r;
  r.path = name;
  if (legs.empty()) {
    return r;
  }
  const sim::Path& path = *legs.front();
  r.run = run;
  r.mode = mode;
  if (mode == LocalizationMode::Dynamic) {
    map.clear();
    map.setMode(MapMode::Dynamic);
  }
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);

  // Since calibration the wheel has a load or wear, the steering encoder has drifted.
  sim::SimVehicleParams truth = cfg.vehicle;
  truth.radiusChange += cfg.floor.radiusChangeStdDev * normal(rng);
  truth.steerEncoderDrift += cfg.floor.steerDriftStdDev * normal(rng);
  sim::SimVehicle vehicle(truth, seed ^ 0x9E3779B97F4A7C15ULL);
  sim::SimLaser laser(caster, cfg.laser, seed ^ 0xC2B2AE3D27D4EB4FULL);
  sim::SimPlcPeer plc;
  sim::SimClock clock;
  sim::CanEncoderSource canEncoders(vehicle, cfg.can);  // encoder samples only through CAN frames
  EncoderTap encoders(canEncoders);
  hal::DriveControl& drive = vehicle;
  nav::Pipeline pipeline(pipelineParams(cfg, mode), map, nav::PipelineDevices{encoders, laser, plc, clock});
  if (mode == LocalizationMode::Natural) {
    pipeline.setLikelihoodField(maps.field);
  }
  if (pipeline.configure() != Status::Ok || pipeline.activate() != Status::Ok) {
    return r;
  }

  const Pose2d start{path.start.x + cfg.startPositionStdDev * normal(rng),
                     path.start.y + cfg.startPositionStdDev * normal(rng),
                     normalizeAngle(path.start.theta + cfg.startHeadingStdDev * normal(rng))};
  Timestamp t{};
  vehicle.reset(start, t);
  sim::PathFollowerParams fp;
  fp.wheelbase = cfg.estimate.kinematics.wheelbase;
  fp.steerOffset = cfg.estimate.kinematics.steerOffsetForward;
  std::size_t leg = 0;
  auto follower = std::make_unique<sim::PathFollower>(path, fp);

  // At rest: turn the steering to the first command; the pipeline reads every sample of that
  // second (idle), then the PLC sets the pose at the newest one.
  hal::DriveCommand first = follower->update(vehicle.truePose());
  first.speed = 0.0;
  static_cast<void>(drive.command(first));
  t = t + Duration::fromSeconds(1.0);
  vehicle.advanceTo(t);
  clock.set(t);
  for (int i = 0; i < 1000 && (pipeline.cycle() == Status::Ok && pipeline.lastCycle().encoderSamples > 0); ++i) {
  }
  std::vector<hal::EncoderSample> atRest = encoders.take();
  if (atRest.empty()) {
    return r;
  }
  hal::PlcCommand localize;
  localize.stamp = t;
  localize.kind = hal::PlcCommandKind::Localize;
  localize.initialPose = vehicle.truePose();
  plc.send(localize);
  static_cast<void>(pipeline.cycle());
  if (!pipeline.localizing()) {
    return r;
  }
  DeadReckoning withTruth(cfg.vehicle.truth);
  DeadReckoning withNominal(cfg.nominal.kinematics);
  DeadReckoning withEstimate(cfg.estimate.kinematics);
  withTruth.reset(vehicle.truePose(), atRest.back());
  withNominal.reset(vehicle.truePose(), atRest.back());
  withEstimate.reset(vehicle.truePose(), atRest.back());
  double usedSum = 0.0;
  double keypointSum = 0.0;

  const Duration scanPeriod = laser.period();
  Timestamp nextScan = t;
  Pose2d laserPoseAtScanStart = vehicle.trueLaserPose();
  double reflectorSum = 0.0;
  double validSum = 0.0;
  r.minReflectorsPerScan = static_cast<std::size_t>(-1);
  const Timestamp tStart = t;
  // A run of several legs (a mission) has the time of a run per leg, and its standstills.
  const double legs1 = static_cast<double>(legs.size());
  const Timestamp deadline =
      t + Duration::fromSeconds(legs1 * cfg.maxRunSeconds + (legs1 - 1.0) * std::max(0.0, cfg.dwellSeconds));
  Timestamp dwellEnd = t;
  bool stopped = false;  // at the current leg's operation point

  while (t < deadline) {
    const hal::DriveCommand cmd = follower->update(vehicle.truePose());
    if (drive.command(cmd) != Status::Ok) {
      break;
    }
    const Pose2d before = vehicle.truePose();
    t = t + cfg.controlPeriod;
    vehicle.advanceTo(t);
    clock.set(t);
    r.distance += positionError(vehicle.truePose(), before);
    // A laser sweep since the last one: the pose is interpolated between the control steps around
    // the sweep (the sweep ends one beam before the next starts; the difference is sub-millimetre).
    if (t >= nextScan + scanPeriod) {
      const Pose2d laserPoseNow = vehicle.trueLaserPose();
      static_cast<void>(laser.capture(laserPoseAtScanStart, laserPoseNow, nextScan));
      laserPoseAtScanStart = laserPoseNow;
      nextScan = t;
    }
    static_cast<void>(pipeline.cycle());
    for (const hal::EncoderSample& sample : encoders.take()) {
      withTruth.update(sample);
      withNominal.update(sample);
      withEstimate.update(sample);
    }
    const nav::CycleReport& c = pipeline.lastCycle();
    if (c.sweep) {
      const hal::LaserMeasurement& scan = pipeline.lastMeasurement();
      ++r.scans;
      reflectorSum += static_cast<double>(scan.reflectors.size());
      r.minReflectorsPerScan = std::min(r.minReflectorsPerScan, scan.reflectors.size());
      std::size_t valid = 0;
      for (std::size_t i = 0; i < scan.scan.size(); ++i) {
        valid += scan.scan.isValid(i) ? 1U : 0U;
      }
      validSum += static_cast<double>(valid) / static_cast<double>(std::max<std::size_t>(1, scan.scan.size()));
      const LocalizerHealth& h = pipeline.localizer().health();
      usedSum += static_cast<double>(h.used);
      keypointSum += static_cast<double>(c.corners);
      r.scansWithoutFix += hasFlag(h.flags, LocalizerFlag::NoFix) ? 1U : 0U;
      if (mode == LocalizationMode::Mapping && maps.corners != nullptr) {
        collectCorners(pipeline, *maps.corners);
      }
      if (mode == LocalizationMode::Mapping && maps.surfaces != nullptr) {
        collectSurfaces(pipeline, *maps.surfaces);
      }
    }
    r.history.push_back(TrajectorySample{r.distance, vehicle.truePose(), withTruth.pose(), withNominal.pose(),
                                         withEstimate.pose(), pipeline.localizer().pose()});
    if (!stopped && follower->finished() && drive.isStandstill()) {
      // At the operation point: what the PLC has, against the truth.
      stopped = true;
      OperationPoint op;
      op.index = static_cast<int>(leg) + 1;
      op.distance = r.distance;
      op.truth = vehicle.truePose();
      op.localized = plc.reports().empty() ? pipeline.localizer().pose() : plc.reports().back().pose;
      op.withTruth = withTruth.pose();
      op.withNominal = withNominal.pose();
      op.withEstimate = withEstimate.pose();
      op.lost = pipeline.localizer().lost();
      r.stops.push_back(op);
      if (leg + 1 == legs.size()) {
        r.finished = true;
        break;
      }
      dwellEnd = t + Duration::fromSeconds(cfg.dwellSeconds);  // the pick or drop
    }
    if (stopped && t >= dwellEnd) {
      ++leg;
      follower = std::make_unique<sim::PathFollower>(*legs[leg], fp);
      stopped = false;
    }
  }
  r.simSeconds = (t - tStart).seconds();
  r.finalTruth = vehicle.truePose();
  r.can = canEncoders.counters();
  r.finalWithTruth = withTruth.pose();
  r.finalWithNominal = withNominal.pose();
  r.plcReports = plc.reports().size();
  r.finalWithEstimate = withEstimate.pose();
  r.finalLocalized = plc.reports().empty() ? pipeline.localizer().pose() : plc.reports().back().pose;
  r.localizerLost = pipeline.localizer().lost();
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

/// The simulated laser with each true reflector detection dropped with probability `miss`, and
/// `spurious` fixed reflector detections (world places) added to every sweep, seen from the
/// vehicle's true laser pose, 1 cm noise, unstamped.
class ClutteredLaser final : public hal::LaserSource {
 public:
  ClutteredLaser(sim::SimLaser& laser, const sim::SimVehicle& vehicle, std::vector<Pose2d::Vector2> spurious,
                 double miss, std::uint64_t seed)
      : laser_(laser), vehicle_(vehicle), spurious_(std::move(spurious)), miss_(miss), rng_(seed) {}
  Status read(hal::LaserMeasurement& out) noexcept override {
    const Status st = laser_.read(out);
    if (st != Status::Ok || !out.hasReflectors) {
      return st;
    }
    if (miss_ > 0.0) {
      std::size_t kept = 0;
      for (std::size_t i = 0; i < out.reflectors.size(); ++i) {
        if (unit_(rng_) >= miss_) {
          out.reflectors[kept++] = out.reflectors[i];
        }
      }
      while (out.reflectors.size() > kept) {
        out.reflectors.pop_back();
      }
    }
    const Pose2d pose = vehicle_.trueLaserPose();
    for (const Pose2d::Vector2& w : spurious_) {
      const Pose2d::Vector2 v = pose.inverseTransformPoint(w);
      hal::ReflectorObservation o;
      o.x = static_cast<float>(v.x() + 0.01 * normal_(rng_));
      o.y = static_cast<float>(v.y() + 0.01 * normal_(rng_));
      o.positionStdDev = 0.01F;
      static_cast<void>(out.reflectors.push_back(o));
    }
    return Status::Ok;
  }
  Status health() const noexcept override { return laser_.health(); }

 private:
  sim::SimLaser& laser_;
  const sim::SimVehicle& vehicle_;
  std::vector<Pose2d::Vector2> spurious_;
  double miss_;
  std::mt19937_64 rng_;
  std::uniform_real_distribution<double> unit_{0.0, 1.0};
  std::normal_distribution<double> normal_{0.0, 1.0};
};

/// Adversarial decoys: up to `count` world places where a shiny object completes the wrong pose
/// `other` (the oracle's runner-up: the distinct pose explaining most of the reflectors visible
/// from `truth`). A map reflector L that the wrong pose's laser would see (field of view, the
/// reflector range, beyond the minimum range) and that none of the true view's reflectors
/// explains under it (within `gate`) is a place the wrong hypothesis expects and the truth lacks.
/// The decoy goes where the true laser sees the point the wrong laser would see L at:
/// trueLaser * otherLaser^-1 * L, so it lands on L under the wrong pose. Physical rules: the true
/// laser must see the decoy (a ray from it reaches the place with nothing in front, within 0.05 m),
/// and it must not be within 0.3 m of a real reflector pole (a decoy is an object next to the
/// poles, not one of them). Nearest first. Empty when the oracle found no distinct pose.
std::vector<Pose2d::Vector2> relocDecoys(const sim::RayCaster& caster, const ScenarioConfig& cfg,
                                         const std::vector<OraclePoint>& landmarks,
                                         const std::vector<OraclePoint>& seenVehicle, const Pose2d& truth,
                                         const Pose2d& other, int count, double gate) {
  std::vector<std::pair<double, Pose2d::Vector2>> places;
  if (count <= 0) {
    return {};
  }
  const Pose2d trueLaser = truth.compose(cfg.vehicle.laserMount);
  const Pose2d otherLaser = other.compose(cfg.vehicle.laserMount);
  const sim::World& world = caster.world();
  for (const OraclePoint& l : landmarks) {
    const Pose2d::Vector2 v = otherLaser.inverseTransformPoint(Pose2d::Vector2(l.x, l.y));
    const double d = v.norm();
    const double bearing = std::atan2(v.y(), v.x());
    if (std::fabs(bearing) > 0.5 * cfg.laser.fieldOfView || d > cfg.laser.reflectorMaxRange ||
        d < std::max(cfg.laser.rangeMin, 2.0 * gate)) {
      continue;
    }
    bool explained = false;
    for (const OraclePoint& o : seenVehicle) {
      const Pose2d::Vector2 w = other.transformPoint(Pose2d::Vector2(o.x, o.y));
      explained = explained || std::hypot(w.x() - l.x, w.y() - l.y) <= gate;
    }
    if (explained) {
      continue;
    }
    const Pose2d::Vector2 w = trueLaser.transformPoint(v);
    const sim::RayHit hit = caster.cast(sim::Point2{trueLaser.x, trueLaser.y}, trueLaser.theta + bearing, d);
    if (hit.hit && hit.range < d - 0.05) {
      continue;  // something in front of it: the true laser would not see it
    }
    bool nearPole = false;
    for (const sim::Circle& c : world.circles) {
      nearPole = nearPole ||
                 (c.kind == sim::ObstacleKind::Reflector && std::hypot(c.centre.x - w.x(), c.centre.y - w.y()) < 0.3);
    }
    if (!nearPole) {
      places.emplace_back(d, w);
    }
  }
  std::sort(places.begin(), places.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<Pose2d::Vector2> out;
  for (std::size_t i = 0; i < places.size() && out.size() < static_cast<std::size_t>(count); ++i) {
    out.push_back(places[i].second);
  }
  return out;
}

/// One relocalization trial (see `RelocTrial`): standing vehicle, the landmarks of `kind` on `map`
/// (reflectors: the surveyed map, the pipeline in the reflector mode; corners: the frozen FALKO
/// corners, the pipeline in the static_falko mode).
RelocTrial relocTrial(const sim::RayCaster& caster, const ScenarioConfig& cfg, LandmarkMap& map, LandmarkKind kind,
                      const LikelihoodFieldBase* field, const Pose2d& start, const Pose2d* kidnapFrom,
                      double maxSeconds, std::uint64_t seed) {
  RelocTrial trial;
  trial.kidnapped = kidnapFrom != nullptr;
  trial.truth = start;
  trial.onField = field != nullptr;
  std::vector<Pose2d::Vector2> decoys;
  const LocalizationMode mode = field != nullptr               ? LocalizationMode::Natural
                                : kind == LandmarkKind::Corner ? LocalizationMode::StaticFalko
                                                               : LocalizationMode::Reflectors;
  nav::PipelineParams params = pipelineParams(cfg, mode);
  if (field == nullptr) {
    // The oracle: the landmarks of the kind visible from the truth, noise-free, in the vehicle
    // frame, against the map's landmarks of that kind.
    std::vector<OraclePoint> landmarks;
    map.forEach([&](LandmarkIndex, const Landmark& l) {
      if (l.kind == kind) {
        landmarks.push_back(OraclePoint{l.x, l.y});
      }
    });
    const Pose2d laserPose = start.compose(cfg.vehicle.laserMount);
    std::vector<OraclePoint> seen =
        kind == LandmarkKind::Reflector
            ? visibleReflectors(caster, cfg.laser, laserPose)
            : visibleMapPoints(caster, cfg.laser, laserPose, landmarks, params.falko.maxExtractionRange);
    for (OraclePoint& p : seen) {
      const Pose2d::Vector2 v = start.inverseTransformPoint(Pose2d::Vector2(p.x, p.y));
      p = OraclePoint{v.x(), v.y()};
    }
    const Uniqueness u = judgeUniqueness(landmarks, seen, start);
    trial.unique = u.unique;
    trial.visibleReflectors = u.visible;
    trial.otherSupport = u.otherSupport;
    if (u.otherSupport > 0 && kind == LandmarkKind::Reflector) {
      decoys = relocDecoys(caster, cfg, landmarks, seen, start, u.other, cfg.relocDecoys, UniquenessParams{}.tolerance);
    }
    trial.decoys = decoys.size();
  }
  sim::SimVehicleParams truth = cfg.vehicle;
  sim::SimVehicle vehicle(truth, seed ^ 0x9E3779B97F4A7C15ULL);
  sim::SimLaser laser(caster, cfg.laser, seed ^ 0xC2B2AE3D27D4EB4FULL);
  sim::SimPlcPeer plc;
  sim::SimClock clock;
  sim::CanEncoderSource canEncoders(vehicle, cfg.can);
  std::vector<Pose2d::Vector2> spurious;
  std::mt19937_64 clutterRng(seed ^ 0x5851F42D4C957F2DULL);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int k = 0; k < cfg.relocSpurious; ++k) {
    const double r = 1.0 + 19.0 * unit(clutterRng);
    const double a = 2.0 * 3.14159265358979323846 * unit(clutterRng);
    spurious.emplace_back(start.x + r * std::cos(a), start.y + r * std::sin(a));
  }
  spurious.insert(spurious.end(), decoys.begin(), decoys.end());
  ClutteredLaser cluttered(laser, vehicle, std::move(spurious), cfg.relocMissProbability, seed ^ 0x2545F4914F6CDD1DULL);
  params.relocalization.search.ambiguityMargin = cfg.relocAmbiguityMargin;
  params.relocalization.search.refutedMargin = cfg.relocRefutedMargin;
  nav::Pipeline pipeline(params, map, nav::PipelineDevices{canEncoders, cluttered, plc, clock});
  if (field != nullptr) {
    pipeline.setLikelihoodField(field);
  }
  Timestamp t{};
  vehicle.reset(kidnapFrom != nullptr ? *kidnapFrom : start, t);
  clock.set(t);
  if (pipeline.configure() != Status::Ok || pipeline.activate() != Status::Ok) {
    return trial;
  }
  const Duration period = laser.period();
  Timestamp nextSweep = t;
  const auto runFor = [&](double seconds, const std::function<bool()>& done) {
    const Timestamp end = t + Duration::fromSeconds(seconds);
    while (t < end && !done()) {
      static_cast<void>(vehicle.command(hal::DriveCommand{}));
      t = t + cfg.controlPeriod;
      vehicle.advanceTo(t);
      clock.set(t);
      if (t >= nextSweep + period) {
        const Pose2d here = vehicle.trueLaserPose();
        static_cast<void>(laser.capture(here, here, nextSweep));
        nextSweep = t;
      }
      static_cast<void>(pipeline.cycle());
    }
  };
  if (kidnapFrom != nullptr) {
    // Localized where it stands by the PLC's set-pose, then carried away with the wheels still.
    hal::PlcCommand localize;
    localize.stamp = t;
    localize.kind = hal::PlcCommandKind::Localize;
    localize.initialPose = *kidnapFrom;
    plc.send(localize);
    runFor(1.0, [] { return false; });
    vehicle.reset(start, t);
  }
  const std::uint64_t sweepsBefore = pipeline.counters().sweeps;
  std::uint64_t searchStart = 0;
  bool searchSeen = !trial.kidnapped;
  runFor(maxSeconds, [&] {
    if (trial.kidnapped && !searchSeen && pipeline.searching()) {
      searchSeen = true;
      searchStart = pipeline.counters().sweeps;
    }
    trial.lostDetected = trial.lostDetected || pipeline.localizer().lost();
    if (pipeline.lastCycle().fieldSearchEnded) {
      trial.fieldSearchEnded = true;
      trial.lastFieldOutcome = pipeline.lastCycle().fieldSearchOutcome;
    }
    return pipeline.counters().relocalizations > 0;
  });
  trial.fieldSearches = pipeline.counters().fieldSearches;
  trial.found = pipeline.counters().relocalizations > 0;
  trial.ambiguous = pipeline.counters().ambiguous;
  trial.searches = pipeline.counters().searches;
  trial.candidates = pipeline.counters().candidates;
  trial.unconfirmed = pipeline.counters().unconfirmed;
  if (!trial.found && field == nullptr) {
    // The last sweep searched again with the pipeline's parameters: why it was refused.
    const hal::LaserMeasurement& meas = pipeline.lastMeasurement();
    std::vector<PointObservation> obs;
    if (kind == LandmarkKind::Reflector) {
      for (std::size_t i = 0; i < meas.reflectors.size(); ++i) {
        obs.push_back(PointObservation{static_cast<double>(meas.reflectors[i].x),
                                       static_cast<double>(meas.reflectors[i].y), LandmarkKind::Reflector});
      }
    } else {
      for (const Pose2d::Vector2& c : pipeline.sweepCorners()) {
        obs.push_back(PointObservation{c.x(), c.y(), LandmarkKind::Corner});
      }
    }
    trial.detected = obs.size();
    GlobalLocalizerParams search = params.relocalization.search;
    search.laserMount = cfg.estimate.laserMount;
    const auto reloc = std::make_unique<GlobalLocalizer>(search);
    RelocReport rr;
    (void)reloc->localize(map, Span<const PointObservation>(obs.data(), obs.size()), meas.scan, rr);
    trial.lastOutcome = rr.outcome;
    trial.lastInliers = rr.inliers;
    trial.lastSecondInliers = rr.hasSecond ? rr.secondInliers : 0U;
    trial.lastMissed = rr.missed;
    trial.lastSecondMissed = rr.hasSecond ? rr.secondMissed : 0U;
  }
  if (trial.found) {
    trial.sweeps =
        static_cast<std::size_t>(pipeline.counters().sweeps - (trial.kidnapped ? searchStart : sweepsBefore));
    // The pose published after the restart (one more report).
    runFor(0.1, [] { return false; });
    const Pose2d published = plc.reports().empty() ? pipeline.localizer().pose() : plc.reports().back().pose;
    trial.positionError = positionError(published, vehicle.truePose());
    trial.headingError = headingError(published, vehicle.truePose());
    trial.wrong = trial.positionError > 0.1 || trial.headingError > deg2rad(1.0);
  }
  return trial;
}

}  // namespace

std::vector<RelocTrial> runRelocalization(const sim::World& world, const ScenarioConfig& config, LandmarkMap& map,
                                          int count, int kidnaps, double maxSeconds, LandmarkKind kind,
                                          const LikelihoodFieldBase* field) {
  std::vector<RelocTrial> trials;
  if (world.paths.empty()) {
    return trials;
  }
  const sim::RayCaster caster(world, 1.0);
  std::mt19937_64 rng(config.seed * 7919U + 17U);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const auto draw = [&]() {
    const sim::Path& p =
        world.paths[static_cast<std::size_t>(unit(rng) * static_cast<double>(world.paths.size())) % world.paths.size()];
    const Pose2d& q =
        p.points[static_cast<std::size_t>(unit(rng) * static_cast<double>(p.points.size())) % p.points.size()];
    return Pose2d{q.x, q.y, normalizeAngle((2.0 * unit(rng) - 1.0) * 3.14159265358979323846)};
  };
  for (int i = 0; i < count + kidnaps; ++i) {
    const Pose2d at = draw();
    Pose2d from = draw();
    for (int k = 0; k < 20 && std::hypot(from.x - at.x, from.y - at.y) < 3.0; ++k) {
      from = draw();
    }
    const std::uint64_t seed = config.seed * 1000003U + 900000U + static_cast<std::uint64_t>(i);
    trials.push_back(relocTrial(caster, config, map, kind, field, at, i >= count ? &from : nullptr, maxSeconds, seed));
  }
  return trials;
}

namespace {

/// What runs of paths and of missions both need: valid laser and encoder-bus parameters, at least
/// one run, and for the natural mode a built likelihood field. False with `error` set otherwise.
bool checkRunInputs(const ScenarioConfig& config, LocalizationMode mode, const RunMaps& maps, int runs,
                    const char* tooFewRuns, std::string* error) {
  const Status laserStatus = config.laser.validate();
  if (laserStatus != Status::Ok) {
    *error = std::string("laser parameters: ") + toString(laserStatus);
    return false;
  }
  if (sim::validateSimCanEncoders(config.can) != Status::Ok) {
    *error = "encoder CAN bus parameters refused by the decoder";
    return false;
  }
  if (runs < 1) {
    *error = tooFewRuns;
    return false;
  }
  if (mode == LocalizationMode::Natural && (maps.field == nullptr || !maps.field->built())) {
    *error = "natural navigation needs the likelihood field of a mapping run";
    return false;
  }
  return true;
}

/// How many threads run the runs of one call: `config.jobs` (0: the machine's cores, at most
/// 8), one for mapping runs (their sightings and scans are accumulated in run order) and never
/// more than the runs.
int workerCount(const ScenarioConfig& config, const RunMaps& maps, std::size_t runs) {
  if (maps.corners != nullptr || maps.surfaces != nullptr) {
    return 1;
  }
  int workers = config.jobs;
  if (workers <= 0) {
    workers = std::clamp(static_cast<int>(std::thread::hardware_concurrency()), 1, 8);
  }
  return static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(workers), std::max<std::size_t>(runs, 1U)));
}

/// Runs `job(i, map)` for i = 0..count-1 on `workers` threads and hands each result to
/// `deliver(result, i)` on the calling thread, in index order, as soon as it and those before it
/// are done. With one worker the jobs run here, in order, on `map` itself (a Dynamic run clears
/// it and leaves its own map there); with more, each worker localizes on its own copy of `map`
/// (the localizer writes to the map it is given), so a run's result does not depend on which
/// thread ran it or on the runs before it on that thread (every run is seeded by its index).
void runJobs(std::size_t count, int workers, LandmarkMap& map,
             const std::function<RunResult(std::size_t, LandmarkMap&)>& job,
             const std::function<void(RunResult&, std::size_t)>& deliver) {
  if (workers <= 1 || count <= 1) {
    for (std::size_t i = 0; i < count; ++i) {
      RunResult r = job(i, map);
      deliver(r, i);
    }
    return;
  }
  std::vector<std::unique_ptr<RunResult>> done(count);
  std::mutex mutex;
  std::condition_variable ready;
  std::atomic<std::size_t> next{0};
  std::vector<std::thread> threads;
  threads.reserve(static_cast<std::size_t>(workers));
  for (int w = 0; w < workers; ++w) {
    threads.emplace_back([&]() {
      auto own = std::make_unique<LandmarkMap>();
      own->copyFrom(map);
      for (std::size_t i = next++; i < count; i = next++) {
        auto r = std::make_unique<RunResult>(job(i, *own));
        const std::lock_guard<std::mutex> lock(mutex);
        done[i] = std::move(r);
        ready.notify_all();
      }
    });
  }
  for (std::size_t i = 0; i < count; ++i) {
    std::unique_ptr<RunResult> r;
    {
      std::unique_lock<std::mutex> lock(mutex);
      ready.wait(lock, [&]() { return done[i] != nullptr; });
      r = std::move(done[i]);
    }
    deliver(*r, i);
  }
  for (std::thread& t : threads) {
    t.join();
  }
}

}  // namespace

bool runScenario(const sim::World& world, const ScenarioConfig& config, LocalizationMode mode, LandmarkMap& map,
                 const RunMaps& maps, const std::vector<std::size_t>& pathIndices, int runsPerPath,
                 std::uint64_t seedSalt, const std::function<void(const RunResult&, int index, int total)>& progress,
                 std::vector<RunResult>* results, std::string* error) {
  if (world.paths.empty()) {
    *error = "the world has no path to drive";
    return false;
  }
  if (!checkRunInputs(config, mode, maps, runsPerPath, "runs per path must be >= 1", error)) {
    return false;
  }
  const sim::RayCaster caster(world, 1.0);
  std::vector<std::size_t> paths = pathIndices;
  if (paths.empty()) {
    for (std::size_t p = 0; p < world.paths.size(); ++p) {
      paths.push_back(p);
    }
  }
  for (const std::size_t p : paths) {
    if (p >= world.paths.size()) {
      *error = "path index out of range";
      return false;
    }
  }
  const std::size_t perPath = static_cast<std::size_t>(runsPerPath);
  const std::size_t total = paths.size() * perPath;
  runJobs(
      total, workerCount(config, maps, total), map,
      [&](std::size_t i, LandmarkMap& runMap) {
        const std::size_t p = paths[i / perPath];
        const int run = static_cast<int>(i % perPath) + 1;
        const std::uint64_t runIndex = static_cast<std::uint64_t>(static_cast<unsigned>(run));
        const std::uint64_t seed = (config.seed + seedSalt) * 1000003U + p * 1000U + runIndex;
        return runOne(caster, world.paths[p].name, {&world.paths[p]}, run, config, mode, runMap, maps, seed);
      },
      [&](RunResult& r, std::size_t i) {
        results->push_back(std::move(r));
        if (progress) {
          progress(results->back(), static_cast<int>(i) + 1, static_cast<int>(total));
        }
      });
  return true;
}

std::vector<sim::Point2> missionKeepClear(const sim::World& world) {
  constexpr double kLaserAhead = 1.7;  // [m] the laser mount ahead of the logical point, and margin
  std::vector<sim::Point2> points;
  for (const sim::Mission& m : world.missions) {
    for (const sim::Path& leg : m.legs) {
      for (const Pose2d& q : leg.points) {
        points.push_back(sim::Point2{q.x, q.y});
        points.push_back(sim::Point2{q.x + kLaserAhead * std::cos(q.theta), q.y + kLaserAhead * std::sin(q.theta)});
      }
    }
  }
  return points;
}

bool runMissions(const sim::World& world, const ScenarioConfig& config, LocalizationMode mode, LandmarkMap& map,
                 const RunMaps& maps, int runsPerMission, std::uint64_t seedSalt, bool movePallets,
                 const std::function<void(const RunResult&, int index, int total)>& progress,
                 std::vector<RunResult>* results, std::string* error) {
  if (world.missions.empty()) {
    *error = "the world has no mission to drive";
    return false;
  }
  if (!checkRunInputs(config, mode, maps, runsPerMission, "runs per mission must be >= 1", error)) {
    return false;
  }
  const std::vector<sim::Point2> keepClear = movePallets ? missionKeepClear(world) : std::vector<sim::Point2>{};
  const std::size_t perMission = static_cast<std::size_t>(runsPerMission);
  const std::size_t total = world.missions.size() * perMission;
  runJobs(
      total, workerCount(config, maps, total), map,
      [&](std::size_t i, LandmarkMap& runMap) {
        const std::size_t m = i / perMission;
        const sim::Mission& mission = world.missions[m];
        std::vector<const sim::Path*> legs;
        for (const sim::Path& leg : mission.legs) {
          legs.push_back(&leg);
        }
        const int run = static_cast<int>(i % perMission) + 1;
        const std::uint64_t runIndex = static_cast<std::uint64_t>(static_cast<unsigned>(run));
        // Vehicle seeds apart from the paths' (path index * 1000 + run, paths < 500).
        const std::uint64_t seed = (config.seed + seedSalt) * 1000003U + (500U + m) * 1000U + runIndex;
        sim::World moved;
        sim::PalletChanges changes;
        if (movePallets) {
          // The layout depends on the session, the mission and the run only: every mode meets it.
          const std::uint64_t layoutSeed = config.seed * 2654435761U + m * 7919U + runIndex * 104729U + 0x9A11E7U;
          sim::rearrangePallets(world, config.palletMoves, layoutSeed, keepClear, moved, changes);
        }
        const sim::World& runWorld = movePallets ? moved : world;
        const sim::RayCaster caster(runWorld, 1.0);
        RunResult r = runOne(caster, mission.name, legs, run, config, mode, runMap, maps, seed);
        r.mission = true;
        r.pallets = changes;
        r.palletFingerprint = sim::palletFingerprint(runWorld);
        return r;
      },
      [&](RunResult& r, std::size_t i) {
        results->push_back(std::move(r));
        if (progress) {
          progress(results->back(), static_cast<int>(i) + 1, static_cast<int>(total));
        }
      });
  return true;
}

}  // namespace agv::hil
