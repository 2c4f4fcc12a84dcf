#pragma once
/// @file clock.hpp
/// The vehicle's monotonic clock as a device.

#include "agv/core/timestamp.hpp"

namespace agv::hal {

/// Source of the monotonic time every sample is stamped with. Real: CLOCK_MONOTONIC (Linux
/// driver) or a hardware timer (MCU); simulated: a clock the simulation advances.
class Clock {
 public:
  /// Current time. Never decreases between calls.
  virtual Timestamp now() const noexcept = 0;

 protected:
  Clock() = default;
  Clock(const Clock&) = default;
  Clock& operator=(const Clock&) = default;
  ~Clock() = default;  // not deletable through the interface: devices are owned by value
};

}  // namespace agv::hal
