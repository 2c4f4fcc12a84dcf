#include "agv/loop/affine_hough.hpp"

#include <cmath>

#include "association_common.hpp"

namespace agv {
namespace {

constexpr std::uint16_t kNoCell = 0xFFFF;
constexpr std::size_t kMaxSlices = 4096;

std::size_t gridSide(const AffineHoughParams& p) noexcept {
  return static_cast<std::size_t>(std::ceil(2.0F * p.maxTranslation / p.translationStep - 1e-4F));
}
std::size_t halfSlices(const AffineHoughParams& p) noexcept {
  return static_cast<std::size_t>(std::floor(p.maxRotation / p.rotationStep + 1e-4F));
}

}  // namespace

bool isValid(const AffineHoughParams& p) noexcept {
  const bool finite = std::isfinite(p.maxTranslation) && std::isfinite(p.translationStep) &&
                      std::isfinite(p.maxRotation) && std::isfinite(p.rotationStep) && std::isfinite(p.inlierGate);
  if (!finite || p.maxTranslation <= 0.0F || p.translationStep <= 0.0F || p.maxRotation < 0.0F ||
      p.rotationStep <= 0.0F || p.inlierGate <= 0.0F || p.maxVotes < 1 || p.minPairs < 3 || p.refinementPasses < 0 ||
      p.refinementPasses > 10 || p.maxRotation > 4.0F) {
    return false;
  }
  if (2.0F * p.maxTranslation / p.translationStep > 4096.0F || p.maxRotation / p.rotationStep > 2048.0F) {
    return false;
  }
  const std::size_t side = gridSide(p);
  return side >= 1 && side * side <= kMaxHoughCells && 2 * halfSlices(p) + 1 <= kMaxSlices;
}

AffineHoughMatcher::AffineHoughMatcher(const AffineHoughParams& params) noexcept : params_(params) {}

Status AffineHoughMatcher::match(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second,
                                 PointAssociation& out) noexcept {
  out = PointAssociation{};
  peak_ = 0;
  const Status st = detail::checkMatchInput(isValid(params_), first, second);
  if (st != Status::Ok) {
    return st;
  }
  (void)allCandidatePairs(first.size(), second.size(), all_);
  return run(first, second, Span<const PointPair>(all_.data(), all_.size()), out);
}

Status AffineHoughMatcher::match(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second,
                                 Span<const PointPair> candidates, PointAssociation& out) noexcept {
  out = PointAssociation{};
  peak_ = 0;
  const Status st = detail::checkMatchInput(isValid(params_), first, second, &candidates);
  if (st != Status::Ok) {
    return st;
  }
  return run(first, second, candidates, out);
}

Status AffineHoughMatcher::run(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second,
                               Span<const PointPair> cand, PointAssociation& out) noexcept {
  const AffineHoughParams& p = params_;
  const std::size_t side = gridSide(p);
  const std::size_t half = halfSlices(p);
  const std::size_t nSlices = 2 * half + 1;
  const std::size_t k = cand.size();
  for (std::size_t c = 0; c < side * side; ++c) {
    slice_[c] = 0;
  }
  const float invStep = 1.0F / p.translationStep;
  const float sideF = static_cast<float>(side);
  std::uint32_t votes = 0;
  std::uint16_t peak = 0;
  float bestTheta = 0.0F;
  std::uint16_t bestCell = kNoCell;
  // Slices by increasing |theta|: 0, +step, -step, +2 step, ...
  for (std::size_t n = 0; n < nSlices; ++n) {
    if (votes + k > p.maxVotes) {
      out.budgetHit = true;
      break;
    }
    votes += static_cast<std::uint32_t>(k);
    const std::size_t m = (n + 1) / 2;
    const float theta = static_cast<float>(m) * p.rotationStep * ((n % 2 == 1) ? 1.0F : -1.0F);
    const float c = std::cos(theta);
    const float s = std::sin(theta);
    for (std::size_t q = 0; q < k; ++q) {
      const Eigen::Vector2f& a = first[cand[q].first];
      const Eigen::Vector2f& b = second[cand[q].second];
      const float ux = (a.x() - (c * b.x() - s * b.y()) + p.maxTranslation) * invStep;
      const float uy = (a.y() - (s * b.x() + c * b.y()) + p.maxTranslation) * invStep;
      if (!(ux >= 0.0F && ux < sideF && uy >= 0.0F && uy < sideF)) {
        cellOf_[q] = kNoCell;
        continue;
      }
      const auto cell = static_cast<std::uint16_t>(static_cast<std::size_t>(uy) * side + static_cast<std::size_t>(ux));
      cellOf_[q] = cell;
      const std::uint16_t count = ++slice_[cell];
      if (count > peak) {
        peak = count;
        bestTheta = theta;
        bestCell = cell;
      }
    }
    for (std::size_t q = 0; q < k; ++q) {  // take the votes back: the slice is clean again
      if (cellOf_[q] != kNoCell) {
        slice_[cellOf_[q]] = 0;
      }
    }
  }
  out.work = votes;
  peak_ = peak;
  if (bestCell != kNoCell) {
    // The winning cell's pairs, one-to-one: per first point the pair nearest to the cell's motion,
    // then per second point the nearest of those.
    const float c = std::cos(bestTheta);
    const float s = std::sin(bestTheta);
    const float tx = (static_cast<float>(bestCell % side) + 0.5F) * p.translationStep - p.maxTranslation;
    const std::size_t row = bestCell / side;
    const float ty = (static_cast<float>(row) + 0.5F) * p.translationStep - p.maxTranslation;
    std::array<float, kMaxLoopPoints> resFirst{};
    std::array<std::uint16_t, kMaxLoopPoints> secondOf{};
    for (std::size_t i = 0; i < first.size(); ++i) {
      secondOf[i] = kNoCell;
    }
    for (std::size_t q = 0; q < k; ++q) {
      const Eigen::Vector2f& a = first[cand[q].first];
      const Eigen::Vector2f& b = second[cand[q].second];
      const float rx = a.x() - (c * b.x() - s * b.y());
      const float ry = a.y() - (s * b.x() + c * b.y());
      const float ux = (rx + p.maxTranslation) * invStep;
      const float uy = (ry + p.maxTranslation) * invStep;
      if (!(ux >= 0.0F && ux < sideF && uy >= 0.0F && uy < sideF) ||
          static_cast<std::size_t>(uy) * side + static_cast<std::size_t>(ux) != bestCell) {
        continue;
      }
      const float res = (rx - tx) * (rx - tx) + (ry - ty) * (ry - ty);
      const std::uint16_t i = cand[q].first;
      if (secondOf[i] == kNoCell || res < resFirst[i]) {
        secondOf[i] = cand[q].second;
        resFirst[i] = res;
      }
    }
    std::array<float, kMaxLoopPoints> resSecond{};
    std::array<std::uint16_t, kMaxLoopPoints> firstOf{};
    for (std::size_t j = 0; j < second.size(); ++j) {
      firstOf[j] = kNoCell;
    }
    for (std::size_t i = 0; i < first.size(); ++i) {
      const std::uint16_t j = secondOf[i];
      if (j != kNoCell && (firstOf[j] == kNoCell || resFirst[i] < resSecond[j])) {
        firstOf[j] = static_cast<std::uint16_t>(i);
        resSecond[j] = resFirst[i];
      }
    }
    for (std::size_t j = 0; j < second.size(); ++j) {
      if (firstOf[j] != kNoCell) {
        (void)out.pairs.push_back(PointPair{firstOf[j], static_cast<std::uint16_t>(j)});
      }
    }
    detail::fitPairs(first, second, out);
    if (out.pairs.size() >= 3) {
      detail::refine(first, second, p.inlierGate, p.refinementPasses, out);
    }
  }
  if (out.budgetHit) {
    return Status::NotConverged;
  }
  return out.pairs.size() >= p.minPairs ? Status::Ok : Status::NotEnoughData;
}

}  // namespace agv
