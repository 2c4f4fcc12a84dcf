// Instructions per localizer cycle on the emulated Cortex-M7 (single-precision FPU: the filter's
// double arithmetic is emulated in software). The scene is BM_EkfCycle/map256's: 256 landmarks on
// a 3 m grid with jitter, laser range 14 m, 40 observations, 10 odometry predictions per cycle, the
// scan 50 ms late. Prints the figure; fails if the scene does not associate its 40 observations.
#include <cmath>
#include <cstdint>

#include "agv/localization/landmark_map.hpp"
#include "agv/localization/localizer.hpp"
#include "ekf_cycle_scene.hpp"
#include "instruction_counter.h"
#include "semihosting.h"

namespace {
using namespace agv;

LandmarkMap map;
ScanObservations scan;
}  // namespace

int main() {
  if (agv_icount_init() == 0U) {
    semihosting_write0("SysTick does not advance: run QEMU with -icount shift=0\n");
    return 1;
  }
  LocalizerParams params;
  params.laser.mounting = Pose2d{1.0, 0.0, 0.0};
  params.laser.rangeMax = 14.0;
  static Localizer loc(params);
  const Pose2d pose{0.3, 0.2, 0.4};
  const std::size_t observed = test::buildEkfCycleScene(params, pose, 16, 40U, map, scan);
  Timestamp t = Timestamp::fromSeconds(1.0);
  (void)loc.reset(t, pose, Eigen::Matrix3d::Identity() * 1e-4);
  OdometryIncrement inc;
  inc.covariance = Eigen::Matrix3d::Identity() * 1e-10;
  const int cycles = 5;
  std::uint64_t predictTicks = 0;
  std::uint64_t correctTicks = 0;
  int failures = 0;
  for (int c = 0; c < cycles + 1; ++c) {
    const std::uint64_t t0 = agv_icount_ticks();
    for (int i = 0; i < 10; ++i) {
      t = t + Duration::fromMilliseconds(10);
      inc.stamp = t;
      (void)loc.predict(inc);
    }
    const std::uint64_t t1 = agv_icount_ticks();
    scan.stamp = t - Duration::fromMilliseconds(50);
    const LocalizerHealth& h = loc.correct(scan, map);
    const std::uint64_t t2 = agv_icount_ticks();
    agv_icount_poll();
    if (c > 0) {  // the first cycle warms up
      predictTicks += t1 - t0;
      correctTicks += t2 - t1;
    }
    if (h.used != observed || observed != 40U) {
      ++failures;
    }
  }
  semihosting_write0("EKF cycle on Cortex-M7 (map256 scene, 40 observations): 10 predictions ");
  semihosting_write_int(static_cast<long long>(agv_icount_instructions(predictTicks) / cycles));
  semihosting_write0(" instructions, lagged correction + map maintenance ");
  semihosting_write_int(static_cast<long long>(agv_icount_instructions(correctTicks) / cycles));
  semihosting_write0(" instructions\n");
  return failures == 0 ? 0 : 1;
}
