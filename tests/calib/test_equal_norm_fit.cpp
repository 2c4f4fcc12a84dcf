// The ATC constrained fit against brute force over the constraint set: regular instances,
// the degenerate (hard) case at either end of the bracket, and refusals.
#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>
#include <random>

#include "agv/calib/equal_norm_fit.hpp"
#include "agv/core/angle.hpp"
#include "agv_test.hpp"

using agv::EqualNormFit;
using agv::Status;
using Eigen::Matrix2d;
using Eigen::Vector2d;

namespace {

double blockCost(const Matrix2d& m, const Vector2d& g, const Vector2d& psi) {
  return psi.dot(m * psi) - 2.0 * g.dot(psi);
}

/// min over the angle of blockCost at radius r (fine grid): the problem separates per radius.
double circleMin(const Matrix2d& m, const Vector2d& g, double r) {
  double best = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 720; ++k) {
    const double a = agv::kTwoPi<double> * k / 720.0;
    best = std::fmin(best, blockCost(m, g, Vector2d(r * std::cos(a), r * std::sin(a))));
  }
  return best;
}

/// Upper bound on the constrained minimum from feasible grid points (|psi_F| = |psi_B| = r).
double bruteForce(const Matrix2d& mF, const Vector2d& gF, const Matrix2d& mB, const Vector2d& gB, double rMax) {
  double best = std::numeric_limits<double>::infinity();
  for (int i = 0; i <= 300; ++i) {
    const double r = rMax * i / 300.0;
    best = std::fmin(best, circleMin(mF, gF, r) + circleMin(mB, gB, r));
  }
  return best;
}

double totalCost(const Matrix2d& mF, const Vector2d& gF, const Matrix2d& mB, const Vector2d& gB,
                 const EqualNormFit& f) {
  return blockCost(mF, gF, f.psiF) + blockCost(mB, gB, f.psiB);
}

Matrix2d randomPsd(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Matrix2d a;
  a << n(rng), n(rng), n(rng), n(rng);
  return a.transpose() * a + 0.05 * Matrix2d::Identity();
}

}  // namespace

TEST_CASE("equal-norm fit: random instances reach the brute-force minimum on the constraint", "[calib][atc]") {
  std::mt19937_64 rng(31);
  std::normal_distribution<double> n(0.0, 1.0);
  int boundary = 0;
  for (int t = 0; t < 25; ++t) {
    const Matrix2d mF = randomPsd(rng);
    const Matrix2d mB = randomPsd(rng);
    const Vector2d gF(n(rng), n(rng));
    const Vector2d gB(n(rng), n(rng));
    EqualNormFit fit;
    REQUIRE(agv::solveEqualNormFit(mF, gF, mB, gB, fit) == Status::Ok);
    const double r = fit.psiF.norm();
    CHECK(std::fabs(fit.psiF.squaredNorm() - fit.psiB.squaredNorm()) <= 1e-10 * (1.0 + r * r));
    const double brute = bruteForce(mF, gF, mB, gB, 2.0 * r + 1.0);
    const double solved = totalCost(mF, gF, mB, gB, fit);
    INFO("instance " << t << " solved " << solved << " brute " << brute);
    CHECK(solved <= brute + 1e-9 * (1.0 + std::fabs(brute)));
    // the grid is fine enough to come close: the solver is not "better" by violating anything
    CHECK(solved >= brute - 1e-2 * (1.0 + std::fabs(brute)));
    boundary += fit.boundary ? 1 : 0;
    // lambda makes both blocks positive semi-definite
    Eigen::SelfAdjointEigenSolver<Matrix2d> ef(mF);
    Eigen::SelfAdjointEigenSolver<Matrix2d> eb(mB);
    CHECK(fit.lambda >= -ef.eigenvalues()(0));
    CHECK(fit.lambda <= eb.eigenvalues()(0));
  }
  CHECK(boundary == 0);  // generic data never hit the degenerate case
}

