#include "agv/lidar3d/place_database.hpp"

#include <cmath>

namespace agv {

namespace {
bool positiveFinite(float v) noexcept {
  return std::isfinite(v) && v > 0.0F;
}
}  // namespace

bool isValid(const PlaceParams& p) noexcept {
  return positiveFinite(p.keyThreshold) && positiveFinite(p.chiSquareThreshold) &&
         positiveFinite(p.sorensenThreshold) && p.minYawOverlap >= 1 && p.minYawOverlap <= kOrientationBins;
}

Status PlaceDatabaseBase::setParams(const PlaceParams& params) noexcept {
  if (!isValid(params)) {
    return Status::InvalidArgument;
  }
  params_ = params;
  return Status::Ok;
}

Status PlaceDatabaseBase::add(const NormalSignature& normal, const OrientationSignature& orientation,
                              std::uint32_t scan, PlaceUpdate& out) noexcept {
  out = PlaceUpdate{};
  if (normal.empty()) {
    ++refusedEmpty_;
    return Status::EmptyInput;
  }
  // 1. Loop query over the keys older than the newest m.
  const std::size_t searchable = size_ > params_.skipRecentKeys ? size_ - params_.skipRecentKeys : 0;
  for (std::size_t i = 0; i < searchable; ++i) {
    const float chi2 = chiSquareDistance(keys_[i].normal, normal);
    if (!(chi2 < params_.chiSquareThreshold)) {
      continue;
    }
    const float sor = sorensenDistance(keys_[i].normal, normal);
    if (!(sor < params_.sorensenThreshold)) {
      continue;
    }
    ++out.candidates;
    if (!out.loop || chi2 < out.chiSquare) {
      out.loop = true;
      out.loopKey = static_cast<std::uint32_t>(i);
      out.loopScan = keys_[i].scan;
      out.chiSquare = chi2;
      out.sorensen = sor;
    }
  }
  if (out.loop) {
    const Result<YawEstimate> yaw = relativeYaw(keys_[out.loopKey].orientation, orientation, params_.minYawOverlap);
    if (yaw.ok()) {
      out.hasYaw = true;
      out.yaw = yaw.value();
    }
  }
  // 2. Key decision.
  if (size_ == 0) {
    out.isKey = true;
  } else {
    out.chiSquareToLastKey = chiSquareDistance(keys_[size_ - 1].normal, normal);
    out.isKey = out.chiSquareToLastKey > params_.keyThreshold;
  }
  if (!out.isKey) {
    return Status::Ok;
  }
  if (size_ >= capacity_) {
    ++refusedFull_;
    return Status::CapacityExceeded;
  }
  keys_[size_].normal = normal;
  keys_[size_].orientation = orientation;
  keys_[size_].scan = scan;
  out.keyIndex = static_cast<std::uint32_t>(size_);
  ++size_;
  return Status::Ok;
}

}  // namespace agv
