#pragma once
/// @file likelihood_field.hpp
/// A fixed-size likelihood field (a truncated *signed* distance map) of the surfaces seen in a
/// mapping run: for any world point, the distance to the nearest mapped surface point, positive on
/// the side the surface was seen from (free space) and negative behind it, and its gradient.
/// Signed, because the scan matcher interpolates it: an unsigned distance has a V at the surface
/// that bilinear interpolation between cell centres fills up to half a cell with a zero gradient
/// at the bottom, exactly where a matched point sits; a signed distance crosses zero linearly. The scan matcher
/// (`scan_matcher.hpp`) aligns a scan's points with it: the "natural navigation" observation that needs no reflectors
/// and no corners, only the walls, racks and columns the laser sees anyway.
///
/// Storage: one byte per cell, the signed distance quantised to `maxDistance / 127` (4 mm at the
/// 0.5 m default), so a 50 m x 50 m hall at 5 cm is 1 MB. `LikelihoodFieldBase` holds the logic over
/// storage it is given; `LikelihoodField<MaxCells>` owns the storage (capacity in the type).
///
/// Use: `configure` the area, `addPoint` every surface point of the mapping run (world frame; a
/// few per cell are enough, e.g. the mean of the points that fell in each cell) with its normal
/// towards the side it was seen from, `build`, then
/// `sample` as often as needed. Distances are exact to the points themselves, not to cell
/// centres: a wall is placed where its points are, not quantised to the grid (a 5 cm grid would
/// otherwise shift each wall by up to 2.5 cm). Building runs offline or at start-up: each
/// `addPoint` updates the (2 w + 1)^2 cells around the point, w = ceil(maxDistance / resolution).

#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "agv/core/status.hpp"

namespace agv {

/// Geometry of a likelihood field.
struct LikelihoodFieldParams {
  /// [m] cell size. 5 cm: finer than the corridor details a scan can resolve at 10 m with a
  /// 0.5 deg laser (9 cm between beams), coarse enough for a hall in a megabyte.
  double resolution = 0.05;
  /// [m] distances saturate here. A scan point farther than this from every mapped surface is not
  /// on the map (a pallet, a person, a moved rack) and carries no information about the pose.
  double maxDistance = 0.5;
  /// `Ok`, `NonFiniteInput`, or `InvalidArgument` (resolution not positive, maxDistance not above
  /// two cells or more than 127 cells).
  Status validate() const noexcept;
};

/// The distance to the nearest mapped surface at a point.
struct FieldSample {
  /// [m] signed (negative behind the surface), bilinear between cell centres, in
  /// [-maxDistance, maxDistance]
  double distance = 0.0;
  Eigen::Vector2d gradient = Eigen::Vector2d::Zero();  ///< d distance / d (x, y) [1]
  bool inside = false;  ///< false outside the field or out of reach of every surface (distance = maxDistance)
};

/// A rectangle of cells: columns [x0, x1), rows [y0, y1).
struct CellRange {
  std::size_t x0 = 0;
  std::size_t y0 = 0;
  std::size_t x1 = 0;
  std::size_t y1 = 0;
};

/// The field over caller-provided storage (see `LikelihoodField<MaxCells>` for the owning type).
class LikelihoodFieldBase {
 public:
  LikelihoodFieldBase(const LikelihoodFieldBase&) = delete;
  LikelihoodFieldBase& operator=(const LikelihoodFieldBase&) = delete;

  /// Sets the area: `width` x `height` cells whose lower-left corner is the world point
  /// (`originX`, `originY`), every cell free (distance saturated), not built.
  /// `InvalidArgument` (invalid params, zero size), `NonFiniteInput` (origin),
  /// `CapacityExceeded` (more cells than the storage): the field is then empty (zero cells).
  Status configure(const LikelihoodFieldParams& params, double originX, double originY, std::size_t width,
                   std::size_t height) noexcept;

  /// Adds a surface point (x, y) whose surface faces (`normalX`, `normalY`) (towards where it was
  /// seen from; any length but zero): every cell centre within maxDistance keeps, of its value and
  /// its Euclidean distance to this point, the one nearer to zero, signed negative when the cell
  /// lies behind the point (within 45 deg of straight behind along the normal: past the end of a
  /// face, at a box's corner, the point's normal cannot say which side a cell is on). `NonFiniteInput`,
  /// `InvalidArgument` (zero normal), `OutOfRange` (outside the area; counted in `pointsOutside()`), `NotInitialized`.
  Status addPoint(double x, double y, double normalX, double normalY) noexcept;

  /// Adds the straight surface from (ax, ay) to (bx, by) facing (`normalX`, `normalY`): as
  /// `addPoint` with the distance of each cell to the nearest point of the segment (the point's
  /// case when both ends coincide). For surfaces sampled sparsely (beams 10 cm apart on a wall at
  /// 12 m), where the distance to the points alone would be up to half their spacing too large
  /// on the wall itself. Both ends must lie inside the area (`OutOfRange` otherwise); counted as
  /// one surface point. Work: the cells within maxDistance of the segment's bounding box.
  Status addSegment(double ax, double ay, double bx, double by, double normalX, double normalY) noexcept;

  /// The same restricted to the cells of `cells` (within the area), whether or not the segment's
  /// ends lie inside the area: for rebuilding a field whose area moved (a surface that crosses the
  /// area's edge is kept up to the edge). Counted as one surface point. `NonFiniteInput`,
  /// `InvalidArgument` (zero normal), `NotInitialized`.
  Status addSegmentIn(const CellRange& cells, double ax, double ay, double bx, double by, double normalX,
                      double normalY) noexcept;

