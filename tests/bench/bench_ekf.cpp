// BM_EkfCycle/<map>: one laser cycle of the localizer at 10 Hz with 100 Hz odometry: 10 odometry
// predictions, then a scan lagging 50 ms with 40 point observations: rewind through the history,
// associate (grid query + gate), sequential updates, map maintenance (reinforce, in-view decrement),
// re-prediction. The maps have the same landmark density (one per 9 m^2, a 3 m grid with jitter)
// and grow in area, as a larger warehouse does: 256 landmarks on 48 m x 48 m, 4096 on 192 m x 192 m;
// laser range 14 m (~45 landmarks in view). A third case measures the worst case of the docs. The
// `_scan` cases also pass the sweep's ranges (270 deg at 0.25 deg, nothing nearer than the landmarks)
// so that every landmark inside the limits goes through the occlusion test.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>
#include <memory>

#include "agv/localization/landmark_map.hpp"
#include "agv/localization/localizer.hpp"
#include "agv/localization/sweep_motion.hpp"
#include "ekf_cycle_scene.hpp"

namespace {
using namespace agv;

struct EkfBenchWorld {
  LocalizerParams params;
  std::unique_ptr<Localizer> loc;
  std::unique_ptr<LandmarkMap> map;
  std::unique_ptr<ScanObservations> scan;
  Pose2d pose;
  Timestamp t = Timestamp::fromSeconds(1.0);
  std::size_t observed = 0;

  std::size_t wanted = 40;

  std::unique_ptr<LaserScan> beams;

  EkfBenchWorld(int side, double rangeMax, std::size_t observations, bool withScan) : wanted(observations) {
    params.laser.mounting = Pose2d{1.0, 0.0, 0.0};
    params.laser.rangeMax = rangeMax;
    loc = std::make_unique<Localizer>(params);
    map = std::make_unique<LandmarkMap>();
    scan = std::make_unique<ScanObservations>();
    pose = Pose2d{0.3, 0.2, 0.4};
    scan->kindsDetected = kAllLandmarkKinds;
    observed = test::buildEkfCycleScene(params, pose, side, wanted, *map, *scan);
    Eigen::Matrix3d P0 = Eigen::Matrix3d::Identity() * 1e-4;
    (void)loc->reset(t, pose, P0);
    if (withScan) {
      beams = std::make_unique<LaserScan>();
      beams->angleMin = -2.35619449F;
      beams->angleIncrement = 0.0043633231F;  // 0.25 deg
      beams->rangeMin = 0.05F;
      beams->rangeMax = 80.0F;
      for (int i = 0; i < 1081; ++i) {
        (void)beams->ranges.push_back(static_cast<float>(rangeMax) + 10.0F);
      }
    }
  }

  void cycle() {
    OdometryIncrement inc;
    inc.covariance = Eigen::Matrix3d::Identity() * 1e-10;
    for (int i = 0; i < 10; ++i) {
      t = t + Duration::fromMilliseconds(10);
      inc.stamp = t;
      (void)loc->predict(inc);
    }
    scan->stamp = t - Duration::fromMilliseconds(50);
    const LocalizerHealth& h = beams ? loc->correct(*scan, *beams, *map) : loc->correct(*scan, *map);
    benchmark::DoNotOptimize(&h);
  }
};

void BM_EkfCycle(benchmark::State& state, int side, double rangeMax, std::size_t observations, bool withScan) {
  EkfBenchWorld w(side, rangeMax, observations, withScan);
  w.cycle();
  for (auto _ : state) {
    w.cycle();
  }
  const LocalizerHealth& h = w.loc->health();
  state.counters["landmarks"] = static_cast<double>(w.map->size());
  state.counters["observations"] = static_cast<double>(h.observations);
  state.counters["used"] = static_cast<double>(h.used);
  state.counters["inView"] = static_cast<double>(h.expectedInView);
  if (h.used != w.observed || w.observed != observations) {
    state.SkipWithError("the benchmark scene did not associate all its observations");
  }
}
BENCHMARK_CAPTURE(BM_EkfCycle, map256, 16, 14.0, 40, false)->Name("BM_EkfCycle/map256");
BENCHMARK_CAPTURE(BM_EkfCycle, map4096, 64, 14.0, 40, false)->Name("BM_EkfCycle/map4096");
BENCHMARK_CAPTURE(BM_EkfCycle, map256s, 16, 14.0, 40, true)->Name("BM_EkfCycle/map256_scan");
BENCHMARK_CAPTURE(BM_EkfCycle, map4096s, 64, 14.0, 40, true)->Name("BM_EkfCycle/map4096_scan");
// Worst case for the docs: kMaxObservations observations, 30 m range (~235 landmarks in view).
BENCHMARK_CAPTURE(BM_EkfCycle, worst, 64, 30.0, kMaxObservations, false)->Name("BM_EkfCycle/map4096_obs128_range30");

// BM_SweepCompensation/obs40: the motion compensation of one sweep of agvnav-vehicle / agvnav-hil:
// the 8 dead-reckoning poses of 100 Hz encoders during a 12.5 Hz sweep period go into the history
// (full: 51 poses of 0.5 s), then 40 observations of a 1081-beam, 40 ms sweep are moved to its end
// (a history look-up and two pose compositions each). Vehicle at 1.5 m/s turning at 0.5 rad/s.
void BM_SweepCompensation(benchmark::State& state) {
  auto history = std::make_unique<MotionHistory>();
  auto scan = std::make_unique<LaserScan>();
  scan->angleMin = -2.35619449F;
  scan->angleIncrement = 0.0043633231F;
  scan->rangeMin = 0.05F;
  scan->rangeMax = 80.0F;
  for (int i = 0; i < 1081; ++i) {
    (void)scan->ranges.push_back(5.0F);
  }
  scan->sweepDuration = Duration::fromMilliseconds(40);
  Timestamp t = Timestamp::fromSeconds(1.0);
  Pose2d pose;
  const Pose2d step{0.015, 0.0, 0.005};  // 10 ms at 1.5 m/s, 0.5 rad/s
  auto advance = [&]() {
    t = t + Duration::fromMilliseconds(10);
    pose = pose * step;
    (void)history->add(t, pose);
  };
  for (int i = 0; i < 60; ++i) {
    advance();
  }
  double sum = 0.0;
  for (auto _ : state) {
    for (int i = 0; i < 8; ++i) {
      advance();
    }
    scan->stamp = t - Duration::fromMilliseconds(60);
    const SweepCompensation sweep(*history, *scan, Pose2d{1.0, 0.0, 0.0});
    for (std::size_t k = 0; k < 40; ++k) {
      const Pose2d::Vector2 p = sweep.atBeam(k * 27U, 3.0, 1.0);
      sum += p.x();
    }
    benchmark::DoNotOptimize(sum);
  }
  state.counters["history"] = static_cast<double>(history->size());
}
BENCHMARK(BM_SweepCompensation)->Name("BM_SweepCompensation/obs40");
}  // namespace
