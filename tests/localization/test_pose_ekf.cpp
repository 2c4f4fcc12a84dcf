// PoseEkf: Jacobians, Joseph update, gating, floors, bad inputs (host only).
#include <Eigen/Eigenvalues>

#include "agv/localization/chi_square.hpp"
#include "agv/localization/pose_ekf.hpp"
#include "agv_test.hpp"

using namespace agv;

namespace {
Eigen::Vector2d observe(const Pose2d& x, const Pose2d& laser, const Eigen::Vector2d& m) {
  return x.compose(laser).inverseTransformPoint(m);
}
Eigen::Matrix3d diag3(double a, double b, double c) {
  Eigen::Matrix3d P = Eigen::Matrix3d::Zero();
  P(0, 0) = a;
  P(1, 1) = b;
  P(2, 2) = c;
  return P;
}
}  // namespace

TEST_CASE("pose EKF: observation Jacobian matches numerical differentiation", "[localization][ekf]") {
  PoseEkf ekf;
  const Pose2d x{3.0, -2.0, 0.7};
  const Pose2d laser{1.1, -0.05, 0.02};
  REQUIRE(ekf.reset(x, diag3(1e-4, 1e-4, 1e-5)) == Status::Ok);
  const Eigen::Vector2d m(8.0, 1.5);
  const Eigen::Vector2d z = observe(x, laser, m);
  const PointInnovation in = ekf.innovation(z, m, Eigen::Matrix2d::Identity() * 1e-4, laser);
  REQUIRE(in.valid);
  AGV_CHECK_NEAR(in.innovation.norm(), 0.0, 1e-12);
  const double h = 1e-6;
  for (int j = 0; j < 3; ++j) {
    Pose2d xp = x;
    Pose2d xm = x;
    (j == 0 ? xp.x : j == 1 ? xp.y : xp.theta) += h;
    (j == 0 ? xm.x : j == 1 ? xm.y : xm.theta) -= h;
    const Eigen::Vector2d d = (observe(xp, laser, m) - observe(xm, laser, m)) / (2 * h);
    AGV_CHECK_NEAR(in.H(0, j), d.x(), 1e-7);
    AGV_CHECK_NEAR(in.H(1, j), d.y(), 1e-7);
  }
}

TEST_CASE("pose EKF: prediction Jacobians match numerical differentiation", "[localization][ekf]") {
  // P' = F P F^T + G Q G^T: check with P = e_j e_j^T that F's column j is d(x ⊕ u)/dx_j.
  const Pose2d x{1.0, 2.0, -2.2};
  OdometryIncrement inc;
  inc.delta = Pose2d{0.3, 0.05, 0.1};
  inc.covariance.setZero();
  const double h = 1e-6;
  for (int j = 0; j < 3; ++j) {
    Pose2d xp = x;
    Pose2d xm = x;
    (j == 0 ? xp.x : j == 1 ? xp.y : xp.theta) += h;
    (j == 0 ? xm.x : j == 1 ? xm.y : xm.theta) -= h;
    const Pose2d a = xp.compose(inc.delta);
    const Pose2d b = xm.compose(inc.delta);
    const Eigen::Vector3d col((a.x - b.x) / (2 * h), (a.y - b.y) / (2 * h), angleDiff(a.theta, b.theta) / (2 * h));
    PoseEkf ekf(PoseEkfParams{0.0, 0.0});
    Eigen::Matrix3d P = Eigen::Matrix3d::Zero();
    P(j, j) = 1.0;
    REQUIRE(ekf.reset(x, P) == Status::Ok);
    REQUIRE(ekf.predict(inc) == Status::Ok);
    // P' = F e_j e_j^T F^T: its diagonal is col^2
    for (int r = 0; r < 3; ++r)
      AGV_CHECK_NEAR(ekf.covariance()(r, r), col(r) * col(r), 1e-8);
  }
}

