// Tricycle / unicycle odometry increments and their derived process noise (host only: Monte Carlo).
#include <Eigen/Core>
#include <cmath>
#include <random>

#include "agv/localization/odometry.hpp"
#include "agv_test.hpp"

using namespace agv;

namespace {
TricycleParams vehicle() {
  TricycleParams v;
  v.wheelbase = 1.5;
  v.driveScale = 5e-4;
  return v;
}
}  // namespace

TEST_CASE("tricycle increment composes to the RK2 step of the kinematics header", "[localization][odometry]") {
  const TricycleOdometry odo(vehicle(), TricycleNoiseParams{});
  const Pose2d start{12.0, -3.0, 2.5};
  for (double ds : {0.02, -0.015, 0.0, 0.3}) {
    for (double a0 : {-0.6, 0.0, 0.4}) {
      const double a1 = a0 + 0.05;
      const OdometryIncrement inc = odo.increment(Timestamp{}, ds, a0, a1, true);
      const Pose2d viaInc = start.compose(inc.delta);
      const Pose2d rk2 = tricycleRk2Step(start, ds, a0, a1, 1.5);
      AGV_CHECK_NEAR(viaInc.x, rk2.x, 1e-12);
      AGV_CHECK_NEAR(viaInc.y, rk2.y, 1e-12);
      AGV_CHECK_NEAR(angleDiff(viaInc.theta, rk2.theta), 0.0, 1e-12);
      CHECK(inc.isValid());
    }
  }
}

TEST_CASE("tricycle process noise matches Monte Carlo propagation of the input noise", "[localization][odometry]") {
  TricycleNoiseParams noise;
  noise.slipVariancePerMetre = 4e-4;  // large so that the test has power
  noise.steeringSigma = deg2rad(0.5);
  noise.samplesPerCorrection = 4.0;
  const TricycleParams v = vehicle();
  const TricycleOdometry odo(v, noise);
  const double ds = 0.2;
  const double a0 = 0.3;
  const double a1 = 0.35;
  const OdometryIncrement inc = odo.increment(Timestamp{}, ds, a0, a1, true);
  // Input variances from the documented model, independently of the code under test.
  const double varDs =
      noise.slipVariancePerMetre * ds + v.driveScale * v.driveScale / (6.0 * noise.samplesPerCorrection);
  const double varA = noise.steeringSigma * noise.steeringSigma;
  std::mt19937_64 rng(7);
  std::normal_distribution<double> n01(0.0, 1.0);
  const int N = 40000;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Matrix3d second = Eigen::Matrix3d::Zero();
  for (int i = 0; i < N; ++i) {
    const double dsi = ds + std::sqrt(varDs) * n01(rng);
    const double da = std::sqrt(varA) * n01(rng);
    const Pose2d d = tricycleRk2Step(Pose2d{}, dsi, a0 + da, a1 + da, v.wheelbase);
    const Eigen::Vector3d e(d.x - inc.delta.x, d.y - inc.delta.y, angleDiff(d.theta, inc.delta.theta));
    mean += e;
    second += e * e.transpose();
  }
  mean /= N;
  const Eigen::Matrix3d cov = second / N - mean * mean.transpose();
  // Sampling error of a variance estimate: sqrt(2/N) = 0.7 %; first-order error at these noise
  // levels is below that. Allow 4 %.
  for (int r = 0; r < 3; ++r) {
    AGV_CHECK_NEAR(cov(r, r) / inc.covariance(r, r), 1.0, 0.04);
  }
  // Correlation between forward travel and heading change is carried too.
  const double corrMc = cov(0, 2) / std::sqrt(cov(0, 0) * cov(2, 2));
  const double corrModel = inc.covariance(0, 2) / std::sqrt(inc.covariance(0, 0) * inc.covariance(2, 2));
  AGV_CHECK_NEAR(corrMc, corrModel, 0.03);
}

