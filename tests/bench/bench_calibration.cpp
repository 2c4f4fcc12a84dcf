// Calibration solves on 40 simulated segments (20 forward, 20 backward; steering 18..50 deg left
// and right; egomotion noise 5 mm / 0.1 deg; 14-bit steering): closed-form STC and ATC (each
// including the laser pose) and the joint refinement started from the ATC result.
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "../calib/calib_sim.hpp"
#include "agv/calib/refinement.hpp"

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

const int kRegistered = [] {
  benchmark::RegisterBenchmark("BM_Calibration/stc40", stc40);
  benchmark::RegisterBenchmark("BM_Calibration/atc40", atc40);
  benchmark::RegisterBenchmark("BM_Calibration/refine40", refine40);
  return 0;
}();

}  // namespace
