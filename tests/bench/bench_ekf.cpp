// BM_EkfCycle/<map>: one laser cycle of the localizer at 10 Hz with 100 Hz odometry: 10 odometry
// predictions, then a scan lagging 50 ms with 40 point observations: rewind through the history,
// associate (grid query + gate), sequential updates, map maintenance (reinforce, in-view decrement),
// re-prediction. The maps have the same landmark density (one per 9 m^2, a 3 m grid with jitter)
// and grow in area, as a larger warehouse does: 256 landmarks on 48 m x 48 m, 4096 on 192 m x 192 m;
// laser range 14 m (~45 landmarks in view). A third case measures the worst case of the docs.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>
#include <memory>

#include "agv/localization/landmark_map.hpp"
#include "agv/localization/localizer.hpp"

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

  EkfBenchWorld(int side, double rangeMax, std::size_t observations) : wanted(observations) {
    params.laser.mounting = Pose2d{1.0, 0.0, 0.0};
    params.laser.rangeMax = rangeMax;
    loc = std::make_unique<Localizer>(params);
    map = std::make_unique<LandmarkMap>();
    scan = std::make_unique<ScanObservations>();
    const double spacing = 3.0;
    const double half = 0.5 * spacing * side;
    pose = Pose2d{0.3, 0.2, 0.4};
    const Pose2d laserWorld = pose.compose(params.laser.mounting);
    std::uint64_t s = 99;
    auto jitter = [&s]() {
      s = s * 6364136223846793005ULL + 1442695040888963407ULL;
      return (static_cast<double>(s >> 11) * (1.0 / 9007199254740992.0) - 0.5) * 1.0;
    };
    std::uint32_t id = 1;
    scan->kindsDetected = kAllLandmarkKinds;
    for (int i = 0; i < side; ++i) {
      for (int j = 0; j < side; ++j) {
        const double x = -half + spacing * (i + 0.5) + jitter();
        const double y = -half + spacing * (j + 0.5) + jitter();
        const Eigen::Vector2d z = laserWorld.inverseTransformPoint(Eigen::Vector2d(x, y));
        const double r = z.norm();
        const double b = std::atan2(z.y(), z.x());
        const bool visible = r > params.laser.rangeMin + 0.5 && r < params.laser.rangeMax - 0.5 &&
                             std::fabs(b) < params.laser.angleMax - 0.05;
        if (visible && observed < wanted) {
          // observed every cycle: a dynamic landmark that lives through the lifecycle
          const auto idx = map->insert(LandmarkKind::Reflector, x, y, 1e-6);
          for (int k = 0; k < 30; ++k)
            (void)map->reinforce(idx.value(), x, y, 1e-6, 0U);
          const double n = 0.002 * jitter();
          (void)scan->points.push_back(PointObservation{z.x() + n, z.y() - n, LandmarkKind::Reflector});
          ++observed;
        } else {
          (void)map->addSurveyed(LandmarkKind::Reflector, x, y, 0.001, 100000U + id);
        }
        ++id;
      }
    }
    Eigen::Matrix3d P0 = Eigen::Matrix3d::Identity() * 1e-4;
    (void)loc->reset(t, pose, P0);
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
    const LocalizerHealth& h = loc->correct(*scan, *map);
    benchmark::DoNotOptimize(&h);
  }
};

void BM_EkfCycle(benchmark::State& state, int side, double rangeMax, std::size_t observations) {
  EkfBenchWorld w(side, rangeMax, observations);
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
BENCHMARK_CAPTURE(BM_EkfCycle, map256, 16, 14.0, 40)->Name("BM_EkfCycle/map256");
BENCHMARK_CAPTURE(BM_EkfCycle, map4096, 64, 14.0, 40)->Name("BM_EkfCycle/map4096");
// Worst case for the docs: kMaxObservations observations, 30 m range (~235 landmarks in view).
BENCHMARK_CAPTURE(BM_EkfCycle, worst, 64, 30.0, kMaxObservations)->Name("BM_EkfCycle/map4096_obs128_range30");
}  // namespace
