// World text format: the built-in warehouse and the error reports.
#include <cmath>
#include <string>
#include <vector>

#include "agv/core/angle.hpp"
#include "agv/sim/world.hpp"
#include "agv_test.hpp"

using agv::Status;
using agv::sim::World;
using agv::sim::WorldParseError;

TEST_CASE("The built-in warehouse parses with its four reference paths", "[sim][world]") {
  World w;
  WorldParseError e;
  REQUIRE(agv::sim::parseWorld(agv::sim::defaultWorldText(), w, e) == Status::Ok);
  CHECK(w.reflectorCount() == 18U);
  agv::sim::Point2 lo;
  agv::sim::Point2 hi;
  w.bounds(&lo, &hi);
  CHECK(lo.x == Approx(0.0));
  CHECK(lo.y == Approx(0.0));
  CHECK(hi.x == Approx(40.0));
  CHECK(hi.y == Approx(25.0));
  REQUIRE(w.paths.size() == 4U);
  struct Expected {
    const char* name;
    double length;
    double endX;
    double endY;
  };
  // End points from the geometry of the pieces (docs/world-format.md), not from the sampler.
  const Expected expected[] = {
      {"P1", 12.0, 30.0, 10.0}, {"P2", 12.0, 30.0, 14.0}, {"P3", 12.0, 30.0, 6.0}, {"P4", 7.0, 30.0, 18.0}};
  for (const Expected& x : expected) {
    const agv::sim::Path* p = w.findPath(x.name);
    REQUIRE(p != nullptr);
    CHECK(p->length == Approx(x.length).margin(1e-5));
    CHECK(p->points.back().x == Approx(x.endX).margin(1e-5));
    CHECK(p->points.back().y == Approx(x.endY).margin(1e-5));
    CHECK(std::fabs(p->points.back().theta) < 1e-6);  // all end heading +x into their lane
    // Samples are dense and their polyline length matches the exact length (chords of arcs are
    // shorter by O(step^2 / r^2)).
    double poly = 0.0;
    for (std::size_t i = 1; i < p->points.size(); ++i) {
      const double d = std::hypot(p->points[i].x - p->points[i - 1].x, p->points[i].y - p->points[i - 1].y);
      CHECK(d <= agv::sim::kPathSampleStep + 1e-9);
      poly += d;
    }
    CHECK(poly == Approx(x.length).margin(1e-3));
  }
  CHECK(w.findPath("P5") == nullptr);
}

TEST_CASE("An arc path ends where circle geometry puts it", "[sim][world]") {
  World w;
  WorldParseError e;
  // Quarter circle of radius 2 to the left from the origin heading +x: ends at (2, 2) heading +y.
  REQUIRE(agv::sim::parseWorld("wall 0 -1 1 -1\npath A 0 0 0 L 2 90  # comment\n\n", w, e) == Status::Ok);
  const agv::sim::Path& p = w.paths.at(0);
  CHECK(p.points.back().x == Approx(2.0).margin(1e-9));
  CHECK(p.points.back().y == Approx(2.0).margin(1e-9));
  CHECK(p.points.back().theta == Approx(agv::kPi<double> / 2).margin(1e-9));
  CHECK(p.length == Approx(agv::kPi<double>));
}

TEST_CASE("Racks expand into two lines of uprights", "[sim][world]") {
  World w;
  WorldParseError e;
  REQUIRE(agv::sim::parseWorld("rack 0 0 10 0 1.0 2.5\n", w, e) == Status::Ok);
  // Uprights at x = 0, 2.5, 5, 7.5, 10 on y = 0 and y = 1 (left of +x): 10 boxes of 4 edges.
  CHECK(w.segments.size() == 40U);
}

TEST_CASE("World numbers are decimal: leading zeros, signs and exponents", "[sim][world]") {
  World w;
  WorldParseError e;
  REQUIRE(agv::sim::parseWorld("wall 010 +2 1.5e1 -.5\n", w, e) == Status::Ok);
  REQUIRE(w.segments.size() == 1U);
  CHECK(w.segments[0].a.x == 10.0);  // not octal 8
  CHECK(w.segments[0].a.y == 2.0);
  CHECK(w.segments[0].b.x == 15.0);
  CHECK(w.segments[0].b.y == -0.5);
}

