// Ray casting against geometry whose ranges are known in closed form.
#include <cmath>
#include <random>

#include "agv/core/angle.hpp"
#include "agv/sim/ray_caster.hpp"
#include "agv_test.hpp"

using agv::sim::Circle;
using agv::sim::ObstacleKind;
using agv::sim::Point2;
using agv::sim::RayCaster;
using agv::sim::Segment;
using agv::sim::World;

TEST_CASE("A wall at distance D is hit at D / cos(angle)", "[sim][raycast]") {
  World w;
  w.segments.push_back(Segment{{5.0, -10.0}, {5.0, 10.0}, ObstacleKind::Wall});
  const RayCaster caster(w, 0.7);
  const double limit = std::atan(10.0 / 5.0);
  for (double a = -1.5; a <= 1.5; a += 0.01) {
    const agv::sim::RayHit h = caster.cast(Point2{0.0, 0.0}, a, 100.0);
    if (std::fabs(a) < limit - 1e-6) {
      REQUIRE(h.hit);
      CHECK(h.range == Approx(5.0 / std::cos(a)).epsilon(1e-12));
      CHECK_FALSE(h.circle);
    } else if (std::fabs(a) > limit + 1e-6) {
      CHECK_FALSE(h.hit);
    }
  }
  // Behind the origin and beyond the range limit: no hit.
  CHECK_FALSE(caster.cast(Point2{0.0, 0.0}, agv::kPi<double>, 100.0).hit);
  CHECK_FALSE(caster.cast(Point2{0.0, 0.0}, 0.0, 4.99).hit);
  // A ray parallel to the wall does not hit it.
  CHECK_FALSE(caster.cast(Point2{5.0, -20.0}, agv::kPi<double> / 2, 100.0).hit);
  // Origins outside the grid: a ray entering from far away still hits.
  const agv::sim::RayHit far = caster.cast(Point2{-50.0, 3.0}, 0.0, 100.0);
  REQUIRE(far.hit);
  CHECK(far.range == Approx(55.0));
}

TEST_CASE("A pole of radius r at distance d is hit at d - r on its centre ray", "[sim][raycast]") {
  World w;
  const double r = 0.04;
  const Point2 c{7.0, 3.0};
  w.circles.push_back(Circle{c, r, ObstacleKind::Reflector});
  const RayCaster caster(w, 1.0);
  const double d = std::hypot(c.x, c.y);
  const double phi0 = std::atan2(c.y, c.x);
  const agv::sim::RayHit h = caster.cast(Point2{0.0, 0.0}, phi0, 50.0);
  REQUIRE(h.hit);
  CHECK(h.circle);
  CHECK(h.index == 0U);
  CHECK(h.range == Approx(d - r).epsilon(1e-12));
  // Off-centre rays: t = d cos(phi) - sqrt(r^2 - d^2 sin^2(phi)), none beyond asin(r / d).
  const double half = std::asin(r / d);
  for (int k = -20; k <= 20; ++k) {
    const double phi = half * k / 20.0 * 0.999;
    const agv::sim::RayHit hk = caster.cast(Point2{0.0, 0.0}, phi0 + phi, 50.0);
    REQUIRE(hk.hit);
    const double s = std::sin(phi);
    CHECK(hk.range == Approx(d * std::cos(phi) - std::sqrt(r * r - d * d * s * s)).epsilon(1e-9));
  }
  CHECK_FALSE(caster.cast(Point2{0.0, 0.0}, phi0 + half * 1.01, 50.0).hit);
  // From inside the pole the boundary is ahead at r.
  const agv::sim::RayHit inside = caster.cast(c, 0.3, 50.0);
  REQUIRE(inside.hit);
  CHECK(inside.range == Approx(r));
}

TEST_CASE("The nearer of two obstacles on a ray is reported (occlusion)", "[sim][raycast]") {
  World w;
  w.segments.push_back(Segment{{10.0, -1.0}, {10.0, 1.0}, ObstacleKind::Wall});
  w.circles.push_back(Circle{{4.0, 0.0}, 0.25, ObstacleKind::Pillar});
  const RayCaster caster(w, 1.0);
  const agv::sim::RayHit h = caster.cast(Point2{0.0, 0.0}, 0.0, 50.0);
  REQUIRE(h.hit);
  CHECK(h.circle);
  CHECK(h.range == Approx(3.75));
  const agv::sim::RayHit past = caster.cast(Point2{0.0, 0.6}, 0.0, 50.0);  // passes above the pillar
  REQUIRE(past.hit);
  CHECK_FALSE(past.circle);
  CHECK(past.range == Approx(10.0));
}

