#pragma once
// One simulated localization run: the vehicle drives a path, the tricycle odometry feeds the
// localizer, lagged scans correct it; per-cycle errors, NEES and health are recorded.
#include <memory>
#include <vector>

#include <Eigen/LU>

#include "agv/localization/landmark_map.hpp"
#include "agv/localization/localizer.hpp"
#include "agv/localization/odometry.hpp"
#include "sim_world.hpp"

namespace agv::sim {

struct RunConfig {
  PathSpec path = path12m();
  SimNoise noise{};
  double lagSeconds = 0.05;
  MapMode mapMode = MapMode::Dynamic;
  bool surveyedMap = true;  // load the world's reflectors as surveyed landmarks
  int kidnapAtCycle = -1;   // teleport the vehicle after this correction cycle
  Pose2d kidnapOffset{2.0, 1.0, 0.5};
  std::uint32_t seed = 1;
  double initialSigmaXY = 0.01;
  double initialSigmaTheta = 0.5 * kPi<double> / 180.0;
  double standstillSeconds = 0.3;  // after the path, so the last lagged scans arrive
  double surveySigma = 0.0;        // surveyed positions are off by N(0, sigma) and declared with sigma
  bool clearMap = true;            // false: keep the map of a previous run (e.g. a mapping run)
  bool cornerWorld = false;        // the block-storage corridor with FALKO corners instead of reflectors
  bool stampAtDelivery = false;
  /// Feed the filter through the unicycle input: the encoders' RK2 increments, re-integrated over
  /// each 100 ms like a recorded log's ODOM lines, with the generic odometry motion-model noise.
  bool unicycleOdometry = false;
  UnicycleNoiseParams unicycleNoise{};  // ignore the lag: stamp scans with their delivery time (wrong on purpose)
};

struct CycleRecord {
  Eigen::Vector3d error;  // estimate - truth (x, y, wrapped theta)
  double nees = 0.0;
  LocalizerHealth health;
};

struct RunResult {
  std::vector<CycleRecord> cycles;
  Eigen::Vector3d endError = Eigen::Vector3d::Zero();
  int lostAtCycle = -1;  // first cycle flagged lost (counted from the kidnap when there is one)
};

inline TricycleParams simVehicle() {
  TricycleParams v;
  v.wheelbase = 1.5;
  v.driveScale = 5e-4;
  return v;
}
inline LaserModel simLaser() {
  LaserModel l;
  l.mounting = Pose2d{1.1, -0.05, 0.01};
  return l;
}
inline TricycleNoiseParams filterNoise(const SimNoise& n) {
  TricycleNoiseParams p;
  p.slipVariancePerMetre = n.slipVariancePerMetre;
  p.steeringSigma = n.steeringSigma;
  p.samplesPerCorrection = 10.0;
  return p;
}

inline void loadSurveyed(LandmarkMap& map, const std::vector<WorldLandmark>& world, double sigma = 0.0,
                         std::uint32_t seed = 0) {
  std::mt19937_64 rng(seed ^ 0x5eedULL);
  std::normal_distribution<double> n(0.0, sigma > 0.0 ? sigma : 1.0);
  std::uint32_t id = 1;
  for (const auto& w : world) {
    const double ex = sigma > 0.0 ? n(rng) : 0.0;
    const double ey = sigma > 0.0 ? n(rng) : 0.0;
    (void)map.addSurveyed(w.kind, w.x + ex, w.y + ey, sigma, id++);
  }
}

inline RunResult runOnce(const RunConfig& cfg, LandmarkMap& map, LocalizerParams lp = LocalizerParams{}) {
  RunResult out;
  const TricycleParams veh = simVehicle();
  const LaserModel laser = simLaser();
  lp.laser.mounting = laser.mounting;
  lp.laser.rangeSigma = cfg.noise.rangeSigma;
  lp.laser.bearingSigma = cfg.noise.bearingSigma;
  lp.laser.kindSigma[static_cast<std::size_t>(LandmarkKind::Corner)] = cfg.noise.cornerSigma;
  const auto world = cfg.cornerWorld ? cornerWorld() : reflectorWorld();
  Simulator sim(veh, laser, cfg.noise, world, cfg.seed);
  sim.lagSeconds = cfg.lagSeconds;
  if (cfg.clearMap)
    map.clear();
  map.setMode(cfg.mapMode);
  if (cfg.surveyedMap)
    loadSurveyed(map, world, cfg.surveySigma, cfg.seed);

  auto loc = std::make_unique<Localizer>(lp);
  Eigen::Matrix3d P0 = Eigen::Matrix3d::Zero();
  P0(0, 0) = P0(1, 1) = cfg.initialSigmaXY * cfg.initialSigmaXY;
  P0(2, 2) = cfg.initialSigmaTheta * cfg.initialSigmaTheta;
  const Pose2d start{sim.gauss(cfg.initialSigmaXY), sim.gauss(cfg.initialSigmaXY), sim.gauss(cfg.initialSigmaTheta)};
  (void)loc->reset(sim.now, start, P0);
  TricycleOdometry odo(veh, filterNoise(cfg.noise));
  (void)odo.step(sim.encoder());
  auto scan = std::make_unique<ScanObservations>();
  Pose2d logDelta{};
  int cycle = 0;
  int extra = static_cast<int>(cfg.standstillSeconds / sim.dt);
  for (int guard = 0; guard < 100000; ++guard) {
    const bool moving = sim.advance(cfg.path);
    if (!moving && extra-- <= 0)
      break;
    const auto inc = odo.step(sim.encoder());
    if (cfg.unicycleOdometry) {
      if (inc.ok())
        logDelta = logDelta.compose(inc.value().delta);
      if (sim.isScanStep()) {
        (void)loc->predict(unicycleIncrement(sim.now, logDelta, cfg.unicycleNoise));
        logDelta = Pose2d{};
      }
    } else if (inc.ok()) {
      (void)loc->predict(inc.value());
    }
    while (sim.takeScan(*scan)) {
      if (cfg.stampAtDelivery)
        scan->stamp = sim.now;
      const LocalizerHealth h = loc->correct(*scan, map);
      ++cycle;
      const Pose2d truth = sim.truthAt(loc->stamp());
      const Pose2d est = loc->pose();
      CycleRecord rec;
      rec.error = Eigen::Vector3d(est.x - truth.x, est.y - truth.y, angleDiff(est.theta, truth.theta));
      rec.nees = rec.error.dot(loc->covariance().inverse() * rec.error);
      rec.health = h;
      out.cycles.push_back(rec);
      if (h.lost && out.lostAtCycle < 0)
        out.lostAtCycle = cycle;
      if (cycle == cfg.kidnapAtCycle)
        sim.kidnap(cfg.kidnapOffset);
    }
  }
  if (!out.cycles.empty())
    out.endError = out.cycles.back().error;
  return out;
}

}  // namespace agv::sim
