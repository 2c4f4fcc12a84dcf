// Multi-beam lidar place benchmarks:
//   BM_NormalSignature/hdl64        one iteration = one real KITTI 00 HDL-64E revolution (frame 94,
//                                   121 618 points) put into a 64 x 2000 range image and turned into
//                                   its 101-bin normal signature.
//   BM_NormalSignature/vlp16        the same for a simulated VLP-16 revolution (16 x 1800 cells,
//                                   ray-cast box room with a ramp, 5 mm range noise; written into the
//                                   image cell by cell as a decoder would, so only the signature is timed).
//   BM_OrientationSignature/compare one relativeYaw of two 360-bin orientation signatures (KITTI 94 vs 95).
//   BM_OrientationSignature/align   one alignProfiles of the same two (from relativeYaw's estimate):
//                                   the geometric verification of one loop candidate, one start.
// Counters: normals = normals in the histogram; points = returns per revolution.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

#include "agv/datasets/lidar3d_scans.hpp"
#include "agv/lidar3d/normal_signature.hpp"
#include "agv/lidar3d/orientation_signature.hpp"
#include "agv/lidar3d/profile_alignment.hpp"
#include "lidar3d_sim.hpp"

namespace {

const agv::datasets::Revolution& kitti(int frame) {
  static agv::datasets::Revolution revs[2];
  static bool loaded[2] = {false, false};
  const int k = frame == 94 ? 0 : 1;
  if (!loaded[k]) {
    std::string err;
    char name[64];
    std::snprintf(name, sizeof(name), "/lidar3d/kitti00_hdl64/%06d.bin", frame);
    if (!agv::datasets::readKittiVelodyne(std::string(AGV_SHARED_DATA_DIR) + name, revs[k], err)) {
      std::fprintf(stderr, "bench_lidar3d: %s\n", err.c_str());
      std::abort();
    }
    loaded[k] = true;
  }
  return revs[k];
}

void BM_NormalSignatureHdl64(benchmark::State& state) {
  const agv::datasets::Revolution& rev = kitti(94);
  auto image = std::make_unique<agv::Hdl64RangeImage>();
  const agv::Span<const agv::RingPoint> pts(rev.points.data(), rev.points.size());
  agv::NormalSignature sig;
  for (auto _ : state) {
    benchmark::DoNotOptimize(image->buildFromRings(pts));
    benchmark::DoNotOptimize(agv::computeNormalSignature(*image, agv::NormalSignatureParams{}, sig));
  }
  state.counters["points"] = static_cast<double>(rev.points.size());
  state.counters["normals"] = sig.counts.normals;
}
BENCHMARK(BM_NormalSignatureHdl64)->Name("BM_NormalSignature/hdl64")->Unit(benchmark::kMillisecond);

void BM_NormalSignatureVlp16(benchmark::State& state) {
  auto image = std::make_unique<agv::Vlp16RangeImage>();
  const agv::test::SimLidar lidar = agv::test::vlp16At10Hz(0.005);
  const agv::test::SimScene scene = agv::test::rampYard();
  agv::test::LoopRng rng{1};
  const std::size_t points = agv::test::castScene(scene, lidar, Eigen::Vector3d::Zero(), 0.3, 0.0, rng, *image);
  agv::NormalSignatureParams params;
  params.normals.laserStep = 1;  // VLP-16: 2-deg laser steps (see tests/lidar3d)
  agv::NormalSignature sig;
  for (auto _ : state) {
    benchmark::DoNotOptimize(agv::computeNormalSignature(*image, params, sig));
  }
  state.counters["points"] = static_cast<double>(points);
  state.counters["normals"] = sig.counts.normals;
}
BENCHMARK(BM_NormalSignatureVlp16)->Name("BM_NormalSignature/vlp16")->Unit(benchmark::kMicrosecond);

/// The orientation signatures of KITTI revolutions 94 (`a`) and 95 (`b`), a true revisit.
void kittiOrientationSignatures(agv::OrientationSignature& a, agv::OrientationSignature& b) {
  auto image = std::make_unique<agv::Hdl64RangeImage>();
  const agv::datasets::Revolution& r94 = kitti(94);
  (void)image->buildFromRings(agv::Span<const agv::RingPoint>(r94.points.data(), r94.points.size()));
  (void)agv::computeOrientationSignature(*image, agv::OrientationParams{}, a);
  const agv::datasets::Revolution& r95 = kitti(95);
  (void)image->buildFromRings(agv::Span<const agv::RingPoint>(r95.points.data(), r95.points.size()));
  (void)agv::computeOrientationSignature(*image, agv::OrientationParams{}, b);
}

void BM_OrientationCompare(benchmark::State& state) {
  agv::OrientationSignature a;
  agv::OrientationSignature b;
  kittiOrientationSignatures(a, b);
  for (auto _ : state) {
    benchmark::DoNotOptimize(agv::relativeYaw(a, b));
  }
}
BENCHMARK(BM_OrientationCompare)->Name("BM_OrientationSignature/compare")->Unit(benchmark::kMicrosecond);

void BM_OrientationAlign(benchmark::State& state) {
  agv::OrientationSignature a;
  agv::OrientationSignature b;
  kittiOrientationSignatures(a, b);
  const float yaw = agv::relativeYaw(a, b).valueOr(agv::YawEstimate{}).yaw;
  agv::ProfileAlignment last;
  for (auto _ : state) {
    last = agv::alignProfiles(a, b, yaw).valueOr(agv::ProfileAlignment{});
    benchmark::DoNotOptimize(last);
  }
  state.counters["iterations"] = last.iterations;
}
BENCHMARK(BM_OrientationAlign)->Name("BM_OrientationSignature/align")->Unit(benchmark::kMicrosecond);

}  // namespace
