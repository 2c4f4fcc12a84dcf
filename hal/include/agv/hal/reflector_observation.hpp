#pragma once
/// @file reflector_observation.hpp
/// Reflectors reported by a navigation laser in one scan.

#include <cstdint>

#include "agv/core/capacities.hpp"
#include "agv/core/fixed_vector.hpp"
#include "agv/core/timestamp.hpp"

namespace agv::hal {

/// Centre of one artificial reflector (a retro-reflective pole or foil) as measured by a
/// navigation laser, in the *sensor* frame (x forward, y left) [m]. Navigation lasers report the
/// centre of a cylindrical reflector (they correct for the radius themselves); a driver of a
/// laser that reports the surface point must add the radius before filling this in.
///
/// Float: the reported centre has cm-level noise, far above float resolution at 100 m.
struct ReflectorObservation {
  float x = 0.0F;               ///< [m] centre, sensor frame
  float y = 0.0F;               ///< [m] centre, sensor frame
  float positionStdDev = 0.0F;  ///< [m] the device's stated 1-sigma of each coordinate (0 = unknown)
  std::uint16_t id = 0;         ///< device-assigned reflector id (0 = none; not a map association)
  /// When the sensor saw it (vehicle monotonic clock), for sensors that stamp each reflector (the
  /// NAV350); `stamped` false: not reported, the reflector's time follows from its bearing within
  /// the sweep (`LaserScan::stamp`, `sweepDuration`).
  Timestamp stamp;
  bool stamped = false;
};

/// The reflectors of one scan (at most `kMaxReflectors`; a driver that sees more pushes until the
/// list refuses and the refusals are counted in `refusedCount()`).
using ReflectorList = FixedVector<ReflectorObservation, kMaxReflectors>;

}  // namespace agv::hal
