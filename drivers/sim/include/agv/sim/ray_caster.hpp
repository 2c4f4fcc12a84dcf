#pragma once
/// @file ray_caster.hpp
/// Ray casting against the world's segments and circles, accelerated by a uniform grid.

#include <cstdint>
#include <vector>

#include "agv/sim/world.hpp"

namespace agv::sim {

/// First intersection of a ray with the world.
struct RayHit {
  bool hit = false;         ///< false: nothing within the range asked for
  double range = 0.0;       ///< [m] distance from the ray origin to the hit
  bool circle = false;      ///< true: `index` is into World::circles, else into World::segments
  std::uint32_t index = 0;  ///< primitive that was hit
};

/// Distance t >= 0 along the ray o + t*d (d unit) to segment s, if they intersect. A ray parallel
/// to the segment does not hit it (a laser beam grazing a wall sees the next obstacle).
bool intersectSegment(const Point2& o, const Point2& d, const Segment& s, double* t) noexcept;
/// Distance t >= 0 along the ray o + t*d (d unit) to the circle's boundary: the near root, or the
/// far one when the origin is inside the circle.
bool intersectCircle(const Point2& o, const Point2& d, const Circle& c, double* t) noexcept;

/// Casts rays against a `World` (which must outlive the caster and not change).
///
/// The obstacles are binned into square cells; a ray walks the cells it crosses in order
/// (Amanatides-Woo) and stops at the first cell that contains a hit closer than the cell's exit,
/// so a ray tests only the primitives near its path: a 1440-beam sweep of the built-in warehouse
/// costs about 0.4 ms instead of 3.3 ms by brute force (BM_SimLaserScan, BM_SimRayCastBruteForce).
class RayCaster {
 public:
  /// `cellSize` [m] > 0: the grid's cell side (about the typical obstacle spacing works best).
  /// The grid never exceeds 4 million cells: for a larger world the cells are made coarser.
  explicit RayCaster(const World& world, double cellSize = 1.0);

  /// First obstacle hit by the ray from `origin` at world angle `angle` [rad] closer than
  /// `maxRange` [m].
  RayHit cast(const Point2& origin, double angle, double maxRange) const noexcept;
  /// The same by testing every primitive (reference for tests and benchmarks).
  RayHit castBruteForce(const Point2& origin, double angle, double maxRange) const noexcept;

  const World& world() const noexcept { return *world_; }
  /// Grid size (cells along x and y) and the number of (cell, primitive) entries.
  int cellsX() const noexcept { return nx_; }
  int cellsY() const noexcept { return ny_; }
  double cellSize() const noexcept { return cell_; }
  std::size_t entries() const noexcept { return items_.size(); }

 private:
  void testCell(int cell, const Point2& o, const Point2& d, RayHit* best) const noexcept;

  const World* world_;
  double cell_;
  Point2 lo_;
  int nx_ = 0;
  int ny_ = 0;
  std::vector<std::uint32_t> cellStart_;  // nx*ny + 1 offsets into items_
  std::vector<std::uint32_t> items_;      // primitive index, top bit set for circles
};

}  // namespace agv::sim
