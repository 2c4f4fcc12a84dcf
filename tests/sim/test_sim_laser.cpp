// Simulated laser: ranges against a known room, reflector detection statistics, occlusion,
// no-return handling and parameter validation.
#include <cmath>
#include <vector>

#include "agv/core/angle.hpp"
#include "agv/sim/sim_laser.hpp"
#include "agv_test.hpp"

using agv::Pose2d;
using agv::Status;
using agv::Timestamp;
using agv::sim::Circle;
using agv::sim::ObstacleKind;
using agv::sim::Point2;
using agv::sim::RayCaster;
using agv::sim::SimLaser;
using agv::sim::SimLaserParams;
using agv::sim::World;

namespace {

// A 20 m x 10 m room centred on the origin.
World room() {
  World w;
  agv::sim::WorldParseError e;
  REQUIRE(agv::sim::parseWorld("hall -10 -5 10 5\n", w, e) == Status::Ok);
  return w;
}

// Analytic range from (px, py) at world angle a to the walls of room().
double roomRange(double px, double py, double a) {
  const double c = std::cos(a);
  const double s = std::sin(a);
  double t = 1e300;
  if (c > 1e-12)
    t = std::min(t, (10.0 - px) / c);
  if (c < -1e-12)
    t = std::min(t, (-10.0 - px) / c);
  if (s > 1e-12)
    t = std::min(t, (5.0 - py) / s);
  if (s < -1e-12)
    t = std::min(t, (-5.0 - py) / s);
  return t;
}

}  // namespace

TEST_CASE("Noise-free scan ranges equal the analytic ranges in a room", "[sim][laser]") {
  const World w = room();
  const RayCaster caster(w);
  SimLaserParams p;
  p.rangeNoiseStdDev = 0.0;
  p.reportsReflectors = false;
  SimLaser laser(caster, p, 1);
  REQUIRE(laser.status() == Status::Ok);
  static agv::hal::LaserMeasurement m;
  const Pose2d pose{1.5, -0.7, 0.4};
  REQUIRE(laser.scan(pose, Timestamp::fromSeconds(3.0), m) == Status::Ok);
  REQUIRE(m.scan.size() == 1440U);
  CHECK(m.scan.stamp == Timestamp::fromSeconds(3.0));
  CHECK(m.scan.angleIncrement == Approx(agv::deg2rad(0.25)));
  CHECK(m.scan.fieldOfView() == Approx(agv::kTwoPi<float>));
  CHECK_FALSE(m.hasReflectors);
  for (std::size_t i = 0; i < m.scan.size(); ++i) {
    REQUIRE(m.scan.isValid(i));
    const double expected = roomRange(pose.x, pose.y, pose.theta + static_cast<double>(m.scan.angle(i)));
    CHECK(m.scan.ranges[i] == Approx(expected).epsilon(2e-6));  // float storage
  }
}

TEST_CASE("Range noise has the injected mean and standard deviation", "[sim][laser]") {
  const World w = room();
  const RayCaster caster(w);
  SimLaserParams p;
  p.rangeNoiseStdDev = 0.02;
  p.angularResolution = agv::deg2rad(0.5);
  p.reportsReflectors = false;
  SimLaser laser(caster, p, 7);
  static agv::hal::LaserMeasurement m;
  const Pose2d pose{-2.0, 1.0, -0.3};
  double sum = 0.0;
  double sum2 = 0.0;
  int n = 0;
  for (int k = 0; k < 20; ++k) {
    REQUIRE(laser.scan(pose, Timestamp{}, m) == Status::Ok);
    for (std::size_t i = 0; i < m.scan.size(); ++i) {
      const double err =
          m.scan.ranges[i] - roomRange(pose.x, pose.y, pose.theta + static_cast<double>(m.scan.angle(i)));
      sum += err;
      sum2 += err * err;
      ++n;
    }
  }
  const double mean = sum / n;
  const double sd = std::sqrt(sum2 / n - mean * mean);
  // n = 14400: the mean's sampling std is sigma/sqrt(n) (1.7e-4 m), the std's sigma/sqrt(2n).
  CHECK(std::fabs(mean) < 4.0 * p.rangeNoiseStdDev / std::sqrt(n));
  CHECK(std::fabs(sd - p.rangeNoiseStdDev) < 4.0 * p.rangeNoiseStdDev / std::sqrt(2.0 * n));
}

