#pragma once
/// @file encoder_sample.hpp
/// One reading of the vehicle's drive and steering encoders, in SI units.

#include <cstdint>

#include "agv/core/timestamp.hpp"

namespace agv::hal {

/// Drive encoder count and steering angle at one instant. The driver converts raw CAN values
/// (counts, centi-degrees) into these units; the driving scale s_w [m/tick] is a calibration
/// result and is applied by the odometry, not here.
struct EncoderSample {
  Timestamp stamp;              ///< acquisition time on the vehicle's monotonic clock
  std::int64_t driveTicks = 0;  ///< accumulated drive-wheel ticks, unwrapped (signed: + forward)
  double steeringAngle = 0.0;   ///< measured steering angle [rad], + = left, before offset correction
};

}  // namespace agv::hal
