#include "association_common.hpp"

#include <array>
#include <cmath>

#include "agv/calib/rigid_fit.hpp"
#include "agv/core/capacities.hpp"

namespace agv {

Status allCandidatePairs(std::size_t nFirst, std::size_t nSecond, IVector<PointPair>& out) noexcept {
  out.clear();
  if (nFirst > kMaxLoopPoints || nSecond > kMaxLoopPoints || nFirst * nSecond > out.capacity()) {
    return Status::CapacityExceeded;
  }
  for (std::size_t i = 0; i < nFirst; ++i) {
    for (std::size_t j = 0; j < nSecond; ++j) {
      (void)out.push_back(PointPair{static_cast<std::uint16_t>(i), static_cast<std::uint16_t>(j)});
    }
  }
  return Status::Ok;
}

namespace detail {

Status checkPointSets(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second) noexcept {
  if (first.empty() || second.empty()) {
    return Status::EmptyInput;
  }
  if (first.size() > kMaxLoopPoints || second.size() > kMaxLoopPoints) {
    return Status::CapacityExceeded;
  }
  for (const Span<const Eigen::Vector2f>& set : {first, second}) {
    for (const Eigen::Vector2f& p : set) {
      if (!std::isfinite(p.x()) || !std::isfinite(p.y())) {
        return Status::NonFiniteInput;
      }
    }
  }
  return Status::Ok;
}

Status checkMatchInput(bool paramsValid, Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second,
                       const Span<const PointPair>* candidates) noexcept {
  if (!paramsValid) {
    return Status::InvalidArgument;
  }
  const Status st = checkPointSets(first, second);
  if (st != Status::Ok || candidates == nullptr) {
    return st;
  }
  return checkCandidates(*candidates, first.size(), second.size());
}

Status checkCandidates(Span<const PointPair> candidates, std::size_t nFirst, std::size_t nSecond) noexcept {
  if (candidates.empty()) {
    return Status::EmptyInput;
  }
  if (candidates.size() > CandidatePairs::kCapacity) {
    return Status::CapacityExceeded;
  }
  for (const PointPair& c : candidates) {
    if (c.first >= nFirst || c.second >= nSecond) {
      return Status::InvalidArgument;
    }
  }
  return Status::Ok;
}

void fitPairs(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second, PointAssociation& out) noexcept {
  std::array<Eigen::Vector2d, kMaxLoopPoints> a;
  std::array<Eigen::Vector2d, kMaxLoopPoints> b;
  std::array<std::uint16_t, kMaxLoopPoints> pairOf{};
  for (std::size_t i = 0; i < first.size(); ++i) {
    a[i] = first[i].cast<double>();
  }
  for (std::size_t j = 0; j < second.size(); ++j) {
    b[j] = second[j].cast<double>();
    pairOf[j] = kNoPair;
  }
  for (const PointPair& p : out.pairs) {
    pairOf[p.second] = p.first;
  }
  const Span<const Eigen::Vector2d> sa(a.data(), first.size());
  const Span<const Eigen::Vector2d> sb(b.data(), second.size());
  const Span<const std::uint16_t> po(pairOf.data(), second.size());
  if (out.pairs.size() < 3) {
    out.transform = Pose2d{};
    out.rms = 0.0;
    return;
  }
  out.transform = fitRigid2d(sa, sb, po);
  out.rms = rigidFitRms(sa, sb, po, out.transform);
}

std::size_t associateNearest(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second,
                             const Pose2d& motion, float gate, IVector<PointPair>& out) noexcept {
  std::array<float, kMaxLoopPoints> claim{};
  std::array<std::uint16_t, kMaxLoopPoints> owner{};
  for (std::size_t i = 0; i < first.size(); ++i) {
    owner[i] = kNoPair;
  }
  const Pose2f m = motion.cast<float>();
  const float gate2 = gate * gate;
  for (std::size_t j = 0; j < second.size(); ++j) {
    const Eigen::Vector2f q = m.transformPoint(second[j]);
    float best = gate2;
    std::size_t bestI = kMaxLoopPoints;
    for (std::size_t i = 0; i < first.size(); ++i) {
      const float d2 = (first[i] - q).squaredNorm();
      if (d2 <= best) {
        best = d2;
        bestI = i;
      }
    }
    if (bestI == kMaxLoopPoints || (owner[bestI] != kNoPair && claim[bestI] <= best)) {
      continue;
    }
    owner[bestI] = static_cast<std::uint16_t>(j);
    claim[bestI] = best;
  }
  out.clear();
  for (std::size_t i = 0; i < first.size(); ++i) {
    if (owner[i] != kNoPair) {
      (void)out.push_back(PointPair{static_cast<std::uint16_t>(i), owner[i]});
    }
  }
  return out.size();
}

void refine(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second, float gate, int passes,
            PointAssociation& out) noexcept {
  FixedVector<PointPair, kMaxLoopPoints> pairs;
  for (int k = 0; k < passes; ++k) {
    if (associateNearest(first, second, out.transform, gate, pairs) < 3) {
      return;
    }
    (void)out.pairs.assign(pairs);
    fitPairs(first, second, out);
  }
}

}  // namespace detail
}  // namespace agv
