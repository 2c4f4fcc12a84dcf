#include "agv/lidar3d/orientation_signature.hpp"

#include <Eigen/Core>
#include <cmath>

#include "agv/core/angle.hpp"

namespace agv {

Result<std::size_t> orientationRow(const RangeImageBase& image, float targetElevation) noexcept {
  if (!std::isfinite(targetElevation)) {
    return Status::NonFiniteInput;
  }
  bool found = false;
  std::size_t best = 0;
  float bestGap = 0.0F;
  for (std::size_t r = 0; r < image.rows(); ++r) {
    float sum = 0.0F;
    std::uint32_t n = 0;
    for (std::size_t c = 0; c < image.columns(); ++c) {
      const RangeCell& cell = image.at(r, c);
      if (cell.valid()) {
        sum += std::asin(cell.point.z() / cell.range);
        ++n;
      }
    }
    if (n == 0) {
      continue;
    }
    const float gap = std::fabs(sum / static_cast<float>(n) - targetElevation);
    if (!found || gap < bestGap) {
      found = true;
      best = r;
      bestGap = gap;
    }
  }
  if (!found) {
    return Status::EmptyInput;
  }
  return best;
}

Status computeOrientationSignature(const RangeImageBase& image, const OrientationParams& params,
                                   OrientationSignature& out) noexcept {
  out = OrientationSignature{};
  if (!std::isfinite(params.minRange) || !std::isfinite(params.maxRange) || params.minRange < 0.0F ||
      params.minRange >= params.maxRange || params.minFilledBins > kOrientationBins) {
    return Status::InvalidArgument;
  }
  if (image.validCount() == 0) {
    return Status::EmptyInput;
  }
  std::size_t row = 0;
  if (params.row < 0) {
    const Result<std::size_t> r = orientationRow(image, params.targetElevation);
    if (!r.ok()) {
      return r.status();
    }
    row = r.value();
  } else {
    row = static_cast<std::size_t>(params.row);
    if (row >= image.rows()) {
      return Status::InvalidArgument;
    }
  }
  std::array<float, kOrientationBins> sum{};
  std::array<std::uint16_t, kOrientationBins> count{};
  constexpr float kBinsPerRad = static_cast<float>(kOrientationBins) / kTwoPi<float>;
  for (std::size_t c = 0; c < image.columns(); ++c) {
    const RangeCell& cell = image.at(row, c);
    if (!cell.valid() || cell.range < params.minRange || cell.range > params.maxRange) {
      continue;
    }
    float az = std::atan2(cell.point.y(), cell.point.x());
    if (az < 0.0F) {
      az += kTwoPi<float>;
    }
    auto b = static_cast<std::size_t>(az * kBinsPerRad);
    if (b >= kOrientationBins) {
      b = kOrientationBins - 1;
    }
    sum[b] += cell.range;
    if (count[b] < 65535U) {
      ++count[b];
    }
  }
  std::uint16_t filled = 0;
  for (std::size_t b = 0; b < kOrientationBins; ++b) {
    if (count[b] > 0) {
      out.meanRange[b] = sum[b] / static_cast<float>(count[b]);
      ++filled;
    }
  }
  if (filled < params.minFilledBins || filled == 0) {
    out = OrientationSignature{};
    return Status::NotEnoughData;
  }
  out.filled = filled;
  out.row = static_cast<std::uint16_t>(row);
  return Status::Ok;
}

Result<YawEstimate> relativeYaw(const OrientationSignature& a, const OrientationSignature& b,
                                std::size_t minOverlap) noexcept {
  if (minOverlap == 0) {
    minOverlap = 1;
  }
  if (a.filled < minOverlap || b.filled < minOverlap) {
    return Status::NotEnoughData;
  }
  constexpr std::size_t kN = kOrientationBins;
  // a twice in a row, so that a[k + s] needs no modulo; validity as 0/1 weights: the inner loop is
  // branch-free arithmetic over a fixed count and vectorises.
  std::array<float, 2 * kN> a2{};
  std::array<float, 2 * kN> am2{};
  std::array<float, kN> bm{};
  for (std::size_t k = 0; k < kN; ++k) {
    a2[k] = a.meanRange[k];
    a2[k + kN] = a.meanRange[k];
    am2[k] = a.meanRange[k] > 0.0F ? 1.0F : 0.0F;
    am2[k + kN] = am2[k];
    bm[k] = b.meanRange[k] > 0.0F ? 1.0F : 0.0F;
  }
  std::array<float, kN> cost{};
  std::array<std::uint16_t, kN> overlap{};
  using Bins = Eigen::Array<float, static_cast<int>(kN), 1>;
  const Eigen::Map<const Bins> bv(b.meanRange.data());
  const Eigen::Map<const Bins> bw(bm.data());
  for (std::size_t s = 0; s < kN; ++s) {
    // Eigen's packet reductions vectorise the sums (a plain loop does not: float addition is not
    // associative, so the compiler keeps the order).
    const Eigen::Map<const Bins> as(a2.data() + s);
    const Eigen::Map<const Bins> ams(am2.data() + s);
    const float n = (ams * bw).sum();
    const float sad = (ams * bw * (as - bv).abs()).sum();
    overlap[s] = static_cast<std::uint16_t>(n);
    cost[s] = n > 0.0F ? sad / n : 0.0F;
  }
  bool found = false;
  std::size_t best = 0;
  for (std::size_t s = 0; s < kN; ++s) {
    if (overlap[s] >= minOverlap && (!found || cost[s] < cost[best])) {
      found = true;
      best = s;
    }
  }
  if (!found) {
    return Status::NotEnoughData;
  }
  // Parabola through (-1, c-), (0, c0), (+1, c+): vertex at (c- - c+) / (2 (c- - 2 c0 + c+)).
  const std::size_t prev = best == 0 ? kN - 1 : best - 1;
  const std::size_t next = best + 1 == kN ? 0 : best + 1;
  float offset = 0.0F;
  if (overlap[prev] >= minOverlap && overlap[next] >= minOverlap) {
    const float curvature = cost[prev] - 2.0F * cost[best] + cost[next];
    if (curvature > 0.0F) {
      offset = 0.5F * (cost[prev] - cost[next]) / curvature;
      offset = offset > 0.5F ? 0.5F : (offset < -0.5F ? -0.5F : offset);
    }
  }
  YawEstimate e;
  {
    const Eigen::Map<const Bins> as(a2.data() + best);
    const Eigen::Map<const Bins> ams(am2.data() + best);
    e.meanRange = 0.5F * (ams * bw * (as + bv)).sum() / static_cast<float>(overlap[best]);
  }
  e.shift = static_cast<std::uint16_t>(best);
  e.cost = cost[best];
  e.overlap = overlap[best];
  e.yaw = normalizeAngle(deg2rad(static_cast<float>(best) + offset));
  return e;
}

}  // namespace agv
