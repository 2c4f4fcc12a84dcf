// A few localizer cycles on a tiny scene; portable subset, also run in the Cortex-M7 image (no
// heap there: the image's symbol check proves the cycle links no allocator).
#include "agv/localization/localizer.hpp"
#include "agv/localization/odometry.hpp"
#include "agv_test.hpp"

using namespace agv;

TEST_CASE("localizer: tricycle odometry and reflector corrections converge on a tiny scene", "[localization][mcu]") {
  static LandmarkMap map;
  static Localizer loc;
  static ScanObservations scan;
  map.clear();
  const double pts[4][2] = {{6.0, 2.0}, {5.0, -3.0}, {9.0, 0.5}, {3.0, 4.0}};
  for (std::uint32_t i = 0; i < 4; ++i) {
    REQUIRE(map.addSurveyed(LandmarkKind::Reflector, pts[i][0], pts[i][1], 0.0, i + 1U).ok());
  }
  Eigen::Matrix3d P0 = Eigen::Matrix3d::Zero();
  P0(0, 0) = 4e-4;
  P0(1, 1) = 4e-4;
  P0(2, 2) = 1e-4;
  Timestamp t = Timestamp::fromSeconds(1.0);
  // the estimate starts 1.5 cm / 0.3 deg off the truth (the origin)
  REQUIRE(loc.reset(t, Pose2d{0.015, -0.01, 0.005}, P0) == Status::Ok);
  TricycleParams veh;
  TricycleOdometry odo(veh, TricycleNoiseParams{});
  TricycleSample s;
  s.stamp = t;
  CHECK(odo.step(s).status() == Status::NotEnoughData);
  Pose2d truth{};
  const Pose2d laser = loc.params().laser.mounting;
  for (int cycle = 0; cycle < 5; ++cycle) {
    for (int k = 0; k < 10; ++k) {
      t = t + Duration::fromMilliseconds(10);
      s.stamp = t;
      s.driveTicks += 20;  // 1 cm per sample, straight
      const auto inc = odo.step(s);
      REQUIRE(inc.ok());
      REQUIRE(loc.predict(inc.value()) == Status::Ok);
      truth = truth.compose(tricycleArc(20.0 * veh.driveScale, 0.0, veh.wheelbase));
    }
    scan.stamp = t;
    scan.points.clear();
    const Pose2d lw = truth.compose(laser);
    for (const auto& p : pts) {
      const Eigen::Vector2d z = lw.inverseTransformPoint(Eigen::Vector2d(p[0], p[1]));
      REQUIRE(scan.points.push_back(PointObservation{z.x(), z.y(), LandmarkKind::Reflector}) == Status::Ok);
    }
    AGV_CHECK_NO_ALLOCATIONS((void)loc.correct(scan, map));
    CHECK(loc.health().used == 4U);
    CHECK_FALSE(loc.health().lost);
  }
  AGV_CHECK_NEAR(loc.pose().x, truth.x, 0.002);
  AGV_CHECK_NEAR(loc.pose().y, truth.y, 0.002);
  AGV_CHECK_NEAR(loc.pose().theta, truth.theta, 0.0005);
}
