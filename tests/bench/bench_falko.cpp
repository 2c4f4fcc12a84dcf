// FALKO benchmarks: BM_Falko/<set> (detector) and BM_FalkoDescriptors/<set> (BSC + CGH of all
// keypoints of a scan). One iteration = one scan, cycling over every scan of the set, so the
// reported time is the mean per scan. Sets: intel, fr079, mitcsail (all scans of the FLIRTLib
// logs in the shared data) and dense1440 (360 deg, 0.25 deg scans of a simulated room).
// BM_FalkoReferenceParams/<set> times the same detector with the public reference
// implementation's own default parameters instead of the thesis defaults, for a comparison with
// the reference's published times at equal parameters (see docs/falko.md).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <initializer_list>
#include <memory>
#include <string>
#include <vector>

#include "agv/datasets/carmen_log.hpp"
#include "agv/falko/falko_descriptors.hpp"
#include "agv/falko/falko_detector.hpp"
#include "room_sim.hpp"

namespace {

using Scans = std::vector<std::unique_ptr<agv::LaserScan>>;

Scans loadLog(const char* rel) {
  Scans out;
  agv::datasets::CarmenLog log;
  std::string err;
  const std::string path = std::string(AGV_SHARED_DATA_DIR) + "/laser2d/" + rel;
  if (!agv::datasets::readCarmenLog(path, log, err)) {
    std::fprintf(stderr, "bench_falko: %s\n", err.c_str());
    std::abort();  // the data must be there (CI has it)
  }
  for (const auto& s : log.scans) {
    auto scan = std::make_unique<agv::LaserScan>();
    (void)s.toLaserScan(*scan);
    out.push_back(std::move(scan));
  }
  return out;
}

Scans dense1440() {
  Scans out;
  const agv::test::World w = agv::test::testRoom();
  const float inc = 0.25F * 0.017453292519943295F;
  for (int k = 0; k < 64; ++k) {
    const double f = static_cast<double>(k) / 64.0;
    const agv::test::SensorPose pose{2.5 + 2.5 * f, 2.0 + 2.0 * f, 6.283185307179586 * f};
    auto scan = std::make_unique<agv::LaserScan>();
    agv::test::simulateScan(w, pose, -3.14159265F, inc, 1440, 0.01, static_cast<std::uint32_t>(k + 1), *scan);
    out.push_back(std::move(scan));
  }
  return out;
}

const Scans& scanSet(int set) {
  static Scans sets[4];
  static bool loaded[4] = {false, false, false, false};
  if (!loaded[set]) {
    switch (set) {
      case 0:
        sets[0] = loadLog("intel/intel-lab.log.gz");
        break;
      case 1:
        sets[1] = loadLog("fr079/fr079.log.gz");
        break;
      case 2:
        sets[2] = loadLog("mit-csail/mit-cscail.log.gz");
        break;
      default:
        sets[3] = dense1440();
        break;
    }
    loaded[set] = true;
  }
  return sets[set];
}

struct Work {
  explicit Work(const agv::FalkoParams& params = agv::FalkoParams{}) : detector(params) {}
  agv::FalkoDetector detector;
  agv::FalkoDescriber describer;
  agv::FalkoKeypoints keypoints;
  agv::BscDescriptors bsc;
  agv::CghDescriptors cgh;
};

void timeDetector(benchmark::State& state, int set, const agv::FalkoParams& params) {
  const Scans& scans = scanSet(set);
  auto w = std::make_unique<Work>(params);
  std::size_t i = 0;
  std::size_t keypoints = 0;
  for (auto _ : state) {
    const agv::Status st = w->detector.detect(*scans[i], w->keypoints);
    benchmark::DoNotOptimize(st);
    keypoints += w->keypoints.size();
    i = i + 1 == scans.size() ? 0 : i + 1;
  }
  state.counters["scans"] = static_cast<double>(scans.size());
  state.counters["kp_per_scan"] = static_cast<double>(keypoints) / static_cast<double>(state.iterations());
}

void BM_Falko(benchmark::State& state, int set) {
  timeDetector(state, set, agv::FalkoParams{});
}

void BM_FalkoReferenceParams(benchmark::State& state, int set) {
  timeDetector(state, set, agv::falkoReferenceParams());
}

void BM_FalkoDescriptors(benchmark::State& state, int set) {
  const Scans& scans = scanSet(set);
  auto w = std::make_unique<Work>();
  std::size_t i = 0;
  for (auto _ : state) {
    (void)w->detector.detect(*scans[i], w->keypoints);  // not timed (manual time below)
    const auto t0 = std::chrono::steady_clock::now();
    const agv::Status st = w->describer.describe(w->detector.points(), w->keypoints, w->bsc, w->cgh);
    const auto t1 = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(st);
    benchmark::DoNotOptimize(w->cgh.data());
    state.SetIterationTime(std::chrono::duration<double>(t1 - t0).count());
    i = i + 1 == scans.size() ? 0 : i + 1;
  }
}

/// The fastest repetition, next to Google Benchmark's mean / median / stddev: on a shared machine
/// other jobs only ever add time, so with --benchmark_repetitions the minimum is the steadiest
/// figure to compare two builds by (`*_min` rows).
double minOf(const std::vector<double>& v) {
  return v.empty() ? 0.0 : *std::min_element(v.begin(), v.end());
}

/// Registers one row: `family`/<set> for each set, times in µs, with the `*_min` statistic;
/// `manualTime` for the descriptor rows, which time only the describe call.
void addRows(const char* family, void (*fn)(benchmark::State&, int), std::initializer_list<int> sets, bool manualTime) {
  static const char* const kSetNames[] = {"intel", "fr079", "mitcsail", "dense1440"};
  for (const int set : sets) {
    const std::string name = std::string(family) + "/" + kSetNames[set];
    auto* b = benchmark::RegisterBenchmark(name.c_str(), fn, set)->Unit(benchmark::kMicrosecond);
    b->ComputeStatistics("min", minOf);
    if (manualTime) {
      b->UseManualTime();
    }
  }
}

const int kRegistered = [] {
  addRows("BM_Falko", BM_Falko, {0, 1, 2, 3}, false);
  addRows("BM_FalkoReferenceParams", BM_FalkoReferenceParams, {1, 3}, false);
  addRows("BM_FalkoDescriptors", BM_FalkoDescriptors, {0, 1, 2, 3}, true);
  return 0;
}();

}  // namespace
