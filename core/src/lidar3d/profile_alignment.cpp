#include "agv/lidar3d/profile_alignment.hpp"

#include <Eigen/Core>
#include <Eigen/Dense>
#include <array>
#include <cmath>

#include "agv/core/angle.hpp"

namespace agv {

namespace {
constexpr std::size_t kN = kOrientationBins;
constexpr float kBinRad = kTwoPi<float> / static_cast<float>(kN);
}  // namespace

bool isValid(const ProfileAlignParams& p) noexcept {
  return p.maxIterations >= 1 && p.searchBins < kN / 4 && std::isfinite(p.startGate) && std::isfinite(p.endGate) &&
         p.endGate > 0.0F && p.startGate >= p.endGate && std::isfinite(p.gateDecay) && p.gateDecay > 0.0F &&
         p.gateDecay <= 1.0F && std::isfinite(p.cauchyScale) && p.cauchyScale > 0.0F &&
         std::isfinite(p.maxNeighbourRatio) && p.maxNeighbourRatio > 0.0F && p.minPairs >= 3 &&
         std::isfinite(p.inlierResidual) && p.inlierResidual > 0.0F;
}

float ProfileAlignment::translation() const noexcept {
  return std::sqrt(x * x + y * y);
}

Result<ProfileAlignment> alignProfiles(const OrientationSignature& a, const OrientationSignature& b, float initialYaw,
                                       const ProfileAlignParams& params) noexcept {
  if (!isValid(params) || !std::isfinite(initialYaw)) {
    return Status::InvalidArgument;
  }
  if (a.empty() || b.empty()) {
    return Status::NotEnoughData;
  }
  // Points of both profiles at the bin centres; a's normals from its neighbouring bins.
  std::array<Eigen::Vector2f, kN> pa{};
  std::array<Eigen::Vector2f, kN> na{};
  std::array<bool, kN> hasNormal{};
  std::array<Eigen::Vector2f, kN> pb{};
  std::uint16_t bBins = 0;
  for (std::size_t k = 0; k < kN; ++k) {
    const float az = (static_cast<float>(k) + 0.5F) * kBinRad;
    const Eigen::Vector2f dir(std::cos(az), std::sin(az));
    pa[k] = a.meanRange[k] * dir;
    pb[k] = b.meanRange[k] * dir;
    bBins = static_cast<std::uint16_t>(bBins + (b.meanRange[k] > 0.0F ? 1U : 0U));
  }
  for (std::size_t k = 0; k < kN; ++k) {
    const std::size_t prev = k == 0 ? kN - 1 : k - 1;
    const std::size_t next = k + 1 == kN ? 0 : k + 1;
    const float r = a.meanRange[k];
    hasNormal[k] = false;
    if (r <= 0.0F || a.meanRange[prev] <= 0.0F || a.meanRange[next] <= 0.0F) {
      continue;
    }
    const float limit = params.maxNeighbourRatio * r;
    if ((pa[prev] - pa[k]).norm() > limit || (pa[next] - pa[k]).norm() > limit) {
      continue;
    }
    const Eigen::Vector2f tangent = pa[next] - pa[prev];
    const float len = tangent.norm();
    if (!(len > 0.0F)) {
      continue;
    }
    na[k] = Eigen::Vector2f(-tangent.y(), tangent.x()) / len;
    hasNormal[k] = true;
  }

  double yaw = static_cast<double>(initialYaw);
  double tx = 0.0;
  double ty = 0.0;
  ProfileAlignment out;
  out.bins = bBins;
  float gate = params.startGate;
  const int w = static_cast<int>(params.searchBins);
  // One pairing pass at the current estimate: accumulates the normal equations (when wanted) and
  // the matched count / residual within `gateNow`.
  std::uint32_t inliers = 0;
  auto pass = [&](float gateNow, Eigen::Matrix3d& h, Eigen::Vector3d& g, std::uint32_t& pairs, double& sumSq) {
    h.setZero();
    g.setZero();
    pairs = 0;
    sumSq = 0.0;
    inliers = 0;
    const float c = std::cos(static_cast<float>(yaw));
    const float s = std::sin(static_cast<float>(yaw));
    const Eigen::Vector2f t(static_cast<float>(tx), static_cast<float>(ty));
    // The robust scale follows the gate (half of it, at least cauchyScale): the first steps, far
    // from the solution, must not discount the large residuals that carry it.
    const float scale = 0.5F * gateNow > params.cauchyScale ? 0.5F * gateNow : params.cauchyScale;
    const float invScale2 = 1.0F / (scale * scale);
    for (std::size_t j = 0; j < kN; ++j) {
      if (b.meanRange[j] <= 0.0F) {
        continue;
      }
      const Eigen::Vector2f rp(c * pb[j].x() - s * pb[j].y(), s * pb[j].x() + c * pb[j].y());
      const Eigen::Vector2f q = rp + t;
      float az = std::atan2(q.y(), q.x());
      if (az < 0.0F) {
        az += kTwoPi<float>;
      }
      const int k0 = static_cast<int>(az / kBinRad);
      int bestK = -1;
      float bestD2 = gateNow * gateNow;
      for (int dk = -w; dk <= w; ++dk) {
        const int k = ((k0 + dk) % static_cast<int>(kN) + static_cast<int>(kN)) % static_cast<int>(kN);
        if (!hasNormal[static_cast<std::size_t>(k)]) {
          continue;
        }
        const float d2 = (q - pa[static_cast<std::size_t>(k)]).squaredNorm();
        if (d2 < bestD2) {
          bestD2 = d2;
          bestK = k;
        }
      }
      if (bestK < 0) {
        continue;
      }
      const Eigen::Vector2f& n = na[static_cast<std::size_t>(bestK)];
      const float r = n.dot(q - pa[static_cast<std::size_t>(bestK)]);
      const float wgt = 1.0F / (1.0F + r * r * invScale2);
      // d(q)/d(yaw) = perp(R p_b) = (-rp.y, rp.x).
      const Eigen::Vector3d jac(n.x(), n.y(), n.x() * -rp.y() + n.y() * rp.x());
      h.noalias() += static_cast<double>(wgt) * jac * jac.transpose();
      g.noalias() += static_cast<double>(wgt * r) * jac;
      sumSq += static_cast<double>(r) * static_cast<double>(r);
      ++pairs;
      inliers += std::fabs(r) <= params.inlierResidual ? 1U : 0U;
    }
  };
  Eigen::Matrix3d h;
  Eigen::Vector3d g;
  std::uint32_t pairs = 0;
  double sumSq = 0.0;
  for (std::uint16_t it = 0; it < params.maxIterations; ++it) {
    pass(gate, h, g, pairs, sumSq);
    if (pairs < params.minPairs) {
      return Status::NotEnoughData;
    }
    const Eigen::LDLT<Eigen::Matrix3d> ldlt(h);
    if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 1e-9 * ldlt.vectorD().maxCoeff())) {
      return Status::NotEnoughData;
    }
    const Eigen::Vector3d step = -ldlt.solve(g);
    if (!step.allFinite()) {
      return Status::NotEnoughData;
    }
    tx += step.x();
    ty += step.y();
    yaw += step.z();
    out.iterations = static_cast<std::uint16_t>(it + 1);
    const bool small = std::hypot(step.x(), step.y()) < 2e-3 && std::fabs(step.z()) < deg2rad(1e-2);
    if (small && gate <= params.endGate) {
      out.converged = true;
      break;
    }
    gate = gate * params.gateDecay;
    gate = gate < params.endGate ? params.endGate : gate;
  }
  pass(params.endGate, h, g, pairs, sumSq);
  // h's translation block is sum w n n^T; its trace is sum w (unit normals).
  const double trace = h(0, 0) + h(1, 1);
  if (trace > 0.0) {
    const double half = 0.5 * trace;
    const double diff = 0.5 * (h(0, 0) - h(1, 1));
    const double smallest = half - std::sqrt(diff * diff + h(0, 1) * h(0, 1));
    out.translationObservability = static_cast<float>(smallest / trace);
  }
  out.yaw = normalizeAngle(static_cast<float>(yaw));
  out.x = static_cast<float>(tx);
  out.y = static_cast<float>(ty);
  out.matched = static_cast<std::uint16_t>(pairs);
  out.inliers = static_cast<std::uint16_t>(inliers);
  out.rms = pairs > 0 ? static_cast<float>(std::sqrt(sumSq / static_cast<double>(pairs))) : 0.0F;
  return out;
}

}  // namespace agv
