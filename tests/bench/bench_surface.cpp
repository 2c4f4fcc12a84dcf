// BM_SurfaceMap/{insert,match}: the map-less natural navigation's two steps per sweep in the
// built-in warehouse (1440-beam simulated sweeps along lane y = 10, 8 cm apart): adding a sweep to
// a surface map that has already seen the place (the steady state of a vehicle at 2 m/s and
// 25 Hz: every beam sampled, few new points), and matching a sweep against it from a prior 2 cm /
// 0.1 deg off with a 1 cm / 0.05 deg covariance (the refinement alone, as on the vehicle).
// BM_SurfaceMap/search: the same match from a wide prior (10 cm / 3 deg off, 10 cm / 3 deg sigmas:
// the coarse search scores the +-30 cm / +-9 deg window's 1 519 poses first), the sparse logs'
// case: one scan per 0.3-1 m of odometry.
// BM_SurfaceMap/recentre/{rebuild,shift}: an insert that moves the field (the sweep 9.6 m from the
// field's centre, beyond the 8 m a 40 m field with a 12 m margin allows), with every piece of the
// lane's sweeps kept: the longest insert of a vehicle's cycle, once per 8 m driven, by
// `SurfaceMapParams::recentreByShift`.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

#include "agv/core/angle.hpp"
#include "agv/localization/scan_matcher.hpp"
#include "agv/localization/surface_map.hpp"
#include "agv/sim/sim_laser.hpp"
#include "agv/sim/world.hpp"

namespace {

using namespace agv;

/// The sweeps and their laser poses, and a surface map that has taken every one of them.
struct LaneSweeps {
  static constexpr int kSweeps = 50;
  std::vector<std::unique_ptr<hal::LaserMeasurement>> sweeps;
  std::vector<Pose2d> poses;
  /// Each sweep's beams within the map's range, as the pipeline matches them.
  std::vector<std::unique_ptr<MatchPoints>> points;
  std::unique_ptr<HallSurfaceMap> map = std::make_unique<HallSurfaceMap>();

  /// A sweep 9.6 m along the lane from the first (`BM_SurfaceMap/recentre`).
  std::unique_ptr<hal::LaserMeasurement> far = std::make_unique<hal::LaserMeasurement>();
  Pose2d farPose{29.6, 10.0, 0.0};