TEST_CASE("equal-norm fit: degenerate case where the secular function stays finite", "[calib][atc]") {
  SECTION("at the lower end A = -min eig(M_F)") {
    // g_F has no component along the eigenvector of M_F's smallest eigenvalue (e_x), and the
    // backward block wants a larger norm than the forward block can reach inside (A, B).
    const Matrix2d mF = Vector2d(1.0, 4.0).asDiagonal();
    const Vector2d gF(0.0, 4.0);
    const Matrix2d mB = Vector2d(2.0, 3.0).asDiagonal();
    const Vector2d gB(6.0, 0.0);
    EqualNormFit fit;
    REQUIRE(agv::solveEqualNormFit(mF, gF, mB, gB, fit) == Status::Ok);
    CHECK(fit.boundary);
    AGV_CHECK_NEAR(fit.lambda, -1.0, 1e-12);
    // psi_B = g_B / (2 + 1) = (2, 0); psi_F = (t, 4/3) with t^2 = 4 - 16/9
    AGV_CHECK_NEAR(fit.psiB.x(), 2.0, 1e-12);
    AGV_CHECK_NEAR(fit.psiB.y(), 0.0, 1e-12);
    AGV_CHECK_NEAR(std::fabs(fit.psiF.x()), std::sqrt(20.0 / 9.0), 1e-12);
    AGV_CHECK_NEAR(fit.psiF.y(), 4.0 / 3.0, 1e-12);
    const double brute = bruteForce(mF, gF, mB, gB, 4.0);
    CHECK(totalCost(mF, gF, mB, gB, fit) <= brute + 1e-9);
  }
  SECTION("at the upper end B = min eig(M_B)") {
    const Matrix2d mB = Vector2d(1.0, 4.0).asDiagonal();
    const Vector2d gB(0.0, 4.0);
    const Matrix2d mF = Vector2d(2.0, 3.0).asDiagonal();
    const Vector2d gF(6.0, 0.0);
    EqualNormFit fit;
    REQUIRE(agv::solveEqualNormFit(mF, gF, mB, gB, fit) == Status::Ok);
    CHECK(fit.boundary);
    AGV_CHECK_NEAR(fit.lambda, 1.0, 1e-12);
    AGV_CHECK_NEAR(fit.psiF.x(), 2.0, 1e-12);
    AGV_CHECK_NEAR(std::fabs(fit.psiB.x()), std::sqrt(20.0 / 9.0), 1e-12);
    AGV_CHECK_NEAR(fit.psiB.y(), 4.0 / 3.0, 1e-12);
    CHECK(totalCost(mF, gF, mB, gB, fit) <= bruteForce(mF, gF, mB, gB, 4.0) + 1e-9);
  }
  SECTION("finite at an end but with a root inside: the regular root is taken") {
    const Matrix2d mF = Vector2d(1.0, 4.0).asDiagonal();
    const Vector2d gF(0.0, 4.0);
    const Matrix2d mB = Vector2d(2.0, 3.0).asDiagonal();
    const Vector2d gB(1.0, 0.0);  // small: f(A) > 0, root inside
    EqualNormFit fit;
    REQUIRE(agv::solveEqualNormFit(mF, gF, mB, gB, fit) == Status::Ok);
    CHECK_FALSE(fit.boundary);
    CHECK(fit.lambda > -1.0);
    AGV_CHECK_NEAR(fit.psiF.squaredNorm(), fit.psiB.squaredNorm(), 1e-12);
    CHECK(totalCost(mF, gF, mB, gB, fit) <= bruteForce(mF, gF, mB, gB, 4.0) + 1e-9);
  }
}

TEST_CASE("equal-norm fit refuses an empty bracket and non-finite input", "[calib][atc]") {
  EqualNormFit fit;
  const Matrix2d singular = Vector2d(0.0, 1.0).asDiagonal();
  CHECK(agv::solveEqualNormFit(singular, Vector2d(0.0, 1.0), singular, Vector2d(0.0, 1.0), fit) ==
        Status::Unobservable);
  Matrix2d bad = Matrix2d::Identity();
  bad(0, 1) = std::numeric_limits<double>::quiet_NaN();
  CHECK(agv::solveEqualNormFit(bad, Vector2d(1.0, 0.0), Matrix2d::Identity(), Vector2d(1.0, 0.0), fit) ==
        Status::NonFiniteInput);
}
