#pragma once
/// @file angle.hpp
/// Angle constants and normalisation (radians everywhere).

#include <cmath>

namespace agv {

/// pi in the precision of `S`.
template <typename S>
inline constexpr S kPi = static_cast<S>(3.14159265358979323846264338327950288);
/// 2*pi in the precision of `S`.
template <typename S>
inline constexpr S kTwoPi = static_cast<S>(6.28318530717958647692528676655900577);

/// Degrees to radians.
template <typename S>
constexpr S deg2rad(S deg) noexcept {
  return deg * (kPi<S> / static_cast<S>(180));
}
/// Radians to degrees.
template <typename S>
constexpr S rad2deg(S rad) noexcept {
  return rad * (static_cast<S>(180) / kPi<S>);
}

/// Wraps `angle` into (-pi, pi]. Constant time for any finite input; NaN/inf give NaN.
template <typename S>
S normalizeAngle(S angle) noexcept {
  S r = std::remainder(angle, kTwoPi<S>);  // [-pi, pi], exact reduction
  if (r <= -kPi<S>) {
    r += kTwoPi<S>;
  }
  return r;
}

/// Smallest signed difference a - b, in (-pi, pi].
template <typename S>
S angleDiff(S a, S b) noexcept {
  return normalizeAngle(a - b);
}

}  // namespace agv
