#pragma once
/// @file ekf_cycle_scene.hpp
/// The scene of BM_EkfCycle and of the Cortex-M7 cycle-cost image: landmarks on a 3 m grid with
/// deterministic jitter (one per 9 m^2) over a `side` x `side` square centred on the origin. The
/// first `wanted` landmarks the laser sees from `pose` are dynamic landmarks (inserted and
/// reinforced) and observed in `scan` with 2 mm noise; every other one is surveyed.
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "agv/localization/landmark_map.hpp"
#include "agv/localization/localizer.hpp"

namespace agv::test {

/// Fills `map` and `scan`; returns how many landmarks were put into the scan.
inline std::size_t buildEkfCycleScene(const LocalizerParams& params, const Pose2d& pose, int side, std::size_t wanted,
                                      LandmarkMap& map, ScanObservations& scan) {
  const double spacing = 3.0;
  const double half = 0.5 * spacing * side;
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
      if (visible && observed < wanted) {
        // observed every cycle: a dynamic landmark that lives through the lifecycle
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
  return observed;
}

}  // namespace agv::test
