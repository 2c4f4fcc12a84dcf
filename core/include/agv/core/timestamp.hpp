#pragma once
/// @file timestamp.hpp
/// Monotonic time as integer nanoseconds.
///
/// Time in the core is a count of nanoseconds on one monotonic clock (the vehicle's steady clock,
/// or a sensor clock mapped onto it by the driver). Integer nanoseconds do not lose resolution over
/// a shift the way `float` seconds would (a float has 1 ms resolution after 2.3 h), and comparisons
/// are exact. Convert to seconds only for a difference (`Duration::seconds()`).

#include <cstdint>

namespace agv {

/// A signed span of time in nanoseconds.
struct Duration {
  std::int64_t ns = 0;

  static constexpr Duration fromNanoseconds(std::int64_t n) noexcept { return Duration{n}; }
  static constexpr Duration fromMicroseconds(std::int64_t us) noexcept { return Duration{us * 1000}; }
  static constexpr Duration fromMilliseconds(std::int64_t ms) noexcept { return Duration{ms * 1000000}; }
  /// Rounds to the nearest nanosecond. `s` must be finite and within +-292 years.
  static constexpr Duration fromSeconds(double s) noexcept {
    const double n = s * 1e9;
    return Duration{static_cast<std::int64_t>(n < 0.0 ? n - 0.5 : n + 0.5)};
  }
  /// The span in seconds.
  constexpr double seconds() const noexcept { return static_cast<double>(ns) * 1e-9; }

  friend constexpr Duration operator+(Duration a, Duration b) noexcept { return Duration{a.ns + b.ns}; }
  friend constexpr Duration operator-(Duration a, Duration b) noexcept { return Duration{a.ns - b.ns}; }
  friend constexpr Duration operator-(Duration a) noexcept { return Duration{-a.ns}; }
  friend constexpr bool operator==(Duration a, Duration b) noexcept { return a.ns == b.ns; }
  friend constexpr bool operator!=(Duration a, Duration b) noexcept { return a.ns != b.ns; }
  friend constexpr bool operator<(Duration a, Duration b) noexcept { return a.ns < b.ns; }
  friend constexpr bool operator<=(Duration a, Duration b) noexcept { return a.ns <= b.ns; }
  friend constexpr bool operator>(Duration a, Duration b) noexcept { return a.ns > b.ns; }
  friend constexpr bool operator>=(Duration a, Duration b) noexcept { return a.ns >= b.ns; }
};

/// A point in monotonic time: nanoseconds since an arbitrary, fixed epoch (e.g. boot).
struct Timestamp {
  std::int64_t ns = 0;

  static constexpr Timestamp fromNanoseconds(std::int64_t n) noexcept { return Timestamp{n}; }
  /// Rounds to the nearest nanosecond. `s` must be finite and within +-292 years.
  static constexpr Timestamp fromSeconds(double s) noexcept { return Timestamp{Duration::fromSeconds(s).ns}; }
  /// Seconds since the epoch (loses sub-microsecond resolution after ~100 days; prefer differences).
  constexpr double seconds() const noexcept { return static_cast<double>(ns) * 1e-9; }

  friend constexpr Duration operator-(Timestamp a, Timestamp b) noexcept { return Duration{a.ns - b.ns}; }
  friend constexpr Timestamp operator+(Timestamp t, Duration d) noexcept { return Timestamp{t.ns + d.ns}; }
  friend constexpr Timestamp operator-(Timestamp t, Duration d) noexcept { return Timestamp{t.ns - d.ns}; }
  friend constexpr bool operator==(Timestamp a, Timestamp b) noexcept { return a.ns == b.ns; }
  friend constexpr bool operator!=(Timestamp a, Timestamp b) noexcept { return a.ns != b.ns; }
  friend constexpr bool operator<(Timestamp a, Timestamp b) noexcept { return a.ns < b.ns; }
  friend constexpr bool operator<=(Timestamp a, Timestamp b) noexcept { return a.ns <= b.ns; }
  friend constexpr bool operator>(Timestamp a, Timestamp b) noexcept { return a.ns > b.ns; }
  friend constexpr bool operator>=(Timestamp a, Timestamp b) noexcept { return a.ns >= b.ns; }
};

}  // namespace agv