namespace {
Point2 rotate(const Point2& p, const Point2& pivot, double a) {
  const double c = std::cos(a);
  const double s = std::sin(a);
  const double x = p.x - pivot.x;
  const double y = p.y - pivot.y;
  return Point2{pivot.x + c * x - s * y, pivot.y + s * x + c * y};
}
}  // namespace

TEST_CASE("Ranges are invariant under a rigid rotation of world and sensor", "[sim][raycast]") {
  World a;
  agv::sim::WorldParseError e;
  REQUIRE(agv::sim::parseWorld(agv::sim::defaultWorldText(), a, e) == agv::Status::Ok);
  const Point2 pivot{20.0, 12.0};
  for (double rot : {0.3, 1.0, -2.2, agv::kPi<double> / 2}) {
    World b = a;
    for (Segment& s : b.segments) {
      s.a = rotate(s.a, pivot, rot);
      s.b = rotate(s.b, pivot, rot);
    }
    for (Circle& c : b.circles) {
      c.centre = rotate(c.centre, pivot, rot);
    }
    const RayCaster ca(a, 1.0);
    const RayCaster cb(b, 1.3);  // a different grid too: the result must not depend on it
    const Point2 o{18.0, 10.0};
    const Point2 ob = rotate(o, pivot, rot);
    for (int i = 0; i < 720; ++i) {
      const double ang = -agv::kPi<double> + i * agv::kTwoPi<double> / 720;
      const agv::sim::RayHit ha = ca.cast(o, ang, 60.0);
      const agv::sim::RayHit hb = cb.cast(ob, ang + rot, 60.0);
      REQUIRE(ha.hit == hb.hit);
      CHECK(ha.range == Approx(hb.range).margin(1e-9));
    }
  }
}

TEST_CASE("The grid gives the brute-force result on the warehouse", "[sim][raycast]") {
  World w;
  agv::sim::WorldParseError e;
  REQUIRE(agv::sim::parseWorld(agv::sim::defaultWorldText(), w, e) == agv::Status::Ok);
  const RayCaster caster(w, 1.0);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> ux(-5.0, 45.0);
  std::uniform_real_distribution<double> uy(-5.0, 30.0);
  std::uniform_real_distribution<double> ua(-agv::kPi<double>, agv::kPi<double>);
  int mismatches = 0;
  for (int i = 0; i < 20000; ++i) {
    const Point2 o{ux(rng), uy(rng)};
    const double a = ua(rng);
    const agv::sim::RayHit g = caster.cast(o, a, 30.0);
    const agv::sim::RayHit b = caster.castBruteForce(o, a, 30.0);
    if (g.hit != b.hit || std::fabs(g.range - b.range) > 1e-9) {
      ++mismatches;
    }
  }
  CHECK(mismatches == 0);
}

TEST_CASE("Degenerate rays return no hit", "[sim][raycast]") {
  World w;
  w.segments.push_back(Segment{{5.0, -10.0}, {5.0, 10.0}, ObstacleKind::Wall});
  const RayCaster caster(w);
  CHECK_FALSE(caster.cast(Point2{0.0, 0.0}, std::nan(""), 10.0).hit);
  CHECK_FALSE(caster.cast(Point2{std::nan(""), 0.0}, 0.0, 10.0).hit);
  CHECK_FALSE(caster.cast(Point2{0.0, 0.0}, 0.0, 0.0).hit);
  CHECK_FALSE(caster.cast(Point2{0.0, 0.0}, 0.0, -1.0).hit);
}

TEST_CASE("A huge world gets a coarser grid and still casts exactly", "[sim][raycast]") {
  World w;
  w.segments.push_back(Segment{{0.0, 0.0}, {100000.0, 0.0}, ObstacleKind::Wall});
  w.segments.push_back(Segment{{100000.0, 0.0}, {100000.0, 50000.0}, ObstacleKind::Wall});
  const RayCaster caster(w, 0.5);
  CHECK(static_cast<double>(caster.cellsX()) * caster.cellsY() <= 4.0e6);
  CHECK(caster.cellSize() > 0.5);
  const agv::sim::RayHit h = caster.cast(Point2{99000.0, 10.0}, 0.0, 5000.0);
  REQUIRE(h.hit);
  CHECK(h.range == Approx(1000.0));
}