  LaneSweeps() {
    sim::World world;
    sim::WorldParseError e;
    static_cast<void>(sim::parseWorld(sim::defaultWorldText(), world, e));
    const sim::RayCaster caster(world, 1.0);
    sim::SimLaserParams p;
    p.angularResolution = kTwoPi<double> / 1440.0;
    sim::SimLaser laser(caster, p, 1);
    static_cast<void>(laser.scan(farPose, Timestamp{}, *far));
    for (int k = 0; k < kSweeps; ++k) {
      const Pose2d pose{20.0 + 0.08 * k, 10.0, 0.002 * std::sin(0.3 * k)};
      auto m = std::make_unique<hal::LaserMeasurement>();
      static_cast<void>(laser.scan(pose, Timestamp{}, *m));
      static_cast<void>(map->insert(m->scan, pose));
      auto pts = std::make_unique<MatchPoints>();
      map->takenBeams(m->scan, *pts);
      points.push_back(std::move(pts));
      sweeps.push_back(std::move(m));
      poses.push_back(pose);
    }
  }
};

LaneSweeps& lane() {
  static LaneSweeps l;
  return l;
}

void BM_SurfaceMapInsert(benchmark::State& state) {
  LaneSweeps& l = lane();
  int k = 0;
  for (auto _ : state) {
    const SurfaceInsert in =
        l.map->insert(l.sweeps[static_cast<std::size_t>(k)]->scan, l.poses[static_cast<std::size_t>(k)]);
    benchmark::DoNotOptimize(in.added);
    k = (k + 1) % LaneSweeps::kSweeps;
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_SurfaceMapInsert)->Name("BM_SurfaceMap/insert")->Unit(benchmark::kMicrosecond);

void BM_SurfaceMapMatch(benchmark::State& state) {
  LaneSweeps& l = lane();
  auto matcher = std::make_unique<ScanMatcher>();
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  cov.diagonal() << 1e-4, 1e-4, 7.6e-7;
  int k = 0;
  int fused = 0;
  for (auto _ : state) {
    const Pose2d truth = l.poses[static_cast<std::size_t>(k)];
    const Pose2d prior{truth.x + 0.02, truth.y - 0.01, truth.theta + 0.0017};
    const ScanMatchResult m =
        matcher->match(*l.points[static_cast<std::size_t>(k)], Pose2d{}, prior, cov, l.map->field());
    fused += m.status == Status::Ok ? 1 : 0;
    k = (k + 1) % LaneSweeps::kSweeps;
  }
  state.counters["ok_fraction"] = static_cast<double>(fused) / static_cast<double>(state.iterations());
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_SurfaceMapMatch)->Name("BM_SurfaceMap/match")->Unit(benchmark::kMicrosecond);

void BM_SurfaceMapSearch(benchmark::State& state) {
  LaneSweeps& l = lane();
  auto matcher = std::make_unique<ScanMatcher>();
  const double sigmaT = 0.1;
  const double sigmaR = 3.0 * kPi<double> / 180.0;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  cov.diagonal() << sigmaT * sigmaT, sigmaT * sigmaT, sigmaR * sigmaR;
  int k = 0;
  int fused = 0;
  std::uint64_t scored = 0;
  for (auto _ : state) {
    const Pose2d truth = l.poses[static_cast<std::size_t>(k)];
    const Pose2d prior{truth.x + 0.1, truth.y - 0.1, truth.theta + sigmaR};
    const ScanMatchResult m =
        matcher->match(*l.points[static_cast<std::size_t>(k)], Pose2d{}, prior, cov, l.map->field());
    fused += m.status == Status::Ok ? 1 : 0;
    scored += m.searched;
    k = (k + 1) % LaneSweeps::kSweeps;
  }
  state.counters["ok_fraction"] = static_cast<double>(fused) / static_cast<double>(state.iterations());
  state.counters["poses"] = static_cast<double>(scored) / static_cast<double>(state.iterations());
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_SurfaceMapSearch)->Name("BM_SurfaceMap/search")->Unit(benchmark::kMicrosecond);

void BM_SurfaceMapRecentre(benchmark::State& state) {
  LaneSweeps& l = lane();
  SurfaceMapParams p;
  p.recentreByShift = state.range(0) != 0;
  auto map = std::make_unique<HallSurfaceMap>(p);
  for (int k = 0; k < LaneSweeps::kSweeps; ++k) {
    static_cast<void>(map->insert(l.sweeps[static_cast<std::size_t>(k)]->scan, l.poses[static_cast<std::size_t>(k)]));
  }
  static_cast<void>(map->insert(l.far->scan, l.farPose));
  // Two places 9.6 m apart along the lane: every insert moves the field to the sensor.
  const Pose2d places[2] = {l.poses.front(), l.farPose};
  const hal::LaserMeasurement* sweeps[2] = {l.sweeps.front().get(), l.far.get()};
  int k = 0;
  std::size_t recentred = 0;
  for (auto _ : state) {
    const SurfaceInsert in = map->insert(sweeps[k]->scan, places[k]);
    recentred += in.recentred ? 1U : 0U;
    k = 1 - k;
  }
  state.counters["pieces"] = static_cast<double>(map->size());
  state.counters["recentred_fraction"] = static_cast<double>(recentred) / static_cast<double>(state.iterations());
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_SurfaceMapRecentre)->Name("BM_SurfaceMap/recentre/rebuild")->Arg(0)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_SurfaceMapRecentre)->Name("BM_SurfaceMap/recentre/shift")->Arg(1)->Unit(benchmark::kMicrosecond);

}  // namespace