TEST_CASE("pose EKF: Joseph update keeps the covariance symmetric positive definite and floored",
          "[localization][ekf]") {
  PoseEkfParams params;
  PoseEkf ekf(params);
  const Pose2d truth{0.0, 0.0, 0.0};
  REQUIRE(ekf.reset(Pose2d{0.05, -0.03, 0.01}, diag3(0.01, 0.01, 0.001)) == Status::Ok);
  const Pose2d laser{0.5, 0.0, 0.0};
  const Eigen::Vector2d landmarks[] = {{5.0, 2.0}, {-3.0, 6.0}, {4.0, -5.0}};
  const Eigen::Matrix2d R = Eigen::Matrix2d::Identity() * 1e-14;  // nearly exact: stresses the update
  for (int it = 0; it < 2000; ++it) {
    const Eigen::Vector2d& m = landmarks[it % 3];
    const PointInnovation in = ekf.innovation(observe(truth, laser, m), m, R, laser);
    const Status s = ekf.update(in, 1e12);
    CHECK(s == Status::Ok);
    const Eigen::Matrix3d& P = ekf.covariance();
    CHECK((P - P.transpose()).norm() == 0.0);
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(P);
    CHECK(es.eigenvalues().minCoeff() > 0.0);
    CHECK(P(0, 0) >= params.varianceFloorXY);
    CHECK(P(2, 2) >= params.varianceFloorTheta);
  }
  AGV_CHECK_NEAR(ekf.pose().x, truth.x, 1e-6);
  AGV_CHECK_NEAR(ekf.pose().y, truth.y, 1e-6);
  AGV_CHECK_NEAR(ekf.pose().theta, truth.theta, 1e-6);
}

TEST_CASE("pose EKF: the gate rejects a far innovation without touching the state", "[localization][ekf]") {
  PoseEkf ekf;
  REQUIRE(ekf.reset(Pose2d{}, diag3(1e-4, 1e-4, 1e-6)) == Status::Ok);
  const Pose2d laser{};
  const Eigen::Vector2d m(5.0, 0.0);
  const Eigen::Matrix2d R = Eigen::Matrix2d::Identity() * 1e-4;
  // S = H P H^T + R: along x the variance is 1e-4 + 1e-4; an error of 5 sigma along x fails the 99 % gate.
  const double sigmaX = std::sqrt(2e-4);
  const PointInnovation far = ekf.innovation(Eigen::Vector2d(5.0 + 5.0 * sigmaX, 0.0), m, R, laser);
  CHECK(far.mahalanobis2 > kChiSquare2Dof99);
  AGV_CHECK_NEAR(far.mahalanobis2, 25.0, 0.5);
  const Pose2d before = ekf.pose();
  const Eigen::Matrix3d Pbefore = ekf.covariance();
  CHECK(ekf.update(far, kChiSquare2Dof99) == Status::Rejected);
  CHECK(ekf.pose().x == before.x);
  CHECK(ekf.covariance() == Pbefore);
  const PointInnovation near = ekf.innovation(Eigen::Vector2d(5.0 + 1.0 * sigmaX, 0.0), m, R, laser);
  CHECK(ekf.update(near, kChiSquare2Dof99) == Status::Ok);
  CHECK(ekf.covariance()(0, 0) < Pbefore(0, 0));
}

TEST_CASE("pose EKF: non-finite inputs are refused without corrupting the state", "[localization][ekf]") {
  PoseEkf ekf;
  REQUIRE(ekf.reset(Pose2d{1.0, 2.0, 0.3}, diag3(1e-4, 1e-4, 1e-6)) == Status::Ok);
  const Pose2d x0 = ekf.pose();
  const Eigen::Matrix3d P0 = ekf.covariance();
  const double nan = std::nan("");
  CHECK(ekf.reset(Pose2d{nan, 0.0, 0.0}, P0) == Status::InvalidArgument);
  Eigen::Matrix3d Pbad = P0;
  Pbad(1, 1) = -1.0;
  CHECK(ekf.reset(x0, Pbad) == Status::InvalidArgument);
  OdometryIncrement inc;
  inc.delta = Pose2d{0.1, 0.0, std::numeric_limits<double>::infinity()};
  CHECK(ekf.predict(inc) == Status::NonFiniteInput);
  inc.delta = Pose2d{0.1, 0.0, 0.0};
  inc.covariance(0, 0) = nan;
  CHECK(ekf.predict(inc) == Status::NonFiniteInput);
  const PointInnovation in = ekf.innovation(Eigen::Vector2d(nan, 1.0), Eigen::Vector2d(3.0, 3.0),
                                            Eigen::Matrix2d::Identity() * 1e-4, Pose2d{});
  CHECK_FALSE(in.valid);
  CHECK(ekf.update(in, 1e9) == Status::Rejected);
  CHECK(ekf.pose().x == x0.x);
  CHECK(ekf.pose().theta == x0.theta);
  CHECK(ekf.covariance() == P0);
}

