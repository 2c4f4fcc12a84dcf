#include "agv/lidar3d/laser_intrinsics.hpp"

#include <cmath>

namespace agv {

namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr float kRadPerCentiDeg = 3.14159265358979323846F / 18000.0F;

bool finite(const LaserParams& p) noexcept {
  return std::isfinite(p.distCorrection) && std::isfinite(p.vertOffset) && std::isfinite(p.horizOffset) &&
         std::isfinite(p.theta) && std::isfinite(p.alpha);
}
}  // namespace

Status LaserIntrinsics::reset(std::size_t lasers) noexcept {
  if (lasers == 0) {
    return Status::InvalidArgument;
  }
  if (lasers > kMaxLidarLasers) {
    return Status::CapacityExceeded;
  }
  for (std::size_t i = 0; i < lasers_.size(); ++i) {
    lasers_[i] = Laser{};
  }
  size_ = lasers;
  return Status::Ok;
}

Status LaserIntrinsics::set(std::size_t id, const LaserParams& params) noexcept {
  if (id >= size_) {
    return Status::OutOfRange;
  }
  if (!finite(params)) {
    return Status::NonFiniteInput;
  }
  if (std::fabs(params.theta) > kPi || std::fabs(params.alpha) > kPi) {
    return Status::InvalidArgument;
  }
  Laser& l = lasers_[id];
  l.p = params;
  l.distCorrection = static_cast<float>(params.distCorrection);
  l.vertOffset = static_cast<float>(params.vertOffset);
  l.horizOffset = static_cast<float>(params.horizOffset);
  l.cosTheta = static_cast<float>(std::cos(params.theta));
  l.sinTheta = static_cast<float>(std::sin(params.theta));
  l.cosAlpha = static_cast<float>(std::cos(params.alpha));
  l.sinAlpha = static_cast<float>(std::sin(params.alpha));
  return Status::Ok;
}

Status LaserIntrinsics::setDistanceResolution(double metresPerCount) noexcept {
  if (!std::isfinite(metresPerCount) || metresPerCount <= 0.0 || metresPerCount > 0.1) {
    return Status::InvalidArgument;
  }
  resolution_ = metresPerCount;
  resolutionF_ = static_cast<float>(metresPerCount);
  return Status::Ok;
}

Eigen::Vector3f LaserIntrinsics::laserPoint(std::size_t laser, std::uint16_t raw,
                                            float azimuthCentiDeg) const noexcept {
  const float phi = azimuthCentiDeg * kRadPerCentiDeg;
  return laserPoint(laser, raw, std::sin(phi), std::cos(phi));
}

}  // namespace agv
