// Motion of the sensor during a sweep: the dead-reckoning history and the compensation of the
// points of a sweep into the sensor frame at its end, against the exact motion of a vehicle on an
// arc; no allocation.
#include <cmath>

#include "agv/core/angle.hpp"
#include "agv/localization/sweep_motion.hpp"
#include "agv_test.hpp"

using namespace agv;

namespace {

/// Exact pose at time t [s] of a vehicle turning at constant speed v [m/s] and yaw rate w [rad/s]
/// from `start` at t = 0.
Pose2d arcPose(const Pose2d& start, double v, double w, double t) {
  const double th = w * t;
  const double dx = std::fabs(w) > 1e-12 ? v / w * std::sin(th) : v * t;
  const double dy = std::fabs(w) > 1e-12 ? v / w * (1.0 - std::cos(th)) : 0.0;
  return start.compose(Pose2d{dx, dy, th});
}

Timestamp at(double s) {
  return Timestamp::fromSeconds(s);
}

/// A 360 deg sweep of 1440 beams taking `sweep` seconds from t = 0 (ranges unused here).
LaserScan sweepOf(double sweep, float angleMin = -kPi<float>) {
  LaserScan s;
  s.stamp = at(0.0);
  s.sweepDuration = Duration::fromSeconds(sweep);
  s.angleMin = angleMin;
  s.angleIncrement = kTwoPi<float> / 1440.0F;
  s.rangeMin = 0.05F;
  s.rangeMax = 30.0F;
  for (int i = 0; i < 1440; ++i) {
    (void)s.ranges.push_back(5.0F);
  }
  return s;
}

}  // namespace

TEST_CASE("motion history: interpolation, limits, refusals, age and capacity", "[localization][sweep]") {
  MotionHistory h;
  CHECK(h.at(at(1.0)).status() == Status::NotEnoughData);
  REQUIRE(h.add(at(1.0), Pose2d{1.0, 2.0, 3.1}) == Status::Ok);
  REQUIRE(h.add(at(1.01), Pose2d{1.2, 1.6, -3.1}) == Status::Ok);
  // Midway: position halfway, heading along the short arc through +-pi (not through 0).
  const Pose2d mid = h.at(at(1.005)).value();
  AGV_CHECK_NEAR(mid.x, 1.1, 1e-12);
  AGV_CHECK_NEAR(mid.y, 1.8, 1e-12);
  AGV_CHECK_NEAR(std::fabs(mid.theta), kPi<double>, 1e-9);
  const Pose2d quarter = h.at(at(1.0025)).value();
  AGV_CHECK_NEAR(angleDiff(quarter.theta, 3.1), 0.25 * (kTwoPi<double> - 6.2), 1e-9);
  // Outside the stored interval: the end poses.
  CHECK(h.at(at(0.5)).value().x == 1.0);
  CHECK(h.at(at(2.0)).value().x == 1.2);
  // Refused: not after the newest, non-finite; nothing changes.
  CHECK(h.add(at(1.01), Pose2d{}) == Status::InvalidArgument);
  CHECK(h.add(at(0.9), Pose2d{}) == Status::InvalidArgument);
  CHECK(h.add(at(1.02), Pose2d{std::nan(""), 0.0, 0.0}) == Status::NonFiniteInput);
  CHECK(h.add(at(1.02), Pose2d{0.0, INFINITY, 0.0}) == Status::NonFiniteInput);
  CHECK(h.size() == 2U);

  // 100 Hz for 1 s: the default 0.5 s window keeps the newest 51 poses.
  MotionHistory aged;
  for (int k = 0; k <= 100; ++k) {
    REQUIRE(aged.add(at(0.01 * k), Pose2d{0.01 * k, 0.0, 0.0}) == Status::Ok);
  }
  CHECK(aged.size() == 51U);
  CHECK(aged.oldest() == at(0.5));
  CHECK(aged.newest() == at(1.0));
  // Poses far apart in time: the two newest stay whatever their age.
  MotionHistory sparse;
  REQUIRE(sparse.add(at(0.0), Pose2d{}) == Status::Ok);
  REQUIRE(sparse.add(at(10.0), Pose2d{1.0, 0.0, 0.0}) == Status::Ok);
  REQUIRE(sparse.add(at(20.0), Pose2d{2.0, 0.0, 0.0}) == Status::Ok);
  CHECK(sparse.size() == 2U);
  AGV_CHECK_NEAR(sparse.at(at(15.0)).value().x, 1.5, 1e-12);
  // Capacity: a long window at 1 kHz keeps the newest kCapacity poses.
  MotionHistory full(Duration::fromSeconds(100.0));
  for (int k = 0; k < 300; ++k) {
    REQUIRE(full.add(at(0.001 * k), Pose2d{static_cast<double>(k), 0.0, 0.0}) == Status::Ok);
  }
  CHECK(full.size() == MotionHistory::kCapacity);
  CHECK(full.at(at(0.0)).value().x == static_cast<double>(300 - MotionHistory::kCapacity));
  AGV_CHECK_NEAR(full.at(at(0.2985)).value().x, 298.5, 1e-9);
}

