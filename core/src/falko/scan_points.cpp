#include "agv/falko/scan_points.hpp"

#include <cmath>

#include "agv/core/angle.hpp"

namespace agv {

void ScanPoints::rebuildGeometry(float angleMin, float increment, std::size_t n) noexcept {
  for (std::size_t i = 0; i < n; ++i) {
    const float a = angleMin + static_cast<float>(i) * increment;  // same as LaserScan::angle
    cos_[i] = std::cos(a);
    sin_[i] = std::sin(a);
  }
  const float halfPi = 0.5F * kPi<float>;
  for (std::size_t k = 0; k < n; ++k) {
    const float a = static_cast<float>(k) * increment;
    // Beyond 90 deg every point is at least `range` away from the centre: never in a window
    // narrower than the range (callers handle radius >= range separately).
    sinStep_[k] = a < halfPi ? std::sin(a) : 2.0F;
  }
  geomAngleMin_ = angleMin;
  geomIncrement_ = increment;
  geomSize_ = n;
}

Status ScanPoints::assign(const LaserScan& scan) noexcept {
  const std::size_t n = scan.size();
  if (!std::isfinite(scan.angleIncrement) || !(scan.angleIncrement > 0.0F) || !std::isfinite(scan.angleMin)) {
    size_ = 0;
    validCount_ = 0;
    maxSideOffset_ = 0;
    wraps_ = false;
    return Status::InvalidArgument;
  }
  // Exact comparison on purpose: any change of geometry rebuilds the tables.
  if (n > geomSize_ || scan.angleMin != geomAngleMin_ || scan.angleIncrement != geomIncrement_) {  // NOLINT
    rebuildGeometry(scan.angleMin, scan.angleIncrement, n);
  }
  size_ = n;
  increment_ = scan.angleIncrement;
  // A scan wraps when its beams cover the full circle (within half a beam).
  wraps_ = n >= 3 && static_cast<float>(n) * scan.angleIncrement >= kTwoPi<float> - 0.5F * scan.angleIncrement;
  maxSideOffset_ = n == 0 ? 0 : (wraps_ ? (n - 1) / 2 : n - 1);
  std::size_t validCount = 0;
  const float rmin = scan.rangeMin;
  const float rmax = scan.rangeMax;
  for (std::size_t i = 0; i < n; ++i) {
    const float r = scan.ranges[i];
    // NaN fails every comparison; +inf fails r < rmax; zero is never a measurement.
    const bool ok = r > 0.0F && r >= rmin && r < rmax && r <= 1.0e6F;
    valid_[i] = ok ? 1U : 0U;
    const float rr = ok ? r : 0.0F;
    range_[i] = rr;
    x_[i] = rr * cos_[i];
    y_[i] = rr * sin_[i];
    validCount += ok ? 1U : 0U;
  }
  validCount_ = validCount;
  return Status::Ok;
}

std::size_t ScanPoints::maxOffset(float rangeAtCentre, float radius) const noexcept {
  if (!(radius < rangeAtCentre)) {
    return maxSideOffset_;
  }
  // Largest k with sinStep_[k] * range <= radius; sinStep_ is non-decreasing in k.
  std::size_t lo = 0;  // sinStep_[0] = 0 satisfies it
  std::size_t hi = maxSideOffset_ + 1;
  if (hi > size_) {
    hi = size_;
  }
  while (hi - lo > 1) {
    const std::size_t mid = lo + (hi - lo) / 2;
    if (sinStep_[mid] * rangeAtCentre <= radius) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  return lo;
}

}  // namespace agv
