#pragma once
// Internal helpers of the FALKO module (not installed).

#include <cmath>

#include <cstddef>

#include "agv/core/angle.hpp"
#include "agv/falko/scan_points.hpp"

namespace agv {
namespace falko_detail {

/// atan2 in float with a 7th..9th order minimax polynomial: |error| < 2e-5 rad, far below the
/// 22.5 deg sector width it is used for; several times cheaper than std::atan2. (0, 0) gives 0.
inline float fastAtan2(float y, float x) noexcept {
  const float ax = std::fabs(x);
  const float ay = std::fabs(y);
  const float mx = ax > ay ? ax : ay;
  const float mn = ax > ay ? ay : ax;
  if (mx <= 0.0F) {
    return 0.0F;
  }
  const float z = mn / mx;
  const float z2 = z * z;
  float r = z * (0.9998660F + z2 * (-0.3302995F + z2 * (0.1801410F + z2 * (-0.0851330F + z2 * 0.0208351F))));
  if (ay > ax) {
    r = 0.5F * kPi<float> - r;
  }
  if (x < 0.0F) {
    r = kPi<float> - r;
  }
  return y < 0.0F ? -r : r;
}

/// Index in [0, bins) of the angle atan2(v, u), bin 0 *centred* on -pi (bin k covers
/// -pi + (k -+ 1/2) * width). Centred bins put the walls of 90 and 135 deg corners (at +-45 and
/// +-67.5 deg from the corner orientation) in the middle of a bin instead of on a boundary,
/// where range noise would flip them from one bin to the next.
inline unsigned sectorOf(float v, float u, float binsPerRadian, unsigned bins) noexcept {
  const float a = fastAtan2(v, u) + kPi<float>;
  const float f = a * binsPerRadian + 0.5F;
  if (!(f > 0.0F)) {
    return 0U;
  }
  const auto k = static_cast<unsigned>(f);
  return k < bins ? k : 0U;  // the upper half of the last half-bin is bin 0 again
}

/// Fast path of sectorOf for 16 bins: the bin of (u, v) from three sign tests and four
/// comparisons against the tangents of the bin boundaries (11.25, 33.75, 56.25, 78.75 deg); no
/// division, no polynomial. Same result as sectorOf(v, u, 16 / (2 pi), 16) except exactly on a
/// boundary.
inline unsigned sector16(float u, float v) noexcept {
  const float ax = std::fabs(u);
  const float ay = std::fabs(v);
  // Steps of 22.5 deg within the quadrant, 0 (on the u axis) .. 4 (on the v axis).
  const unsigned q = static_cast<unsigned>(ay > 0.19891237F * ax) + static_cast<unsigned>(ay > 0.66817864F * ax) +
                     static_cast<unsigned>(ay > 1.49660576F * ax) + static_cast<unsigned>(ay > 5.02733949F * ax);
  // Bin of the angle counted from 0 deg, 0..15: quadrant I: q; II: 8 - q; III: 8 + q; IV: 16 - q.
  const unsigned fromZero = u >= 0.0F ? (v >= 0.0F ? q : 16U - q) : (v >= 0.0F ? 8U - q : 8U + q);
  // Bin 0 is centred on -pi (180 deg).
  return (fromZero + 8U) & 15U;
}

/// Calls f(j) for the beams 1..k steps from beam i in direction dir (-1 or +1), nearest first,
/// wrapping on 360 deg scans and stopping at the scan ends otherwise. Plain index loops (no modulo
/// per step); k must not exceed pts.maxOffset(...) so that the two directions never overlap.
template <typename F>
inline void walkBeams(const ScanPoints& pts, std::size_t i, int dir, std::size_t k, F&& f) {
  const std::size_t n = pts.size();
  if (dir < 0) {
    const std::size_t direct = k <= i ? k : i;
    for (std::size_t s = 1; s <= direct; ++s) {
      f(i - s);
    }
    if (pts.wraps() && k > direct) {
      for (std::size_t s = 0; s < k - direct; ++s) {
        f(n - 1 - s);
      }
    }
  } else {
    const std::size_t direct = i + k < n ? k : n - 1 - i;
    for (std::size_t s = 1; s <= direct; ++s) {
      f(i + s);
    }
    if (pts.wraps() && k > direct) {
      for (std::size_t s = 0; s < k - direct; ++s) {
        f(s);
      }
    }
  }
}

}  // namespace falko_detail
}  // namespace agv
