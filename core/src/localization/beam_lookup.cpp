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

namespace {

/// The beams bracketing a bearing: i0 at or before it, i1 at or after it (equal at a scan end).
struct Bracket {
  std::size_t i0 = 0;
  std::size_t i1 = 0;
  bool fullRevolution = false;
};

Result<Bracket> bracket(const LaserScan& scan, double bearing) noexcept {
  const Status geometry = checkBeamGeometry(scan);
  if (geometry != Status::Ok) {
    return geometry;
  }
  if (!std::isfinite(bearing)) {
    return Status::NonFiniteInput;
  }
  const std::size_t n = scan.size();
  const double inc = static_cast<double>(scan.angleIncrement);
  Bracket b;
  b.fullRevolution = static_cast<double>(n) * inc >= kTwoPi<double> - 0.5 * inc;
  // Offset from beam 0, wrapped into [0, 2 pi).
  double u = normalizeAngle(bearing - static_cast<double>(scan.angleMin));
  if (u < 0.0) {
    u += kTwoPi<double>;
  }
  const double f = u / inc;  // fractional beam index (huge for a tiny increment: cast only when <= n - 1)
  const double last = static_cast<double>(n - 1U);
  if (f <= last) {
    b.i0 = static_cast<std::size_t>(f);  // floor: 0 <= f <= n - 1
    b.i1 = b.i0 + 1U < n ? b.i0 + 1U : b.i0;
  } else if (b.fullRevolution) {
    b.i0 = n - 1U;  // between the last beam and the first
    b.i1 = 0;
  } else if (f <= last + 0.5) {
    b.i0 = n - 1U;  // just past the last beam
    b.i1 = b.i0;
  } else if (u >= kTwoPi<double> - 0.5 * inc) {
    b.i0 = 0;  // just before the first beam
    b.i1 = 0;
  } else {
    return Status::OutOfRange;
  }
  return b;
}

}  // namespace

Result<double> farthestReturnNear(const LaserScan& scan, double bearing) noexcept {
  const Result<Bracket> br = bracket(scan, bearing);
  if (!br.ok()) {
    return br.status();
  }
  double best = -1.0;
  const std::size_t idx[2] = {br.value().i0, br.value().i1};
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

Result<SideSupport> sideSupport(const LaserScan& scan, double range, double bearing, double radius,
                                std::size_t maxPerSide) noexcept {
  if (!(range > 0.0) || !(radius > 0.0) || !std::isfinite(range) || !std::isfinite(radius)) {
    return Status::InvalidArgument;
  }
  const Result<Bracket> br = bracket(scan, bearing);
  if (!br.ok()) {
    return br.status();
  }
  const std::size_t n = scan.size();
  const double inc = static_cast<double>(scan.angleIncrement);
  const double qx = range * std::cos(bearing);
  const double qy = range * std::sin(bearing);
  const double r2 = radius * radius;
  // Beams farther than asin(radius / range) from the bearing cannot reach the disc.
  const double window = (radius >= range ? kPi<double> : std::asin(radius / range)) + inc;
  const double stepsWanted = window / inc + 1.0;  // compared as double: a tiny increment gives a huge count
  const std::size_t steps = stepsWanted < static_cast<double>(n) ? static_cast<std::size_t>(stepsWanted) : n;
  SideSupport out;
  for (int side = 0; side < 2; ++side) {
    std::size_t i = side == 0 ? br.value().i0 : br.value().i1;
    std::size_t& count = side == 0 ? out.before : out.after;
    for (std::size_t k = 0; k < steps && count < maxPerSide; ++k) {
      if (scan.isValid(i)) {
        const double r = static_cast<double>(scan.ranges[i]);
        const double a = static_cast<double>(scan.angle(i));
        const double dx = r * std::cos(a) - qx;
        const double dy = r * std::sin(a) - qy;
        count += dx * dx + dy * dy <= r2 ? 1U : 0U;
      }
      if (side == 0) {
        if (i == 0U && !br.value().fullRevolution) {
          break;
        }
        i = i == 0U ? n - 1U : i - 1U;
      } else {
        if (i + 1U == n && !br.value().fullRevolution) {
          break;
        }
        i = i + 1U == n ? 0U : i + 1U;
      }
    }
  }
  return out;
}

}  // namespace agv
