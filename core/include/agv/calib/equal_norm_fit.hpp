#pragma once
/// @file equal_norm_fit.hpp
/// The ATC core: a least-squares fit of two 2-vectors under the quadratic equality constraint
/// that their norms are equal,
///
///   min_psi  psi_F^T M_F psi_F - 2 g_F^T psi_F + psi_B^T M_B psi_B - 2 g_B^T psi_B
///   s.t.     |psi_F|^2 - |psi_B|^2 = 0,
///
/// given the normal equations (M = A^T A, g = A^T b) of the forward and backward rotation fits.
/// Solved through its multiplier lambda: each 2x2 block is diagonalised, the coefficients are
/// sign-fixed (with their eigenvectors), and the secular function |psi_F|^2 - |psi_B|^2 is
/// brought to zero by a bracketed root search on (A, B), A = -min eig(M_F), B = min eig(M_B).
/// The degenerate ("hard") case in which the secular function stays finite at an end of the
/// bracket and has no root inside is solved at that end. Derivation: docs/calibration.md.
///
/// Precision: double (the root lies close to poles of the secular function; see calibration.hpp).

#include <Eigen/Core>

#include "agv/core/status.hpp"

namespace agv {

/// Solution of the equal-norm fit.
struct EqualNormFit {
  Eigen::Vector2d psiF = Eigen::Vector2d::Zero();
  Eigen::Vector2d psiB = Eigen::Vector2d::Zero();
  double lambda = 0.0;    ///< Lagrange multiplier, in [A, B]
  bool boundary = false;  ///< true in the degenerate case (lambda = A or B)
  int iterations = 0;     ///< root-search iterations (at most 200)
};

/// Solves the fit. `mF`, `mB` must be symmetric positive semi-definite. Returns Ok;
/// NonFiniteInput for NaN/inf entries; Unobservable when min eig(M_F) + min eig(M_B) is not
/// positive (the bracket (A, B) is empty: both blocks singular).
Status solveEqualNormFit(const Eigen::Matrix2d& mF, const Eigen::Vector2d& gF, const Eigen::Matrix2d& mB,
                         const Eigen::Vector2d& gB, EqualNormFit& out) noexcept;

}  // namespace agv
