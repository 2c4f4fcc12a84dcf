#include "agv/loop/glarot.hpp"

#include <cmath>
#include <limits>

#include "agv/core/angle.hpp"
#include "glarot_l1.hpp"

namespace agv {
namespace {

/// Gaussian weights of the cell holding u (in cells) and its two neighbours, for offsets from
/// the cell centres; k = 0, 1, 2 stand for the cells c - 1, c, c + 1.
void spread(float u, std::size_t n, float inv2Sigma2, std::size_t& c, std::array<float, 3>& w) noexcept {
  float fc = std::floor(u);
  if (fc < 0.0F) {
    fc = 0.0F;
  }
  c = static_cast<std::size_t>(fc);
  if (c >= n) {
    c = n - 1;
  }
  const float f = u - (static_cast<float>(c) + 0.5F);  // offset from the centre of cell c
  for (int k = 0; k < 3; ++k) {
    const float d = f - static_cast<float>(k - 1);
    w[static_cast<std::size_t>(k)] = std::exp(-d * d * inv2Sigma2);
  }
}

template <typename Get>
Status compute(std::size_t n, Get get, const GlarotParams& p, GlarotSignature& out) noexcept {
  out = GlarotSignature{};
  if (!isValid(p)) {
    return Status::InvalidArgument;
  }
  out.thetaBins = static_cast<std::uint16_t>(p.thetaBins);
  out.rhoBins = static_cast<std::uint16_t>(p.rhoBins);
  if (n == 0) {
    return Status::EmptyInput;
  }
  if (n > kMaxKeypoints) {
    return Status::CapacityExceeded;
  }
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector2f q = get(i);
    if (!std::isfinite(q.x()) || !std::isfinite(q.y())) {
      return Status::NonFiniteInput;
    }
  }
  const std::size_t nT = p.thetaBins;
  const std::size_t nR = p.rhoBins;
  const float thetaScale = static_cast<float>(nT) / kPi<float>;
  const float rhoScale = static_cast<float>(nR) / p.maxDistance;
  const float maxD2 = p.maxDistance * p.maxDistance;
  const float invT = 0.5F / (p.sigmaTheta * p.sigmaTheta);
  const float invR = 0.5F / (p.sigmaRho * p.sigmaRho);
  float* cells = out.cells.data();
  for (std::size_t i = 0; i + 1 < n; ++i) {
    const Eigen::Vector2f a = get(i);
    for (std::size_t j = i + 1; j < n; ++j) {
      const Eigen::Vector2f d = get(j) - a;
      const float d2 = d.squaredNorm();
      if (!(d2 < maxD2)) {
        ++out.pairsBeyond;
        continue;
      }
      float angle = std::atan2(d.y(), d.x());  // (-pi, pi]
      if (angle < 0.0F) {
        angle += kPi<float>;
      }
      if (angle >= kPi<float>) {
        angle -= kPi<float>;
      }
      std::size_t ct = 0;
      std::size_t cr = 0;
      std::array<float, 3> wt{};
      std::array<float, 3> wr{};
      spread(angle * thetaScale, nT, invT, ct, wt);
      spread(std::sqrt(d2) * rhoScale, nR, invR, cr, wr);
      if (cr == 0) {
        wr[0] = 0.0F;
      }
      if (cr + 1 >= nR) {
        wr[2] = 0.0F;
      }
      const float norm = 1.0F / ((wt[0] + wt[1] + wt[2]) * (wr[0] + wr[1] + wr[2]));
      for (std::size_t kt = 0; kt < 3; ++kt) {
        const std::size_t t = (ct + nT + kt - 1) % nT;  // circular in theta
        const float w = wt[kt] * norm;
        for (std::size_t kr = 0; kr < 3; ++kr) {
          if (wr[kr] > 0.0F) {
            cells[t * nR + cr + kr - 1] += w * wr[kr];
          }
        }
      }
      ++out.pairs;
    }
  }
  if (out.pairs == 0) {
    return Status::NotEnoughData;
  }
  const float inv = 1.0F / static_cast<float>(out.pairs);
  for (std::size_t k = 0; k < nT * nR; ++k) {
    cells[k] *= inv;
  }
  return Status::Ok;
}

}  // namespace

bool isValid(const GlarotParams& p) noexcept {
  return p.thetaBins >= 2 && p.rhoBins >= 1 && p.rhoBins <= kGlarotMaxRhoBins &&
         p.thetaBins <= kGlarotMaxCells / p.rhoBins && std::isfinite(p.maxDistance) && p.maxDistance > 0.0F &&
         std::isfinite(p.sigmaTheta) && p.sigmaTheta > 0.0F && std::isfinite(p.sigmaRho) && p.sigmaRho > 0.0F;
}

Status computeGlarot(Span<const Eigen::Vector2f> points, const GlarotParams& params, GlarotSignature& out) noexcept {
  return compute(
      points.size(), [&](std::size_t i) noexcept { return points[i]; }, params, out);
}

Status computeGlarot(Span<const FalkoKeypoint> keypoints, const GlarotParams& params, GlarotSignature& out) noexcept {
  return compute(
      keypoints.size(), [&](std::size_t i) noexcept { return Eigen::Vector2f(keypoints[i].x, keypoints[i].y); }, params,
      out);
}

Result<GlarotMatch> glarotDistance(const GlarotSignature& a, const GlarotSignature& b) noexcept {
  if (a.thetaBins != b.thetaBins || a.rhoBins != b.rhoBins || a.size() == 0 || a.size() > kGlarotMaxCells) {
    return Status::InvalidArgument;
  }
  GlarotMatch best{std::numeric_limits<float>::infinity(), 0};
  for (std::size_t s = 0; s < a.thetaBins; ++s) {
    const float d =
        detail::glarotShiftedL1Kernel(a.cells.data(), b.cells.data(), a.thetaBins, a.rhoBins, s, best.distance);
    if (d < best.distance) {
      best.distance = d;
      best.shift = static_cast<std::uint16_t>(s);
    }
  }
  return best;
}

float glarotShiftedL1(const GlarotSignature& a, const GlarotSignature& b, std::size_t shift) noexcept {
  if (a.thetaBins != b.thetaBins || a.rhoBins != b.rhoBins || a.size() == 0 || a.size() > kGlarotMaxCells ||
      shift >= a.thetaBins) {
    return -1.0F;
  }
  return detail::glarotShiftedL1Kernel(a.cells.data(), b.cells.data(), a.thetaBins, a.rhoBins, shift,
                                       std::numeric_limits<float>::infinity());
}

float glarotRotation(std::size_t shift, std::size_t thetaBins) noexcept {
  if (thetaBins == 0) {
    return 0.0F;
  }
  const std::size_t s = shift % thetaBins;
  const float cell = kPi<float> / static_cast<float>(thetaBins);
  return 2 * s <= thetaBins ? static_cast<float>(s) * cell
                            : (static_cast<float>(s) - static_cast<float>(thetaBins)) * cell;
}

}  // namespace agv
