#include "agv/lidar3d/range_image.hpp"

#include <cmath>

#include "agv/core/angle.hpp"

namespace agv {

namespace {
bool finite3(const Eigen::Vector3f& p) noexcept {
  return std::isfinite(p.x()) && std::isfinite(p.y()) && std::isfinite(p.z());
}
}  // namespace

Status RangeImageBase::reset(std::size_t rows, std::size_t columns) noexcept {
  if (rows == 0 || columns == 0) {
    return Status::InvalidArgument;
  }
  if (rows > rowCapacity_ || columns > columnCapacity_) {
    ++shapeRefused_;
    clear();
    return Status::CapacityExceeded;
  }
  rows_ = rows;
  columns_ = columns;
  clear();
  return Status::Ok;
}

void RangeImageBase::clear() noexcept {
  const std::size_t n = rows_ * columns_;
  for (std::size_t i = 0; i < n; ++i) {
    cells_[i] = RangeCell{};
  }
  valid_ = 0;
  stats_ = RangeImageStats{};
}

std::size_t RangeImageBase::columnOf(const Eigen::Vector3f& point) const noexcept {
  float az = std::atan2(point.y(), point.x());
  if (az < 0.0F) {
    az += kTwoPi<float>;
  }
  auto c = static_cast<std::size_t>(az * (static_cast<float>(columns_) / kTwoPi<float>));
  return c < columns_ ? c : columns_ - 1;  // az rounds up to 2 pi for tiny negative angles
}

void RangeImageBase::place(std::size_t row, std::size_t column, const Eigen::Vector3f& point) noexcept {
  RangeCell& cell = cells_[row * columns_ + column];
  const float range = point.norm();
  if (cell.valid()) {
    ++stats_.collisions;
    if (range >= cell.range) {
      return;
    }
  } else {
    ++valid_;
  }
  cell.point = point;
  cell.range = range;
  ++stats_.placed;
}

Status RangeImageBase::set(std::size_t row, std::size_t column, const Eigen::Vector3f& point) noexcept {
  if (!finite3(point)) {
    ++stats_.nonFinite;
    return Status::NonFiniteInput;
  }
  if (row >= rows_) {
    ++stats_.rowOverCapacity;
    return Status::OutOfRange;
  }
  if (column >= columns_) {
    ++stats_.columnOverCapacity;
    return Status::OutOfRange;
  }
  if (point.x() == 0.0F && point.y() == 0.0F && point.z() == 0.0F) {
    ++stats_.noReturn;
    return Status::Ok;
  }
  place(row, column, point);
  return Status::Ok;
}

Status RangeImageBase::finishBuild() const noexcept {
  if (stats_.rowOverCapacity > 0 || stats_.columnOverCapacity > 0) {
    return Status::CapacityExceeded;
  }
  if (stats_.nonFinite > 0) {
    return Status::NonFiniteInput;
  }
  return valid_ == 0 ? Status::NotEnoughData : Status::Ok;
}

Status RangeImageBase::buildFromRings(Span<const RingPoint> points) noexcept {
  clear();
  if (points.empty()) {
    return Status::EmptyInput;
  }
  for (const RingPoint& p : points) {
    if (!finite3(p.point)) {
      ++stats_.nonFinite;
      continue;
    }
    if (p.ring >= rows_) {
      ++stats_.rowOverCapacity;
      continue;
    }
    (void)set(p.ring, columnOf(p.point), p.point);
  }
  return finishBuild();
}

Status RangeImageBase::buildFromFirings(Span<const FiringReturn> returns,
                                        Span<const std::uint16_t> rowOfLaser) noexcept {
  clear();
  if (returns.empty()) {
    return Status::EmptyInput;
  }
  for (const FiringReturn& r : returns) {
    if (r.laser >= rowOfLaser.size()) {
      ++stats_.rowOverCapacity;
      continue;
    }
    (void)set(rowOfLaser[r.laser], r.firing, r.point);  // refusals counted by set()
  }
  return finishBuild();
}

Status elevationRanks(Span<const float> elevations, Span<std::uint16_t> rowOfLaser) noexcept {
  const std::size_t n = elevations.size();
  if (n != rowOfLaser.size() || n > 256) {
    return Status::InvalidArgument;
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(elevations[i])) {
      return Status::NonFiniteInput;
    }
  }
  for (std::size_t i = 0; i < n; ++i) {
    std::uint16_t rank = 0;
    for (std::size_t j = 0; j < n; ++j) {
      if (elevations[j] < elevations[i] || (elevations[j] == elevations[i] && j < i)) {
        ++rank;
      }
    }
    rowOfLaser[i] = rank;
  }
  return Status::Ok;
}

}  // namespace agv