  /// Moves the area by whole cells: the cell (ix, iy) takes the value of the cell (ix + dx, iy + dy)
  /// where that one exists and is free (saturated) elsewhere; the origin becomes (`originX`,
  /// `originY`), which the caller computes as the old origin plus (dx, dy) cells (passed, not
  /// accumulated here, so that repeated moves do not drift). The cells that came from the old
  /// area are exactly what adding the same surfaces anew would give them; the others must be
  /// added again (`addSegmentIn`). Built state and counts are kept. `NotInitialized`,
  /// `NonFiniteInput` (origin), `OutOfRange` (|dx| >= width or |dy| >= height: nothing overlaps).
  Status shift(long dx, long dy, double originX, double originY) noexcept;

  /// Makes the field ready for `sample`. `NotInitialized` (not configured), `EmptyInput` (no
  /// surface point). Points may still be added afterwards (the field stays usable).
  Status build() noexcept;

  /// Signed distance to the nearest surface and its gradient at a world point (bilinear between the
  /// four nearest cell centres). Before `build`, outside the area, for a non-finite point, or where
  /// one of the four cells has no surface within maxDistance: `inside = false` and the saturated
  /// distance.
  FieldSample sample(double x, double y) const noexcept;

  /// `sample(x, y).distance` alone, without the gradient (the same value, bit for bit): the
  /// saturated maxDistance wherever `sample` says not inside. For the loops that only score poses.
  double distance(double x, double y) const noexcept;

  /// The same at grid coordinates u = (x - originX) / resolution - 0.5, v likewise (cell centres
  /// at whole values): for loops that move many points by one offset, which then costs an addition
  /// per point. Non-finite coordinates give the saturated distance.
  double distanceAtGrid(double u, double v) const noexcept;

  /// The stored signed distance of cell (ix, iy) [m] (maxDistance outside or before build).
  double cellDistance(std::size_t ix, std::size_t iy) const noexcept;

  bool built() const noexcept { return built_; }
  std::size_t width() const noexcept { return width_; }
  std::size_t height() const noexcept { return height_; }
  std::size_t capacity() const noexcept { return capacity_; }
  std::size_t surfacePoints() const noexcept { return surfacePoints_; }
  std::size_t pointsOutside() const noexcept { return pointsOutside_; }
  double originX() const noexcept { return originX_; }
  double originY() const noexcept { return originY_; }
  const LikelihoodFieldParams& params() const noexcept { return params_; }

 protected:
  LikelihoodFieldBase(std::int8_t* cells, std::size_t capacity) noexcept : cells_(cells), capacity_(capacity) {}
  ~LikelihoodFieldBase() = default;

 private:
  /// `NotInitialized`, `NonFiniteInput` or `InvalidArgument` (zero normal) for a segment to add.
  Status checkSegment(double ax, double ay, double bx, double by, double normalX, double normalY) const noexcept;
  /// Writes the segment's distances into the cells of columns [cx0, cx1] and rows [cy0, cy1]
  /// (inclusive, within the area) that lie within maxDistance of it.
  void paintSegment(double ax, double ay, double bx, double by, double normalX, double normalY, long cx0, long cx1,
                    long cy0, long cy1) noexcept;

  std::int8_t* cells_;
  std::size_t capacity_;
  LikelihoodFieldParams params_{};
  double originX_ = 0.0;
  double originY_ = 0.0;
  double quantum_ = 0.5 / 127.0;  // [m] per stored unit
  std::size_t width_ = 0;
  std::size_t height_ = 0;
  std::size_t surfacePoints_ = 0;
  std::size_t pointsOutside_ = 0;
  bool built_ = false;
};

inline double LikelihoodFieldBase::distance(double x, double y) const noexcept {
  if (!std::isfinite(x) || !std::isfinite(y)) {
    return params_.maxDistance;
  }
  return distanceAtGrid((x - originX_) / params_.resolution - 0.5, (y - originY_) / params_.resolution - 0.5);
}

inline double LikelihoodFieldBase::distanceAtGrid(double u, double v) const noexcept {
  // NaN fails every comparison below; an infinity fails the upper bounds.
  if (!built_ || !(u >= 0.0) || !(v >= 0.0) || u >= static_cast<double>(width_ - 1) ||
      v >= static_cast<double>(height_ - 1)) {
    return params_.maxDistance;
  }
  const auto i = static_cast<std::size_t>(u);
  const auto j = static_cast<std::size_t>(v);
  const double fx = u - static_cast<double>(i);
  const double fy = v - static_cast<double>(j);
  const std::int8_t* row0 = cells_ + j * width_ + i;
  const std::int8_t* row1 = row0 + width_;
  constexpr std::int8_t saturated = 127;
  if (row0[0] == saturated || row0[1] == saturated || row1[0] == saturated || row1[1] == saturated) {
    return params_.maxDistance;
  }
  const double d00 = static_cast<double>(row0[0]) * quantum_;
  const double d10 = static_cast<double>(row0[1]) * quantum_;
  const double d01 = static_cast<double>(row1[0]) * quantum_;
  const double d11 = static_cast<double>(row1[1]) * quantum_;
  return (1.0 - fy) * ((1.0 - fx) * d00 + fx * d10) + fy * ((1.0 - fx) * d01 + fx * d11);
}

/// A likelihood field with room for `MaxCells` cells (one byte each) inside the object: give it
/// static storage or allocate it once.
template <std::size_t MaxCells>
class LikelihoodField : public LikelihoodFieldBase {
  static_assert(MaxCells >= 4, "a likelihood field needs at least 2 x 2 cells");

 public:
  LikelihoodField() noexcept : LikelihoodFieldBase(storage_, MaxCells) {}

 private:
  std::int8_t storage_[MaxCells] = {};
};

}  // namespace agv
