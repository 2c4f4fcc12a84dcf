// The HIL's uniqueness oracle (apps/hil/reloc_oracle.hpp): symmetric layouts are judged not
// unique, asymmetric ones unique, and the visibility rule follows the simulated laser's.
#include <catch.hpp>

#include <cmath>
#include <vector>

#include "agv/sim/ray_caster.hpp"
#include "agv/sim/sim_laser.hpp"
#include "agv/sim/world.hpp"
#include "reloc_oracle.hpp"

namespace {

using agv::Pose2d;
using agv::hil::judgeUniqueness;
using agv::hil::OraclePoint;
using agv::hil::Uniqueness;

/// The landmarks within `range` of `truth`, noise-free, in the vehicle frame (no occlusion).
std::vector<OraclePoint> seenFrom(const std::vector<OraclePoint>& map, const Pose2d& truth, double range) {
  std::vector<OraclePoint> out;
  for (const OraclePoint& l : map) {
    const Pose2d::Vector2 v = truth.inverseTransformPoint(Pose2d::Vector2(l.x, l.y));
    if (v.norm() <= range) {
      out.push_back(OraclePoint{v.x(), v.y()});
    }
  }
  return out;
}

/// 12 poles on the border of a 20 m x 10 m rectangle (corners and edge midpoints and thirds).
std::vector<OraclePoint> rectangle() {
  return {{0, 0}, {10, 0}, {20, 0}, {20, 5}, {20, 10}, {10, 10}, {0, 10}, {0, 5}, {5, 0}, {15, 0}, {5, 10}, {15, 10}};
}

}  // namespace

TEST_CASE("oracle: a point-symmetric layout is not unique", "[hil][reloc_oracle]") {
  const std::vector<OraclePoint> map = rectangle();
  for (const Pose2d truth : {Pose2d{7.0, 4.0, 0.3}, Pose2d{12.5, 6.0, -2.0}, Pose2d{3.0, 2.0, 1.2}}) {
    const Uniqueness u = judgeUniqueness(map, seenFrom(map, truth, 50.0), truth);
    CHECK(u.visible == 12);
    CHECK(u.truthSupport == 12);
    CHECK(u.otherSupport == 12);  // the pose rotated by 180 deg about (10, 5)
    CHECK_FALSE(u.unique);
    const Pose2d mirrored{20.0 - truth.x, 10.0 - truth.y, agv::normalizeAngle(truth.theta + 3.14159265358979)};
    CHECK(std::hypot(u.other.x - mirrored.x, u.other.y - mirrored.y) < 0.05);
  }
}

TEST_CASE("oracle: the rectangle with three poles added on one side is unique", "[hil][reloc_oracle]") {
  std::vector<OraclePoint> map = rectangle();
  map.push_back({2.0, 1.5});
  map.push_back({3.5, 2.5});
  map.push_back({1.0, 3.7});
  const Pose2d truth{8.0, 5.0, 0.7};
  const Uniqueness u = judgeUniqueness(map, seenFrom(map, truth, 50.0), truth);
  CHECK(u.visible == 15);
  CHECK(u.truthSupport == 15);
  CHECK(u.otherSupport < 15);
  CHECK(u.unique);
}

TEST_CASE("oracle: a regular grid seen in part is not unique, an irregular scatter is", "[hil][reloc_oracle]") {
  std::vector<OraclePoint> grid;
  std::vector<OraclePoint> scatter;
  unsigned s = 12345U;
  const auto jitter = [&s]() {
    s = s * 1103515245U + 12345U;
    return (static_cast<double>((s >> 8U) % 1000U) / 1000.0 - 0.5) * 2.0;  // [-1, 1)
  };
  for (int i = 0; i < 8; ++i) {
    for (int j = 0; j < 8; ++j) {
      grid.push_back({6.0 * i, 6.0 * j});
      scatter.push_back({6.0 * i + jitter(), 6.0 * j + jitter()});
    }
  }
  const Pose2d truth{21.0, 20.0, 0.4};
  const Uniqueness g = judgeUniqueness(grid, seenFrom(grid, truth, 10.0), truth);
  CHECK(g.visible >= 4);
  CHECK_FALSE(g.unique);  // shifted by one grid step, or turned by 90 deg
  const Uniqueness r = judgeUniqueness(scatter, seenFrom(scatter, truth, 10.0), truth);
  CHECK(r.visible >= 4);
  CHECK(r.unique);
}

