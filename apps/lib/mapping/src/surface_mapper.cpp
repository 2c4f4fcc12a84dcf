#include "agv/mapping/surface_mapper.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

namespace agv::mapping {

SurfaceMapper::SurfaceMapper(double resolution) : resolution_(resolution > 0.0 ? resolution : 0.05) {}

void SurfaceMapper::add(const Eigen::Vector2d& world, const Eigen::Vector2d& sensor) {
  if (!world.allFinite() || !sensor.allFinite()) {
    return;
  }
  const auto cx = static_cast<std::int64_t>(std::floor(world.x() / resolution_));
  const auto cy = static_cast<std::int64_t>(std::floor(world.y() / resolution_));
  const std::uint64_t key = (static_cast<std::uint64_t>(cx) << 32U) ^ (static_cast<std::uint64_t>(cy) & 0xffffffffULL);
  Cell& c = cells_[key];
  c.x += world.x();
  c.y += world.y();
  c.xx += world.x() * world.x();
  c.xy += world.x() * world.y();
  c.yy += world.y() * world.y();
  const Eigen::Vector2d v = sensor - world;
  if (v.squaredNorm() > 0.0) {
    c.view += v.normalized();
  }
  ++c.points;
  if (c.lastScan != scan_) {
    c.lastScan = scan_;
    ++c.scans;
  }
  ++points_;
  minX_ = std::min(minX_, world.x());
  minY_ = std::min(minY_, world.y());
  maxX_ = std::max(maxX_, world.x());
  maxY_ = std::max(maxY_, world.y());
}

Status SurfaceMapper::build(const LikelihoodFieldParams& params, std::size_t minScans, LikelihoodFieldBase& field,
                            std::string& error) const {
  if (points_ == 0) {
    error = "the mapping run has no surface point";
    return Status::EmptyInput;
  }
  const double res = params.resolution;
  const double margin = params.maxDistance + 2.0 * res;
  const double ox = minX_ - margin;
  const double oy = minY_ - margin;
  const auto width = static_cast<std::size_t>(std::ceil((maxX_ - minX_ + 2.0 * margin) / res));
  const auto height = static_cast<std::size_t>(std::ceil((maxY_ - minY_ + 2.0 * margin) / res));
  const Status st = field.configure(params, ox, oy, width, height);
  if (st != Status::Ok) {
    error = "likelihood field of " + std::to_string(width) + " x " + std::to_string(height) + " cells refused (" +
            toString(st) + "; capacity " + std::to_string(field.capacity()) + " cells)";
    return st;
  }
  for (const auto& kv : cells_) {
    const Cell& c = kv.second;
    if (c.scans < minScans) {
      continue;
    }
    const double n = static_cast<double>(c.points);
    const Eigen::Vector2d mean(c.x / n, c.y / n);
    Eigen::Matrix2d cov;
    cov << c.xx / n - mean.x() * mean.x(), c.xy / n - mean.x() * mean.y(), c.xy / n - mean.x() * mean.y(),
        c.yy / n - mean.y() * mean.y();
    Eigen::Vector2d normal = c.view;
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(cov);
    if (c.points >= 3 && es.eigenvalues()(1) > 4.0 * es.eigenvalues()(0)) {
      normal = es.eigenvectors().col(0);
      if (normal.dot(c.view) < 0.0) {
        normal = -normal;
      }
    }
    if (normal.squaredNorm() > 0.0) {
      (void)field.addPoint(mean.x(), mean.y(), normal.x(), normal.y());
    }
  }
  if (field.build() != Status::Ok) {
    error = "the mapping run leaves no surface seen in " + std::to_string(minScans) + " scans";
    return Status::EmptyInput;
  }
  return Status::Ok;
}

}  // namespace agv::mapping
