#include "agv/sim/pallet_moves.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>

namespace agv::sim {

namespace {

using Corners = std::array<Point2, 4>;

Corners boxCorners(const PalletBox& b) {
  return Corners{Point2{b.xmin, b.ymin}, Point2{b.xmax, b.ymin}, Point2{b.xmax, b.ymax}, Point2{b.xmin, b.ymax}};
}

/// The box's corners rotated by `rot` about its centre and shifted by (dx, dy).
Corners transform(const Corners& c, double dx, double dy, double rot) {
  const double cx = 0.25 * (c[0].x + c[1].x + c[2].x + c[3].x);
  const double cy = 0.25 * (c[0].y + c[1].y + c[2].y + c[3].y);
  const double cs = std::cos(rot);
  const double sn = std::sin(rot);
  Corners out{};
  for (std::size_t i = 0; i < 4; ++i) {
    const double x = c[i].x - cx;
    const double y = c[i].y - cy;
    out[i] = Point2{cx + cs * x - sn * y + dx, cy + sn * x + cs * y + dy};
  }
  return out;
}

bool insidePolygon(const Point2& p, const Corners& c) {
  bool in = false;
  for (std::size_t i = 0, j = 3; i < 4; j = i++) {
    if ((c[i].y > p.y) != (c[j].y > p.y) && p.x < (c[j].x - c[i].x) * (p.y - c[i].y) / (c[j].y - c[i].y) + c[i].x) {
      in = !in;
    }
  }
  return in;
}

/// Distance from `p` to the box (0 inside).
double distanceToBox(const Point2& p, const Corners& c) {
  if (insidePolygon(p, c)) {
    return 0.0;
  }
  double d = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < 4; ++i) {
    d = std::min(d, distanceToSegment(p, Segment{c[i], c[(i + 1) % 4], ObstacleKind::Pallet}));
  }
  return d;
}

double clearanceFrom(const std::vector<Point2>& points, const Corners& c) {
  double d = std::numeric_limits<double>::infinity();
  for (const Point2& p : points) {
    d = std::min(d, distanceToBox(p, c));
  }
  return d;
}

/// Smallest distance between the box and an obstacle of `w` (segments: sampled every 5 cm along
/// the obstacle and the box's edges; circles: centre distance minus radius).
double clearanceFromObstacles(const World& w, const Corners& c) {
  double d = std::numeric_limits<double>::infinity();
  const auto sampleSegment = [&](const Point2& a, const Point2& b, const auto& visit) {
    const double len = std::hypot(b.x - a.x, b.y - a.y);
    const int n = std::max(1, static_cast<int>(std::ceil(len / 0.05)));
    for (int i = 0; i <= n; ++i) {
      const double t = static_cast<double>(i) / static_cast<double>(n);
      visit(Point2{a.x + t * (b.x - a.x), a.y + t * (b.y - a.y)});
    }
  };
  for (const Segment& s : w.segments) {
    sampleSegment(s.a, s.b, [&](const Point2& p) { d = std::min(d, distanceToBox(p, c)); });
  }
  for (std::size_t i = 0; i < 4; ++i) {
    sampleSegment(c[i], c[(i + 1) % 4], [&](const Point2& p) {
      for (const Segment& s : w.segments) {
        d = std::min(d, distanceToSegment(p, s));
      }
    });
  }
  for (const Circle& k : w.circles) {
    d = std::min(d, std::max(0.0, distanceToBox(k.centre, c) - k.radius));
  }
  return d;
}

void addPolygon(World& w, const Corners& c) {
  PalletBox b;
  b.xmin = std::min({c[0].x, c[1].x, c[2].x, c[3].x});
  b.xmax = std::max({c[0].x, c[1].x, c[2].x, c[3].x});
  b.ymin = std::min({c[0].y, c[1].y, c[2].y, c[3].y});
  b.ymax = std::max({c[0].y, c[1].y, c[2].y, c[3].y});
  b.firstSegment = w.segments.size();
  w.pallets.push_back(b);
  for (std::size_t i = 0; i < 4; ++i) {
    w.segments.push_back(Segment{c[i], c[(i + 1) % 4], ObstacleKind::Pallet});
  }
}

}  // namespace

