#pragma once
// Internal helpers of the FALKO module (not installed).

#include <cmath>

#include "agv/core/angle.hpp"

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

}  // namespace falko_detail
}  // namespace agv