namespace {
void checkError(const std::string& text, Status status, int line, const std::string& fragment) {
  World w;
  w.circles.push_back({{1.0, 1.0}, 0.5, agv::sim::ObstacleKind::Pillar});
  WorldParseError e;
  CHECK(agv::sim::parseWorld(text, w, e) == status);
  CHECK(e.line == line);
  INFO("message: " << e.message);
  CHECK(e.message.find(fragment) != std::string::npos);
  CHECK(w.circles.size() == 1U);  // the output is untouched on failure
}
}  // namespace

TEST_CASE("World parse errors name the line and the problem", "[sim][world]") {
  checkError("hall 0 0 40 25\n# comment\nshelf 1 2 3 4\n", Status::Malformed, 3, "unknown keyword 'shelf'");
  checkError("\n\nwall 0 0 1\n", Status::Malformed, 3, "wall needs 4 numbers");
  checkError("rack 0 0 10 0\n", Status::Malformed, 1, "rack needs 6 numbers (x0 y0 x1 y1 depth pitch), got 4");
  checkError("wall 0 0 1 abc\n", Status::Malformed, 1, "y1: 'abc' is not a number");
  checkError("wall 0 0 1 2x\n", Status::Malformed, 1, "'2x' is not a number");
  checkError("wall 0 0 1 nan\n", Status::NonFiniteInput, 1, "not finite");
  checkError("wall 0 0 1 inf\n", Status::NonFiniteInput, 1, "not finite");
  // Decimal only, no locale: hexadecimal and a decimal comma are not numbers; beyond double's
  // range is not finite.
  checkError("wall 0 0 1 0x10\n", Status::Malformed, 1, "'0x10' is not a number");
  checkError("wall 0 0 1 1,5\n", Status::Malformed, 1, "'1,5' is not a number");
  checkError("wall 0 0 1 +-1\n", Status::Malformed, 1, "'+-1' is not a number");
  checkError("wall 0 0 1 -inf\n", Status::NonFiniteInput, 1, "not finite");
  checkError("wall 0 0 1 1e400\n", Status::NonFiniteInput, 1, "not finite");
  checkError("wall 1 1 1 1\n", Status::InvalidArgument, 1, "same point");
  checkError("hall 0 0 0 5\n", Status::InvalidArgument, 1, "xmax > xmin");
  checkError("wall 0 0 1 1\nreflector 1 2 -0.1\n", Status::InvalidArgument, 2, "radius");
  checkError("wall 0 0 1 1\npath A 0 0 0 S 1\npath A 0 0 0 S 2\n", Status::InvalidArgument, 3, "duplicate name 'A'");
  checkError("wall 0 0 1 1\npath A 0 0 0 X 1\n", Status::Malformed, 2, "unknown piece 'X'");
  checkError("wall 0 0 1 1\npath A 0 0 0 L 1\n", Status::Malformed, 2, "needs radius and angle");
  checkError("wall 0 0 1 1\npath A 0 0 0 L 1 400\n", Status::InvalidArgument, 2, "angle in (0, 360]");
  checkError("wall 0 0 1 1\npath A 0 0 0\n", Status::Malformed, 2, "at least one piece");
  checkError("wall 0 0 1 1\npath A 0 0 0 S -1\n", Status::InvalidArgument, 2, "length must be > 0");
  checkError("# nothing\n\n", Status::EmptyInput, 0, "no obstacle");
  checkError("", Status::EmptyInput, 0, "no obstacle");
}

TEST_CASE("A missing world file is reported as not found", "[sim][world]") {
  World w;
  WorldParseError e;
  CHECK(agv::sim::loadWorldFile("/nonexistent/dir/world.txt", w, e) == Status::NotFound);
  CHECK(e.message.find("/nonexistent/dir/world.txt") != std::string::npos);
}

