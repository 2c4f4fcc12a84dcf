#include "agv/calib/equal_norm_fit.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>

namespace agv {
namespace {

/// Spectral data of one block: M = U diag(d) U^T, c = U^T g with signs fixed so that c >= 0.
struct Block {
  Eigen::Vector2d d;  // ascending
  Eigen::Matrix2d u;  // columns: eigenvectors, flipped where c was negative
  Eigen::Vector2d c;  // >= 0
};

Block diagonalise(const Eigen::Matrix2d& m, const Eigen::Vector2d& g) noexcept {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es;
  es.computeDirect(m);
  Block b{es.eigenvalues(), es.eigenvectors(), Eigen::Vector2d::Zero()};
  b.c = b.u.transpose() * g;
  for (int i = 0; i < 2; ++i) {
    if (b.c(i) < 0.0) {  // sign fix: the eigenvector flips with its coefficient
      b.c(i) = -b.c(i);
      b.u.col(i) = -b.u.col(i);
    }
  }
  return b;
}

/// sum_i c_i / (d_i + shift) u_i over the components whose denominator exceeds `tiny` (the others
/// have a zero coefficient in the degenerate case and are left out).
Eigen::Vector2d blockSolution(const Block& b, double shift, double tiny) noexcept {
  Eigen::Vector2d psi = Eigen::Vector2d::Zero();
  for (int i = 0; i < 2; ++i) {
    const double den = b.d(i) + shift;
    if (den > tiny) {
      psi += (b.c(i) / den) * b.u.col(i);
    }
  }
  return psi;
}

/// f(lambda) = |psi_F|^2 - |psi_B|^2 and f'(lambda); components with a denominator <= tiny are
/// left out (their limit when the coefficient is zero).
void secular(const Block& f, const Block& b, double lambda, double tiny, double* value, double* slope) noexcept {
  double v = 0.0;
  double dv = 0.0;
  for (int i = 0; i < 2; ++i) {
    const double df = f.d(i) + lambda;
    if (df > tiny) {
      const double q = f.c(i) / df;
      v += q * q;
      dv -= 2.0 * q * q / df;
    }
    const double db = b.d(i) - lambda;
    if (db > tiny) {
      const double q = b.c(i) / db;
      v -= q * q;
      dv -= 2.0 * q * q / db;
    }
  }
  *value = v;
  *slope = dv;
}

/// True when f has a pole at the end where `block.d(i) + sign*end` vanishes: some component with a
/// vanishing denominator has a non-zero coefficient.
bool hasPole(const Block& block, double shift, double tiny, double cTiny) noexcept {
  for (int i = 0; i < 2; ++i) {
    if (block.d(i) + shift <= tiny && block.c(i) > cTiny) {
      return true;
    }
  }
  return false;
}

}  // namespace

Status solveEqualNormFit(const Eigen::Matrix2d& mF, const Eigen::Vector2d& gF, const Eigen::Matrix2d& mB,
                         const Eigen::Vector2d& gB, EqualNormFit& out) noexcept {
  out = EqualNormFit{};
  if (!mF.allFinite() || !gF.allFinite() || !mB.allFinite() || !gB.allFinite()) {
    return Status::NonFiniteInput;
  }
  const Block bf = diagonalise(mF, gF);
  const Block bb = diagonalise(mB, gB);
  const double scale = std::fmax(std::fabs(bf.d(1)), std::fabs(bb.d(1)));
  const double tiny = 1e-13 * scale;
  const double lowEnd = -bf.d(0);  // A
  const double highEnd = bb.d(0);  // B
  if (!(highEnd - lowEnd > tiny) || !(scale > 0.0)) {
    return Status::Unobservable;
  }
  // Coefficients below this count as zero: f then stays finite at that end of the bracket.
  const double cTiny = 1e-14 * std::fmax(gF.norm(), gB.norm());
  double slope = 0.0;
  if (!hasPole(bf, lowEnd, tiny, cTiny)) {
    double fLow = 0.0;
    secular(bf, bb, lowEnd, tiny, &fLow, &slope);
    if (fLow <= 0.0) {
      // Degenerate case at A: M_F + A I is singular and psi_F gains a free component along its
      // null eigenvector, sized so that the norms are equal.
      out.lambda = lowEnd;
      out.boundary = true;
      out.psiB = blockSolution(bb, -lowEnd, tiny);
      out.psiF = blockSolution(bf, lowEnd, tiny);
      const double t2 = out.psiB.squaredNorm() - out.psiF.squaredNorm();
      out.psiF += std::sqrt(std::fmax(0.0, t2)) * bf.u.col(0);
      return Status::Ok;
    }
  }
  if (!hasPole(bb, -highEnd, tiny, cTiny)) {
    double fHigh = 0.0;
    secular(bf, bb, highEnd, tiny, &fHigh, &slope);
    if (fHigh >= 0.0) {
      out.lambda = highEnd;
      out.boundary = true;
      out.psiF = blockSolution(bf, highEnd, tiny);
      out.psiB = blockSolution(bb, -highEnd, tiny);
      const double t2 = out.psiF.squaredNorm() - out.psiB.squaredNorm();
      out.psiB += std::sqrt(std::fmax(0.0, t2)) * bb.u.col(0);
      return Status::Ok;
    }
  }
  // f decreases strictly on (A, B) from > 0 to < 0: Newton steps kept inside a shrinking
  // bisection bracket. Start at 0 (the root for consistent data) when it lies inside.
  double lo = lowEnd;
  double hi = highEnd;
  double lambda = (0.0 > lo && 0.0 < hi) ? 0.0 : 0.5 * (lo + hi);
  constexpr int kMaxIterations = 200;
  int it = 0;
  for (; it < kMaxIterations; ++it) {
    double value = 0.0;
    secular(bf, bb, lambda, 0.0, &value, &slope);
    if (value == 0.0) {
      break;
    }
    if (value > 0.0) {
      lo = lambda;
    } else {
      hi = lambda;
    }
    if (hi - lo <= 4.0 * std::numeric_limits<double>::epsilon() * std::fmax(std::fabs(lo), std::fabs(hi))) {
      break;
    }
    double next = slope < 0.0 ? lambda - value / slope : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) {
      next = 0.5 * (lo + hi);
    }
    if (next == lambda) {
      break;
    }
    lambda = next;
  }
  out.iterations = it;
  out.lambda = lambda;
  out.psiF = blockSolution(bf, lambda, 0.0);
  out.psiB = blockSolution(bb, -lambda, 0.0);
  return Status::Ok;
}

}  // namespace agv
