#pragma once
/// @file laser_measurement.hpp
/// What a laser source delivers per sweep: the range scan and, for navigation lasers, reflectors.

#include "agv/hal/reflector_observation.hpp"
#include "agv/scan/laser_scan.hpp"

namespace agv::hal {

/// One sweep of a 2D laser: ranges plus an optional reflector list, both in the sensor frame and
/// stamped by `scan.stamp` (time of the first beam on the vehicle's monotonic clock).
struct LaserMeasurement {
  LaserScan scan;              ///< ranges of the sweep (see LaserScan for validity rules)
  ReflectorList reflectors;    ///< reflector centres of the same sweep (empty if none or unsupported)
  bool hasReflectors = false;  ///< true when the device reports reflectors (an empty list then means "none seen")
};

}  // namespace agv::hal
