#include "agv/localization/beam_lookup.hpp"

#include <cmath>
#include <cstddef>

#include "agv/core/angle.hpp"

namespace agv {

Status checkBeamGeometry(const LaserScan& scan) noexcept {
  if (scan.size() == 0U) {
    return Status::EmptyInput;
  }
  const double a0 = static_cast<double>(scan.angleMin);
  const double inc = static_cast<double>(scan.angleIncrement);
  if (!std::isfinite(a0) || !std::isfinite(inc)) {
    return Status::NonFiniteInput;
  }
  if (!(inc > 0.0) || inc > kPi<double> / 8.0) {
    return Status::InvalidArgument;
  }
  if (static_cast<double>(scan.size()) * inc > kTwoPi<double> + 0.5 * inc) {
    return Status::InvalidArgument;
  }
  return Status::Ok;
}

Result<double> farthestReturnNear(const LaserScan& scan, double bearing) noexcept {
  const Status geometry = checkBeamGeometry(scan);
  if (geometry != Status::Ok) {
    return geometry;
  }
  if (!std::isfinite(bearing)) {
    return Status::NonFiniteInput;
  }
  const std::size_t n = scan.size();
  const double inc = static_cast<double>(scan.angleIncrement);
  const double span = static_cast<double>(n) * inc;
  // Offset from beam 0, wrapped into [0, 2 pi).
  double u = normalizeAngle(bearing - static_cast<double>(scan.angleMin));
  if (u < 0.0) {
    u += kTwoPi<double>;
  }
  const double f = u / inc;  // fractional beam index, < 2 pi / inc <= 2^k * n-ish (finite, bounded)
  const double last = static_cast<double>(n - 1U);
  std::size_t i0 = 0;
  std::size_t i1 = 0;
  if (f <= last) {
    i0 = static_cast<std::size_t>(f);  // floor: f >= 0 and <= n - 1
    i1 = i0 + 1U < n ? i0 + 1U : i0;
  } else if (span >= kTwoPi<double> - 0.5 * inc) {
    i0 = n - 1U;  // full revolution: between the last beam and the first
    i1 = 0;
  } else if (f <= last + 0.5) {
    i0 = n - 1U;  // just past the last beam
    i1 = i0;
  } else if (u >= kTwoPi<double> - 0.5 * inc) {
    i0 = 0;  // just before the first beam
    i1 = 0;
  } else {
    return Status::OutOfRange;
  }
  double best = -1.0;
  const std::size_t idx[2] = {i0, i1};
  for (const std::size_t i : idx) {
    if (scan.isValid(i)) {
      const double r = static_cast<double>(scan.ranges[i]);
      best = r > best ? r : best;
    }
  }
  if (best < 0.0) {
    return Status::NotFound;
  }
  return best;
}

}  // namespace agv
