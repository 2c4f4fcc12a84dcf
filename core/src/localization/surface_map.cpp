#include "agv/localization/surface_map.hpp"

#include <cmath>

namespace agv {

Status SurfaceMapParams::validate() const noexcept {
  const Status f = field.validate();
  if (f != Status::Ok) {
    return f;
  }
  if (!std::isfinite(side) || !std::isfinite(recentreMargin) || !std::isfinite(newSurfaceDistance) ||
      !std::isfinite(maxRange) || !std::isfinite(normalSpan)) {
    return Status::NonFiniteInput;
  }
  if (!(side > 0.0) || recentreMargin < 0.0 || !(recentreMargin < 0.5 * side) || !(newSurfaceDistance > 0.0) ||
      !(maxRange > 0.0) || !(normalSpan > 0.0) || side / field.resolution < 2.0) {
    return Status::InvalidArgument;
  }
  return Status::Ok;
}

bool mayExtendSurfaceMap(const LocalizerHealth& health) noexcept {
  if (health.status != Status::Ok || health.lost) {
    return false;
  }
  const ScanMatchHealth& m = health.scanMatch;
  return !m.attempted || m.fused || m.status == Status::NotEnoughData;
}

ScanMatchParams surfaceMapMatching(const ScanMatchParams& base) noexcept {
  ScanMatchParams p = base;
  p.resyncAfter = 0;
  p.widenAfter = 0;
  return p;
}

void SurfaceMapBase::clear() noexcept {
  head_ = 0;
  size_ = 0;
  added_ = 0;
  dropped_ = 0;
  recentres_ = 0;
  // An unconfigured field: the next insert centres it on its sensor.
  static_cast<void>(field_.configure(LikelihoodFieldParams{}, 0.0, 0.0, 0, 0));
}

Status SurfaceMapBase::recentre(double x, double y) noexcept {
  const auto cells = static_cast<std::size_t>(std::ceil(params_.side / params_.field.resolution));
  const double half = 0.5 * static_cast<double>(cells) * params_.field.resolution;
  const Status s = field_.configure(params_.field, x - half, y - half, cells, cells);
  if (s != Status::Ok) {
    return s;
  }
  for (std::size_t k = 0; k < size_; ++k) {
    const SurfacePoint& p = points_[(head_ + k) % capacity_];
    // Points outside the new area stay in the ring (they return when the vehicle does).
    static_cast<void>(field_.addPoint(static_cast<double>(p.x), static_cast<double>(p.y), static_cast<double>(p.nx),
                                      static_cast<double>(p.ny)));
  }
  if (size_ > 0) {
    static_cast<void>(field_.build());
  }
  ++recentres_;
  return Status::Ok;
}

bool SurfaceMapBase::prepare(const Pose2d& sensor, SurfaceInsert& out) noexcept {
  out = SurfaceInsert{};
  if (valid_ != Status::Ok) {
    out.status = valid_;
    return false;
  }
  if (!sensor.isFinite()) {
    out.status = Status::NonFiniteInput;
    return false;
  }
  const double res = params_.field.resolution;
  const double x0 = field_.originX();
  const double y0 = field_.originY();
  const double x1 = x0 + static_cast<double>(field_.width()) * res;
  const double y1 = y0 + static_cast<double>(field_.height()) * res;
  const double m = params_.recentreMargin;
  if (field_.width() == 0 || sensor.x < x0 + m || sensor.x > x1 - m || sensor.y < y0 + m || sensor.y > y1 - m) {
    const Status s = recentre(sensor.x, sensor.y);
    if (s != Status::Ok) {
      out.status = s;
      return false;
    }
    out.recentred = true;
  }
  return true;
}

bool SurfaceMapBase::offer(double x, double y, double nx, double ny) noexcept {
  if (field_.built()) {
    const FieldSample f = field_.sample(x, y);
    if (f.inside && std::fabs(f.distance) < params_.newSurfaceDistance) {
      return false;
    }
  }
  if (field_.addPoint(x, y, nx, ny) != Status::Ok) {
    return false;  // outside the field (beyond maxRange of a recentred field cannot happen) or degenerate
  }
  const SurfacePoint p{static_cast<float>(x), static_cast<float>(y), static_cast<float>(nx), static_cast<float>(ny)};
  if (size_ == capacity_) {
    points_[head_] = p;  // overwrite the oldest
    head_ = (head_ + 1) % capacity_;
    ++dropped_;
  } else {
    points_[(head_ + size_) % capacity_] = p;
    ++size_;
  }
  ++added_;
  return true;
}

void SurfaceMapBase::finish() noexcept {
  if (!field_.built() && size_ > 0) {
    static_cast<void>(field_.build());
  }
}

SurfaceInsert SurfaceMapBase::insert(const LaserScan& scan, const Pose2d& sensor) noexcept {
  scratch_.clear();
  for (std::size_t i = 0; i < scan.size(); ++i) {
    if (scan.isValid(i)) {
      const double a = static_cast<double>(scan.angle(i));
      const double r = static_cast<double>(scan.ranges[i]);
      static_cast<void>(
          scratch_.push_back(MatchPoint{static_cast<float>(r * std::cos(a)), static_cast<float>(r * std::sin(a))}));
    }
  }
  return insert(scratch_, sensor);
}

SurfaceInsert SurfaceMapBase::insert(const MatchPoints& points, const Pose2d& sensor) noexcept {
  SurfaceInsert out;
  if (!prepare(sensor, out)) {
    return out;
  }
  const double r2max = params_.maxRange * params_.maxRange;
  const double span2 = params_.normalSpan * params_.normalSpan;
  const auto usable = [&](std::size_t i, Eigen::Vector2d& p) noexcept {
    p = Eigen::Vector2d(static_cast<double>(points[i].x), static_cast<double>(points[i].y));
    return p.allFinite() && p.squaredNorm() <= r2max;
  };
  const std::size_t n = points.size();
  for (std::size_t i = 0; i < n; ++i) {
    Eigen::Vector2d p;
    if (!usable(i, p)) {
      continue;
    }
    ++out.beams;
    // The surface's direction from the neighbouring beams on it (laser frame): the normal is
    // across it, on the sensor's side.
    Eigen::Vector2d before = p;
    Eigen::Vector2d after = p;
    Eigen::Vector2d q;
    if (i > 0 && usable(i - 1, q) && (q - p).squaredNorm() <= span2) {
      before = q;
    }
    if (i + 1 < n && usable(i + 1, q) && (q - p).squaredNorm() <= span2) {
      after = q;
    }
    const Eigen::Vector2d tangent = after - before;
    Eigen::Vector2d normal = -p;  // with no neighbour on its surface: back along the beam
    if (tangent.squaredNorm() > 0.0) {
      const Eigen::Vector2d across(-tangent.y(), tangent.x());
      normal = across.dot(-p) >= 0.0 ? across : Eigen::Vector2d(-across);
    }
    const Eigen::Vector2d w = sensor.transformPoint(p);
    const Eigen::Vector2d wn = sensor.rotation() * normal;
    if (offer(w.x(), w.y(), wn.x(), wn.y())) {
      ++out.added;
    }
  }
  finish();
  return out;
}

}  // namespace agv
