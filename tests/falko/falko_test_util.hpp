#pragma once
// Matching helpers shared by the FALKO tests (no heap).

#include <array>
#include <cmath>
#include <cstddef>

#include "agv/core/fixed_vector.hpp"
#include "agv/falko/falko_keypoint.hpp"
#include "room_sim.hpp"

namespace agv {
namespace test {

/// Distance from (x, y) to the nearest of the first `n` points of `pts`.
template <std::size_t N>
double nearestDistance(double x, double y, const std::array<P2, N>& pts, std::size_t n, std::size_t* index = nullptr) {
  double best = 1e300;
  for (std::size_t k = 0; k < n; ++k) {
    const double d = std::hypot(x - pts[k].x, y - pts[k].y);
    if (d < best) {
      best = d;
      if (index != nullptr) {
        *index = k;
      }
    }
  }
  return best;
}

/// Distance from point p to the nearest keypoint (1e300 when there is none).
inline double nearestKeypoint(const IVector<FalkoKeypoint>& kps, P2 p, std::size_t* index = nullptr) {
  double best = 1e300;
  for (std::size_t k = 0; k < kps.size(); ++k) {
    const double d = std::hypot(static_cast<double>(kps[k].x) - p.x, static_cast<double>(kps[k].y) - p.y);
    if (d < best) {
      best = d;
      if (index != nullptr) {
        *index = k;
      }
    }
  }
  return best;
}

/// Largest distance from an expected corner to its nearest keypoint.
template <std::size_t N>
double worstMiss(const IVector<FalkoKeypoint>& kps, const std::array<P2, N>& corners, std::size_t n) {
  double worst = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    const double d = nearestKeypoint(kps, corners[k]);
    worst = d > worst ? d : worst;
  }
  return worst;
}

/// Largest distance from a keypoint to its nearest expected corner (0 without keypoints).
template <std::size_t N>
double worstSpurious(const IVector<FalkoKeypoint>& kps, const std::array<P2, N>& corners, std::size_t n) {
  double worst = 0.0;
  for (const FalkoKeypoint& kp : kps) {
    const double d = nearestDistance(static_cast<double>(kp.x), static_cast<double>(kp.y), corners, n);
    worst = d > worst ? d : worst;
  }
  return worst;
}

}  // namespace test
}  // namespace agv
