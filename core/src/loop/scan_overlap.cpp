#include "agv/loop/scan_overlap.hpp"

#include <algorithm>
#include <cmath>

namespace agv {

namespace {
// Cells farther than this from the sensor are not representable (about 214 km at 0.1 m): their
// points are skipped like invalid readings.
constexpr float kMaxCellIndex = 2.0e6F;

bool finitePositive(float v) noexcept {
  return std::isfinite(v) && v > 0.0F;
}
}  // namespace

bool isValid(const ScanOverlapParams& p) noexcept {
  return finitePositive(p.cell) && finitePositive(p.conflictMargin) && finitePositive(p.conflictRatio);
}

Status ScanOverlap::setParams(const ScanOverlapParams& params) noexcept {
  if (!isValid(params)) {
    return Status::InvalidArgument;
  }
  params_ = params;
  hasReference_ = false;
  return Status::Ok;
}

std::size_t ScanOverlap::slot(std::int32_t cx, std::int32_t cy) const noexcept {
  // Two large odd multipliers (spatial hashing), folded to the table size.
  const std::uint32_t h = (static_cast<std::uint32_t>(cx) * 73856093U) ^ (static_cast<std::uint32_t>(cy) * 19349663U);
  return static_cast<std::size_t>((h ^ (h >> 15U)) & (kOverlapTableBits - 1U));
}

bool ScanOverlap::cellOf(float x, float y, std::int32_t& cx, std::int32_t& cy) const noexcept {
  const float fx = std::floor(x / params_.cell + 0.5F);
  const float fy = std::floor(y / params_.cell + 0.5F);
  if (!std::isfinite(fx) || !std::isfinite(fy) || std::fabs(fx) > kMaxCellIndex || std::fabs(fy) > kMaxCellIndex) {
    return false;
  }
  cx = static_cast<std::int32_t>(fx);
  cy = static_cast<std::int32_t>(fy);
  return true;
}

Status ScanOverlap::setReference(const LaserScan& reference) noexcept {
  hasReference_ = false;
  ranges_.clear();
  if (!finitePositive(reference.angleIncrement) || !std::isfinite(reference.angleMin)) {
    return Status::InvalidArgument;
  }
  bits_.fill(0U);
  angleMin_ = reference.angleMin;
  angleIncrement_ = reference.angleIncrement;
  std::size_t marked = 0;
  for (std::size_t b = 0; b < reference.size(); ++b) {
    std::int32_t cx = 0;
    std::int32_t cy = 0;
    const float r = reference.ranges[b];
    const float a = reference.angle(b);
    if (!reference.isValid(b) || !cellOf(r * std::cos(a), r * std::sin(a), cx, cy)) {
      (void)ranges_.push_back(-1.0F);  // capacity equals the scan's: never refused
      continue;
    }
    (void)ranges_.push_back(r);
    for (std::int32_t dx = -1; dx <= 1; ++dx) {
      for (std::int32_t dy = -1; dy <= 1; ++dy) {
        const std::size_t s = slot(cx + dx, cy + dy);
        bits_[s / 64U] |= std::uint64_t{1} << (s % 64U);
      }
    }
    ++marked;
  }
  if (marked == 0) {
    return Status::EmptyInput;
  }
  hasReference_ = true;
  return Status::Ok;
}

bool ScanOverlap::seenThrough(float bearing, float range, bool& inView) const noexcept {
  inView = false;
  const float k = std::floor((bearing - angleMin_) / angleIncrement_ + 0.5F);
  if (!(k >= 1.0F) || !(k + 1.0F < static_cast<float>(ranges_.size()))) {
    return false;
  }
  const std::size_t i = static_cast<std::size_t>(k);
  const float nearest = std::min(ranges_[i - 1], std::min(ranges_[i], ranges_[i + 1]));
  if (nearest < 0.0F) {
    return false;  // a beam without a return says nothing
  }
  inView = true;
  return nearest > range + std::max(params_.conflictMargin, params_.conflictRatio * range);
}

Status ScanOverlap::score(const LaserScan& scan, const Pose2d& transform, ScanOverlapScore& out) const noexcept {
  out = ScanOverlapScore{};
  if (!hasReference_) {
    return Status::NotInitialized;
  }
  if (!std::isfinite(transform.x) || !std::isfinite(transform.y) || !std::isfinite(transform.theta)) {
    return Status::NonFiniteInput;
  }
  if (!finitePositive(scan.angleIncrement) || !std::isfinite(scan.angleMin)) {
    return Status::InvalidArgument;
  }
  const float c = static_cast<float>(std::cos(transform.theta));
  const float s = static_cast<float>(std::sin(transform.theta));
  const float tx = static_cast<float>(transform.x);
  const float ty = static_cast<float>(transform.y);
  constexpr float kPi = 3.14159265358979323846F;
  for (std::size_t b = 0; b < scan.size(); ++b) {
    if (!scan.isValid(b)) {
      continue;
    }
    const float a = scan.angle(b);
    const float px = scan.ranges[b] * std::cos(a);
    const float py = scan.ranges[b] * std::sin(a);
    const float x = tx + c * px - s * py;
    const float y = ty + s * px + c * py;
    std::int32_t cx = 0;
    std::int32_t cy = 0;
    if (!cellOf(x, y, cx, cy)) {
      continue;
    }
    ++out.points;
    const std::size_t k = slot(cx, cy);
    out.hits += ((bits_[k / 64U] >> (k % 64U)) & 1U) != 0U ? 1U : 0U;
    // Bearing in the reference's angle range: [angleMin, angleMin + 2 pi).
    float bearing = std::atan2(y, x);
    while (bearing < angleMin_) {
      bearing += 2.0F * kPi;
    }
    bool inView = false;
    out.conflicts += seenThrough(bearing, std::sqrt(x * x + y * y), inView) ? 1U : 0U;
    out.inView += inView ? 1U : 0U;
  }
  return out.points == 0 ? Status::EmptyInput : Status::Ok;
}

Status mutualOverlap(ScanOverlap& first, const LaserScan& firstScan, ScanOverlap& second, const LaserScan& secondScan,
                     const Pose2d& transform, MutualOverlap& out) noexcept {
  out = MutualOverlap{};
  ScanOverlapScore forward;
  ScanOverlapScore backward;
  Status st = first.setReference(firstScan);
  if (st == Status::Ok) {
    st = first.score(secondScan, transform, forward);
  }
  if (st == Status::Ok) {
    st = second.setReference(secondScan);
  }
  if (st == Status::Ok) {
    st = second.score(firstScan, transform.inverse(), backward);
  }
  if (st != Status::Ok) {
    return st;
  }
  out.hitFraction = std::min(forward.hitFraction(), backward.hitFraction());
  out.conflictFraction = std::max(forward.conflictFraction(), backward.conflictFraction());
  out.inViewFraction = std::min(forward.inViewFraction(), backward.inViewFraction());
  return Status::Ok;
}

}  // namespace agv
