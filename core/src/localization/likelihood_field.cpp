#include "agv/localization/likelihood_field.hpp"

#include <cmath>

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
  if (width_ == 0) {
    return Status::NotInitialized;
  }
  if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(normalX) || !std::isfinite(normalY)) {
    return Status::NonFiniteInput;
  }
  if (normalX == 0.0 && normalY == 0.0) {
    return Status::InvalidArgument;
  }
  const double u = (x - originX_) / params_.resolution;
  const double v = (y - originY_) / params_.resolution;
  if (!(u >= 0.0) || !(v >= 0.0) || u >= static_cast<double>(width_) || v >= static_cast<double>(height_)) {
    ++pointsOutside_;
    return Status::OutOfRange;
  }
  const double normalLength = std::hypot(normalX, normalY);
  const auto w = static_cast<long>(std::ceil(params_.maxDistance / params_.resolution));
  const auto cx = static_cast<long>(u);
  const auto cy = static_cast<long>(v);
  const auto W = static_cast<long>(width_);
  const auto H = static_cast<long>(height_);
  const long y0 = cy - w < 0 ? 0 : cy - w;
  const long y1 = cy + w >= H ? H - 1 : cy + w;
  const long x0 = cx - w < 0 ? 0 : cx - w;
  const long x1 = cx + w >= W ? W - 1 : cx + w;
  for (long iy = y0; iy <= y1; ++iy) {
    const double dy = (static_cast<double>(iy) + 0.5) * params_.resolution - (y - originY_);
    for (long ix = x0; ix <= x1; ++ix) {
      const double dx = (static_cast<double>(ix) + 0.5) * params_.resolution - (x - originX_);
      const double d = std::sqrt(dx * dx + dy * dy);
      if (d >= params_.maxDistance) {
        continue;
      }
      const long q = std::lround(d / quantum_);
      std::int8_t& cell = cells_[static_cast<std::size_t>(ix + iy * W)];
      if (q < (cell < 0 ? -cell : cell)) {
        // Behind only when clearly so (within 45 deg of straight behind): beyond the end of a face
        // (the corner of a box seen from outside) the nearest point's own normal says nothing.
        const bool behind = dx * normalX + dy * normalY < -kBehindCos * d * normalLength;
        cell = static_cast<std::int8_t>(behind ? -q : q);
      }
    }
  }
  ++surfacePoints_;
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
