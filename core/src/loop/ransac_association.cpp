#include "agv/loop/ransac_association.hpp"

#include <cmath>

#include "association_common.hpp"

namespace agv {

bool isValid(const RansacParams& p) noexcept {
  return std::isfinite(p.inlierGate) && p.inlierGate > 0.0F && std::isfinite(p.epsilon) && p.epsilon > 0.0F &&
         std::isfinite(p.minBaseline) && p.minBaseline >= 0.0F && p.confidence > 0.0F && p.confidence < 1.0F &&
         p.maxSamples >= 1 && p.maxHypotheses >= 1 && p.minPairs >= 3 && p.refinementPasses >= 0 &&
         p.refinementPasses <= 10;
}

RansacMatcher::RansacMatcher(const RansacParams& params) noexcept : params_(params) {}

Status RansacMatcher::match(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second,
                            PointAssociation& out) noexcept {
  out = PointAssociation{};
  hypotheses_ = 0;
  const Status st = detail::checkMatchInput(isValid(params_), first, second);
  if (st != Status::Ok) {
    return st;
  }
  (void)allCandidatePairs(first.size(), second.size(), all_);
  return run(first, second, Span<const PointPair>(all_.data(), all_.size()), out);
}

Status RansacMatcher::match(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second,
                            Span<const PointPair> candidates, PointAssociation& out) noexcept {
  out = PointAssociation{};
  hypotheses_ = 0;
  const Status st = detail::checkMatchInput(isValid(params_), first, second, &candidates);
  if (st != Status::Ok) {
    return st;
  }
  return run(first, second, candidates, out);
}

Status RansacMatcher::run(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second,
                          Span<const PointPair> cand, PointAssociation& out) noexcept {
  const RansacParams& p = params_;
  SplitMix64 rng{p.seed};
  const auto k = static_cast<std::uint32_t>(cand.size());
  const float gate2 = p.inlierGate * p.inlierGate;
  const float minBase2 = p.minBaseline * p.minBaseline;
  const std::size_t most = first.size() < second.size() ? first.size() : second.size();
  const double logMiss = std::log(1.0 - static_cast<double>(p.confidence));
  std::uint32_t needed = p.maxSamples;
  std::uint32_t drawn = 0;
  std::uint32_t hyps = 0;
  std::size_t bestCount = 0;
  float bestSq = 0.0F;
  Pose2f best{};
  bool found = false;
  while (drawn < needed) {
    ++drawn;
    const std::uint32_t u = rng.below(k);
    const std::uint32_t v = rng.below(k);
    const PointPair& pu = cand[u];
    const PointPair& pv = cand[v];
    if (pu.first == pv.first || pu.second == pv.second) {
      continue;
    }
    const Eigen::Vector2f da = first[pv.first] - first[pu.first];
    const Eigen::Vector2f db = second[pv.second] - second[pu.second];
    const float la2 = da.squaredNorm();
    const float lb2 = db.squaredNorm();
    if (lb2 < minBase2 || std::fabs(std::sqrt(la2) - std::sqrt(lb2)) >= p.epsilon) {
      continue;
    }
    if (hyps >= p.maxHypotheses) {
      out.budgetHit = true;
      break;
    }
    ++hyps;
    const float phi = std::atan2(db.x() * da.y() - db.y() * da.x(), db.dot(da));
    const float c = std::cos(phi);
    const float s = std::sin(phi);
    const Eigen::Vector2f ma = 0.5F * (first[pu.first] + first[pv.first]);
    const Eigen::Vector2f mb = 0.5F * (second[pu.second] + second[pv.second]);
    const Pose2f motion{ma.x() - (c * mb.x() - s * mb.y()), ma.y() - (s * mb.x() + c * mb.y()), phi};
    std::size_t count = 0;
    float sumSq = 0.0F;
    for (const Eigen::Vector2f& b : second) {
      const Eigen::Vector2f q = motion.transformPoint(b);
      float nearest = gate2;
      bool hit = false;
      for (const Eigen::Vector2f& a : first) {
        const float d2 = (a - q).squaredNorm();
        if (d2 <= nearest) {
          nearest = d2;
          hit = true;
        }
      }
      if (hit) {
        ++count;
        sumSq += nearest;
      }
    }
    if (count > bestCount || (count == bestCount && found && sumSq < bestSq)) {
      bestCount = count;
      bestSq = sumSq;
      best = motion;
      found = true;
      if (count >= most) {
        break;  // every point explained: nothing better can come
      }
      // Adaptive bound: draws for `confidence` that both candidates of one draw were right.
      const double w = static_cast<double>(count) / static_cast<double>(k);
      const double pGood = w * w;
      if (pGood > 0.0 && pGood < 1.0) {
        const double n = logMiss / std::log(1.0 - pGood);
        if (n < static_cast<double>(needed)) {
          needed = static_cast<std::uint32_t>(n) + 1U;
        }
      }
    }
  }
  if (drawn >= p.maxSamples && needed >= p.maxSamples && !(found && bestCount >= most)) {
    out.budgetHit = true;
  }
  out.work = drawn;
  hypotheses_ = hyps;
  if (found) {
    out.transform = best.cast<double>();
    FixedVector<PointPair, kMaxLoopPoints> pairs;
    if (detail::associateNearest(first, second, out.transform, p.inlierGate, pairs) >= 3) {
      (void)out.pairs.assign(pairs);
      detail::fitPairs(first, second, out);
      detail::refine(first, second, p.inlierGate, p.refinementPasses, out);
    } else {
      (void)out.pairs.assign(pairs);
      out.transform = Pose2d{};
    }
  }
  if (out.budgetHit) {
    return Status::NotConverged;
  }
  return out.pairs.size() >= p.minPairs ? Status::Ok : Status::NotEnoughData;
}

}  // namespace agv
