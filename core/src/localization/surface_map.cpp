#include "agv/localization/surface_map.hpp"

#include <cmath>

namespace agv {

Status SurfaceMapParams::validate() const noexcept {
  const Status f = field.validate();
  if (f != Status::Ok) {
    return f;
  }
  if (!std::isfinite(side) || !std::isfinite(recentreMargin) || !std::isfinite(newSurfaceDistance) ||
      !std::isfinite(maxRange) || !std::isfinite(normalSpan) || !std::isfinite(gridOffsetX) ||
      !std::isfinite(gridOffsetY)) {
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

bool mayExtendFallbackMap(const LocalizerHealth& health) noexcept {
  if (health.status != Status::Ok || health.lost) {
    return false;
  }
  if (health.scanMatch.fused) {
    return true;
  }
  const ScanMatchHealth& f = health.fallbackMatch;
  if (f.attempted) {
    return f.fused || f.status == Status::NotEnoughData;
  }
  return health.scanMatch.attempted && health.scanMatch.status == Status::NotEnoughData;
}

ScanMatchParams surfaceMapMatching(const ScanMatchParams& base) noexcept {
  ScanMatchParams p = base;
  p.resyncAfter = 0;
  p.widenAfter = 0;
  p.softGate = true;
  return p;
}

void SurfaceMapBase::clear() noexcept {
  head_ = 0;
  size_ = 0;
  added_ = 0;
  dropped_ = 0;
  recentres_ = 0;
  droppedAtRebuild_ = 0;
  anchored_ = false;
  // An unconfigured field: the next insert centres it on its sensor.
  static_cast<void>(field_.configure(LikelihoodFieldParams{}, 0.0, 0.0, 0, 0));
}

void SurfaceMapBase::fill(const CellRange& cells) noexcept {
  for (std::size_t k = 0; k < size_; ++k) {
    const SurfacePiece& p = pieces_[(head_ + k) % capacity_];
    const auto ax = static_cast<double>(p.ax);
    const auto ay = static_cast<double>(p.ay);
    const auto bx = static_cast<double>(p.bx);
    const auto by = static_cast<double>(p.by);
    const auto nx = static_cast<double>(p.nx);
    const auto ny = static_cast<double>(p.ny);
    // Pieces outside the area stay in the ring (they return when the vehicle does). Without
    // `recentreByShift`, a piece with an end outside the area is left out whole.
    static_cast<void>(params_.recentreByShift ? field_.addSegmentIn(cells, ax, ay, bx, by, nx, ny)
                                              : field_.addSegment(ax, ay, bx, by, nx, ny));
  }
}

Status SurfaceMapBase::rebuild() noexcept {
  if (field_.width() == 0) {
    return Status::NotInitialized;
  }
  const Status s = field_.configure(params_.field, field_.originX(), field_.originY(), field_.width(), field_.height());
  if (s != Status::Ok) {
    return s;
  }
  fill(CellRange{0, 0, field_.width(), field_.height()});
  if (size_ > 0) {
    static_cast<void>(field_.build());
  }
  droppedAtRebuild_ = dropped_;
  return Status::Ok;
}

Status SurfaceMapBase::recentre(double x, double y) noexcept {
  const double res = params_.field.resolution;
  const auto cells = static_cast<std::size_t>(std::ceil(params_.side / res));
  const double half = 0.5 * static_cast<double>(cells) * res;
  if (!anchored_ || !params_.recentreByShift) {
    // The first insert, or every recentre without moving by cells: centred on (x, y) exactly.
    anchorX_ = x - half + params_.gridOffsetX;
    anchorY_ = y - half + params_.gridOffsetY;
    anchored_ = true;
  }
  // The grid's cell nearest to centring the square on (x, y); origins computed from the anchor,
  // never accumulated.
  const double cx = std::round((x - half - anchorX_) / res);
  const double cy = std::round((y - half - anchorY_) / res);
  const double originX = anchorX_ + cx * res;
  const double originY = anchorY_ + cy * res;
  const double dx = cx - cellX_;
  const double dy = cy - cellY_;
  const double n = static_cast<double>(cells);
  const bool movable = params_.recentreByShift && field_.width() == cells && field_.height() == cells &&
                       dropped_ == droppedAtRebuild_ && std::fabs(dx) < n && std::fabs(dy) < n;
  if (movable) {
    const auto ix = static_cast<long>(dx);
    const auto iy = static_cast<long>(dy);
    const Status s = field_.shift(ix, iy, originX, originY);
    if (s != Status::Ok) {
      return s;
    }
    cellX_ = cx;
    cellY_ = cy;
    // The uncovered strips: the columns that came in (full height), then the rows that came in
    // (the other columns).
    const std::size_t ax = static_cast<std::size_t>(ix < 0 ? -ix : ix);
    const std::size_t ay = static_cast<std::size_t>(iy < 0 ? -iy : iy);
    const std::size_t c0 = ix < 0 ? ax : 0;
    const std::size_t c1 = ix > 0 ? cells - ax : cells;
    if (ax > 0) {
      fill(ix > 0 ? CellRange{c1, 0, cells, cells} : CellRange{0, 0, c0, cells});
    }
    if (ay > 0) {
      fill(iy > 0 ? CellRange{c0, cells - ay, c1, cells} : CellRange{c0, 0, c1, ay});
    }
    ++recentres_;
    return Status::Ok;
  }
  const Status s = field_.configure(params_.field, originX, originY, cells, cells);
  if (s != Status::Ok) {
    return s;
  }
  cellX_ = cx;
  cellY_ = cy;
  fill(CellRange{0, 0, cells, cells});
  if (size_ > 0) {
    static_cast<void>(field_.build());
  }
  droppedAtRebuild_ = dropped_;
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

bool SurfaceMapBase::offer(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& n) noexcept {
  if (field_.built()) {
    const Eigen::Vector2d mid = 0.5 * (a + b);
    bool known = true;
    for (const Eigen::Vector2d& q : {a, mid, b}) {
      const FieldSample f = field_.sample(q.x(), q.y());
      known = known && f.inside && std::fabs(f.distance) < params_.newSurfaceDistance;
    }
    if (known) {
      return false;
    }
  }
  if (field_.addSegment(a.x(), a.y(), b.x(), b.y(), n.x(), n.y()) != Status::Ok) {
    return false;  // an end outside the field, or a degenerate normal
  }
  const SurfacePiece piece{static_cast<float>(a.x()), static_cast<float>(a.y()), static_cast<float>(b.x()),
                           static_cast<float>(b.y()), static_cast<float>(n.x()), static_cast<float>(n.y())};
  if (size_ == capacity_) {
    pieces_[head_] = piece;  // overwrite the oldest
    head_ = (head_ + 1) % capacity_;
    ++dropped_;
  } else {
    pieces_[(head_ + size_) % capacity_] = piece;
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

void SurfaceMapBase::takenBeams(const LaserScan& scan, MatchPoints& out) const noexcept {
  scanToMatchPoints(scan, out, params_.maxRange);
}

SurfaceInsert SurfaceMapBase::insert(const LaserScan& scan, const Pose2d& sensor) noexcept {
  takenBeams(scan, scratch_);
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
  bool previousJoined = false;  // beam i - 1 and beam i lie on one surface
  for (std::size_t i = 0; i < n; ++i) {
    Eigen::Vector2d p;
    if (!usable(i, p)) {
      previousJoined = false;
      continue;
    }
    ++out.beams;
    // The surface between this beam and the next one on it (laser frame), its normal across it
    // on the sensor's side; a beam with no neighbour on its surface is a point facing back along
    // the beam.
    Eigen::Vector2d q;
    const bool joined = i + 1 < n && usable(i + 1, q) && (q - p).squaredNorm() <= span2;
    Eigen::Vector2d end = p;
    Eigen::Vector2d normal = -p;
    if (joined) {
      end = q;
      const Eigen::Vector2d across(-(q - p).y(), (q - p).x());
      normal = across.dot(-p) >= 0.0 ? across : Eigen::Vector2d(-across);
    } else if (previousJoined) {
      previousJoined = false;
      continue;  // the end of a surface already added with the beam before
    }
    previousJoined = joined;
    if (offer(sensor.transformPoint(p), sensor.transformPoint(end), sensor.rotation() * normal)) {
      ++out.added;
    }
  }
  finish();
  return out;
}

}  // namespace agv
