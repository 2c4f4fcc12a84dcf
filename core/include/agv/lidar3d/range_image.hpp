#pragma once
/// @file range_image.hpp
/// The range image of one revolution of a multi-beam lidar: rows = lasers in elevation order,
/// columns = firings (azimuth steps), each cell one return (its Cartesian point in the sensor
/// frame and its range) or invalid (no return).
///
/// `RangeImage<Lasers, Firings>` holds Lasers x Firings cells inline (capacity in the type: an MCU
/// picks `RangeImage<16, 1800>` for a VLP-16, ~460 KiB; a PLC-class computer `RangeImage<64, 2000>`
/// for an HDL-64E, 2 MiB); `RangeImageBase` is its capacity-independent interface, so the normal,
/// signature and orientation functions are not templates (the FixedVector / IVector pattern). The
/// shape in use (rows x columns) is set at run time within the capacity by `reset()`.
///
/// Two ways in:
/// - `buildFromRings`: Cartesian points that carry their ring (laser row in elevation order), e.g.
///   KITTI's points with the ring recovered from the azimuth wrap-arounds. The column is the
///   point's azimuth, atan2(y, x) in [0, 2 pi), in `columns` equal steps (column 0 starts at +x,
///   columns grow counter-clockwise seen from above).
/// - `buildFromFirings`: decoded returns that carry their hardware laser id and firing index (a
///   decoder's output); the laser id goes through a laser -> row table (see `elevationRanks`), the
///   firing index is the column.
///
/// Refusals are counted in `RangeImageStats` and named by the returned status (never silently
/// dropped): NaN/inf points, rings or lasers beyond the rows, firings beyond the columns. Two
/// returns that fall into one cell keep the nearer and count a collision (azimuth binning of points
/// that are not on a regular grid). A zero range is "no return" (Velodyne's convention).
///
/// Precision: float (ranges up to 120 m; float resolution there is 8 um).
/// Work: reset O(rows * columns); build O(points).

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>

#include "agv/core/span.hpp"
#include "agv/core/status.hpp"

namespace agv {

/// One cell: a return, or none (`range == 0`).
struct RangeCell {
  Eigen::Vector3f point = Eigen::Vector3f::Zero();  ///< [m] in the sensor frame (z up)
  float range = 0.0F;                               ///< [m] |point|; 0 = no return
  bool valid() const noexcept { return range > 0.0F; }
};

/// A Cartesian point with its ring (row in elevation order; either direction, the same for every
/// point of a revolution).
struct RingPoint {
  Eigen::Vector3f point = Eigen::Vector3f::Zero();  ///< [m] sensor frame, z up
  std::uint16_t ring = 0;
};

/// A decoded return: hardware laser id and firing index within the revolution.
struct FiringReturn {
  Eigen::Vector3f point = Eigen::Vector3f::Zero();  ///< [m] sensor frame, z up; zero = no return
  std::uint16_t laser = 0;                          ///< hardware laser id (mapped to a row by a table)
  std::uint32_t firing = 0;                         ///< firing index within the revolution (the column)
};

/// What the last build placed and refused.
struct RangeImageStats {
  std::uint32_t placed = 0;              ///< returns stored in a cell
  std::uint32_t noReturn = 0;            ///< zero points (no return; not an error)
  std::uint32_t collisions = 0;          ///< returns that fell on an occupied cell (the nearer kept)
  std::uint32_t nonFinite = 0;           ///< refused: NaN or infinite coordinate
  std::uint32_t rowOverCapacity = 0;     ///< refused: ring / laser row >= rows in use
  std::uint32_t columnOverCapacity = 0;  ///< refused: firing index >= columns in use
  /// Total refused (nonFinite + rowOverCapacity + columnOverCapacity).
  std::uint32_t refused() const noexcept { return nonFinite + rowOverCapacity + columnOverCapacity; }
};

/// Capacity-independent interface of a `RangeImage`. Not constructible on its own.
class RangeImageBase {
 public:
  RangeImageBase(const RangeImageBase&) = delete;
  RangeImageBase& operator=(const RangeImageBase&) = delete;

  /// Sets the shape in use (rows = lasers of the sensor, columns = firings per revolution) and
  /// marks every cell invalid; the stats are zeroed. InvalidArgument for a zero size,
  /// CapacityExceeded (counted in shapeRefusedCount()) beyond the capacity; the image is then
  /// left empty with its previous shape.
  Status reset(std::size_t rows, std::size_t columns) noexcept;

  /// Clears the cells of the current shape (all invalid) and zeroes the stats.
  void clear() noexcept;

