#include "agv/localization/likelihood_field.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace agv {

namespace {
constexpr std::int8_t kSaturated = 127;
constexpr double kBehindCos = 0.70710678118654752;  // cos 45 deg
}  // namespace

Status LikelihoodFieldParams::validate() const noexcept {
  if (!std::isfinite(resolution) || !std::isfinite(maxDistance)) {
    return Status::NonFiniteInput;
  }
  if (!(resolution > 0.0) || !(maxDistance > 2.0 * resolution) || maxDistance > 127.0 * resolution) {
    return Status::InvalidArgument;
  }
  return Status::Ok;
}

Status LikelihoodFieldBase::configure(const LikelihoodFieldParams& params, double originX, double originY,
                                      std::size_t width, std::size_t height) noexcept {
  width_ = 0;
  height_ = 0;
  surfacePoints_ = 0;
  pointsOutside_ = 0;
  built_ = false;
  const Status valid = params.validate();
  if (valid != Status::Ok) {
    return valid;
  }
  if (!std::isfinite(originX) || !std::isfinite(originY)) {
    return Status::NonFiniteInput;
  }
  if (width < 2 || height < 2) {
    return Status::InvalidArgument;
  }
  if (width > capacity_ / height) {
    return Status::CapacityExceeded;
  }
  params_ = params;
  originX_ = originX;
  originY_ = originY;
  quantum_ = params.maxDistance / 127.0;
  width_ = width;
  height_ = height;
  const std::size_t n = width * height;
  for (std::size_t i = 0; i < n; ++i) {
    cells_[i] = kSaturated;
  }
  return Status::Ok;
}

Status LikelihoodFieldBase::addPoint(double x, double y, double normalX, double normalY) noexcept {
  return addSegment(x, y, x, y, normalX, normalY);
}

Status LikelihoodFieldBase::checkSegment(double ax, double ay, double bx, double by, double normalX,
                                         double normalY) const noexcept {
  if (width_ == 0) {
    return Status::NotInitialized;
  }
  if (!std::isfinite(ax) || !std::isfinite(ay) || !std::isfinite(bx) || !std::isfinite(by) || !std::isfinite(normalX) ||
      !std::isfinite(normalY)) {
    return Status::NonFiniteInput;
  }
  if (normalX == 0.0 && normalY == 0.0) {
    return Status::InvalidArgument;
  }
  return Status::Ok;
}

Status LikelihoodFieldBase::addSegment(double ax, double ay, double bx, double by, double normalX,
                                       double normalY) noexcept {
  const Status valid = checkSegment(ax, ay, bx, by, normalX, normalY);
  if (valid != Status::Ok) {
    return valid;
  }
  // Grid coordinates of both ends; both must lie inside the area.
  const double ua = (ax - originX_) / params_.resolution;
  const double va = (ay - originY_) / params_.resolution;
  const double ub = (bx - originX_) / params_.resolution;
  const double vb = (by - originY_) / params_.resolution;
  const double W = static_cast<double>(width_);
  const double H = static_cast<double>(height_);
  if (!(ua >= 0.0) || !(va >= 0.0) || ua >= W || va >= H || !(ub >= 0.0) || !(vb >= 0.0) || ub >= W || vb >= H) {
    ++pointsOutside_;
    return Status::OutOfRange;
  }
  paintSegment(ax, ay, bx, by, normalX, normalY, 0L, static_cast<long>(width_) - 1, 0L, static_cast<long>(height_) - 1);
  ++surfacePoints_;
  return Status::Ok;
}

