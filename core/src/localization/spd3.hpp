#pragma once
// Inverse of a symmetric positive-definite 3x3 matrix without Eigen's decompositions (their
// dynamic-size temporaries pull malloc into a bare-metal image): cofactors, with the leading
// minors as the positive-definiteness test. Internal to the localization sources.

#include <Eigen/Core>

namespace agv::detail {

/// `inv` = A^-1 for a symmetric A; false (inv untouched) when A is not positive definite (a leading
/// minor not positive) or too close to singular: det(A) <= relTol * a00 * a11 * a22 (Hadamard:
/// for a positive-definite A the ratio lies in (0, 1], 1 for a diagonal matrix, 0 when singular;
/// it does not depend on the units of each axis). Non-finite input fails the minors.
inline bool invertSpd3(const Eigen::Matrix3d& A, double relTol, Eigen::Matrix3d& inv) noexcept {
  const double a = A(0, 0);
  const double b = A(0, 1);
  const double c = A(0, 2);
  const double d = A(1, 1);
  const double e = A(1, 2);
  const double f = A(2, 2);
  const double m2 = a * d - b * b;
  const double c00 = d * f - e * e;
  const double c01 = c * e - b * f;
  const double c02 = b * e - c * d;
  const double det = a * c00 + b * c01 + c * c02;
  if (!(a > 0.0) || !(m2 > 0.0) || !(det > 0.0) || !(det > relTol * a * d * f)) {
    return false;
  }
  const double c11 = a * f - c * c;
  const double c12 = b * c - a * e;
  const double c22 = m2;
  inv << c00, c01, c02, c01, c11, c12, c02, c12, c22;
  inv /= det;
  return inv.allFinite();
}

}  // namespace agv::detail