TEST_CASE("steering noise: the white-equivalent per-step variance matches the heading drift of RK2 means",
          "[localization][odometry]") {
  // Each steering reading enters two consecutive RK2 means with weight 1/2. Over many steps the
  // heading variance therefore grows by the full reading variance per step, which the model uses.
  TricycleNoiseParams noise;
  noise.slipVariancePerMetre = 0.0;
  noise.steeringSigma = deg2rad(0.2);
  const TricycleParams v = vehicle();
  TricycleOdometry odo(v, noise);
  const int steps = 200;
  const double ds = 0.01;
  // Model: sum of the per-step heading variances (straight driving, so no coupling).
  double modelVar = 0.0;
  for (int k = 0; k < steps; ++k)
    modelVar += odo.increment(Timestamp{}, ds, 0.0, 0.0, false).covariance(2, 2);
  std::mt19937_64 rng(11);
  std::normal_distribution<double> n(0.0, noise.steeringSigma);
  const int runs = 20000;
  double sum2 = 0.0;
  for (int r = 0; r < runs; ++r) {
    double prev = n(rng);
    double theta = 0.0;
    for (int k = 0; k < steps; ++k) {
      const double cur = n(rng);
      theta += ds * std::sin(0.5 * (prev + cur)) / v.wheelbase;
      prev = cur;
    }
    sum2 += theta * theta;
  }
  const double mcVar = sum2 / runs;
  // Exact for this sequence: (steps - 1/2)/steps of the model; sampling error 1 %.
  AGV_CHECK_NEAR(mcVar / modelVar, (steps - 0.5) / steps, 0.04);
}

TEST_CASE("tricycle odometry: samples, offsets and bad inputs", "[localization][odometry]") {
  TricycleParams v = vehicle();
  v.steerOffsetForward = 0.01;
  v.steerOffsetBackward = -0.02;
  TricycleOdometry odo(v, TricycleNoiseParams{});
  TricycleSample s;
  s.stamp = Timestamp::fromSeconds(1.0);
  s.driveTicks = 1000;
  s.steeringAngle = 0.2;
  CHECK(odo.step(s).status() == Status::NotEnoughData);
  // forward 100 ticks
  s.stamp = Timestamp::fromSeconds(1.01);
  s.driveTicks = 1100;
  s.steeringAngle = 0.3;
  auto r = odo.step(s);
  REQUIRE(r.ok());
  const Pose2d expectF = tricycleRk2Step(Pose2d{}, 100 * v.driveScale, 0.2 + 0.01, 0.3 + 0.01, v.wheelbase);
  AGV_CHECK_NEAR(r.value().delta.x, expectF.x, 1e-15);
  AGV_CHECK_NEAR(r.value().delta.theta, expectF.theta, 1e-15);
  CHECK(r.value().stamp == s.stamp);
  // NaN steering: refused, the next valid sample integrates from the last valid one.
  TricycleSample bad = s;
  bad.stamp = Timestamp::fromSeconds(1.02);
  bad.steeringAngle = std::nan("");
  CHECK(odo.step(bad).status() == Status::NonFiniteInput);
  // stamp not increasing: refused
  TricycleSample old = s;
  old.driveTicks = 1200;
  CHECK(odo.step(old).status() == Status::InvalidArgument);
  // backward 40 ticks, uses the backward offset
  s.stamp = Timestamp::fromSeconds(1.03);
  s.driveTicks = 1060;
  s.steeringAngle = 0.3;
  r = odo.step(s);
  REQUIRE(r.ok());
  const Pose2d expectB = tricycleRk2Step(Pose2d{}, -40 * v.driveScale, 0.3 - 0.02, 0.3 - 0.02, v.wheelbase);
  AGV_CHECK_NEAR(r.value().delta.x, expectB.x, 1e-15);
  AGV_CHECK_NEAR(r.value().delta.y, expectB.y, 1e-15);
  // implausible tick jump: refused and the sequence restarts there
  s.stamp = Timestamp::fromSeconds(1.04);
  s.driveTicks = 1060 + 10000000;
  CHECK(odo.step(s).status() == Status::OutOfRange);
  s.stamp = Timestamp::fromSeconds(1.05);
  s.driveTicks += 10;
  r = odo.step(s);
  REQUIRE(r.ok());
  AGV_CHECK_NEAR(std::hypot(r.value().delta.x, r.value().delta.y), 10 * v.driveScale * std::cos(0.31), 1e-9);
  // standing still: no quantisation noise, no slip; only steering (which has no effect at ds = 0)
  s.stamp = Timestamp::fromSeconds(1.06);
  r = odo.step(s);
  REQUIRE(r.ok());
  CHECK(r.value().covariance.norm() == 0.0);
}

