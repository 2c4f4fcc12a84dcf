// Global localization benchmark:
//   BM_Relocalize/map256   one iteration = one GlobalLocalizer::localize call, no prior, against a
//                          synthetic warehouse of 256 reflector poles over 220 m x 220 m (at least
//                          3 m apart) seen from a random interior pose: every pole within 30 m and
//                          360 deg, 1 cm noise, 10 % missed, 2 spurious detections (~15 per scan).
// Iterations cycle over 64 pre-drawn scans (seeded). Counters: obs = detections per scan; found =
// fraction answered Ok; wrong = fraction answered Ok farther than 5 cm / 0.5 deg from the truth;
// windows and nodes = correspondence-graph windows and branch-and-bound nodes per call.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstddef>
#include <memory>

#include "agv/core/angle.hpp"
#include "agv/localization/landmark_map.hpp"
#include "agv/loop/global_localizer.hpp"
#include "loop_test_util.hpp"

namespace {

constexpr std::size_t kPoles = 256;
constexpr std::size_t kScans = 64;
constexpr double kSide = 220.0;
constexpr double kRange = 30.0;

struct Scene {
  agv::LandmarkMap map;
  agv::GlobalLocalizer localizer;
  agv::Pose2d truth[kScans];
  agv::PointObservation obs[kScans][agv::kMaxLoopPoints];
  std::size_t n[kScans] = {};
};

void BM_Relocalize(benchmark::State& state) {
  auto scene = std::make_unique<Scene>();  // ~0.5 MB: heap, once, outside the timed loop
  const agv::Pose2d mount{0.85, 0.05, 0.02};
  agv::GlobalLocalizerParams params;
  params.laserMount = mount;
  scene->localizer.setParams(params);
  agv::test::LoopRng rng{17};
  static Eigen::Vector2f poles[kPoles];
  agv::test::randomPoints(rng, kPoles, 0.0, 0.0, kSide, kSide, 3.0, poles);
  for (std::size_t i = 0; i < kPoles; ++i) {
    (void)scene->map.addSurveyed(agv::LandmarkKind::Reflector, poles[i].x(), poles[i].y(), 0.005,
                                 static_cast<std::uint32_t>(i + 1));
  }
  double obsCount = 0.0;
  for (std::size_t s = 0; s < kScans; ++s) {
    const agv::Pose2d truth{rng.uniform(20.0, kSide - 20.0), rng.uniform(20.0, kSide - 20.0), rng.uniform(-3.14, 3.14)};
    scene->truth[s] = truth;
    const agv::Pose2d laser = truth.compose(mount);
    std::size_t n = 0;
    for (std::size_t i = 0; i < kPoles && n + 2 < agv::kMaxLoopPoints; ++i) {
      const Eigen::Vector2d p = laser.inverseTransformPoint(poles[i].cast<double>());
      if (p.norm() > kRange || rng.uniform() < 0.10) {
        continue;
      }
      scene->obs[s][n++] =
          agv::PointObservation{p.x() + 0.01 * rng.normal(), p.y() + 0.01 * rng.normal(), agv::LandmarkKind::Reflector};
    }
    for (int k = 0; k < 2; ++k) {
      const double r = rng.uniform(1.0, kRange);
      const double a = rng.uniform(-3.14159, 3.14159);
      scene->obs[s][n++] = agv::PointObservation{r * std::cos(a), r * std::sin(a), agv::LandmarkKind::Reflector};
    }
    scene->n[s] = n;
    obsCount += static_cast<double>(n);
  }
  double found = 0.0;
  double wrong = 0.0;
  double windows = 0.0;
  double nodes = 0.0;
  agv::RelocReport report;
  for (std::size_t s = 0; s < kScans; ++s) {
    const agv::Status st = scene->localizer.localize(
        scene->map, agv::Span<const agv::PointObservation>(scene->obs[s], scene->n[s]), report);
    windows += report.windows;
    nodes += report.nodes;
    if (st == agv::Status::Ok) {
      const bool ok = std::hypot(report.pose.x - scene->truth[s].x, report.pose.y - scene->truth[s].y) <= 0.05 &&
                      std::fabs(agv::angleDiff(report.pose.theta, scene->truth[s].theta)) <= 0.5 * 0.0174533;
      (ok ? found : wrong) += 1.0;
    }
  }
  std::size_t s = 0;
  for (auto _ : state) {
    const agv::Status st = scene->localizer.localize(
        scene->map, agv::Span<const agv::PointObservation>(scene->obs[s], scene->n[s]), report);
    benchmark::DoNotOptimize(st);
    benchmark::DoNotOptimize(report.pose);
    s = s + 1 == kScans ? 0 : s + 1;
  }
  state.counters["obs"] = obsCount / kScans;
  state.counters["found"] = found / kScans;
  state.counters["wrong"] = wrong / kScans;
  state.counters["windows"] = windows / kScans;
  state.counters["nodes"] = nodes / kScans;
}

const int kRegistered = [] {
  benchmark::RegisterBenchmark("BM_Relocalize/map256", BM_Relocalize)->Unit(benchmark::kMicrosecond);
  return 0;
}();

}  // namespace
