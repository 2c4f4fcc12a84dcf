#pragma once
/// @file surface_mapper.hpp
/// The surfaces of a mapping run, collected scan by scan (world points with the sensor position
/// they were seen from) and turned into a `LikelihoodFieldBase` for scan-to-map matching: one
/// surface point per cell of the field's resolution seen in enough scans (a person walking through
/// the mapping run leaves no wall behind), at the mean of its points, facing the side it was seen
/// from (the normal of the points' principal axes when they form a line, else the mean direction
/// to the sensor). Host code (heap, offline or at start-up).

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <string>
#include <unordered_map>

#include "agv/core/status.hpp"
#include "agv/localization/likelihood_field.hpp"

namespace agv::mapping {

class SurfaceMapper {
 public:
  /// `resolution` [m] of the cells the points are pooled in (use the field's).
  explicit SurfaceMapper(double resolution = LikelihoodFieldParams{}.resolution);

  /// Starts the next scan (points of one scan count once per cell).
  void beginScan() noexcept { ++scan_; }
  /// A surface point `world` seen from `sensor` (world frame). Non-finite points are skipped.
  void add(const Eigen::Vector2d& world, const Eigen::Vector2d& sensor);

  std::size_t points() const noexcept { return points_; }
  std::size_t cells() const noexcept { return cells_.size(); }

  /// Configures `field` with `params` over the points' bounding box plus maxDistance and two cells,
  /// and adds the surface of every cell seen in at least `minScans` scans, then builds it.
  /// `EmptyInput` (no point, or no cell seen often enough), or the field's refusal (e.g.
  /// `CapacityExceeded` when the area does not fit), with `error` saying which.
  Status build(const LikelihoodFieldParams& params, std::size_t minScans, LikelihoodFieldBase& field,
               std::string& error) const;

 private:
  struct Cell {
    double x = 0.0, y = 0.0, xx = 0.0, xy = 0.0, yy = 0.0;
    Eigen::Vector2d view = Eigen::Vector2d::Zero();
    std::uint32_t points = 0;
    std::uint32_t scans = 0;
    std::uint64_t lastScan = 0;
  };
  double resolution_;
  std::uint64_t scan_ = 1;
  std::size_t points_ = 0;
  double minX_ = 1e300, minY_ = 1e300, maxX_ = -1e300, maxY_ = -1e300;
  std::unordered_map<std::uint64_t, Cell> cells_;
};

}  // namespace agv::mapping
