#include "agv/kinematics/tricycle.hpp"
#include "agv_test.hpp"

TEST_CASE("tricycle arc: straight line, pure rotation limit and full circle", "[core][kinematics]") {
  const double L = 1.5;
  const agv::Pose2d straight = agv::tricycleArc(2.0, 0.0, L);
  AGV_CHECK_NEAR(straight.x, 2.0, 1e-15);
  AGV_CHECK_NEAR(straight.y, 0.0, 1e-15);
  AGV_CHECK_NEAR(straight.theta, 0.0, 1e-15);
  // Steering at 90 deg: the vehicle turns on the spot about the logical point.
  const agv::Pose2d spin = agv::tricycleArc(0.5, agv::kPi<double> / 2.0, L);
  AGV_CHECK_NEAR(spin.x, 0.0, 1e-12);
  AGV_CHECK_NEAR(spin.y, 0.0, 1e-12);
  AGV_CHECK_NEAR(spin.theta, 0.5 / L, 1e-12);
  // Radius of the logical point's circle is L / tan(alpha); a full turn returns to the start.
  const double alpha = agv::deg2rad(30.0);
  const double fullTurnDs = agv::kTwoPi<double> * L / std::sin(alpha);
  const agv::Pose2d full = agv::tricycleArc(fullTurnDs, alpha, L);
  AGV_CHECK_NEAR(full.x, 0.0, 1e-9);
  AGV_CHECK_NEAR(full.y, 0.0, 1e-9);
  // A half turn ends 2R to the left.
  const agv::Pose2d half = agv::tricycleArc(0.5 * fullTurnDs, alpha, L);
  AGV_CHECK_NEAR(half.x, 0.0, 1e-9);
  AGV_CHECK_NEAR(half.y, 2.0 * L / std::tan(alpha), 1e-9);
  // Backward motion undoes forward motion.
  const agv::Pose2d fwd = agv::tricycleArc(1.3, alpha, L);
  const agv::Pose2d back = agv::tricycleArc(-1.3, alpha, L);
  const agv::Pose2d round = fwd.compose(back);
  AGV_CHECK_NEAR(round.x, 0.0, 1e-12);
  AGV_CHECK_NEAR(round.y, 0.0, 1e-12);
  AGV_CHECK_NEAR(round.theta, 0.0, 1e-12);
}

TEST_CASE("tricycle arc is continuous through the small-angle series", "[core][kinematics]") {
  const double L = 1.5;
  for (double a = -2e-4; a <= 2e-4; a += 1e-5) {
    const agv::Pose2d p = agv::tricycleArc(1.0, a, L);
    // first-order: x = cos a, y ~ t/2 with t = sin(a)/L
    AGV_CHECK_NEAR(p.x, std::cos(a) * (1.0 - std::pow(std::sin(a) / L, 2) / 6.0), 1e-12);
    AGV_CHECK_NEAR(p.y, std::cos(a) * 0.5 * std::sin(a) / L, 1e-12);
  }
}

TEST_CASE("RK2 steps integrate a constant-steering arc to third order", "[core][kinematics]") {
  const double L = 1.5;
  const double alpha = agv::deg2rad(25.0);
  const double total = 3.0;
  const agv::Pose2d exact = agv::tricycleArc(total, alpha, L);
  double errPrev = 0.0;
  for (int n : {10, 20, 40}) {
    agv::Pose2d p{};
    for (int i = 0; i < n; ++i) {
      p = agv::tricycleRk2Step(p, total / n, alpha, alpha, L);
    }
    const double err = std::hypot(p.x - exact.x, p.y - exact.y);
    if (errPrev > 0.0) {
      // global error O(h^2): halving the step divides it by ~4
      CHECK(errPrev / err > 3.5);
      CHECK(errPrev / err < 4.5);
    }
    errPrev = err;
    AGV_CHECK_NEAR(p.theta, exact.theta, 1e-12);  // heading is integrated exactly
  }
  CHECK(errPrev < 1e-3);
}