TEST_CASE("Beams without return carry the no-return value and are invalid", "[sim][laser]") {
  World w;
  w.segments.push_back({{5.0, -1.0}, {5.0, 1.0}, ObstacleKind::Wall});
  const RayCaster caster(w);
  for (float noReturn : {50.0F, 0.0F, std::numeric_limits<float>::infinity()}) {
    SimLaserParams p;
    p.rangeNoiseStdDev = 0.0;
    p.angularResolution = agv::deg2rad(1.0);
    p.fieldOfView = agv::deg2rad(270.0);
    p.noReturnValue = noReturn;
    SimLaser laser(caster, p, 1);
    REQUIRE(laser.status() == Status::Ok);
    static agv::hal::LaserMeasurement m;
    REQUIRE(laser.scan(Pose2d{}, Timestamp{}, m) == Status::Ok);
    REQUIRE(m.scan.size() == 270U);
    CHECK(m.scan.angleMin == Approx(-agv::deg2rad(135.0)));
    int valid = 0;
    for (std::size_t i = 0; i < m.scan.size(); ++i) {
      const double a = static_cast<double>(m.scan.angle(i));
      const bool onWall = std::fabs(std::tan(a) * 5.0) < 1.0 && std::cos(a) > 0.0;
      if (m.scan.isValid(i)) {
        ++valid;
        CHECK(onWall);
        CHECK(m.scan.ranges[i] == Approx(5.0 / std::cos(a)).epsilon(1e-6));
      } else {
        CHECK_FALSE(onWall);
        CHECK(m.scan.ranges[i] == noReturn);  // +inf == +inf: holds for the infinite value too
      }
    }
    CHECK(valid == 23);  // beams within atan(1/5) = 11.3 deg of the axis at 1 deg spacing: -11..11
  }
  // A no-return value that would look valid is refused.
  SimLaserParams bad;
  bad.noReturnValue = 10.0F;
  CHECK(bad.validate() == Status::InvalidArgument);
}

TEST_CASE("Laser parameters are validated", "[sim][laser]") {
  SimLaserParams p;
  CHECK(p.validate() == Status::Ok);
  CHECK(p.beamCount() == 1440U);
  p.angularResolution = agv::deg2rad(0.1);
  CHECK(p.validate() == Status::CapacityExceeded);  // 3600 beams > kMaxScanBeams
  p = SimLaserParams{};
  p.scanRate = 0.0;
  CHECK(p.validate() == Status::InvalidArgument);
  p = SimLaserParams{};
  p.rangeNoiseStdDev = std::nan("");
  CHECK(p.validate() == Status::NonFiniteInput);
  p = SimLaserParams{};
  p.fieldOfView = 7.0;
  CHECK(p.validate() == Status::InvalidArgument);
  const World w = room();
  const RayCaster caster(w);
  SimLaser laser(caster, p, 1);
  static agv::hal::LaserMeasurement m;
  CHECK(laser.scan(Pose2d{}, Timestamp{}, m) == Status::InvalidArgument);
  SimLaser ok(caster, SimLaserParams{}, 1);
  CHECK(ok.scan(Pose2d{std::nan(""), 0.0, 0.0}, Timestamp{}, m) == Status::NonFiniteInput);
}

TEST_CASE("Reflector centres are reported with the injected noise", "[sim][laser][reflector]") {
  World w = room();
  const Point2 centres[] = {{6.0, 2.0}, {-7.0, -3.0}, {2.0, 4.0}};
  for (const Point2& c : centres) {
    w.circles.push_back(Circle{c, 0.04, ObstacleKind::Reflector});
  }
  w.circles.push_back(Circle{{-3.0, 3.0}, 0.2, ObstacleKind::Pillar});  // not a reflector: never reported
  const RayCaster caster(w);
  SimLaserParams p;
  p.reflectorNoiseStdDev = 0.015;
  p.angularResolution = agv::deg2rad(1.0);
  SimLaser laser(caster, p, 11);
  const Pose2d pose{0.5, -1.0, 0.7};
  static agv::hal::LaserMeasurement m;
  // Errors of each reported centre against the nearest true centre, in the sensor frame.
  std::vector<double> ex;
  std::vector<double> ey;
  const int scans = 500;
  for (int k = 0; k < scans; ++k) {
    REQUIRE(laser.scan(pose, Timestamp{}, m) == Status::Ok);
    REQUIRE(m.hasReflectors);
    REQUIRE(m.reflectors.size() == 3U);
    for (const agv::hal::ReflectorObservation& o : m.reflectors) {
      CHECK(o.positionStdDev == Approx(p.reflectorNoiseStdDev));
      double best = 1e9;
      double bx = 0.0;
      double by = 0.0;
      for (const Point2& c : centres) {
        const Pose2d::Vector2 v = pose.inverseTransformPoint(Pose2d::Vector2(c.x, c.y));
        const double dx = o.x - v.x();
        const double dy = o.y - v.y();
        if (dx * dx + dy * dy < best) {
          best = dx * dx + dy * dy;
          bx = dx;
          by = dy;
        }
      }
      ex.push_back(bx);
      ey.push_back(by);
    }
  }
  for (const std::vector<double>* e : {&ex, &ey}) {
    double s = 0.0;
    double s2 = 0.0;
    for (double v : *e) {
      s += v;
      s2 += v * v;
    }
    const double n = static_cast<double>(e->size());
    const double mean = s / n;
    const double sd = std::sqrt(s2 / n - mean * mean);
    const double sigma = p.reflectorNoiseStdDev;
    CHECK(std::fabs(mean) < 4.0 * sigma / std::sqrt(n));
    CHECK(std::fabs(sd - sigma) < 4.0 * sigma / std::sqrt(2.0 * n) + 1e-6);  // + float rounding
  }
}