TEST_CASE("The built-in missions stop where their pieces put them", "[sim][world][missions]") {
  World w;
  WorldParseError e;
  REQUIRE(agv::sim::parseWorld(agv::sim::defaultWorldText(), w, e) == Status::Ok);
  REQUIRE(w.missions.size() == 3U);
  struct Stop {
    double x;
    double y;
    double headingDeg;
  };
  // Operation points from the geometry of the pieces (docs/hil.md, "Missions").
  const std::vector<std::vector<Stop>> expected = {
      {{30.0, 10.0, 0.0}, {32.0, 14.0, 180.0}, {12.0, 22.2, 180.0}},
      {{3.5, 12.0, 90.0}, {3.5, 17.0, 90.0}, {10.0, 22.2, 0.0}, {30.0, 18.0, 0.0}},
      {{30.0, 6.0, 0.0}, {33.0, 18.0, 180.0}, {3.5, 12.0, -90.0}, {13.0, 5.5, 0.0}}};
  for (std::size_t m = 0; m < 3; ++m) {
    const agv::sim::Mission& mission = w.missions[m];
    CHECK(mission.name == "M" + std::to_string(m + 1));
    CHECK(mission.length >= 50.0);
    CHECK(mission.length <= 100.0);
    REQUIRE(mission.legs.size() == expected[m].size());
    double sum = 0.0;
    for (std::size_t k = 0; k < mission.legs.size(); ++k) {
      const agv::sim::Path& leg = mission.legs[k];
      sum += leg.length;
      CHECK(leg.name == mission.name + "/" + std::to_string(k + 1));
      const agv::Pose2d& begin = k == 0 ? mission.start : mission.legs[k - 1].points.back();
      CHECK(leg.start.x == begin.x);  // a leg starts where the previous one ended
      CHECK(leg.start.y == begin.y);
      CHECK(leg.points.back().x == Approx(expected[m][k].x).margin(1e-4));
      CHECK(leg.points.back().y == Approx(expected[m][k].y).margin(1e-4));
      CHECK(std::fabs(agv::angleDiff(leg.points.back().theta, agv::deg2rad(expected[m][k].headingDeg))) < 1e-5);
    }
    CHECK(sum == Approx(mission.length));
  }
  // The pallet blocks of the block storage are the world's movable objects.
  CHECK(w.pallets.size() == 25U);
  CHECK(w.findMission("M2") == &w.missions[1]);
  CHECK(w.findMission("P1") == nullptr);
}

TEST_CASE("Bad missions are refused with their line", "[sim][world][missions]") {
  checkError("wall 0 0 1 1\nmission A 0 0 0 S 1 stop S 2\n", Status::InvalidArgument, 2, "must end with stop");
  checkError("wall 0 0 1 1\n\nmission A 0 0 0 stop S 1 stop\n", Status::InvalidArgument, 3, "stop 1 has no piece");
  checkError("wall 0 0 1 1\nmission A 0 0 0 S 1 stop stop\n", Status::InvalidArgument, 2, "stop 2 has no piece");
  checkError("wall 0 0 1 1\nmission A 0 0 0 S 1 halt\n", Status::Malformed, 2, "unknown piece 'halt'");
  checkError("wall 0 0 1 1\nmission A 0 0 0 S\n", Status::Malformed, 2, "mission needs NAME");
  checkError("wall 0 0 1 1\nmission A 0 0 0 S x stop\n", Status::Malformed, 2, "S length: 'x' is not a number");
  checkError("wall 0 0 1 1\nmission A 0 0 0 R 0 90 stop\n", Status::InvalidArgument, 2, "radius must be > 0");
  checkError("wall 0 0 1 1\npath A 0 0 0 S 1\nmission A 0 0 0 S 1 stop\n", Status::InvalidArgument, 3,
             "duplicate name 'A'");
  checkError("wall 0 0 1 1\nmission A 0 0 0 S 1 stop\npath A 0 0 0 S 1\n", Status::InvalidArgument, 3,
             "duplicate name 'A'");
  // `stop` is a mission piece only.
  checkError("wall 0 0 1 1\npath A 0 0 0 S 1 stop\n", Status::Malformed, 2, "unknown piece 'stop'");
  World w;
  WorldParseError e;
  REQUIRE(agv::sim::parseWorld("wall 0 0 1 1\nmission A 1 2 90 S 2 stop L 1 90 stop\n", w, e) == Status::Ok);
  REQUIRE(w.missions.size() == 1U);
  REQUIRE(w.missions[0].legs.size() == 2U);
  CHECK(w.missions[0].legs[0].points.back().y == Approx(4.0));
  CHECK(w.missions[0].legs[1].points.back().x == Approx(0.0).margin(1e-9));
  CHECK(w.missions[0].legs[1].points.back().y == Approx(5.0));
  CHECK(w.paths.empty());
}
