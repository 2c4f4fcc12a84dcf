#include "agv/sim/ray_caster.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace agv::sim {

namespace {

constexpr std::uint32_t kCircleBit = 0x80000000U;
constexpr double kParallel = 1e-12;

double cross(double ax, double ay, double bx, double by) noexcept {
  return ax * by - ay * bx;
}

/// True when segment a-b touches the axis-aligned box [x0,x1]x[y0,y1] (Liang-Barsky clip).
bool segmentTouchesBox(const Point2& a, const Point2& b, double x0, double y0, double x1, double y1) noexcept {
  double t0 = 0.0;
  double t1 = 1.0;
  const double dx = b.x - a.x;
  const double dy = b.y - a.y;
  const double p[4] = {-dx, dx, -dy, dy};
  const double q[4] = {a.x - x0, x1 - a.x, a.y - y0, y1 - a.y};
  for (int i = 0; i < 4; ++i) {
    if (p[i] == 0.0) {
      if (q[i] < 0.0) {
        return false;
      }
      continue;
    }
    const double r = q[i] / p[i];
    if (p[i] < 0.0) {
      t0 = std::max(t0, r);
    } else {
      t1 = std::min(t1, r);
    }
    if (t0 > t1) {
      return false;
    }
  }
  return true;
}

}  // namespace

bool intersectSegment(const Point2& o, const Point2& d, const Segment& s, double* t) noexcept {
  const double sx = s.b.x - s.a.x;
  const double sy = s.b.y - s.a.y;
  const double denom = cross(d.x, d.y, sx, sy);
  if (denom * denom < kParallel * kParallel * (sx * sx + sy * sy)) {  // |denom| < kParallel |s|
    return false;
  }
  const double ax = s.a.x - o.x;
  const double ay = s.a.y - o.y;
  const double tt = cross(ax, ay, sx, sy) / denom;
  const double u = cross(ax, ay, d.x, d.y) / denom;
  if (tt < 0.0 || u < 0.0 || u > 1.0) {
    return false;
  }
  *t = tt;
  return true;
}

bool intersectCircle(const Point2& o, const Point2& d, const Circle& c, double* t) noexcept {
  const double fx = o.x - c.centre.x;
  const double fy = o.y - c.centre.y;
  const double b = d.x * fx + d.y * fy;
  const double cc = fx * fx + fy * fy - c.radius * c.radius;
  const double disc = b * b - cc;
  if (disc < 0.0) {
    return false;
  }
  const double sq = std::sqrt(disc);
  const double t1 = -b - sq;
  if (t1 >= 0.0) {
    *t = t1;
    return true;
  }
  const double t2 = -b + sq;
  if (t2 >= 0.0) {
    *t = t2;
    return true;
  }
  return false;
}

RayCaster::RayCaster(const World& world, double cellSize) : world_(&world), cell_(cellSize > 0.0 ? cellSize : 1.0) {
  Point2 lo;
  Point2 hi;
  world.bounds(&lo, &hi);
  // Bound the grid's memory for huge worlds: coarser cells rather than more of them.
  constexpr double kMaxCells = 4.0e6;
  const double area = (hi.x - lo.x + cell_) * (hi.y - lo.y + cell_);
  if (area / (cell_ * cell_) > kMaxCells) {
    cell_ = std::sqrt(area / kMaxCells) * 1.01;
  }
  lo_ = {lo.x - 0.5 * cell_, lo.y - 0.5 * cell_};
  nx_ = std::max(1, static_cast<int>(std::ceil((hi.x - lo_.x) / cell_ + 0.5)));
  ny_ = std::max(1, static_cast<int>(std::ceil((hi.y - lo_.y) / cell_ + 0.5)));
  const std::size_t ncell = static_cast<std::size_t>(nx_) * static_cast<std::size_t>(ny_);
  std::vector<std::vector<std::uint32_t>> bins(ncell);
  auto cellRange = [&](double x0, double y0, double x1, double y1, int* i0, int* j0, int* i1, int* j1) {
    *i0 = std::clamp(static_cast<int>(std::floor((x0 - lo_.x) / cell_)), 0, nx_ - 1);
    *j0 = std::clamp(static_cast<int>(std::floor((y0 - lo_.y) / cell_)), 0, ny_ - 1);
    *i1 = std::clamp(static_cast<int>(std::floor((x1 - lo_.x) / cell_)), 0, nx_ - 1);
    *j1 = std::clamp(static_cast<int>(std::floor((y1 - lo_.y) / cell_)), 0, ny_ - 1);
  };
  for (std::size_t k = 0; k < world.segments.size(); ++k) {
    const Segment& s = world.segments[k];
    int i0 = 0;
    int j0 = 0;
    int i1 = 0;
    int j1 = 0;
    cellRange(std::min(s.a.x, s.b.x), std::min(s.a.y, s.b.y), std::max(s.a.x, s.b.x), std::max(s.a.y, s.b.y), &i0, &j0,
              &i1, &j1);
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i) {
        const double x0 = lo_.x + i * cell_;
        const double y0 = lo_.y + j * cell_;
        // A small margin keeps segments lying exactly on a cell border in both cells.
        const double m = 1e-9;
        if (segmentTouchesBox(s.a, s.b, x0 - m, y0 - m, x0 + cell_ + m, y0 + cell_ + m)) {
          bins[static_cast<std::size_t>(j * nx_ + i)].push_back(static_cast<std::uint32_t>(k));
        }
      }
    }
  }
  for (std::size_t k = 0; k < world.circles.size(); ++k) {
    const Circle& c = world.circles[k];
    int i0 = 0;
    int j0 = 0;
    int i1 = 0;
    int j1 = 0;
    cellRange(c.centre.x - c.radius, c.centre.y - c.radius, c.centre.x + c.radius, c.centre.y + c.radius, &i0, &j0, &i1,
              &j1);
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i) {
        bins[static_cast<std::size_t>(j * nx_ + i)].push_back(static_cast<std::uint32_t>(k) | kCircleBit);
      }
    }
  }
  cellStart_.resize(ncell + 1);
  cellStart_[0] = 0;
  for (std::size_t c = 0; c < ncell; ++c) {
    cellStart_[c + 1] = cellStart_[c] + static_cast<std::uint32_t>(bins[c].size());
    items_.insert(items_.end(), bins[c].begin(), bins[c].end());
  }
}

