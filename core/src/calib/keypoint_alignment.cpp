#include "agv/calib/keypoint_alignment.hpp"

#include <Eigen/Core>
#include <array>
#include <cmath>

#include "agv/calib/rigid_fit.hpp"
#include "agv/core/angle.hpp"
#include "agv/core/capacities.hpp"
#include "agv/core/split_mix64.hpp"

namespace agv {
namespace {

static_assert(kMaxKeypoints < kNoPair, "keypoint indices must fit the association table");

/// Candidate partners (indices in the first scan) of each keypoint of the second scan, best
/// descriptor distance first.
struct Candidates {
  std::array<std::array<std::uint16_t, kMaxKeypointCandidates>, kMaxKeypoints> first{};
  std::array<std::uint8_t, kMaxKeypoints> count{};
  std::size_t total = 0;
};

/// Descriptor distance as a float (BSC cells or CGH chi-square); negative when above the limit.
float descriptorDistance(const KeypointScanView& a, std::size_t i, const KeypointScanView& b, std::size_t j,
                         const KeypointAlignmentOptions& opt) noexcept {
  if (opt.descriptor == KeypointDescriptor::Bsc) {
    const std::uint32_t d = bscDistance(a.bsc[i], b.bsc[j]);
    return d <= opt.maxBscDistance ? static_cast<float>(d) : -1.0F;
  }
  const float d = cghDistance(a.cgh[i], b.cgh[j]);
  return d <= opt.maxCghDistance ? d : -1.0F;
}

/// Keeps the `k` first-scan keypoints of smallest descriptor distance for every second keypoint.
void formCandidates(const KeypointScanView& first, const KeypointScanView& second, const KeypointAlignmentOptions& opt,
                    Candidates& c) noexcept {
  c.total = 0;
  const std::size_t k = opt.candidatesPerKeypoint;
  for (std::size_t j = 0; j < second.keypoints.size(); ++j) {
    std::array<float, kMaxKeypointCandidates> best{};
    std::size_t n = 0;
    for (std::size_t i = 0; i < first.keypoints.size() && (second.keypoints[j].refined || !opt.refinedOnly); ++i) {
      if (opt.refinedOnly && !first.keypoints[i].refined) {
        continue;
      }
      const float d = descriptorDistance(first, i, second, j, opt);
      if (d < 0.0F || (n == k && d >= best[n - 1])) {
        continue;
      }
      // insertion into the sorted short list
      std::size_t pos = n < k ? n : k - 1;
      while (pos > 0 && best[pos - 1] > d) {
        best[pos] = best[pos - 1];
        c.first[j][pos] = c.first[j][pos - 1];
        --pos;
      }
      best[pos] = d;
      c.first[j][pos] = static_cast<std::uint16_t>(i);
      n = n < k ? n + 1 : k;
    }
    c.count[j] = static_cast<std::uint8_t>(n);
    c.total += n;
  }
}

/// For every second keypoint, the candidate whose mapped distance is smallest and within the gate
/// (each first keypoint used once: the closer claim wins). Returns the pair count and the sum of
/// squared distances.
std::size_t associate(Span<const Eigen::Vector2d> p, Span<const Eigen::Vector2d> q, const Candidates& c,
                      const Pose2d& motion, double gate, std::array<std::uint16_t, kMaxKeypoints>& pairOf,
                      double& sumSq) noexcept {
  std::array<double, kMaxKeypoints> claim{};  // best squared distance claiming each first keypoint
  std::array<std::uint16_t, kMaxKeypoints> owner{};
  for (std::size_t i = 0; i < p.size(); ++i) {
    owner[i] = kNoPair;
  }
  const double gate2 = gate * gate;
  for (std::size_t j = 0; j < q.size(); ++j) {
    pairOf[j] = kNoPair;
    const Eigen::Vector2d m = motion.transformPoint(q[j]);
    double best = gate2;
    std::uint16_t bestI = kNoPair;
    for (std::size_t k = 0; k < c.count[j]; ++k) {
      const std::uint16_t i = c.first[j][k];
      const double d2 = (p[i] - m).squaredNorm();
      if (d2 <= best) {
        best = d2;
        bestI = i;
      }
    }
    if (bestI == kNoPair) {
      continue;
    }
    if (owner[bestI] != kNoPair) {
      if (claim[bestI] <= best) {
        continue;
      }
      pairOf[owner[bestI]] = kNoPair;
    }
    owner[bestI] = static_cast<std::uint16_t>(j);
    claim[bestI] = best;
    pairOf[j] = bestI;
  }
  std::size_t count = 0;
  sumSq = 0.0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (owner[i] != kNoPair) {
      ++count;
      sumSq += claim[i];
    }
  }
  return count;
}

bool optionsValid(const KeypointAlignmentOptions& o) noexcept {
  return o.candidatesPerKeypoint >= 1 && o.candidatesPerKeypoint <= kMaxKeypointCandidates && o.inlierGate > 0.0 &&
         std::isfinite(o.inlierGate) && o.minBaseline >= 0.0 && o.minInliers >= 3 && o.maxHypotheses >= 1 &&
         o.maxDraws >= 1 && o.refinementPasses >= 1 && o.guessTranslationGate > 0.0 && o.guessRotationGate > 0.0 &&
         o.maxCghDistance >= 0.0F;
}

bool viewValid(const KeypointScanView& v, KeypointDescriptor d) noexcept {
  return d == KeypointDescriptor::Bsc ? v.bsc.size() == v.keypoints.size() : v.cgh.size() == v.keypoints.size();
}

bool viewFinite(const KeypointScanView& v) noexcept {
  for (const FalkoKeypoint& k : v.keypoints) {
    if (!std::isfinite(k.x) || !std::isfinite(k.y)) {
      return false;
    }
  }
  return true;
}

void widen(const KeypointScanView& v, std::array<Eigen::Vector2d, kMaxKeypoints>& pts) noexcept {
  for (std::size_t i = 0; i < v.keypoints.size(); ++i) {
    pts[i] = Eigen::Vector2d(static_cast<double>(v.keypoints[i].x), static_cast<double>(v.keypoints[i].y));
  }
}

}  // namespace