TEST_CASE("Reflectors hidden, out of range or out of view are not reported", "[sim][laser][reflector]") {
  World w = room();
  w.circles.push_back(Circle{{4.0, 0.0}, 0.25, ObstacleKind::Pillar});      // pillar on the x axis
  w.circles.push_back(Circle{{8.0, 0.0}, 0.04, ObstacleKind::Reflector});   // 0: hidden behind it
  w.circles.push_back(Circle{{0.0, 3.0}, 0.04, ObstacleKind::Reflector});   // 1: visible, at +90 deg
  w.circles.push_back(Circle{{0.0, 4.5}, 0.04, ObstacleKind::Reflector});   // 2: behind reflector 1
  w.circles.push_back(Circle{{-9.0, 0.0}, 0.04, ObstacleKind::Reflector});  // 3: behind the sensor
  w.segments.push_back({{-0.5, -2.0}, {0.5, -2.0}, ObstacleKind::Wall});    // wall in front of 4
  w.circles.push_back(Circle{{0.0, -4.0}, 0.04, ObstacleKind::Reflector});  // 4: hidden by the wall
  const RayCaster caster(w);
  SimLaserParams p;
  p.reflectorNoiseStdDev = 0.0;
  p.fieldOfView = agv::deg2rad(270.0);  // blind sector of 90 deg behind
  p.angularResolution = agv::deg2rad(0.5);
  p.reflectorMaxRange = 30.0;
  SimLaser laser(caster, p, 3);
  static agv::hal::LaserMeasurement m;
  REQUIRE(laser.scan(Pose2d{}, Timestamp{}, m) == Status::Ok);
  REQUIRE(m.reflectors.size() == 1U);
  CHECK(m.reflectors[0].x == Approx(0.0).margin(1e-6));
  CHECK(m.reflectors[0].y == Approx(3.0));

  // The same reflector 1 beyond the detection range is dropped.
  p.reflectorMaxRange = 2.9;
  SimLaser shortRange(caster, p, 3);
  REQUIRE(shortRange.scan(Pose2d{}, Timestamp{}, m) == Status::Ok);
  CHECK(m.reflectors.empty());

  // Turned around (360 deg view), reflector 3 comes into view.
  p.reflectorMaxRange = 30.0;
  p.fieldOfView = agv::kTwoPi<double>;
  SimLaser full(caster, p, 3);
  REQUIRE(full.scan(Pose2d{}, Timestamp{}, m) == Status::Ok);
  CHECK(m.reflectors.size() == 2U);
}

TEST_CASE("A moving sensor's scan is distorted as the pose interpolates over the sweep", "[sim][laser]") {
  const World w = room();
  const RayCaster caster(w);
  SimLaserParams p;
  p.rangeNoiseStdDev = 0.0;
  p.reportsReflectors = false;
  SimLaser laser(caster, p, 1);
  static agv::hal::LaserMeasurement m;
  const Pose2d a{0.0, 0.0, 0.0};
  const Pose2d b{0.08, 0.0, 0.0};  // 1 m/s during an 80 ms sweep
  REQUIRE(laser.scan(a, b, Timestamp{}, m) == Status::Ok);
  const std::size_t n = m.scan.size();
  // First beam (angle -pi, looking back) from x = 0; last beam from x = 0.08 * (n-1)/(n-1).
  CHECK(m.scan.ranges[0] == Approx(10.0).epsilon(1e-5));
  CHECK(m.scan.ranges[n / 2] == Approx(10.0 - 0.04).epsilon(1e-4));  // beam at 0 rad, mid-sweep
  CHECK(laser.sweepDuration().seconds() == Approx(0.08 * 1439.0 / 1440.0));
  // As a LaserSource: one capture, one read.
  CHECK(laser.read(m) == Status::NotFound);
  REQUIRE(laser.capture(a, b, Timestamp::fromSeconds(1.0)) == Status::Ok);
  CHECK(laser.read(m) == Status::Ok);
  CHECK(m.scan.stamp == Timestamp::fromSeconds(1.0));
  CHECK(laser.read(m) == Status::NotFound);
}
