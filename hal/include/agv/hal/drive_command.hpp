#pragma once
/// @file drive_command.hpp
/// A motion set-point for the vehicle's drive and steering servos.

#include "agv/core/timestamp.hpp"

namespace agv::hal {

/// Set-point for the drive wheel and the steering servo, as the calibration routine sends it.
/// The steering angle is the angle *as the steering encoder measures it* (the servo closes its loop
/// on that encoder): the true wheel angle differs by the unknown steering offset, which is what
/// the calibration estimates.
struct DriveCommand {
  Timestamp stamp;             ///< when the command was issued
  double speed = 0.0;          ///< [m/s] drive-wheel surface speed, + forward, - backward
  double steeringAngle = 0.0;  ///< [rad] measured-angle set-point, + left
};

}  // namespace agv::hal