TEST_CASE("unicycle increments and splitting an increment at a scan time", "[localization][odometry]") {
  const UnicycleNoiseParams noise;
  const OdometryIncrement u = unicycleIncrement(Timestamp::fromSeconds(2.0), Pose2d{0.1, 0.01, 0.05}, noise);
  CHECK(u.isValid());
  CHECK(u.covariance(0, 0) > 0.0);
  CHECK(u.covariance(2, 2) > noise.rotationVariancePerRadian * 0.05);
  OdometryIncrement bad = u;
  bad.delta.x = std::nan("");
  CHECK_FALSE(bad.isValid());
  bad = u;
  bad.covariance(0, 1) = 1.0;  // not symmetric
  CHECK_FALSE(bad.isValid());

  // A fraction of an RK2 increment is the RK2 increment of that fraction of the travel.
  const TricycleOdometry odo(vehicle(), TricycleNoiseParams{});
  for (double ds : {0.05, -0.05}) {
    const OdometryIncrement full = odo.increment(Timestamp{}, ds, 0.4, 0.4, true);
    const OdometryIncrement third = odo.increment(Timestamp{}, ds / 3.0, 0.4, 0.4, true);
    const Pose2d part = partialIncrement(full.delta, 1.0 / 3.0);
    AGV_CHECK_NEAR(part.x, third.delta.x, 1e-12);
    AGV_CHECK_NEAR(part.y, third.delta.y, 1e-12);
    AGV_CHECK_NEAR(part.theta, third.delta.theta, 1e-12);
    const Pose2d rest = between(part, full.delta);
    const Pose2d again = part.compose(rest);
    AGV_CHECK_NEAR(again.x, full.delta.x, 1e-15);
    AGV_CHECK_NEAR(again.y, full.delta.y, 1e-15);
  }
  const Pose2d spin = partialIncrement(Pose2d{0.0, 0.0, 0.3}, 0.5);
  AGV_CHECK_NEAR(spin.theta, 0.15, 1e-15);
  AGV_CHECK_NEAR(spin.x, 0.0, 0.0);
}

TEST_CASE("bias terms: a steering and a scale bias constant over a correction interval, as Monte Carlo",
          "[localization][odometry]") {
  // A bias drawn once per correction interval of M samples moves the interval's heading and
  // distance by the sum of M correlated steps; the model's M increments, each carrying M times the
  // bias variance, must add up to the variance of that sum.
  TricycleNoiseParams noise;
  noise.slipVariancePerMetre = 0.0;
  noise.steeringSigma = 0.0;
  noise.steeringBiasSigma = deg2rad(0.2);
  noise.scaleBiasSigma = 0.005;
  noise.samplesPerCorrection = 10.0;
  const int M = 10;
  const TricycleParams v = vehicle();
  TricycleOdometry odo(v, noise);
  const double ds = 0.02;
  const double alpha = deg2rad(20.0);
  double modelHeadingVar = 0.0;
  for (int k = 0; k < M; ++k) {
    modelHeadingVar += odo.increment(Timestamp{}, ds, alpha, alpha, false).covariance(2, 2);
  }
  std::mt19937_64 rng(5);
  std::normal_distribution<double> steer(0.0, noise.steeringBiasSigma);
  std::normal_distribution<double> scale(0.0, noise.scaleBiasSigma);
  const int runs = 40000;
  double sum2 = 0.0;
  const double nominal = M * ds * std::sin(alpha) / v.wheelbase;
  for (int r = 0; r < runs; ++r) {
    const double b = steer(rng);
    const double s = scale(rng);
    double theta = 0.0;
    for (int k = 0; k < M; ++k) {
      theta += ds * (1.0 + s) * std::sin(alpha + b) / v.wheelbase;
    }
    sum2 += (theta - nominal) * (theta - nominal);
  }
  // First-order model vs sampled (sampling error ~0.7 %; second-order terms below 0.1 %).
  AGV_CHECK_NEAR(sum2 / runs / modelHeadingVar, 1.0, 0.03);
  // Without the factor M (a white model of the same bias) the prediction would be 10x too small.
  TricycleNoiseParams bad = noise;
  bad.steeringBiasSigma = -1.0;
  CHECK(bad.validate() == Status::InvalidArgument);
  bad = noise;
  bad.scaleBiasSigma = std::nan("");
  CHECK(bad.validate() == Status::NonFiniteInput);
}
