#pragma once
/// @file laser_source.hpp
/// Device interface: a 2D (navigation) laser.

#include "agv/core/status.hpp"
#include "agv/hal/laser_measurement.hpp"

namespace agv::hal {

/// Delivers laser sweeps in time order. Polled by the application loop; never blocks.
class LaserSource {
 public:
  /// Takes the oldest complete sweep not yet read.
  /// - `Ok`: `out` holds a new sweep (ranges and, if supported, reflectors).
  /// - `NotFound`: no new sweep yet; `out` untouched.
  /// - `Timeout`, `DeviceFault`, `Malformed`, `Truncated`: device or link problem; `out` may
  ///   have been partly written and must not be used.
  virtual Status read(LaserMeasurement& out) noexcept = 0;
  /// The device's state between reads, for the health bits and the logs (no I/O, never blocks):
  /// - `Ok`: delivering in time;
  /// - `NotInitialized`: not ready yet (starting, connecting, no first sweep);
  /// - `Timeout`: silent longer than the device's deadline;
  /// - `DeviceFault`: the device or its link reported a fault (EMCY, bus-off, error replies, link down).
  virtual Status health() const noexcept = 0;

 protected:
  LaserSource() = default;
  LaserSource(const LaserSource&) = default;
  LaserSource& operator=(const LaserSource&) = default;
  ~LaserSource() = default;
};

}  // namespace agv::hal