TEST_CASE("sweep compensation: points of a sweep on a turning vehicle land where they are at its end",
          "[localization][sweep]") {
  const Pose2d start{4.0, -2.0, 0.7};
  const Pose2d mount{0.8, 0.1, 0.05};
  const double sweep = 0.04;  // 25 Hz scanner
  const LaserScan scan = sweepOf(sweep);
  const Pose2d worldPoints[] = {{9.0, 1.0, 0}, {1.0, 3.0, 0}, {-1.0, -4.0, 0}, {6.0, -7.0, 0}, {2.5, -1.0, 0}};
  for (const double v : {0.0, 1.5, -1.0}) {
    for (const double w : {0.0, 0.5, -0.8}) {
      INFO("v " << v << " w " << w);
      // Dead reckoning at 100 Hz around the sweep.
      MotionHistory h;
      for (int k = -30; k <= 10; ++k) {
        REQUIRE(h.add(at(0.01 * k), arcPose(start, v, w, 0.01 * k)) == Status::Ok);
      }
      const SweepCompensation comp(h, scan, mount);
      CHECK(comp.referenceStamp() == at(sweep));
      const Pose2d sensorEnd = arcPose(start, v, w, sweep).compose(mount);
      double worstRaw = 0.0;
      for (const Pose2d& wp : worldPoints) {
        // The sweep fraction at which the turning beam meets the point (fixed point of the
        // bearing seen from the pose at that instant).
        double f = 0.5;
        Pose2d::Vector2 seen;
        for (int it = 0; it < 50; ++it) {
          const Pose2d sensor = arcPose(start, v, w, f * sweep).compose(mount);
          seen = sensor.inverseTransformPoint(Pose2d::Vector2(wp.x, wp.y));
          f = comp.fractionOf(seen.x(), seen.y());
        }
        const Pose2d::Vector2 truth = sensorEnd.inverseTransformPoint(Pose2d::Vector2(wp.x, wp.y));
        const Pose2d::Vector2 fixed = comp.atFraction(f, seen.x(), seen.y());
        // Linear interpolation of 10 ms poses on the arc: the chord sagitta (v dt)^2 (w/v) / 8
        // is below 2e-5 m here; headings are exact.
        CHECK((fixed - truth).norm() < 5e-5);
        CHECK((comp.atBearing(seen.x(), seen.y()) - fixed).norm() < 1e-12);
        worstRaw = std::max(worstRaw, (seen - truth).norm());
      }
      if (v != 0.0 || w != 0.0) {
        CHECK(worstRaw > 0.01);  // without compensation: centimetres off
      } else {
        CHECK(worstRaw == 0.0);
      }
    }
  }
}

TEST_CASE("sweep compensation: beams, bearings from any angle_min, and nothing to compensate",
          "[localization][sweep]") {
  MotionHistory h;
  for (int k = -10; k <= 10; ++k) {
    REQUIRE(h.add(at(0.01 * k), arcPose(Pose2d{}, 1.0, 0.3, 0.01 * k)) == Status::Ok);
  }
  const Pose2d mount{0.5, 0.0, 0.0};
  const LaserScan scan = sweepOf(0.08);
  const SweepCompensation comp(h, scan, mount);
  // Beam k is fraction k / (n - 1).
  for (std::size_t k : {std::size_t{0}, std::size_t{100}, std::size_t{1439}}) {
    const Pose2d::Vector2 a = comp.atBeam(k, 3.0, -2.0);
    const Pose2d::Vector2 b = comp.atFraction(static_cast<double>(k) / 1439.0, 3.0, -2.0);
    CHECK(a.x() == b.x());
    CHECK(a.y() == b.y());
  }
  // The last beam is seen at the end of the sweep: unchanged. Fractions are clamped.
  AGV_CHECK_NEAR(comp.atBeam(1439, 3.0, -2.0).x(), 3.0, 1e-12);
  CHECK(comp.atFraction(1.5, 3.0, -2.0).x() == comp.atFraction(1.0, 3.0, -2.0).x());
  CHECK(comp.atFraction(-0.5, 3.0, -2.0).x() == comp.atFraction(0.0, 3.0, -2.0).x());
  // Bearings: from angle_min = -pi, a point straight ahead is half-way; a scanner whose beams
  // start at 0 (0..360 deg) sees a point at -90 deg three quarters through.
  AGV_CHECK_NEAR(comp.fractionOf(2.0, 0.0), 720.0 / 1439.0, 1e-6);
  const LaserScan from0 = sweepOf(0.08, 0.0F);
  const SweepCompensation comp0(h, from0, mount);
  AGV_CHECK_NEAR(comp0.fractionOf(0.0, -2.0), 1080.0 / 1439.0, 1e-6);
  AGV_CHECK_NEAR(comp0.fractionOf(2.0, 0.0), 0.0, 1e-12);

  // Nothing to compensate with: no history, a vehicle standing still, a zero sweep duration.
  const MotionHistory empty;
  MotionHistory still;
  REQUIRE(still.add(at(-0.1), Pose2d{1.0, 1.0, 1.0}) == Status::Ok);
  REQUIRE(still.add(at(0.1), Pose2d{1.0, 1.0, 1.0}) == Status::Ok);
  const LaserScan instant = sweepOf(0.0);
  for (const SweepCompensation& c : {SweepCompensation(empty, scan, mount), SweepCompensation(still, scan, mount),
                                     SweepCompensation(h, instant, mount)}) {
    const Pose2d::Vector2 p = c.atBeam(0, 3.0, -2.0);
    CHECK(p.x() == 3.0);
    CHECK(p.y() == -2.0);
  }
}