void RayCaster::testCell(int cell, const Point2& o, const Point2& d, RayHit* best) const noexcept {
  const std::uint32_t b = cellStart_[static_cast<std::size_t>(cell)];
  const std::uint32_t e = cellStart_[static_cast<std::size_t>(cell) + 1];
  for (std::uint32_t k = b; k < e; ++k) {
    const std::uint32_t item = items_[k];
    double t = 0.0;
    const bool isCircle = (item & kCircleBit) != 0U;
    const std::uint32_t idx = item & ~kCircleBit;
    const bool hit =
        isCircle ? intersectCircle(o, d, world_->circles[idx], &t) : intersectSegment(o, d, world_->segments[idx], &t);
    if (hit && t < best->range) {
      best->hit = true;
      best->range = t;
      best->circle = isCircle;
      best->index = idx;
    }
  }
}

RayHit RayCaster::cast(const Point2& origin, double angle, double maxRange) const noexcept {
  RayHit best;
  best.range = maxRange;
  if (!(maxRange > 0.0) || !std::isfinite(angle) || !std::isfinite(origin.x) || !std::isfinite(origin.y)) {
    return best;
  }
  const Point2 d{std::cos(angle), std::sin(angle)};
  const double inf = std::numeric_limits<double>::infinity();
  // Clip the ray to the grid box.
  const double hx = lo_.x + nx_ * cell_;
  const double hy = lo_.y + ny_ * cell_;
  double tEnter = 0.0;
  double tExit = maxRange;
  const double lo[2] = {lo_.x, lo_.y};
  const double hi[2] = {hx, hy};
  const double o[2] = {origin.x, origin.y};
  const double dd[2] = {d.x, d.y};
  for (int a = 0; a < 2; ++a) {
    if (dd[a] == 0.0) {
      if (o[a] < lo[a] || o[a] > hi[a]) {
        return best;
      }
      continue;
    }
    double t0 = (lo[a] - o[a]) / dd[a];
    double t1 = (hi[a] - o[a]) / dd[a];
    if (t0 > t1) {
      std::swap(t0, t1);
    }
    tEnter = std::max(tEnter, t0);
    tExit = std::min(tExit, t1);
  }
  if (tEnter > tExit) {
    return best;
  }
  const double px = origin.x + tEnter * d.x;
  const double py = origin.y + tEnter * d.y;
  int ix = std::clamp(static_cast<int>(std::floor((px - lo_.x) / cell_)), 0, nx_ - 1);
  int iy = std::clamp(static_cast<int>(std::floor((py - lo_.y) / cell_)), 0, ny_ - 1);
  const int stepX = d.x > 0.0 ? 1 : -1;
  const int stepY = d.y > 0.0 ? 1 : -1;
  const double tDeltaX = d.x != 0.0 ? cell_ / std::fabs(d.x) : inf;
  const double tDeltaY = d.y != 0.0 ? cell_ / std::fabs(d.y) : inf;
  double tMaxX = inf;
  double tMaxY = inf;
  if (d.x != 0.0) {
    tMaxX = (lo_.x + (ix + (d.x > 0.0 ? 1 : 0)) * cell_ - origin.x) / d.x;
  }
  if (d.y != 0.0) {
    tMaxY = (lo_.y + (iy + (d.y > 0.0 ? 1 : 0)) * cell_ - origin.y) / d.y;
  }
  const int maxSteps = nx_ + ny_ + 2;  // a straight ray crosses at most this many cells
  for (int step = 0; step < maxSteps; ++step) {
    testCell(iy * nx_ + ix, origin, d, &best);
    const double tCellExit = std::min(tMaxX, tMaxY);
    if (best.hit && best.range <= tCellExit) {
      break;
    }
    if (tCellExit >= tExit) {
      break;
    }
    if (tMaxX < tMaxY) {
      ix += stepX;
      tMaxX += tDeltaX;
    } else {
      iy += stepY;
      tMaxY += tDeltaY;
    }
    if (ix < 0 || ix >= nx_ || iy < 0 || iy >= ny_) {
      break;
    }
  }
  if (!best.hit) {
    best.range = maxRange;
  }
  return best;
}

RayHit RayCaster::castBruteForce(const Point2& origin, double angle, double maxRange) const noexcept {
  RayHit best;
  best.range = maxRange;
  if (!(maxRange > 0.0) || !std::isfinite(angle)) {
    return best;
  }
  const Point2 d{std::cos(angle), std::sin(angle)};
  for (std::size_t k = 0; k < world_->segments.size(); ++k) {
    double t = 0.0;
    if (intersectSegment(origin, d, world_->segments[k], &t) && t < best.range) {
      best = RayHit{true, t, false, static_cast<std::uint32_t>(k)};
    }
  }
  for (std::size_t k = 0; k < world_->circles.size(); ++k) {
    double t = 0.0;
    if (intersectCircle(origin, d, world_->circles[k], &t) && t < best.range) {
      best = RayHit{true, t, true, static_cast<std::uint32_t>(k)};
    }
  }
  return best;
}

}  // namespace agv::sim
