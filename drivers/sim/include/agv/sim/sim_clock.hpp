#pragma once
/// @file sim_clock.hpp
/// Simulation time as the vehicle's clock.

#include "agv/hal/clock.hpp"

namespace agv::sim {

/// A `hal::Clock` that the simulation sets; never goes backwards.
class SimClock final : public hal::Clock {
 public:
  Timestamp now() const noexcept override { return now_; }
  /// Moves the clock to `t` (ignored if `t` is earlier than now).
  void set(Timestamp t) noexcept {
    if (t > now_) {
      now_ = t;
    }
  }
  void advance(Duration d) noexcept { set(now_ + d); }

 private:
  Timestamp now_;
};

}  // namespace agv::sim