TEST_CASE("sweep compensation: points stamped by the sensor (a NAV350 stamps each reflector)",
          "[localization][sweep]") {
  // A NAV350-like reply: reflectors seen during a 125 ms rotation (8 Hz), the reply received
  // 20 ms after the last of them; no beams, no sweep duration: the reference is the reception.
  const Pose2d start{-3.0, 6.0, -2.2};
  const Pose2d mount{1.1, -0.2, 0.03};
  LaserScan reply;
  reply.stamp = at(0.145);
  const Pose2d worldPoints[] = {{2.0, 9.0, 0}, {-9.0, 4.0, 0}, {-4.0, -3.0, 0}, {5.0, 1.0, 0}};
  const double seenAt[] = {0.0, 0.04, 0.09, 0.125};
  for (const double v : {0.0, 1.2, -0.8}) {
    for (const double w : {0.0, 0.6, -0.4}) {
      INFO("v " << v << " w " << w);
      MotionHistory h;
      for (int k = -20; k <= 20; ++k) {
        REQUIRE(h.add(at(0.01 * k), arcPose(start, v, w, 0.01 * k)) == Status::Ok);
      }
      const SweepCompensation comp(h, reply, mount);
      CHECK(comp.referenceStamp() == reply.stamp);
      const Pose2d sensorRef = arcPose(start, v, w, 0.145).compose(mount);
      double worstRaw = 0.0;
      for (std::size_t i = 0; i < 4; ++i) {
        const Pose2d sensor = arcPose(start, v, w, seenAt[i]).compose(mount);
        const Pose2d::Vector2 wp(worldPoints[i].x, worldPoints[i].y);
        const Pose2d::Vector2 seen = sensor.inverseTransformPoint(wp);
        const Pose2d::Vector2 truth = sensorRef.inverseTransformPoint(wp);
        // As in the sweep above: 10 ms poses interpolated on the arc, sagitta below 2e-5 m.
        CHECK((comp.atStamp(at(seenAt[i]), seen.x(), seen.y()) - truth).norm() < 5e-5);
        worstRaw = std::max(worstRaw, (seen - truth).norm());
      }
      if (v != 0.0 || w != 0.0) {
        CHECK(worstRaw > 0.05);  // 145 ms of motion: decimetres off without it
      } else {
        CHECK(worstRaw == 0.0);
      }
    }
  }
  // With a timed sweep, a stamp is the same as the sweep fraction it falls at.
  MotionHistory h;
  for (int k = -10; k <= 10; ++k) {
    REQUIRE(h.add(at(0.01 * k), arcPose(Pose2d{}, 1.0, 0.3, 0.01 * k)) == Status::Ok);
  }
  const LaserScan scan = sweepOf(0.08);
  const SweepCompensation timed(h, scan, mount);
  for (const double f : {0.0, 0.3, 1.0}) {
    const Pose2d::Vector2 a = timed.atStamp(at(0.08 * f), 3.0, -2.0);
    const Pose2d::Vector2 b = timed.atFraction(f, 3.0, -2.0);
    AGV_CHECK_NEAR(a.x(), b.x(), 1e-12);
    AGV_CHECK_NEAR(a.y(), b.y(), 1e-12);
  }
  // No history: nothing to compensate with.
  const MotionHistory empty;
  const SweepCompensation none(empty, reply, mount);
  CHECK(none.atStamp(at(0.0), 3.0, -2.0).x() == 3.0);
  CHECK(none.atStamp(at(0.0), 3.0, -2.0).y() == -2.0);
}

TEST_CASE("sweep compensation allocates nothing", "[localization][sweep]") {
  static MotionHistory h;
  static const LaserScan scan = sweepOf(0.04);
  double sum = 0.0;
  AGV_CHECK_NO_ALLOCATIONS(
      for (int k = -20; k <= 300; ++k) { (void)h.add(at(0.01 * k), arcPose(Pose2d{}, 1.0, 0.2, 0.01 * k)); });
  AGV_CHECK_NO_ALLOCATIONS({
    const SweepCompensation comp(h, scan, Pose2d{0.3, 0.0, 0.0});
    for (std::size_t k = 0; k < scan.size(); ++k) {
      sum += comp.atBeam(k, 2.0, 1.0).x() + comp.atBearing(-1.0, 3.0).y() + comp.atStamp(at(0.01), 1.0, 1.0).x();
    }
  });
  CHECK(std::isfinite(sum));
}
