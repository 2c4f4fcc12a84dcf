#include "agv/localization/map_changes.hpp"

#include <algorithm>
#include <cmath>

namespace agv {

Status MapChangeParams::validate() const noexcept {
  if (!std::isfinite(distance) || !std::isfinite(sigmas) || !std::isfinite(inlierDistance)) {
    return Status::NonFiniteInput;
  }
  return distance > 0.0 && sigmas > 0.0 && inlierDistance > distance ? Status::Ok : Status::InvalidArgument;
}

SurfaceMapParams changeMapParams(const SurfaceMapParams& surface, const MapChangeParams& changes) noexcept {
  SurfaceMapParams p = surface;
  const double cell = p.field.resolution;
  const double reach = changes.distance + 2.0 * cell;
  const double saturation = reach > 3.0 * cell ? reach : 3.0 * cell;
  if (std::isfinite(saturation) && saturation < p.field.maxDistance) {
    p.field.maxDistance = saturation;
  }
  return p;
}

namespace {

bool finitePose(const Pose2d& p) noexcept {
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.theta);
}

bool finitePoint(const MatchPoint& p) noexcept {
  return std::isfinite(p.x) && std::isfinite(p.y);
}

Eigen::Vector2d toWorld(const Pose2d& sensor, const MatchPoint& p) noexcept {
  return sensor.transformPoint(Eigen::Vector2d(static_cast<double>(p.x), static_cast<double>(p.y)));
}

/// |distance| to the nearest surface of `field` at world point `q`; infinity where it has none
/// within its saturation distance (or outside it).
double surfaceDistance(const LikelihoodFieldBase& field, const Eigen::Vector2d& q) noexcept {
  const FieldSample f = field.sample(q.x(), q.y());
  return f.inside ? std::fabs(f.distance) : HUGE_VAL;
}

}  // namespace

Status MapChangeDetector::select(const MatchPoints& points, const Pose2d& sensor, const LikelihoodFieldBase& field,
                                 MatchPoints& out) noexcept {
  out.clear();
  threshold_ = params_.distance;
  const Status valid = params_.validate();
  if (valid != Status::Ok) {
    return valid;
  }
  if (!finitePose(sensor)) {
    return Status::NonFiniteInput;
  }
  if (!field.built()) {
    return Status::NotInitialized;
  }
  // The scan's own fit: the robust standard deviation of the residuals within the inlier band.
  residuals_.clear();
  for (const MatchPoint& p : points) {
    if (finitePoint(p)) {
      const double d = surfaceDistance(field, toWorld(sensor, p));
      if (d < params_.inlierDistance) {
        (void)residuals_.push_back(static_cast<float>(d));  // capacity: one per beam
      }
    }
  }
  if (!residuals_.empty()) {
    float* const mid = residuals_.begin() + residuals_.size() / 2U;
    std::nth_element(residuals_.begin(), mid, residuals_.end());
    const double robust = params_.sigmas * 1.4826 * static_cast<double>(*mid);
    threshold_ = std::max(params_.distance, robust);
  }
  for (const MatchPoint& p : points) {
    if (finitePoint(p) && surfaceDistance(field, toWorld(sensor, p)) > threshold_) {
      (void)out.push_back(p);  // out has the capacity of points
    }
  }
  return Status::Ok;
}

Status MapChangeDetector::keepUnchanged(const MatchPoints& points, const Pose2d& sensor,
                                        const LikelihoodFieldBase& field, const LikelihoodFieldBase& changes,
                                        MatchPoints& out, std::size_t& dropped) const noexcept {
  out.clear();
  dropped = 0;
  Status status = params_.validate();
  if (status == Status::Ok && !finitePose(sensor)) {
    status = Status::NonFiniteInput;
  }
  const bool filter = status == Status::Ok && changes.built() && field.built();
  for (const MatchPoint& p : points) {
    if (filter && finitePoint(p)) {
      const Eigen::Vector2d q = toWorld(sensor, p);
      if (surfaceDistance(changes, q) <= params_.distance && surfaceDistance(field, q) > params_.distance) {
        ++dropped;
        continue;
      }
    }
    (void)out.push_back(p);
  }
  return status;
}

}  // namespace agv