TEST_CASE("oracle: fewer than two observations never fix a pose", "[hil][reloc_oracle]") {
  std::vector<OraclePoint> map = rectangle();
  map.push_back({2.0, 1.5});
  const Pose2d truth{1.0, 1.0, 0.0};
  CHECK_FALSE(judgeUniqueness(map, {}, truth).unique);
  CHECK_FALSE(judgeUniqueness(map, {OraclePoint{1.0, 0.5}}, truth).unique);
  // Two: the same pair seen the other way round (a 180 deg turn about their midpoint).
  CHECK_FALSE(judgeUniqueness(map, {OraclePoint{1.0, 0.5}, OraclePoint{-1.0, -1.0}}, truth).unique);
}

TEST_CASE("oracle: visibility follows the laser's range and line of sight", "[hil][reloc_oracle]") {
  agv::sim::World world;
  agv::sim::WorldParseError err;
  const char* text =
      "reflector 5 0 0.04\n"
      "reflector 10 0 0.04\n"  // behind the first one, seen from the origin along x
      "reflector 0 5 0.04\n"
      "reflector 40 5 0.04\n";  // beyond the 30 m reflector range
  REQUIRE(agv::sim::parseWorld(text, world, err) == agv::Status::Ok);
  const agv::sim::RayCaster caster(world, 1.0);
  const agv::sim::SimLaserParams laser{};
  const std::vector<OraclePoint> seen = agv::hil::visibleReflectors(caster, laser, Pose2d{0.0, 0.0, 0.0});
  REQUIRE(seen.size() == 2);
  CHECK(seen[0].x == Approx(5.0));
  CHECK(seen[1].y == Approx(5.0));
}

TEST_CASE("oracle: map corners are visible in clear view within range, hidden behind a box", "[hil][reloc_oracle]") {
  agv::sim::World world;
  agv::sim::WorldParseError err;
  // A 20 m x 10 m hall, a pallet block between the laser at (2, 5) and the hall's far corners.
  const char* text =
      "hall 0 0 20 10\n"
      "pallet 8 4 9 6\n";
  REQUIRE(agv::sim::parseWorld(text, world, err) == agv::Status::Ok);
  const agv::sim::RayCaster caster(world, 1.0);
  const agv::sim::SimLaserParams laser{};
  const std::vector<OraclePoint> corners = {{0, 0}, {0, 10}, {20, 0}, {20, 10}, {8, 4}, {9, 5}};
  const Pose2d at{2.0, 5.0, 0.0};
  // (9, 5) is the middle of the block's far side: hidden by its near side. (20, 0) and (20, 10) are
  // in view past the block's corners; within 30 m all but the hidden one are seen.
  std::vector<OraclePoint> seen = agv::hil::visibleMapPoints(caster, laser, at, corners, 30.0);
  REQUIRE(seen.size() == 5);
  for (const OraclePoint& p : seen) {
    CHECK_FALSE((p.x == 9.0 && p.y == 5.0));
  }
  // Within 8 m: the two corners at the laser's end of the hall and the block's near corner.
  seen = agv::hil::visibleMapPoints(caster, laser, at, corners, 8.0);
  CHECK(seen.size() == 3);
  // A laser looking the other way with a 180-deg field of view sees only that end.
  agv::sim::SimLaserParams front = laser;
  front.fieldOfView = 3.14159265358979323846;
  seen = agv::hil::visibleMapPoints(caster, front, Pose2d{2.0, 5.0, 3.14159265358979323846}, corners, 30.0);
  CHECK(seen.size() == 2);
}