double distanceToSegment(const Point2& p, const Segment& s) noexcept {
  const double vx = s.b.x - s.a.x;
  const double vy = s.b.y - s.a.y;
  const double len2 = vx * vx + vy * vy;
  double t = len2 > 0.0 ? ((p.x - s.a.x) * vx + (p.y - s.a.y) * vy) / len2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  return std::hypot(p.x - (s.a.x + t * vx), p.y - (s.a.y + t * vy));
}

void rearrangePallets(const World& base, const PalletMoveParams& params, std::uint64_t seed,
                      const std::vector<Point2>& keepClear, World& out, PalletChanges& changes) {
  changes = PalletChanges{};
  changes.boxes = static_cast<int>(base.pallets.size());
  World w;
  w.circles = base.circles;
  w.paths = base.paths;
  w.missions = base.missions;
  // Everything that is not a pallet box stays.
  std::vector<bool> palletSegment(base.segments.size(), false);
  for (const PalletBox& b : base.pallets) {
    for (std::size_t k = 0; k < 4 && b.firstSegment + k < base.segments.size(); ++k) {
      palletSegment[b.firstSegment + k] = true;
    }
  }
  for (std::size_t i = 0; i < base.segments.size(); ++i) {
    if (!palletSegment[i]) {
      w.segments.push_back(base.segments[i]);
    }
  }
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const auto symmetric = [&](double max) { return (2.0 * unit(rng) - 1.0) * max; };
  for (const PalletBox& b : base.pallets) {
    // Draw everything for every box, so that one box's outcome does not shift the others' draws.
    const double removeDraw = unit(rng);
    const double moveDraw = unit(rng);
    const double dx = symmetric(params.maxShift);
    const double dy = symmetric(params.maxShift);
    const double rot = symmetric(params.maxRotation);
    const Corners original = boxCorners(b);
    if (removeDraw < params.removeProbability) {
      ++changes.removed;
      continue;
    }
    if (moveDraw < params.moveProbability) {
      const Corners moved = transform(original, dx, dy, rot);
      // Not nearer the route than `clearance`, or than the box was where it stood.
      if (clearanceFrom(keepClear, moved) >= std::min(params.clearance, clearanceFrom(keepClear, original))) {
        double shift = 0.0;
        for (std::size_t i = 0; i < 4; ++i) {
          shift = std::max(shift, std::hypot(moved[i].x - original[i].x, moved[i].y - original[i].y));
        }
        changes.maxShift = std::max(changes.maxShift, shift);
        ++changes.moved;
        addPolygon(w, moved);
        continue;
      }
      ++changes.keptForClearance;
    }
    addPolygon(w, original);
  }
  // New pallets at free places of the hall: clear of the route and of every other obstacle.
  Point2 lo;
  Point2 hi;
  base.bounds(&lo, &hi);
  for (int k = 0; k < params.added; ++k) {
    for (int attempt = 0; attempt < 200; ++attempt) {
      const double cx = lo.x + 1.0 + unit(rng) * std::max(0.0, hi.x - lo.x - 2.0);
      const double cy = lo.y + 1.0 + unit(rng) * std::max(0.0, hi.y - lo.y - 2.0);
      const double rot = unit(rng) * 3.14159265358979323846;
      const double hl = 0.5 * params.addedLength;
      const double hw = 0.5 * params.addedWidth;
      const Corners c = transform(Corners{Point2{cx - hl, cy - hw}, Point2{cx + hl, cy - hw}, Point2{cx + hl, cy + hw},
                                          Point2{cx - hl, cy + hw}},
                                  0.0, 0.0, rot);
      if (clearanceFrom(keepClear, c) >= params.clearance && clearanceFromObstacles(w, c) >= params.obstacleClearance) {
        addPolygon(w, c);
        ++changes.added;
        break;
      }
    }
  }
  out = std::move(w);
}

double palletFingerprint(const World& world) noexcept {
  double f = 0.0;
  double weight = 1.0;
  for (const PalletBox& b : world.pallets) {
    for (std::size_t k = 0; k < 4 && b.firstSegment + k < world.segments.size(); ++k) {
      const Segment& s = world.segments[b.firstSegment + k];
      f += weight * (s.a.x + 2.0 * s.a.y + 3.0 * s.b.x + 5.0 * s.b.y);
      weight += 1.0;
    }
  }
  return f;
}

}  // namespace agv::sim
