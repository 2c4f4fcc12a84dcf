// Calibration solves on 40 simulated segments (20 forward, 20 backward; steering 18..50 deg left
// and right; egomotion noise 5 mm / 0.1 deg; 14-bit steering): closed-form STC and ATC (each
// including the laser pose) and the joint refinement started from the ATC result.
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <vector>

#include "../calib/calib_sim.hpp"
#include "../calib/keypoint_scan_sim.hpp"
#include "agv/calib/keypoint_alignment.hpp"
#include "agv/calib/refinement.hpp"
#include "agv/falko/falko_descriptors.hpp"
#include "agv/falko/falko_detector.hpp"
#include "agv/sim/ray_caster.hpp"
#include "agv/sim/sim_laser.hpp"
#include "agv/sim/world.hpp"

namespace {

struct Fixture {
  agv::test::CalibSimConfig cfg;
  std::vector<agv::CalibSegment> segments;
  agv::CalibrationOptions options;
  Fixture() {
    cfg.perDirection = 20;
    cfg.sigmaXY = 5e-3;
    cfg.sigmaTheta = agv::deg2rad(0.1);
    cfg.quantiseTicks = true;
    cfg.steerBits = 14;
    cfg.steerPlacement = agv::deg2rad(0.5);
    std::mt19937_64 rng(40);
    segments = agv::test::simulateCalibration(cfg, rng);
    options = agv::test::nominalOptions(cfg);
  }
  agv::Span<const agv::CalibSegment> span() const { return {segments.data(), segments.size()}; }
};

const Fixture& fixture() {
  static const Fixture f;
  return f;
}

void stc40(benchmark::State& state) {
  const Fixture& f = fixture();
  agv::CalibrationResult r;
  for (auto _ : state) {
    benchmark::DoNotOptimize(agv::calibrateStc(f.span(), f.options, r));
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(f.segments.size()));
}

void atc40(benchmark::State& state) {
  const Fixture& f = fixture();
  agv::CalibrationResult r;
  for (auto _ : state) {
    benchmark::DoNotOptimize(agv::calibrateAtc(f.span(), f.options, r));
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(f.segments.size()));
}

void refine40(benchmark::State& state) {
  const Fixture& f = fixture();
  agv::CalibrationResult start;
  if (agv::calibrateAtc(f.span(), f.options, start) != agv::Status::Ok) {
    state.SkipWithError("closed form failed");
    return;
  }
  agv::RefinementResult r;
  for (auto _ : state) {
    benchmark::DoNotOptimize(agv::refineCalibration(f.span(), start.params, start.laserPose, {}, r));
    benchmark::ClobberMemory();
  }
  state.counters["iterations"] = r.iterations;
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(f.segments.size()));
}

using agv::test::KeypointScan;

/// The two standstill scans of a 42 deg half circle (beta 180 deg) of the calibration routine's
/// start in the built-in warehouse: laser 1.6 m ahead of the logical point, 0.25 deg, 1 cm noise.
struct KeypointFixture {
  KeypointScan a;
  KeypointScan b;
  agv::Pose2d guess;
  KeypointFixture() {
    agv::sim::World world;
    agv::sim::WorldParseError e;
    static_cast<void>(agv::sim::parseWorld(agv::sim::defaultWorldText(), world, e));
    const agv::sim::RayCaster caster(world, 1.0);
    const double diameter = 2.0 * 1.5 / std::tan(agv::deg2rad(42.0));
    const agv::Pose2d mount{1.6, 0.0, 0.0};
    const agv::Pose2d p1 = agv::Pose2d{10.0, 12.5, 0.0}.compose(mount);
    const agv::Pose2d p2 = agv::Pose2d{10.0, 12.5 + diameter, agv::kPi<double>}.compose(mount);
    guess = agv::between(p1, p2);
    static_cast<void>(agv::test::simulateKeypointScan(caster, p1, agv::sim::SimLaserParams{}, 5U, a));
    static_cast<void>(agv::test::simulateKeypointScan(caster, p2, agv::sim::SimLaserParams{}, 6U, b));
  }
};

void keypoints(benchmark::State& state) {
  static const KeypointFixture f;
  agv::KeypointAlignment r;
  agv::KeypointAlignmentOptions opt;
  if (state.range(0) != 0) {  // the routine's gates around the odometry's guess
    opt.guessTranslationGate = 1.0;
    opt.guessRotationGate = agv::deg2rad(10.0);
  }
  agv::Status s = agv::Status::NotInitialized;
  for (auto _ : state) {
    s = agv::alignKeypoints(f.a.view(), f.b.view(), f.guess, opt, r);
    benchmark::DoNotOptimize(s);
    benchmark::ClobberMemory();
  }
  if (s != agv::Status::Ok) {
    state.SkipWithError("alignment failed");
  }
  state.counters["keypoints"] = static_cast<double>(f.a.keypoints.size() + f.b.keypoints.size()) / 2.0;
  state.counters["candidates"] = static_cast<double>(r.candidates);
  state.counters["hypotheses"] = r.hypotheses;
  state.counters["inliers"] = static_cast<double>(r.inliers);
}

const int kRegistered = [] {
  benchmark::RegisterBenchmark("BM_Calibration/stc40", stc40);
  benchmark::RegisterBenchmark("BM_Calibration/atc40", atc40);
  benchmark::RegisterBenchmark("BM_Calibration/refine40", refine40);
  benchmark::RegisterBenchmark("BM_Calibration/keypoints", keypoints)->Arg(0)->Arg(1);
  return 0;
}();

}  // namespace
