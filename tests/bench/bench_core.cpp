// Benchmarks of the core primitives (baseline for the algorithm benchmarks).
#include <benchmark/benchmark.h>

#include "agv/core/fixed_vector.hpp"
#include "agv/core/pose2.hpp"

namespace {
void BM_Pose2Compose(benchmark::State& state) {
  agv::Pose2d acc{};
  const agv::Pose2d inc{0.01, 0.002, 0.001};
  for (auto _ : state) {
    acc = acc.compose(inc);
    benchmark::DoNotOptimize(acc);
  }
}
BENCHMARK(BM_Pose2Compose);

void BM_FixedVectorFillClear(benchmark::State& state) {
  agv::FixedVector<agv::Pose2f, 1024> v;
  for (auto _ : state) {
    v.clear();
    for (int i = 0; i < 1024; ++i) {
      benchmark::DoNotOptimize(v.push_back(agv::Pose2f{1.0F * static_cast<float>(i), 0.0F, 0.0F}));
    }
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * 1024);
}
BENCHMARK(BM_FixedVectorFillClear);
}  // namespace
