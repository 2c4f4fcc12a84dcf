// Multi-beam intrinsic calibration benchmark (docs/lidar-calibration.md):
//   BM_LidarCalibration/hdl64  one iteration = agv::lidar_calibration::calibrateIntrinsics on the
//                              thesis' protocol in the simulator's calibration hall: 45 HDL-64E S2
//                              revolutions (9 distances 3..22 m x 5 tilts 0..24 deg, 6.0 M returns,
//                              2 cm noise), truth = the SZTAKI factory file perturbed by D_corr
//                              +-5 cm, theta +-0.3 deg, alpha +-0.5 deg, started from the factory
//                              file: segmentation (2 passes), Ceres (2 threads), observability,
//                              the noise-bias correction of the thesis' minimum (default).
//                              The scans are simulated once, outside the timing. Wall time (the
//                              solve uses 2 threads).
// Counters: lasers = lasers estimated; returns = returns in the 45 scans.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "agv/core/angle.hpp"
#include "agv/datasets/velodyne_calibration.hpp"
#include "agv/lidar_calibration/hall_scans.hpp"
#include "agv/lidar_calibration/intrinsic_calibration.hpp"

namespace {
namespace lc = agv::lidar_calibration;

void BM_LidarCalibration(benchmark::State& state) {
  static agv::LaserIntrinsics factory;
  static agv::LaserIntrinsics truth;
  std::string error;
  if (!agv::datasets::readVelodyneCalibration(
          std::string(AGV_SHARED_DATA_DIR) + "/lidar3d/calibration/hdl64e_s2.1_sztaki.yaml", factory, error)) {
    state.SkipWithError(error.c_str());
    return;
  }
  std::mt19937_64 rng(1);
  truth = agv::sim::perturbIntrinsics(factory, 0.05, agv::deg2rad(0.3), agv::deg2rad(0.5), 0.0, rng);
  const std::vector<lc::CalibrationScan> scans = lc::simulateHallScans(lc::HallScansConfig{}, truth);
  std::size_t returns = 0;
  for (const lc::CalibrationScan& s : scans) {
    returns += s.returns.size();
  }
  lc::IntrinsicCalibrationResult result;
  for (auto _ : state) {
    if (!lc::calibrateIntrinsics(scans, factory, lc::IntrinsicCalibrationConfig{}, result, error)) {
      state.SkipWithError(error.c_str());
      return;
    }
    benchmark::DoNotOptimize(result.costFinal);
  }
  state.counters["lasers"] = static_cast<double>(result.lasersEstimated);
  state.counters["returns"] = static_cast<double>(returns);
}
BENCHMARK(BM_LidarCalibration)->Name("BM_LidarCalibration/hdl64")->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