TEST_CASE("polar to Cartesian covariance", "[localization][ekf]") {
  const Eigen::Matrix2d c = polarToCartesianCovariance(10.0, 0.0, 0.005, 0.001);
  AGV_CHECK_NEAR(c(0, 0), 0.005 * 0.005, 1e-15);
  AGV_CHECK_NEAR(c(1, 1), 100.0 * 1e-6, 1e-15);
  AGV_CHECK_NEAR(c(0, 1), 0.0, 1e-15);
  const Eigen::Matrix2d d = polarToCartesianCovariance(0.0, 10.0, 0.005, 0.001);
  AGV_CHECK_NEAR(d(1, 1), 0.005 * 0.005, 1e-15);
  AGV_CHECK_NEAR(d(0, 0), 1e-4, 1e-15);
}

TEST_CASE("direct pose update: the information-weighted mean, across the heading seam, gated and refused",
          "[localization][ekf]") {
  PoseEkf ekf;
  const Eigen::Matrix3d P = Eigen::Vector3d(0.04, 0.01, 0.0004).asDiagonal();
  // The state just below +pi, the measurement just above -pi: 0.02 rad apart, not 2 pi.
  REQUIRE(ekf.reset(Pose2d{1.0, 2.0, 3.13159265358979}, P) == Status::Ok);
  const Pose2d z{1.2, 1.9, -3.13159265358979};
  // Equal covariances: the posterior is halfway and its covariance halved (a scalar Kalman gain of
  // 1/2 per axis, the axes uncorrelated).
  const double d2 = ekf.poseMahalanobis2(z, P);
  // nu = (0.2, -0.1, 0.02); S = 2 P.
  AGV_CHECK_NEAR(d2, 0.04 / 0.08 + 0.01 / 0.02 + 0.0004 / 0.0008, 1e-9);
  REQUIRE(ekf.updatePose(z, P, kChiSquare3Dof99) == Status::Ok);
  AGV_CHECK_NEAR(ekf.pose().x, 1.1, 1e-12);
  AGV_CHECK_NEAR(ekf.pose().y, 1.95, 1e-12);
  AGV_CHECK_NEAR(std::fabs(ekf.pose().theta), 3.14159265358979, 1e-9);  // on the seam
  AGV_CHECK_NEAR(ekf.covariance()(0, 0), 0.02, 1e-12);
  AGV_CHECK_NEAR(ekf.covariance()(2, 2), 0.0002, 1e-12);
  AGV_CHECK_NEAR(ekf.covariance()(0, 1), 0.0, 1e-15);
  // A measurement far outside the gate leaves the state alone.
  const Pose2d before = ekf.pose();
  const Eigen::Matrix3d Pbefore = ekf.covariance();
  CHECK(ekf.updatePose(Pose2d{before.x + 5.0, before.y, before.theta}, P, kChiSquare3Dof99) == Status::Rejected);
  CHECK(ekf.pose().x == before.x);
  CHECK(ekf.covariance() == Pbefore);
  // Non-finite input, and a covariance that makes P + R indefinite.
  CHECK(ekf.updatePose(Pose2d{std::nan(""), 0.0, 0.0}, P, 1e9) == Status::NonFiniteInput);
  Eigen::Matrix3d bad = P;
  bad(1, 1) = std::numeric_limits<double>::infinity();
  CHECK(ekf.updatePose(before, bad, 1e9) == Status::NonFiniteInput);
  const Eigen::Matrix3d indefinite = -10.0 * Eigen::Matrix3d::Identity();
  CHECK(std::isinf(ekf.poseMahalanobis2(before, indefinite)));
  CHECK(ekf.updatePose(before, indefinite, 1e9) == Status::Rejected);
  CHECK(ekf.covariance() == Pbefore);
}
