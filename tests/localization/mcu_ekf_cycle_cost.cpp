// Instructions per localizer cycle on the emulated Cortex-M7 (single-precision FPU: the filter's
// double arithmetic is emulated in software). The scene is BM_EkfCycle/map256's: 256 landmarks on
// a 3 m grid with jitter, laser range 14 m, 40 observations, 10 odometry predictions per cycle, the
// scan 50 ms late. Prints the figure; fails if the scene does not associate its 40 observations.
#include <cmath>
#include <cstdint>

#include "agv/localization/landmark_map.hpp"
#include "agv/localization/localizer.hpp"
#include "instruction_counter.h"
#include "semihosting.h"

namespace {
using namespace agv;

void printU64(std::uint64_t v) {
  char buf[24];
  int i = 23;
  buf[i] = '\0';
  do {
    buf[--i] = static_cast<char>('0' + static_cast<int>(v % 10U));
    v /= 10U;
  } while (v != 0U && i > 0);
  semihosting_write0(buf + i);
}

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
  const int side = 16;
  const double spacing = 3.0;
  const double half = 0.5 * spacing * side;
  const Pose2d pose{0.3, 0.2, 0.4};
  const Pose2d laserWorld = pose.compose(params.laser.mounting);
  std::uint64_t s = 99;
  auto jitter = [&s]() {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    return (static_cast<double>(s >> 11) * (1.0 / 9007199254740992.0) - 0.5) * 1.0;
  };
  std::size_t observed = 0;
  std::uint32_t id = 1;
  for (int i = 0; i < side; ++i) {
    for (int j = 0; j < side; ++j) {
      const double x = -half + spacing * (i + 0.5) + jitter();
      const double y = -half + spacing * (j + 0.5) + jitter();
      const Eigen::Vector2d z = laserWorld.inverseTransformPoint(Eigen::Vector2d(x, y));
      const double r = z.norm();
      const double b = std::atan2(z.y(), z.x());
      const bool visible = r > params.laser.rangeMin + 0.5 && r < params.laser.rangeMax - 0.5 &&
                           std::fabs(b) < params.laser.angleMax - 0.05;
      if (visible && observed < 40U) {
        const auto idx = map.insert(LandmarkKind::Reflector, x, y, 1e-6);
        for (int k = 0; k < 30; ++k) {
          (void)map.reinforce(idx.value(), x, y, 1e-6, 0U);
        }
        const double n = 0.002 * jitter();
        (void)scan.points.push_back(PointObservation{z.x() + n, z.y() - n, LandmarkKind::Reflector});
        ++observed;
      } else {
        (void)map.addSurveyed(LandmarkKind::Reflector, x, y, 0.001, 100000U + id);
      }
      ++id;
    }
  }
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
  printU64(agv_icount_instructions(predictTicks) / cycles);
  semihosting_write0(" instructions, lagged correction + map maintenance ");
  printU64(agv_icount_instructions(correctTicks) / cycles);
  semihosting_write0(" instructions\n");
  return failures == 0 ? 0 : 1;
}
