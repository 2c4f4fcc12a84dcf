#pragma once
/// @file laser_scan.hpp
/// One 2D laser scan in the sensor frame, fixed capacity.

#include <cmath>
#include <cstddef>

#include "agv/core/capacities.hpp"
#include "agv/core/fixed_vector.hpp"
#include "agv/core/timestamp.hpp"

namespace agv {

/// Ranges of one sweep, beam i at angle `angleMin + i * angleIncrement` (sensor frame, x forward,
/// y left, counter-clockwise positive). Float: a laser's range noise (mm..cm) is far above float
/// resolution at 100 m, and half the memory matters on an MCU.
///
/// A reading is *valid* when finite, >= rangeMin and < rangeMax. Drivers store the sensor's
/// "no return" value as-is (or as +inf) and set rangeMax so that it is invalid; algorithms must
/// use `isValid()` and never treat an invalid reading as a point or a neighbour.
struct LaserScan {
  Timestamp stamp;                           ///< time of the first beam on the vehicle's monotonic clock
  Duration sweepDuration;                    ///< time from the first to the last beam (0 if unknown)
  float angleMin = 0.0F;                     ///< [rad] angle of beam 0
  float angleIncrement = 0.0F;               ///< [rad] angle step between beams (> 0)
  float rangeMin = 0.0F;                     ///< [m] readings below are invalid
  float rangeMax = 0.0F;                     ///< [m] readings at or above are invalid ("no return")
  FixedVector<float, kMaxScanBeams> ranges;  ///< [m]

  /// Beam count.
  std::size_t size() const noexcept { return ranges.size(); }
  /// Angle of beam `i` [rad].
  float angle(std::size_t i) const noexcept { return angleMin + static_cast<float>(i) * angleIncrement; }
  /// True when reading `i` exists and may be used as a point.
  bool isValid(std::size_t i) const noexcept {
    if (i >= ranges.size()) {
      return false;
    }
    const float r = ranges[i];
    return std::isfinite(r) && r >= rangeMin && r < rangeMax;
  }
  /// Angular span covered by the beams [rad] (n * increment: 2*pi for a full 360 deg scan).
  float fieldOfView() const noexcept { return static_cast<float>(ranges.size()) * angleIncrement; }
};

}  // namespace agv
