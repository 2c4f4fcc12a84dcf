#pragma once
/// @file pose2.hpp
/// SE(2) rigid transform / planar pose (x, y, theta), with compounding and inversion.
///
/// Conventions (Smith-Self-Cheeseman): a pose `a` is the frame A expressed in a parent frame W.
/// - `a.compose(b)` (a ⊕ b): frame B given in A, expressed in W.
/// - `a.inverse()` (⊖a): frame W expressed in A.
/// - `between(a, b)` (⊖a ⊕ b): frame B expressed in A; the relative pose used for odometry
///   increments and scan-pair ground truth.
/// - `a.transformPoint(p)`: a point given in A, expressed in W.
/// Angles are kept in (-pi, pi] by every operation.

#include <Eigen/Core>
#include <cmath>

#include "agv/core/angle.hpp"

namespace agv {

template <typename S>
struct Pose2T {
  using Scalar = S;
  using Vector2 = Eigen::Matrix<S, 2, 1>;
  using Matrix2 = Eigen::Matrix<S, 2, 2>;
  using Vector3 = Eigen::Matrix<S, 3, 1>;

  S x = S(0);      ///< [m]
  S y = S(0);      ///< [m]
  S theta = S(0);  ///< [rad], in (-pi, pi] after any operation

  constexpr Pose2T() noexcept = default;
  /// `theta` is stored as given; call `normalized()` if it may lie outside (-pi, pi].
  constexpr Pose2T(S x_, S y_, S theta_) noexcept : x(x_), y(y_), theta(theta_) {}

  /// The pose with theta wrapped into (-pi, pi].
  Pose2T normalized() const noexcept { return {x, y, normalizeAngle(theta)}; }

  /// Translation part.
  Vector2 translation() const noexcept { return Vector2(x, y); }
  /// Rotation matrix R(theta).
  Matrix2 rotation() const noexcept {
    const S c = std::cos(theta);
    const S s = std::sin(theta);
    Matrix2 r;
    r << c, -s, s, c;
    return r;
  }
  /// (x, y, theta) as a column vector.
  Vector3 vector() const noexcept { return Vector3(x, y, theta); }

  /// a ⊕ b: `b` (given in this frame) expressed in this pose's parent frame.
  Pose2T compose(const Pose2T& b) const noexcept {
    const S c = std::cos(theta);
    const S s = std::sin(theta);
    return {x + c * b.x - s * b.y, y + s * b.x + c * b.y, normalizeAngle(theta + b.theta)};
  }
  /// ⊖a: the parent frame expressed in this pose. `a.compose(a.inverse())` is the identity.
  Pose2T inverse() const noexcept {
    const S c = std::cos(theta);
    const S s = std::sin(theta);
    return {-c * x - s * y, s * x - c * y, normalizeAngle(-theta)};
  }
  /// A point given in this frame, expressed in the parent frame.
  Vector2 transformPoint(const Vector2& p) const noexcept {
    const S c = std::cos(theta);
    const S s = std::sin(theta);
    return Vector2(x + c * p.x() - s * p.y(), y + s * p.x() + c * p.y());
  }
  /// A point given in the parent frame, expressed in this frame (inverse of transformPoint).
  Vector2 inverseTransformPoint(const Vector2& p) const noexcept {
    const S c = std::cos(theta);
    const S s = std::sin(theta);
    const S dx = p.x() - x;
    const S dy = p.y() - y;
    return Vector2(c * dx + s * dy, -s * dx + c * dy);
  }

  /// True when every component is finite.
  bool isFinite() const noexcept { return std::isfinite(x) && std::isfinite(y) && std::isfinite(theta); }

  /// The same pose in another scalar type.
  template <typename T>
  Pose2T<T> cast() const noexcept {
    return {static_cast<T>(x), static_cast<T>(y), static_cast<T>(theta)};
  }
};

/// ⊖a ⊕ b: pose `b` expressed in frame `a` (both given in the same parent frame).
template <typename S>
Pose2T<S> between(const Pose2T<S>& a, const Pose2T<S>& b) noexcept {
  const S c = std::cos(a.theta);
  const S s = std::sin(a.theta);
  const S dx = b.x - a.x;
  const S dy = b.y - a.y;
  return {c * dx + s * dy, -s * dx + c * dy, normalizeAngle(b.theta - a.theta)};
}

/// a ⊕ b.
template <typename S>
Pose2T<S> operator*(const Pose2T<S>& a, const Pose2T<S>& b) noexcept {
  return a.compose(b);
}

/// Double precision pose: EKF state, calibration, maps.
using Pose2d = Pose2T<double>;
/// Single precision pose: scan geometry.
using Pose2f = Pose2T<float>;

}  // namespace agv
