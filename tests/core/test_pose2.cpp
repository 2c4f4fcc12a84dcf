#include <random>

#include "agv/core/angle.hpp"
#include "agv/core/pose2.hpp"
#include "agv_test.hpp"

namespace {
using agv::Pose2d;
using agv::Pose2f;

Pose2d randomPose(std::mt19937& rng) {
  std::uniform_real_distribution<double> pos(-50.0, 50.0);
  std::uniform_real_distribution<double> ang(-3.14159, 3.14159);
  return {pos(rng), pos(rng), ang(rng)};
}

bool near(const Pose2d& a, const Pose2d& b, double tol) {
  return std::fabs(a.x - b.x) <= tol && std::fabs(a.y - b.y) <= tol &&
         std::fabs(agv::angleDiff(a.theta, b.theta)) <= tol;
}
}  // namespace

TEST_CASE("normalizeAngle wraps into (-pi, pi]", "[core][angle]") {
  const double pi = agv::kPi<double>;
  AGV_CHECK_NEAR(agv::normalizeAngle(3.0 * pi), pi, 1e-12);
  AGV_CHECK_NEAR(agv::normalizeAngle(-pi), pi, 1e-12);  // -pi is mapped to +pi
  AGV_CHECK_NEAR(agv::normalizeAngle(pi), pi, 1e-12);
  AGV_CHECK_NEAR(agv::normalizeAngle(2.0 * pi + 0.25), 0.25, 1e-12);
  AGV_CHECK_NEAR(agv::normalizeAngle(-1000.0 * pi - 0.5), -0.5, 1e-9);
  AGV_CHECK_NEAR(agv::normalizeAngle(1e6), std::remainder(1e6, 2.0 * pi), 1e-9);
  CHECK(std::isnan(agv::normalizeAngle(std::nan(""))));
  CHECK(std::isnan(agv::normalizeAngle(HUGE_VAL)));
  for (int k = -200; k <= 200; ++k) {
    const double a = agv::normalizeAngle(0.1 * k);
    CHECK(a > -pi);
    CHECK(a <= pi);
    AGV_CHECK_NEAR(std::cos(a), std::cos(0.1 * k), 1e-12);
    AGV_CHECK_NEAR(std::sin(a), std::sin(0.1 * k), 1e-12);
  }
  // single precision (scan geometry)
  const float af = agv::normalizeAngle(7.0F);
  AGV_CHECK_NEAR(af, 7.0F - agv::kTwoPi<float>, 1e-6);
  AGV_CHECK_NEAR(agv::angleDiff(agv::deg2rad(179.0), agv::deg2rad(-179.0)), agv::deg2rad(-2.0), 1e-12);
  AGV_CHECK_NEAR(agv::rad2deg(agv::deg2rad(37.5)), 37.5, 1e-12);
}

TEST_CASE("compose and transformPoint match hand-computed values", "[core][pose2]") {
  const double half_pi = agv::kPi<double> / 2.0;
  const Pose2d a{1.0, 2.0, half_pi};
  const Pose2d b{1.0, 0.0, 0.0};
  const Pose2d ab = a.compose(b);  // one metre along a's heading (+y)
  AGV_CHECK_NEAR(ab.x, 1.0, 1e-12);
  AGV_CHECK_NEAR(ab.y, 3.0, 1e-12);
  AGV_CHECK_NEAR(ab.theta, half_pi, 1e-12);
  const Pose2d::Vector2 p = a.transformPoint(Pose2d::Vector2(0.0, 1.0));  // left of a = -x
  AGV_CHECK_NEAR(p.x(), 0.0, 1e-12);
  AGV_CHECK_NEAR(p.y(), 2.0, 1e-12);
  const Pose2d inv = a.inverse();  // origin seen from a
  AGV_CHECK_NEAR(inv.x, -2.0, 1e-12);
  AGV_CHECK_NEAR(inv.y, 1.0, 1e-12);
  AGV_CHECK_NEAR(inv.theta, -half_pi, 1e-12);
  // angles stay normalised through compose
  const Pose2d c = Pose2d{0.0, 0.0, 3.0}.compose(Pose2d{0.0, 0.0, 3.0});
  AGV_CHECK_NEAR(c.theta, 6.0 - agv::kTwoPi<double>, 1e-12);
}

TEST_CASE("SE(2) group properties hold for random poses", "[core][pose2]") {
  std::mt19937 rng(12345U);
  const Pose2d identity{};
  for (int i = 0; i < 200; ++i) {
    const Pose2d a = randomPose(rng);
    const Pose2d b = randomPose(rng);
    const Pose2d c = randomPose(rng);
    CHECK(near(a.compose(a.inverse()), identity, 1e-9));
    CHECK(near(a.inverse().compose(a), identity, 1e-9));
    CHECK(near(a.compose(b).compose(c), a.compose(b.compose(c)), 1e-9));  // associativity
    CHECK(near(agv::between(a, a.compose(b)), b, 1e-9));                  // relative pose round trip
    CHECK(near(agv::between(a, b), a.inverse().compose(b), 1e-9));
    CHECK(near(a * b, a.compose(b), 0.0));
    CHECK(near(a.inverse().inverse(), a, 1e-9));
    const Pose2d::Vector2 q = b.translation();
    const Pose2d::Vector2 tq = a.transformPoint(q);
    const Pose2d ab = a.compose(b);
    AGV_CHECK_NEAR(tq.x(), ab.x, 1e-9);
    AGV_CHECK_NEAR(tq.y(), ab.y, 1e-9);
    const Pose2d::Vector2 back = a.inverseTransformPoint(tq);
    AGV_CHECK_NEAR(back.x(), q.x(), 1e-9);
    AGV_CHECK_NEAR(back.y(), q.y(), 1e-9);
    // distances are invariant under a rigid transform
    const Pose2d::Vector2 r = c.translation();
    AGV_CHECK_NEAR((a.transformPoint(q) - a.transformPoint(r)).norm(), (q - r).norm(), 1e-9);
    // rotation() agrees with transformPoint
    const Pose2d::Vector2 viaMatrix = a.rotation() * q + a.translation();
    AGV_CHECK_NEAR(viaMatrix.x(), tq.x(), 1e-9);
    AGV_CHECK_NEAR(viaMatrix.y(), tq.y(), 1e-9);
  }
}

TEST_CASE("single-precision poses agree with double within float resolution", "[core][pose2]") {
  std::mt19937 rng(777U);
  for (int i = 0; i < 100; ++i) {
    const Pose2d a = randomPose(rng);
    const Pose2d b = randomPose(rng);
    const Pose2f af = a.cast<float>();
    const Pose2f bf = b.cast<float>();
    const Pose2d abf = af.compose(bf).cast<double>();
    // |coordinates| <= ~120 m: float resolution ~8e-6 m, a few roundings in compose
    CHECK(near(abf, a.compose(b), 1e-4));
  }
  CHECK(Pose2d{1.0, 2.0, 0.3}.isFinite());
  CHECK_FALSE(Pose2d{std::nan(""), 2.0, 0.3}.isFinite());
  CHECK_FALSE(Pose2d{1.0, HUGE_VAL, 0.3}.isFinite());
}

TEST_CASE("pose operations never allocate", "[core][pose2][alloc]") {
  std::mt19937 rng(1U);
  const Pose2d a = randomPose(rng);
  Pose2d acc{};
  AGV_CHECK_NO_ALLOCATIONS(for (int i = 0; i < 100; ++i) { acc = acc.compose(a).compose(agv::between(a, acc)); });
  CHECK(acc.isFinite());
}
