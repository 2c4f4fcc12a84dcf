#pragma once
/// @file monotonic_clock.hpp
/// The vehicle clock of the Linux drivers: CLOCK_MONOTONIC, as a `hal::Clock`.

#include "agv/core/timestamp.hpp"
#include "agv/hal/clock.hpp"

namespace agv::drivers {

/// Reads CLOCK_MONOTONIC: the clock every Linux driver stamps its samples with (kernel receive
/// times of CAN frames are mapped onto it too).
Timestamp monotonicNow() noexcept;

/// CLOCK_MONOTONIC as the navigation pipeline's `hal::Clock`. Stateless; never decreases.
class MonotonicClock final : public hal::Clock {
 public:
  Timestamp now() const noexcept override { return monotonicNow(); }
};

}  // namespace agv::drivers