Status alignKeypoints(const KeypointScanView& first, const KeypointScanView& second, const Pose2d& guess,
                      const KeypointAlignmentOptions& opt, KeypointAlignment& out) noexcept {
  out = KeypointAlignment{};
  out.motion = guess;
  if (!optionsValid(opt) || !viewValid(first, opt.descriptor) || !viewValid(second, opt.descriptor)) {
    return Status::InvalidArgument;
  }
  if (first.keypoints.empty() || second.keypoints.empty()) {
    return Status::EmptyInput;
  }
  if (first.keypoints.size() > kMaxKeypoints || second.keypoints.size() > kMaxKeypoints) {
    return Status::CapacityExceeded;
  }
  if (!guess.isFinite() || !viewFinite(first) || !viewFinite(second)) {
    return Status::NonFiniteInput;
  }
  std::array<Eigen::Vector2d, kMaxKeypoints> pArr;
  std::array<Eigen::Vector2d, kMaxKeypoints> qArr;
  widen(first, pArr);
  widen(second, qArr);
  const Span<const Eigen::Vector2d> p(pArr.data(), first.keypoints.size());
  const Span<const Eigen::Vector2d> q(qArr.data(), second.keypoints.size());

  static_assert(sizeof(Candidates) <= 8704, "candidate table must stay small for MCU stacks");
  Candidates cand;
  formCandidates(first, second, opt, cand);
  out.candidates = cand.total;
  if (cand.total < opt.minInliers) {
    return Status::NotEnoughData;
  }

  // Consensus: a hypothesis from two candidate matches of different keypoints whose lengths agree
  // (a cheap test), scored by the number of consistent matches, then by their squared distances.
  // All pairs of candidate matches are tried when they are at most maxDraws, else maxDraws pairs
  // are drawn; at most maxHypotheses of them are scored.
  std::array<std::uint16_t, kMaxKeypoints> pairOf{};
  std::size_t bestCount = 0;
  double bestSq = 0.0;
  Pose2d best = guess;
  const auto tryPair = [&](std::size_t ja, std::size_t ka, std::size_t jb, std::size_t kb) noexcept {
    const std::uint16_t ia = cand.first[ja][ka];
    const std::uint16_t ib = cand.first[jb][kb];
    if (ja == jb || ia == ib) {
      return;
    }
    const double baseQ = (q[ja] - q[jb]).norm();
    const double baseP = (p[ia] - p[ib]).norm();
    if (baseQ < opt.minBaseline || std::fabs(baseQ - baseP) > 2.0 * opt.inlierGate) {
      return;
    }
    const std::array<Eigen::Vector2d, 2> p2{p[ia], p[ib]};
    const std::array<Eigen::Vector2d, 2> q2{q[ja], q[jb]};
    const std::array<std::uint16_t, 2> pair2{0, 1};
    const Pose2d motion =
        fitRigid2d(Span<const Eigen::Vector2d>(p2.data(), 2), Span<const Eigen::Vector2d>(q2.data(), 2),
                   Span<const std::uint16_t>(pair2.data(), 2));
    if (std::hypot(motion.x - guess.x, motion.y - guess.y) > opt.guessTranslationGate ||
        std::fabs(angleDiff(motion.theta, guess.theta)) > opt.guessRotationGate) {
      return;
    }
    ++out.hypotheses;
    // Locally optimised: the two-point motion's rotation error (noise over a short base) grows
    // with distance from the pair, so the matches it gates are refitted once and re-gated.
    double sq = 0.0;
    std::size_t n = associate(p, q, cand, motion, opt.inlierGate, pairOf, sq);
    Pose2d refined = motion;
    if (n >= 2) {
      refined = fitRigid2d(p, q, Span<const std::uint16_t>(pairOf.data(), q.size()));
      n = associate(p, q, cand, refined, opt.inlierGate, pairOf, sq);
    }
    if (n > bestCount || (n == bestCount && n > 0 && sq < bestSq)) {
      bestCount = n;
      bestSq = sq;
      best = refined;
    }
  };
  const std::size_t budget = static_cast<std::size_t>(opt.maxHypotheses);
  if (cand.total * (cand.total - 1) / 2 <= static_cast<std::size_t>(opt.maxDraws)) {
    for (std::size_t ja = 0; ja < q.size(); ++ja) {
      for (std::size_t jb = ja + 1; jb < q.size(); ++jb) {
        for (std::size_t ka = 0; ka < cand.count[ja]; ++ka) {
          for (std::size_t kb = 0; kb < cand.count[jb] && static_cast<std::size_t>(out.hypotheses) < budget; ++kb) {
            tryPair(ja, ka, jb, kb);
          }
        }
      }
    }
  } else {
    // Reproducible hypotheses on every platform; draws by remainder (as they always were).
    SplitMix64 rng{opt.seed};
    const auto below = [&rng](std::size_t n) { return static_cast<std::size_t>(rng.next() % n); };
    for (int d = 0; d < opt.maxDraws && static_cast<std::size_t>(out.hypotheses) < budget; ++d) {
      const std::size_t ja = below(q.size());
      const std::size_t jb = below(q.size());
      if (cand.count[ja] == 0 || cand.count[jb] == 0) {
        continue;
      }
      tryPair(ja, below(cand.count[ja]), jb, below(cand.count[jb]));
    }
  }
  out.motion = best;
  if (bestCount < opt.minInliers) {
    out.inliers = bestCount;
    return Status::NotEnoughData;
  }

  // Least squares on the consensus set, re-associated with the improved motion.
  Pose2d motion = best;
  std::size_t count = 0;
  const Span<const std::uint16_t> pairs(pairOf.data(), q.size());
  for (int pass = 0; pass < opt.refinementPasses; ++pass) {
    double sq = 0.0;
    count = associate(p, q, cand, motion, opt.inlierGate, pairOf, sq);
    if (count < opt.minInliers) {
      out.inliers = count;
      out.motion = motion;
      return Status::NotEnoughData;
    }
    motion = fitRigid2d(p, q, pairs);
  }
  double sq = 0.0;
  count = associate(p, q, cand, motion, opt.inlierGate, pairOf, sq);
  out.motion = motion;
  out.inliers = count;
  out.rms = rigidFitRms(p, q, pairs, motion);
  return count >= opt.minInliers ? Status::Ok : Status::NotEnoughData;
}

}  // namespace agv
