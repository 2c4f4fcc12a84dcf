#pragma once
/// @file drive_control.hpp
/// Device interface: motion commands to the drive and steering servos (used by the calibration
/// routine; in normal operation the PLC drives the vehicle).

#include "agv/core/status.hpp"
#include "agv/hal/drive_command.hpp"

namespace agv::hal {

/// Accepts drive set-points and reports standstill.
class DriveControl {
 public:
  /// Sets the speed and steering set-points (the servos ramp to them with their own limits).
  /// `InvalidArgument` / `NonFiniteInput` for a set-point outside the device's range or NaN (the
  /// previous set-point stays); `DeviceFault` if the drive is not enabled.
  virtual Status command(const DriveCommand& cmd) noexcept = 0;
  /// Ramps the speed to zero (steering is kept). Always accepted unless the link is down.
  virtual Status stop() noexcept = 0;
  /// True while the drive wheel is at rest (speed below the device's standstill threshold).
  virtual bool isStandstill() const noexcept = 0;

 protected:
  DriveControl() = default;
  DriveControl(const DriveControl&) = default;
  DriveControl& operator=(const DriveControl&) = default;
  ~DriveControl() = default;
};

}  // namespace agv::hal
