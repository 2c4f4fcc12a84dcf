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
  invIncrement_ = 1.0F / scan.angleIncrement;
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
    invRange_[i] = ok ? 1.0F / rr : 0.0F;
    // Invalid readings sit far away (finite, so squared distances stay finite): every radius
    // test rejects them without a separate validity branch in the inner loops.
    x_[i] = ok ? rr * cos_[i] : kFarAway;
    y_[i] = ok ? rr * sin_[i] : kFarAway;
    validCount += ok ? 1U : 0U;
  }
  validCount_ = validCount;
  return Status::Ok;
}

}  // namespace agv
