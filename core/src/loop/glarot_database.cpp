#include "agv/loop/glarot_database.hpp"

#include <cmath>

#include "glarot_l1.hpp"

namespace agv {
namespace {

bool shapeOk(const GlarotSignature& s) noexcept {
  return s.thetaBins >= 1 && s.rhoBins >= 1 && s.rhoBins <= kGlarotMaxRhoBins && s.size() <= kGlarotMaxCells;
}

}  // namespace

Status GlarotDatabaseBase::insert(const GlarotSignature& signature, const Pose2d& pose) noexcept {
  if (!shapeOk(signature) || (size_ > 0 && (signature.thetaBins != entries_[0].signature.thetaBins ||
                                            signature.rhoBins != entries_[0].signature.rhoBins))) {
    return Status::InvalidArgument;
  }
  if (!pose.isFinite()) {
    return Status::NonFiniteInput;
  }
  if (size_ == capacity_) {
    ++refused_;
    return Status::CapacityExceeded;
  }
  GlarotEntry& e = entries_[size_];
  e.signature = signature;
  e.pose = pose;
  e.travel = size_ == 0 ? 0.0
                        : entries_[size_ - 1].travel +
                              std::hypot(pose.x - entries_[size_ - 1].pose.x, pose.y - entries_[size_ - 1].pose.y);
  const std::size_t nT = signature.thetaBins;
  const std::size_t nR = signature.rhoBins;
  for (std::size_t r = 0; r < nR; ++r) {
    float sum = 0.0F;
    for (std::size_t t = 0; t < nT; ++t) {
      sum += signature.cells[t * nR + r];
    }
    e.rhoMarginal[r] = sum;
  }
  ++size_;
  return Status::Ok;
}

Status GlarotDatabaseBase::query(const GlarotSignature& signature, const GlarotQuery& q,
                                 IVector<GlarotCandidate>& out) const noexcept {
  out.clear();
  if (q.k == 0 || q.k > kGlarotMaxCandidates || q.k > out.capacity() || !shapeOk(signature) ||
      (size_ > 0 && (signature.thetaBins != entries_[0].signature.thetaBins ||
                     signature.rhoBins != entries_[0].signature.rhoBins))) {
    return Status::InvalidArgument;
  }
  const std::size_t end = q.end < size_ ? q.end : size_;
  if (end == 0) {
    return Status::EmptyInput;
  }
  const std::size_t recentStart = q.excludeRecent < end ? end - q.excludeRecent : 0;
  const double newestTravel = entries_[end - 1].travel;
  const std::size_t nT = signature.thetaBins;
  const std::size_t nR = signature.rhoBins;
  std::array<float, kGlarotMaxRhoBins> marginal{};
  for (std::size_t r = 0; r < nR; ++r) {
    float sum = 0.0F;
    for (std::size_t t = 0; t < nT; ++t) {
      sum += signature.cells[t * nR + r];
    }
    marginal[r] = sum;
  }
  std::array<GlarotCandidate, kGlarotMaxCandidates> best{};
  std::size_t n = 0;
  std::size_t admitted = 0;
  const float inf = std::numeric_limits<float>::infinity();
  for (std::size_t i = 0; i < recentStart; ++i) {
    if (i == q.excludeIndex || newestTravel - entries_[i].travel < q.excludeRecentTravel) {
      continue;
    }
    ++admitted;
    const GlarotEntry& e = entries_[i];
    const float worst = n == q.k ? best[n - 1].distance : inf;
    float bound = 0.0F;
    for (std::size_t r = 0; r < nR; ++r) {
      bound += std::fabs(marginal[r] - e.rhoMarginal[r]);
    }
    // The bound is summed in another order than SL1: keep a rounding margin before trusting it.
    if (bound * 0.9999F >= worst) {
      continue;
    }
    float dist = worst;
    std::uint16_t shift = 0;
    bool better = false;
    for (std::size_t s = 0; s < nT; ++s) {
      const float d = detail::glarotShiftedL1Kernel(e.signature.cells.data(), signature.cells.data(), nT, nR, s, dist);
      if (d < dist) {
        dist = d;
        shift = static_cast<std::uint16_t>(s);
        better = true;
      }
    }
    if (!better) {
      continue;
    }
    // Sorted insertion (equal distances keep the lower index first: it came first).
    std::size_t pos = n < q.k ? n : q.k - 1;
    while (pos > 0 && best[pos - 1].distance > dist) {
      best[pos] = best[pos - 1];
      --pos;
    }
    best[pos] = GlarotCandidate{static_cast<std::uint32_t>(i), dist, shift};
    n = n < q.k ? n + 1 : q.k;
  }
  for (std::size_t k = 0; k < n; ++k) {
    (void)out.push_back(best[k]);
  }
  return admitted > 0 ? Status::Ok : Status::EmptyInput;
}

}  // namespace agv
