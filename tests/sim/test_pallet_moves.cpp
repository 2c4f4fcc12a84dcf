// Pallets moved between runs: the seeded rearrangement of a world's pallet boxes.
#include <algorithm>
#include <cmath>
#include <vector>

#include "agv/sim/pallet_moves.hpp"
#include "agv/sim/world.hpp"
#include "agv_test.hpp"

using agv::Status;
using agv::sim::PalletChanges;
using agv::sim::PalletMoveParams;
using agv::sim::Point2;
using agv::sim::World;

namespace {

World builtIn() {
  World w;
  agv::sim::WorldParseError e;
  REQUIRE(agv::sim::parseWorld(agv::sim::defaultWorldText(), w, e) == Status::Ok);
  return w;
}

std::vector<Point2> route(const World& w) {
  std::vector<Point2> points;
  for (const agv::sim::Mission& m : w.missions) {
    for (const agv::sim::Path& leg : m.legs) {
      for (const agv::Pose2d& q : leg.points) {
        points.push_back(Point2{q.x, q.y});
      }
    }
  }
  return points;
}

std::size_t countKind(const World& w, agv::sim::ObstacleKind kind) {
  return static_cast<std::size_t>(
      std::count_if(w.segments.begin(), w.segments.end(), [&](const agv::sim::Segment& s) { return s.kind == kind; }));
}

/// Smallest distance from the route to a pallet segment.
double palletClearance(const World& w, const std::vector<Point2>& points) {
  double d = 1e9;
  for (const agv::sim::Segment& s : w.segments) {
    if (s.kind != agv::sim::ObstacleKind::Pallet) {
      continue;
    }
    for (const Point2& p : points) {
      d = std::min(d, agv::sim::distanceToSegment(p, s));
    }
  }
  return d;
}

}  // namespace

TEST_CASE("Pallets are rearranged per seed, deterministically, and only pallets", "[sim][pallets]") {
  const World base = builtIn();
  const std::vector<Point2> keep = route(base);
  const PalletMoveParams params;
  World a;
  World a2;
  World b;
  PalletChanges ca;
  PalletChanges ca2;
  PalletChanges cb;
  agv::sim::rearrangePallets(base, params, 11, keep, a, ca);
  agv::sim::rearrangePallets(base, params, 11, keep, a2, ca2);
  agv::sim::rearrangePallets(base, params, 12, keep, b, cb);
  // Deterministic for one seed, different for another, different from the mapped layout.
  CHECK(agv::sim::palletFingerprint(a) == agv::sim::palletFingerprint(a2));
  CHECK(ca.moved == ca2.moved);
  CHECK(agv::sim::palletFingerprint(a) != agv::sim::palletFingerprint(b));
  CHECK(agv::sim::palletFingerprint(a) != agv::sim::palletFingerprint(base));
  CHECK(ca.boxes == 25);
  CHECK(ca.moved + ca.removed > 0);
  CHECK(ca.added == params.added);
  CHECK(ca.maxShift > 0.0);
  // A corner moves by the shift and by the rotation about the centre (half-diagonal <= 1.5 m).
  CHECK(ca.maxShift <= std::hypot(params.maxShift, params.maxShift) + 1.5 * params.maxRotation + 1e-9);
  // The pallet boxes left: the original ones not removed, plus the added ones.
  CHECK(a.pallets.size() == static_cast<std::size_t>(ca.boxes - ca.removed + ca.added));
  CHECK(countKind(a, agv::sim::ObstacleKind::Pallet) == 4 * a.pallets.size());
  // Walls, racks, pillars, reflectors, paths and missions untouched.
  CHECK(countKind(a, agv::sim::ObstacleKind::Wall) == countKind(base, agv::sim::ObstacleKind::Wall));
  CHECK(countKind(a, agv::sim::ObstacleKind::Rack) == countKind(base, agv::sim::ObstacleKind::Rack));
  CHECK(a.circles.size() == base.circles.size());
  CHECK(a.reflectorCount() == base.reflectorCount());
  CHECK(a.paths.size() == base.paths.size());
  CHECK(a.missions.size() == base.missions.size());
  // Nothing comes nearer the route than the mapped layout was (or 1 m).
  const double before = palletClearance(base, keep);
  CHECK(palletClearance(a, keep) >= std::min(params.clearance, before) - 1e-9);
  CHECK(palletClearance(b, keep) >= std::min(params.clearance, before) - 1e-9);
}

TEST_CASE("Pallet moves: nothing drawn leaves the layout, everything removed empties it", "[sim][pallets]") {
  const World base = builtIn();
  PalletMoveParams none;
  none.removeProbability = 0.0;
  none.moveProbability = 0.0;
  none.added = 0;
  World same;
  PalletChanges c;
  agv::sim::rearrangePallets(base, none, 5, {}, same, c);
  CHECK(c.moved == 0);
  CHECK(c.removed == 0);
  CHECK(agv::sim::palletFingerprint(same) == agv::sim::palletFingerprint(base));
  CHECK(same.segments.size() == base.segments.size());
  PalletMoveParams all = none;
  all.removeProbability = 1.0;
  World empty;
  agv::sim::rearrangePallets(base, all, 5, {}, empty, c);
  CHECK(c.removed == 25);
  CHECK(empty.pallets.empty());
  CHECK(countKind(empty, agv::sim::ObstacleKind::Pallet) == 0U);
  // An added pallet keeps clear of the route and of the other obstacles.
  PalletMoveParams add = none;
  add.added = 5;
  World more;
  const std::vector<Point2> keep = route(base);
  agv::sim::rearrangePallets(base, add, 9, keep, more, c);
  CHECK(c.added == 5);
  CHECK(more.pallets.size() == 30U);
  CHECK(palletClearance(more, keep) >= std::min(add.clearance, palletClearance(base, keep)) - 1e-9);
}