void LikelihoodFieldBase::paintSegment(double ax, double ay, double bx, double by, double normalX, double normalY,
                                       long cx0, long cx1, long cy0, long cy1) noexcept {
  const double ua = (ax - originX_) / params_.resolution;
  const double va = (ay - originY_) / params_.resolution;
  const double ub = (bx - originX_) / params_.resolution;
  const double vb = (by - originY_) / params_.resolution;
  const double normalLength = std::hypot(normalX, normalY);
  const auto w = static_cast<long>(std::ceil(params_.maxDistance / params_.resolution));
  const long iw = static_cast<long>(width_);
  // The cells within w of the ends' cells (floor: the ends may lie outside the area here), clipped
  // to the range asked for; in double first, so that a far segment cannot overflow a long.
  const double fx0 = std::floor(std::min(ua, ub)) - static_cast<double>(w);
  const double fx1 = std::floor(std::max(ua, ub)) + static_cast<double>(w);
  const double fy0 = std::floor(std::min(va, vb)) - static_cast<double>(w);
  const double fy1 = std::floor(std::max(va, vb)) + static_cast<double>(w);
  if (fx1 < static_cast<double>(cx0) || fx0 > static_cast<double>(cx1) || fy1 < static_cast<double>(cy0) ||
      fy0 > static_cast<double>(cy1)) {
    return;  // no cell of the range within reach
  }
  const long x0 = std::max(cx0, static_cast<long>(std::max(fx0, static_cast<double>(cx0))));
  const long x1 = std::min(cx1, static_cast<long>(std::min(fx1, static_cast<double>(cx1))));
  const long y0 = std::max(cy0, static_cast<long>(std::max(fy0, static_cast<double>(cy0))));
  const long y1 = std::min(cy1, static_cast<long>(std::min(fy1, static_cast<double>(cy1))));
  // In the area's frame (metres from the origin).
  const double px = ax - originX_;
  const double py = ay - originY_;
  const double ex = bx - ax;
  const double ey = by - ay;
  const double e2 = ex * ex + ey * ey;
  // Squared distances at or beyond this are beyond maxDistance whatever the rounding of the root
  // (a margin of 1e-9, far above it): such cells are skipped without the square root.
  const double farSquared = params_.maxDistance * params_.maxDistance * (1.0 + 1e-9);
  // Per row, the cells that can lie within maxDistance: a point within it of the segment is within
  // sqrt(maxDistance^2 - dy^2) in x of the segment's x-range, dy the row's distance from its
  // y-range (one cell of margin for the cell centres; the distance test below decides).
  const double segXMin = std::min(px, px + ex);
  const double segXMax = std::max(px, px + ex);
  const double segYMin = std::min(py, py + ey);
  const double segYMax = std::max(py, py + ey);
  // [1/m] the stored units per metre, for the bound below; the margin (half a quantum for the
  // rounding, and far more than this product's rounding error) keeps the skip conservative.
  const double perQuantum = 1.0 / quantum_;
  constexpr double kSkipMargin = 0.5 + 1e-6;
  for (long iy = y0; iy <= y1; ++iy) {
    const double cy = (static_cast<double>(iy) + 0.5) * params_.resolution;
    const double dyRow = cy < segYMin ? segYMin - cy : (cy > segYMax ? cy - segYMax : 0.0);
    if (dyRow >= params_.maxDistance) {
      continue;
    }
    const double reach = std::sqrt(params_.maxDistance * params_.maxDistance - dyRow * dyRow);
    const double fr0 = std::floor((segXMin - reach) / params_.resolution) - 1.0;
    const double fr1 = std::floor((segXMax + reach) / params_.resolution) + 1.0;
    const long rx0 = fr0 > static_cast<double>(x0) ? static_cast<long>(fr0) : x0;
    const long rx1 = fr1 < static_cast<double>(x1) ? static_cast<long>(fr1) : x1;
    std::int8_t* const row = &cells_[static_cast<std::size_t>(iy * iw)];
    for (long ix = rx0; ix <= rx1; ++ix) {
      std::int8_t& cell = row[ix];
      if (cell == 0) {
        continue;  // a surface passes through the cell already: nothing is nearer
      }
      const double cx = (static_cast<double>(ix) + 0.5) * params_.resolution;
      // The segment's distance is at least the cell centre's distance to its bounding box (the
      // larger of the row's and the column's); when the cell already holds a distance at most
      // that bound less half a quantum, the segment's rounded distance cannot be smaller: the
      // projection and the root are skipped (the cell stays as the full test would leave it).
      const double dxCol = cx < segXMin ? segXMin - cx : (cx > segXMax ? cx - segXMax : 0.0);
      const double bound = (dxCol > dyRow ? dxCol : dyRow) * perQuantum - kSkipMargin;
      if (static_cast<double>(cell < 0 ? -cell : cell) <= bound) {
        continue;
      }
      // The nearest point of the segment to the cell centre.
      double t = e2 > 0.0 ? ((cx - px) * ex + (cy - py) * ey) / e2 : 0.0;
      t = t < 0.0 ? 0.0 : (t > 1.0 ? 1.0 : t);
      const double dx = cx - (px + t * ex);
      const double dy = cy - (py + t * ey);
      const double d2 = dx * dx + dy * dy;
      if (d2 >= farSquared) {
        continue;
      }
      const double d = std::sqrt(d2);
      if (d >= params_.maxDistance) {
        continue;
      }
      // d / quantum rounded half away from zero (std::lround for a non-negative value, inline:
      // the fraction of a double below 2^52 is exact).
      const double r = d / quantum_;
      long q = static_cast<long>(r);
      q += r - static_cast<double>(q) >= 0.5 ? 1L : 0L;
      if (q < (cell < 0 ? -cell : cell)) {
        // Behind only when clearly so (within 45 deg of straight behind): beyond the end of a face
        // (the corner of a box seen from outside) the nearest point's own normal says nothing.
        const bool behind = dx * normalX + dy * normalY < -kBehindCos * d * normalLength;
        cell = static_cast<std::int8_t>(behind ? -q : q);
      }
    }
  }
}

