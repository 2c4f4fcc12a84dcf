#pragma once
/// @file encoder_source.hpp
/// Device interface: the drive and steering encoders.

#include "agv/core/status.hpp"
#include "agv/hal/encoder_sample.hpp"

namespace agv::hal {

/// Delivers `EncoderSample`s in time order. Polled by the application loop; never blocks.
class EncoderSource {
 public:
  /// Takes the oldest sample not yet read.
  /// - `Ok`: `out` holds a new sample (stamps strictly increase from call to call).
  /// - `NotFound`: no new sample yet; `out` untouched.
  /// - `Timeout`: the device has been silent longer than its configured deadline.
  /// - `DeviceFault`, `Malformed`: the device or bus reported a problem; `out` untouched.
  virtual Status read(EncoderSample& out) noexcept = 0;
  /// The device's state between reads, for the health bits and the logs (no I/O, never blocks):
  /// - `Ok`: delivering in time;
  /// - `NotInitialized`: not ready yet (starting, connecting, no first sample);
  /// - `Timeout`: silent longer than the device's deadline;
  /// - `DeviceFault`: the device or its link reported a fault (EMCY, bus-off, error replies, link down).
  virtual Status health() const noexcept = 0;

 protected:
  EncoderSource() = default;
  EncoderSource(const EncoderSource&) = default;
  EncoderSource& operator=(const EncoderSource&) = default;
  ~EncoderSource() = default;
};

}  // namespace agv::hal
