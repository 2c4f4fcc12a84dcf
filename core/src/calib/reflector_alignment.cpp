#include "agv/calib/reflector_alignment.hpp"

#include "agv/calib/rigid_fit.hpp"

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

#include "agv/core/capacities.hpp"

namespace agv {
namespace {

constexpr std::uint16_t kNone = kNoPair;
static_assert(kMaxReflectors < kNone, "reflector indices must fit the association table");

/// Mutual nearest neighbours within `gate` between first[i] and motion(second[j]).
/// pairOf[j] = index in `first` or kNone. Returns the number of pairs. O(n m), n, m <= kMaxReflectors.
std::size_t associate(Span<const Eigen::Vector2d> first, Span<const Eigen::Vector2d> second, const Pose2d& motion,
                      double gate, std::array<std::uint16_t, kMaxReflectors>& pairOf) noexcept {
  std::array<Eigen::Vector2d, kMaxReflectors> mapped;
  for (std::size_t j = 0; j < second.size(); ++j) {
    mapped[j] = motion.transformPoint(second[j]);
  }
  const double gate2 = gate * gate;
  std::size_t count = 0;
  for (std::size_t j = 0; j < second.size(); ++j) {
    pairOf[j] = kNone;
    double best = gate2;
    std::size_t bestI = first.size();
    for (std::size_t i = 0; i < first.size(); ++i) {
      const double d2 = (first[i] - mapped[j]).squaredNorm();
      if (d2 <= best) {
        best = d2;
        bestI = i;
      }
    }
    if (bestI == first.size()) {
      continue;
    }
    // mutual: no other second point is closer to first[bestI]
    bool mutual = true;
    for (std::size_t k = 0; k < second.size() && mutual; ++k) {
      if (k != j && (first[bestI] - mapped[k]).squaredNorm() < best) {
        mutual = false;
      }
    }
    if (mutual) {
      pairOf[j] = static_cast<std::uint16_t>(bestI);
      ++count;
    }
  }
  return count;
}

bool allFinite(Span<const Eigen::Vector2d> pts) noexcept {
  for (const Eigen::Vector2d& p : pts) {
    if (!std::isfinite(p.x()) || !std::isfinite(p.y())) {
      return false;
    }
  }
  return true;
}

}  // namespace

Status alignReflectors(Span<const Eigen::Vector2d> first, Span<const Eigen::Vector2d> second, const Pose2d& guess,
                       const ReflectorAlignmentOptions& opt, ReflectorAlignment& out) noexcept {
  out = ReflectorAlignment{};
  out.motion = guess;
  if (!(opt.associationGate > 0.0) || !(opt.finalGate > 0.0) || opt.minMatches < 2 || opt.maxIterations < 1 ||
      !(opt.convergence >= 0.0)) {
    return Status::InvalidArgument;
  }
  if (first.empty() || second.empty()) {
    return Status::EmptyInput;
  }
  if (first.size() > kMaxReflectors || second.size() > kMaxReflectors) {
    return Status::CapacityExceeded;
  }
  if (!guess.isFinite() || !allFinite(first) || !allFinite(second)) {
    return Status::NonFiniteInput;
  }
  std::array<std::uint16_t, kMaxReflectors> pairOf{};
  Pose2d motion = guess;
  std::size_t count = 0;
  bool converged = false;
  // Phase 0 converges with the wide gate, phase 1 re-associates with the tight gate.
  for (int phase = 0; phase < 2; ++phase) {
    const double gate = phase == 0 ? opt.associationGate : std::fmin(opt.associationGate, opt.finalGate);
    converged = false;
    for (int it = 0; it < opt.maxIterations; ++it) {
      ++out.iterations;
      count = associate(first, second, motion, gate, pairOf);
      if (count < opt.minMatches) {
        out.matches = count;
        return Status::NotEnoughData;
      }
      const Pose2d next = fitRigid2d(first, second, Span<const std::uint16_t>(pairOf.data(), second.size()));
      const double step =
          std::hypot(next.x - motion.x, next.y - motion.y) + std::fabs(angleDiff(next.theta, motion.theta));
      motion = next;
      if (step <= opt.convergence) {
        converged = true;
        break;
      }
    }
  }
  out.motion = motion;
  out.matches = count;
  out.rms = rigidFitRms(first, second, Span<const std::uint16_t>(pairOf.data(), second.size()), motion);
  return converged ? Status::Ok : Status::NotConverged;
}

}  // namespace agv