  /// Stores one return at (row, column). Ok; NonFiniteInput, OutOfRange (row or column beyond
  /// the shape) refused and counted; a zero point counts as no return (Ok, cell unchanged).
  Status set(std::size_t row, std::size_t column, const Eigen::Vector3f& point) noexcept;

  /// reset()s nothing: clears the current shape, then places every point at (ring, azimuth column).
  /// Ok when every point was placed (or was a no-return); otherwise the cells hold what was placed
  /// and the status names the first kind of refusal in this order: CapacityExceeded (a ring beyond
  /// the rows), NonFiniteInput; EmptyInput for no point; NotEnoughData when no cell is valid.
  Status buildFromRings(Span<const RingPoint> points) noexcept;

  /// Clears the current shape, then places each return at (rowOfLaser[laser], firing). A laser id
  /// beyond the table or mapped to a row beyond the shape, and a firing beyond the columns, are
  /// refused (CapacityExceeded); statuses otherwise as buildFromRings.
  Status buildFromFirings(Span<const FiringReturn> returns, Span<const std::uint16_t> rowOfLaser) noexcept;

  std::size_t rows() const noexcept { return rows_; }
  std::size_t columns() const noexcept { return columns_; }
  std::size_t rowCapacity() const noexcept { return rowCapacity_; }
  std::size_t columnCapacity() const noexcept { return columnCapacity_; }
  /// Cell (row, column); precondition row < rows(), column < columns().
  const RangeCell& at(std::size_t row, std::size_t column) const noexcept { return cells_[row * columns_ + column]; }
  /// Number of valid cells.
  std::size_t validCount() const noexcept { return static_cast<std::size_t>(valid_); }
  const RangeImageStats& stats() const noexcept { return stats_; }
  /// reset() calls refused because the shape exceeded the capacity.
  std::uint32_t shapeRefusedCount() const noexcept { return shapeRefused_; }
  /// The column of azimuth atan2(y, x) of `point` with the current shape.
  std::size_t columnOf(const Eigen::Vector3f& point) const noexcept;

 protected:
  RangeImageBase(RangeCell* cells, std::size_t rowCapacity, std::size_t columnCapacity) noexcept
      : cells_(cells),
        rowCapacity_(rowCapacity),
        columnCapacity_(columnCapacity),
        rows_(rowCapacity),
        columns_(columnCapacity) {}
  ~RangeImageBase() = default;

 private:
  Status finishBuild() const noexcept;
  void place(std::size_t row, std::size_t column, const Eigen::Vector3f& point) noexcept;

  RangeCell* cells_;
  std::size_t rowCapacity_;
  std::size_t columnCapacity_;
  std::size_t rows_;
  std::size_t columns_;
  std::uint32_t valid_ = 0;
  std::uint32_t shapeRefused_ = 0;
  RangeImageStats stats_{};
};

namespace detail {
/// Inline cell storage; a base class so that it exists before RangeImageBase takes its address.
template <std::size_t N>
struct RangeImageStorage {
  std::array<RangeCell, N> cells_{};
};
}  // namespace detail

/// A range image of at most Lasers x Firings cells stored inline (large: allocate it statically or
/// as a member). Its shape starts at the full capacity.
template <std::size_t Lasers, std::size_t Firings>
class RangeImage : private detail::RangeImageStorage<Lasers * Firings>, public RangeImageBase {
  static_assert(Lasers > 0 && Firings > 0, "RangeImage capacity must be positive");
  static_assert(Lasers <= 256 && Firings <= 65535, "RangeImage: at most 256 lasers and 65535 firings");
  using Storage = detail::RangeImageStorage<Lasers * Firings>;

 public:
  static constexpr std::size_t kLasers = Lasers;
  static constexpr std::size_t kFirings = Firings;
  RangeImage() noexcept : Storage(), RangeImageBase(Storage::cells_.data(), Lasers, Firings) {}
  RangeImage(const RangeImage&) = delete;
  RangeImage& operator=(const RangeImage&) = delete;
  ~RangeImage() = default;
};

/// Range image of an HDL-64E revolution at 10 Hz (0.18 deg azimuth steps, as in KITTI).
using Hdl64RangeImage = RangeImage<64, 2000>;
/// Range image of a VLP-16 revolution at 10 Hz (0.2 deg azimuth steps).
using Vlp16RangeImage = RangeImage<16, 1800>;

/// The row of each laser in elevation order (rank 0 = lowest elevation): rowOfLaser[i] = number of
/// lasers with a lower elevation than laser i (ties by id). Ok; InvalidArgument when the sizes
/// differ or exceed 256; NonFiniteInput for a NaN elevation. O(n^2), n <= 256.
Status elevationRanks(Span<const float> elevations, Span<std::uint16_t> rowOfLaser) noexcept;

}  // namespace agv