Status LikelihoodFieldBase::addSegmentIn(const CellRange& cells, double ax, double ay, double bx, double by,
                                         double normalX, double normalY) noexcept {
  const Status valid = checkSegment(ax, ay, bx, by, normalX, normalY);
  if (valid != Status::Ok) {
    return valid;
  }
  const std::size_t x1 = std::min(cells.x1, width_);
  const std::size_t y1 = std::min(cells.y1, height_);
  if (cells.x0 < x1 && cells.y0 < y1) {
    paintSegment(ax, ay, bx, by, normalX, normalY, static_cast<long>(cells.x0), static_cast<long>(x1) - 1,
                 static_cast<long>(cells.y0), static_cast<long>(y1) - 1);
  }
  ++surfacePoints_;
  return Status::Ok;
}

Status LikelihoodFieldBase::shift(long dx, long dy, double originX, double originY) noexcept {
  if (width_ == 0) {
    return Status::NotInitialized;
  }
  if (!std::isfinite(originX) || !std::isfinite(originY)) {
    return Status::NonFiniteInput;
  }
  const long iw = static_cast<long>(width_);
  const long ih = static_cast<long>(height_);
  if (dx <= -iw || dx >= iw || dy <= -ih || dy >= ih) {
    return Status::OutOfRange;
  }
  // Rows in the order that reads each source row before it is overwritten.
  for (long k = 0; k < ih; ++k) {
    const long iy = dy >= 0 ? k : ih - 1 - k;
    std::int8_t* const row = &cells_[static_cast<std::size_t>(iy * iw)];
    const long sy = iy + dy;
    if (sy < 0 || sy >= ih) {
      std::memset(row, kSaturated, width_);
      continue;
    }
    const std::int8_t* const src = &cells_[static_cast<std::size_t>(sy * iw)];
    // Columns [c0, c1) take the source's [c0 + dx, c1 + dx); the rest is free.
    const long c0 = dx < 0 ? -dx : 0;
    const long c1 = dx > 0 ? iw - dx : iw;
    std::memmove(row + c0, src + c0 + dx, static_cast<std::size_t>(c1 - c0));
    std::memset(row, kSaturated, static_cast<std::size_t>(c0));
    std::memset(row + c1, kSaturated, static_cast<std::size_t>(iw - c1));
  }
  originX_ = originX;
  originY_ = originY;
  return Status::Ok;
}

Status LikelihoodFieldBase::build() noexcept {
  if (width_ == 0) {
    return Status::NotInitialized;
  }
  if (surfacePoints_ == 0) {
    return Status::EmptyInput;
  }
  built_ = true;
  return Status::Ok;
}

double LikelihoodFieldBase::cellDistance(std::size_t ix, std::size_t iy) const noexcept {
  if (!built_ || ix >= width_ || iy >= height_) {
    return params_.maxDistance;
  }
  return static_cast<double>(cells_[ix + iy * width_]) * quantum_;
}

FieldSample LikelihoodFieldBase::sample(double x, double y) const noexcept {
  FieldSample s;
  s.distance = params_.maxDistance;
  if (!built_ || !std::isfinite(x) || !std::isfinite(y)) {
    return s;
  }
  // Cell centres sit at origin + (i + 0.5) * resolution.
  const double u = (x - originX_) / params_.resolution - 0.5;
  const double v = (y - originY_) / params_.resolution - 0.5;
  if (!(u >= 0.0) || !(v >= 0.0) || u >= static_cast<double>(width_ - 1) || v >= static_cast<double>(height_ - 1)) {
    return s;
  }
  const auto i = static_cast<std::size_t>(u);
  const auto j = static_cast<std::size_t>(v);
  const double fx = u - static_cast<double>(i);
  const double fy = v - static_cast<double>(j);
  const std::int8_t* row0 = cells_ + j * width_ + i;
  const std::int8_t* row1 = row0 + width_;
  // A saturated corner means "no surface within maxDistance" on one side and a distance on the
  // other: interpolating across it would invent a zero crossing behind every wall. Unknown.
  if (row0[0] == kSaturated || row0[1] == kSaturated || row1[0] == kSaturated || row1[1] == kSaturated) {
    return s;
  }
  const double d00 = static_cast<double>(row0[0]) * quantum_;
  const double d10 = static_cast<double>(row0[1]) * quantum_;
  const double d01 = static_cast<double>(row1[0]) * quantum_;
  const double d11 = static_cast<double>(row1[1]) * quantum_;
  s.distance = (1.0 - fy) * ((1.0 - fx) * d00 + fx * d10) + fy * ((1.0 - fx) * d01 + fx * d11);
  s.gradient.x() = ((1.0 - fy) * (d10 - d00) + fy * (d11 - d01)) / params_.resolution;
  s.gradient.y() = ((1.0 - fx) * (d01 - d00) + fx * (d11 - d10)) / params_.resolution;
  s.inside = true;
  return s;
}

}  // namespace agv
