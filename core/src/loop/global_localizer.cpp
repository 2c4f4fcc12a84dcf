#include "agv/loop/global_localizer.hpp"

#include <algorithm>
#include <cmath>

#include "agv/calib/rigid_fit.hpp"
#include "agv/core/angle.hpp"

namespace agv {

static_assert(kMaxLoopPoints <= kMaxObservations, "a localizer scan must fit a pose check");

namespace {

bool finite(double v) noexcept {
  return std::isfinite(v);
}

bool poseFinite(const Pose2d& p) noexcept {
  return finite(p.x) && finite(p.y) && finite(p.theta);
}

/// Two poses farther apart than the search's ambiguity distance or angle (either).
bool distinctPoses(const Pose2d& a, const Pose2d& b, const GlobalLocalizerParams& p) noexcept {
  const double dx = a.x - b.x;
  const double dy = a.y - b.y;
  return std::sqrt(dx * dx + dy * dy) > p.ambiguityDistance ||
         std::fabs(angleDiff(a.theta, b.theta)) > p.ambiguityAngle;
}

/// A pose checked, refitted on its inliers and checked again: the refit when it keeps at least as
/// many inliers, else `pose` (normalised either way), with the kept check.
struct Refit {
  Pose2d pose{};
  PoseCheck check{};
};
Refit refitOnce(const LandmarkMap& map, Span<const PointObservation> observations, const GlobalLocalizerParams& p,
                const Pose2d& pose) noexcept {
  const PoseCheck first = checkPose(map, observations, p.laserMount, pose, p.inlierGate);
  const PoseCheck refined = checkPose(map, observations, p.laserMount, first.refit, p.inlierGate);
  const bool useRefined = refined.inliers >= first.inliers;
  return Refit{useRefined ? first.refit.normalized() : pose.normalized(), useRefined ? refined : first};
}

/// Calls onExpected(index, explained) for every landmark of the observed kinds that `pose` expects
/// in the scan's clear view (docs/loop-closure.md, "Negative evidence"), `explained` when an
/// observation lands within the gate of it. `forEachLandmark(visit)` calls visit(index, x, y,
/// kind) for every landmark.
template <typename ForEachLandmark, typename OnExpected>
void forEachExpected(const GlobalLocalizerParams& params, const Pose2d& pose, Span<const PointObservation> observations,
                     const LaserScan& scan, ForEachLandmark&& forEachLandmark, OnExpected&& onExpected) noexcept {
  const std::size_t beams = scan.size();
  if (beams == 0 || !(scan.angleIncrement > 0.0F)) {
    return;
  }
  std::uint32_t kinds = 0;  // the kinds the detectors reported: only those are expected
  for (std::size_t i = 0; i < observations.size(); ++i) {
    kinds |= 1U << static_cast<unsigned>(observations[i].kind);
  }
  const double inc = static_cast<double>(scan.angleIncrement);
  const double angleMin = static_cast<double>(scan.angleMin);
  const bool fullCircle = static_cast<double>(beams) * inc >= 2.0 * kPi<double> - 0.5 * inc;
  const double gate = params.inlierGate;
  const double maxRange = std::min(params.expectRange, static_cast<double>(scan.rangeMax));
  const Pose2d laser = pose.compose(params.laserMount);
  forEachLandmark([&](std::size_t index, double lx, double ly, LandmarkKind kind) {
    if ((kinds & (1U << static_cast<unsigned>(kind))) == 0U) {
      return;
    }
    const Eigen::Vector2d v = laser.inverseTransformPoint(Eigen::Vector2d(lx, ly));
    const double d = v.norm();
    if (d > maxRange || d <= std::max(2.0 * gate, static_cast<double>(scan.rangeMin))) {
      return;
    }
    // The beams within `gate` of the landmark: all must reach it (nothing in front), one at least.
    const double bearing = std::atan2(v.y(), v.x());
    const double half = std::atan2(gate, d);
    const auto first = static_cast<long>(std::ceil((bearing - half - angleMin) / inc));
    const auto last = static_cast<long>(std::floor((bearing + half - angleMin) / inc));
    const auto n = static_cast<long>(beams);
    if (!fullCircle && (first < 0 || last >= n)) {
      return;  // not wholly in the field of view
    }
    bool clear = true;
    std::size_t reaching = 0;
    for (long b = first; b <= last && b - first < n && clear; ++b) {
      const auto i = static_cast<std::size_t>(((b % n) + n) % n);
      if (!scan.isValid(i)) {
        continue;
      }
      if (static_cast<double>(scan.ranges[i]) < d - gate) {
        clear = false;  // something in front of it: hidden
      }
      ++reaching;
    }
    if (!clear || reaching == 0) {
      return;
    }
    bool explained = false;
    for (std::size_t i = 0; i < observations.size() && !explained; ++i) {
      if (observations[i].kind != kind) {
        continue;
      }
      const Eigen::Vector2d w = laser.transformPoint(Eigen::Vector2d(observations[i].x, observations[i].y));
      explained = (w - Eigen::Vector2d(lx, ly)).squaredNorm() <= gate * gate;
    }
    onExpected(index, explained);
  });
}

/// Every live landmark of `map` as visit(index, x, y, kind).
auto landmarksOf(const LandmarkMap& map) noexcept {
  return [&map](auto&& visit) {
    map.forEach([&](LandmarkIndex index, const Landmark& l) { visit(index, l.x, l.y, l.kind); });
  };
}

}  // namespace

bool isValid(const GlobalLocalizerParams& p) noexcept {
  return poseFinite(p.laserMount) && std::isfinite(p.epsilon) && p.epsilon > 0.0F && finite(p.inlierGate) &&
         p.inlierGate > 0.0 && p.minSupport >= 3 && p.anchorCount >= 1 && finite(p.ambiguityDistance) &&
         p.ambiguityDistance > 0.0 && finite(p.ambiguityAngle) && p.ambiguityAngle > 0.0 && finite(p.expectRange) &&
         p.expectRange > 0.0 && p.maxNodesPerWindow >= 1 && p.maxTotalNodes >= 1;
}

Status toStatus(RelocOutcome outcome) noexcept {
  switch (outcome) {
    case RelocOutcome::Found:
      return Status::Ok;
    case RelocOutcome::InvalidParams:
      return Status::InvalidArgument;
    case RelocOutcome::EmptyInput:
      return Status::EmptyInput;
    case RelocOutcome::NonFiniteInput:
      return Status::NonFiniteInput;
    case RelocOutcome::OverCapacity:
    case RelocOutcome::WindowOverCapacity:
      return Status::CapacityExceeded;
    case RelocOutcome::WeakSupport:
      return Status::NotEnoughData;
    case RelocOutcome::Ambiguous:
      return Status::Rejected;
    case RelocOutcome::WorkBoundHit:
      return Status::NotConverged;
  }
  return Status::InvalidArgument;
}

PoseCheck checkPose(const LandmarkMap& map, Span<const PointObservation> observations, const Pose2d& laserMount,
                    const Pose2d& pose, double gate) noexcept {
  PoseCheck out;
  out.refit = pose;
  const std::size_t n = observations.size();
  if (n == 0 || n > kMaxObservations || !poseFinite(pose) || !poseFinite(laserMount) || !(gate > 0.0)) {
    return out;
  }
  std::array<Eigen::Vector2d, kMaxObservations> vehicle;
  std::array<Eigen::Vector2d, kMaxObservations> landmark;
  std::array<std::uint16_t, kMaxObservations> pairOf;
  double sum = 0.0;
  for (std::size_t j = 0; j < n; ++j) {
    const PointObservation& o = observations[j];
    pairOf[j] = kNoPair;
    vehicle[j] = laserMount.transformPoint(Eigen::Vector2d(o.x, o.y));
    landmark[j] = Eigen::Vector2d::Zero();
    if (!finite(o.x) || !finite(o.y)) {
      continue;
    }
    const Eigen::Vector2d w = pose.transformPoint(vehicle[j]);
    double bestD2 = gate * gate;
    bool found = false;
    map.forEachNear(w.x(), w.y(), gate, [&](LandmarkIndex /*index*/, const Landmark& l) {
      if (l.kind != o.kind) {
        return;
      }
      const double d2 = (Eigen::Vector2d(l.x, l.y) - w).squaredNorm();
      if (d2 <= bestD2) {
        bestD2 = d2;
        landmark[j] = Eigen::Vector2d(l.x, l.y);
        found = true;
      }
    });
    if (found) {
      pairOf[j] = static_cast<std::uint16_t>(j);
      sum += bestD2;
      ++out.inliers;
    }
  }
  if (out.inliers > 0) {
    out.rms = std::sqrt(sum / static_cast<double>(out.inliers));
  }
  if (out.inliers >= 3) {
    out.refit = fitRigid2d(Span<const Eigen::Vector2d>(landmark.data(), n),
                           Span<const Eigen::Vector2d>(vehicle.data(), n), Span<const std::uint16_t>(pairOf.data(), n));
  }
  return out;
}

GlobalLocalizer::GlobalLocalizer(const GlobalLocalizerParams& params) noexcept : params_(params) {}

Status GlobalLocalizer::finish(RelocReport& out, RelocOutcome outcome) noexcept {
  out.outcome = outcome;
  if (outcome != RelocOutcome::Found) {
    out.pose = Pose2d{};
  }
  return toStatus(outcome);
}

bool GlobalLocalizer::distinct(const Pose2d& a, const Pose2d& b) const noexcept {
  return distinctPoses(a, b, params_);
}

void GlobalLocalizer::offer(const Hypothesis& h) noexcept {
  if (!best_.valid) {
    best_ = h;
    return;
  }
  if (!distinct(h.pose, best_.pose)) {
    if (h.inliers > best_.inliers || (h.inliers == best_.inliers && h.rms < best_.rms)) {
      best_ = h;
      if (second_.valid && !distinct(second_.pose, best_.pose)) {
        second_ = Hypothesis{};
      }
    }
    return;
  }
  if (h.inliers > best_.inliers || (h.inliers == best_.inliers && h.rms < best_.rms)) {
    second_ = best_;
    best_ = h;
    return;
  }
  if (!second_.valid || h.inliers > second_.inliers) {
    second_ = h;
  }
}

void GlobalLocalizer::keepMode(const Hypothesis& h) noexcept {
  const auto better = [](const Hypothesis& a, const Hypothesis& b) {
    return a.inliers > b.inliers || (a.inliers == b.inliers && a.rms < b.rms);
  };
  for (std::size_t i = 0; i < modeCount_; ++i) {
    if (!distinct(h.pose, modes_[i].pose)) {
      if (better(h, modes_[i])) {
        modes_[i] = h;
      }
      return;
    }
  }
  if (modeCount_ < modes_.size()) {
    modes_[modeCount_++] = h;
    return;
  }
  // Full: the weakest place gives way to a stronger one; what is dropped is remembered as a
  // competitor that no negative evidence refutes.
  std::size_t weakest = 0;
  for (std::size_t i = 1; i < modeCount_; ++i) {
    if (better(modes_[weakest], modes_[i])) {
      weakest = i;
    }
  }
  modesDropped_ = true;
  if (better(h, modes_[weakest])) {
    droppedInliers_ = std::max(droppedInliers_, modes_[weakest].inliers);
    modes_[weakest] = h;
  } else {
    droppedInliers_ = std::max(droppedInliers_, h.inliers);
  }
}

std::size_t GlobalLocalizer::missed(const Pose2d& pose, Span<const PointObservation> observations,
                                    const LaserScan& scan) const noexcept {
  std::size_t count = 0;
  forEachExpected(
      params_, pose, observations, scan,
      [&](auto&& visit) {
        for (std::size_t j = 0; j < mapSize_; ++j) {
          visit(j, static_cast<double>(map_[j].x), static_cast<double>(map_[j].y), map_[j].kind);
        }
      },
      [&](std::size_t /*index*/, bool explained) { count += explained ? 0U : 1U; });
  return count;
}

std::size_t missedLandmarks(const LandmarkMap& map, Span<const PointObservation> observations, const LaserScan& scan,
                            const Pose2d& pose, const GlobalLocalizerParams& params) noexcept {
  if (!isValid(params) || !poseFinite(pose)) {
    return 0;
  }
  std::size_t count = 0;
  forEachExpected(params, pose, observations, scan, landmarksOf(map),
                  [&](std::size_t /*index*/, bool explained) { count += explained ? 0U : 1U; });
  return count;
}

std::size_t GlobalLocalizer::lowerBound(float x) const noexcept {
  const MapPoint* begin = map_.data();
  const MapPoint* it = std::lower_bound(begin, begin + mapSize_, x, [](const MapPoint& p, float v) { return p.x < v; });
  return static_cast<std::size_t>(it - begin);
}

bool GlobalLocalizer::sameAnswer(const RelocReport& report, const Pose2d& pose) const noexcept {
  return report.outcome == RelocOutcome::Found && poseFinite(pose) && !distinct(report.pose, pose);
}

Status GlobalLocalizer::localize(const LandmarkMap& map, Span<const PointObservation> observations,
                                 RelocReport& out) noexcept {
  return search(map, observations, nullptr, out);
}

Status GlobalLocalizer::localize(const LandmarkMap& map, Span<const PointObservation> observations,
                                 const LaserScan& scan, RelocReport& out) noexcept {
  return search(map, observations, &scan, out);
}

Status GlobalLocalizer::search(const LandmarkMap& map, Span<const PointObservation> observations, const LaserScan* scan,
                               RelocReport& out) noexcept {
  out = RelocReport{};
  best_ = Hypothesis{};
  second_ = Hypothesis{};
  modeCount_ = 0;
  droppedInliers_ = 0;
  modesDropped_ = false;
  if (!isValid(params_)) {
    return finish(out, RelocOutcome::InvalidParams);
  }
  const std::size_t n = observations.size();
  if (n == 0 || map.size() == 0) {
    return finish(out, RelocOutcome::EmptyInput);
  }
  if (n > kMaxLoopPoints) {
    out.refusedObservations = n - kMaxLoopPoints;
    return finish(out, RelocOutcome::OverCapacity);
  }
  for (std::size_t i = 0; i < n; ++i) {
    const PointObservation& o = observations[i];
    if (!finite(o.x) || !finite(o.y) || std::fabs(o.x) > kMaxMapCoordinate || std::fabs(o.y) > kMaxMapCoordinate) {
      return finish(out, RelocOutcome::NonFiniteInput);
    }
    const Eigen::Vector2d v = params_.laserMount.transformPoint(Eigen::Vector2d(o.x, o.y));
    obs_[i] = v.cast<float>();
  }

  // Sorted copy of the map (by x), so that a window's landmarks are one contiguous x-range.
  mapSize_ = 0;
  map.forEach([&](LandmarkIndex /*index*/, const Landmark& l) {
    if (mapSize_ < map_.size()) {
      map_[mapSize_++] = MapPoint{static_cast<float>(l.x), static_cast<float>(l.y), l.kind};
    }
  });
  std::sort(map_.begin(), map_.begin() + static_cast<std::ptrdiff_t>(mapSize_),
            [](const MapPoint& a, const MapPoint& b) { return a.x < b.x; });

  // Anchors: the nearest observations (in the laser frame), up to anchorCount.
  std::array<std::uint16_t, kMaxLoopPoints> order{};
  for (std::size_t i = 0; i < n; ++i) {
    order[i] = static_cast<std::uint16_t>(i);
  }
  auto rangeOf = [&](std::uint16_t i) { return std::hypot(observations[i].x, observations[i].y); };
  std::sort(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(n),
            [&](std::uint16_t a, std::uint16_t b) { return rangeOf(a) < rangeOf(b); });
  const std::size_t anchors = std::min(params_.anchorCount, n);

  CorrespondenceGraphParams cg;
  cg.epsilon = params_.epsilon;
  cg.maxNodes = params_.maxNodesPerWindow;
  cg.minPairs = 3;
  matcher_.setParams(cg);
  const float eps = params_.epsilon;
  const Span<const Eigen::Vector2f> second(obs_.data(), n);
  bool totalBudgetHit = false;

  for (std::size_t ai = 0; ai < anchors && !totalBudgetHit; ++ai) {
    const std::size_t a = order[ai];
    const LandmarkKind anchorKind = observations[a].kind;
    float extent = 0.0F;
    for (std::size_t i = 0; i < n; ++i) {
      anchorDist_[i] = (obs_[i] - obs_[a]).norm();
      extent = std::max(extent, anchorDist_[i]);
    }
    const float radius = extent + eps;
    for (std::size_t j = 0; j < mapSize_ && !totalBudgetHit; ++j) {
      const MapPoint& lj = map_[j];
      if (lj.kind != anchorKind) {
        continue;
      }
      ++out.windows;
      candidates_.clear();
      std::size_t nLocal = 1;
      local_[0] = Eigen::Vector2f(lj.x, lj.y);
      localSource_[0] = static_cast<std::uint32_t>(j);
      (void)candidates_.push_back(PointPair{0, static_cast<std::uint16_t>(a)});
      bool over = false;
      for (std::size_t k = lowerBound(lj.x - radius); k < mapSize_ && map_[k].x <= lj.x + radius && !over; ++k) {
        if (k == j) {
          continue;
        }
        const MapPoint& lk = map_[k];
        const float dy = lk.y - lj.y;
        if (std::fabs(dy) > radius) {
          continue;
        }
        const float dx = lk.x - lj.x;
        const float r = std::sqrt(dx * dx + dy * dy);
        std::size_t localIndex = kMaxLoopPoints;  // assigned on the first pair
        for (std::size_t i = 0; i < n; ++i) {
          if (i == a || observations[i].kind != lk.kind || std::fabs(r - anchorDist_[i]) >= eps) {
            continue;
          }
          if (localIndex == kMaxLoopPoints) {
            if (nLocal == kMaxLoopPoints) {
              over = true;
              break;
            }
            localIndex = nLocal++;
            local_[localIndex] = Eigen::Vector2f(lk.x, lk.y);
            localSource_[localIndex] = static_cast<std::uint32_t>(k);
          }
          if (candidates_.push_back(PointPair{static_cast<std::uint16_t>(localIndex), static_cast<std::uint16_t>(i)}) !=
              Status::Ok) {
            over = true;
            break;
          }
        }
      }
      if (over) {
        ++out.windowsOverCapacity;
        continue;
      }
      if (candidates_.size() < 3) {
        continue;  // no clique of 3 pairs can exist
      }
      const Status st = matcher_.match(Span<const Eigen::Vector2f>(local_.data(), nLocal), second,
                                       Span<const PointPair>(candidates_.data(), candidates_.size()), assoc_);
      out.nodes += assoc_.work;
      if (assoc_.budgetHit) {
        ++out.windowsBudgetHit;
      }
      if (out.nodes >= params_.maxTotalNodes) {
        totalBudgetHit = true;
      }
      if ((st != Status::Ok && st != Status::NotConverged) || assoc_.pairs.size() < 3) {
        continue;
      }
      const Refit fit = refitOnce(map, observations, params_, assoc_.transform);
      Hypothesis h;
      h.valid = true;
      h.pose = fit.pose;
      h.inliers = fit.check.inliers;
      h.rms = fit.check.rms;
      h.clique = assoc_.pairs.size();
      offer(h);
      keepMode(h);
    }
  }

  if (best_.valid) {
    out.pose = best_.pose;
    out.inliers = best_.inliers;
    out.rms = best_.rms;
    out.clique = best_.clique;
  }
  if (second_.valid) {
    out.hasSecond = true;
    out.secondPose = second_.pose;
    out.secondInliers = second_.inliers;
  }
  if (totalBudgetHit || out.windowsBudgetHit > 0) {
    return finish(out, RelocOutcome::WorkBoundHit);
  }
  if (out.windowsOverCapacity > 0) {
    return finish(out, RelocOutcome::WindowOverCapacity);
  }
  if (!best_.valid || best_.inliers < params_.minSupport) {
    return finish(out, RelocOutcome::WeakSupport);
  }
  if (scan == nullptr) {
    if (second_.valid && second_.inliers + params_.ambiguityMargin >= best_.inliers) {
      return finish(out, RelocOutcome::Ambiguous);
    }
    return finish(out, RelocOutcome::Found);
  }
  // Negative evidence: score = inliers - missed. Only a distinct place with inliers within the
  // margin of the best's score can compete (a score never exceeds the inliers).
  out.missed = missed(best_.pose, observations, *scan);
  const long bestScore = static_cast<long>(best_.inliers) - static_cast<long>(out.missed);
  // inliers - missed < minNetSupport, in unsigned terms (any minNetSupport, no wrap-around)
  if (best_.inliers < params_.minNetSupport || best_.inliers - params_.minNetSupport < out.missed) {
    return finish(out, RelocOutcome::WeakSupport);
  }
  const auto margin = static_cast<long>(params_.ambiguityMargin);
  // Against a place the scan refutes (it misses a landmark): refutedMargin, never more than margin.
  const long refutedMargin = std::min(margin, static_cast<long>(params_.refutedMargin));
  bool ambiguous = false;
  bool haveCompetitor = false;
  long competitorScore = 0;
  for (std::size_t i = 0; i < modeCount_; ++i) {
    const Hypothesis& m = modes_[i];
    if (!distinct(m.pose, best_.pose) || static_cast<long>(m.inliers) + margin < bestScore) {
      continue;
    }
    const std::size_t mMissed = missed(m.pose, observations, *scan);
    const long score = static_cast<long>(m.inliers) - static_cast<long>(mMissed);
    if (!haveCompetitor || score > competitorScore) {
      haveCompetitor = true;
      competitorScore = score;
      out.hasSecond = true;
      out.secondPose = m.pose;
      out.secondInliers = m.inliers;
      out.secondMissed = mMissed;
    }
    const bool withinMargin = score + margin >= bestScore;
    const bool withinUsed = score + (mMissed > 0 ? refutedMargin : margin) >= bestScore;
    ambiguous = ambiguous || withinUsed;
    if (withinMargin && !withinUsed) {  // passed over by its refutation alone: confirmed again later
      if (out.refutedRivals < out.rivals.size()) {
        out.rivals[out.refutedRivals++] = m.pose;
      } else {
        ambiguous = true;  // more than can be followed: refuse
      }
    }
  }
  if (modesDropped_ && static_cast<long>(droppedInliers_) + margin >= bestScore) {
    out.modesOverflowed = true;
    ambiguous = true;  // a place not kept: nothing refutes it
  }
  return finish(out, ambiguous ? RelocOutcome::Ambiguous : RelocOutcome::Found);
}

void RelocConfirmer::start(const Pose2d& candidate) noexcept {
  pose_ = candidate;
  confirmed_ = 0;
  rivalCount_ = 0;
  state_ = poseFinite(candidate) ? RelocConfirmState::Pending : RelocConfirmState::Rejected;
}

void RelocConfirmer::start(const RelocReport& found, const GlobalLocalizerParams& search, const LandmarkMap& map,
                           Span<const PointObservation> observations, const LaserScan& scan) noexcept {
  start(found.pose);
  search_ = search;
  if (found.outcome != RelocOutcome::Found || found.refutedRivals > found.rivals.size() || !isValid(search)) {
    state_ = RelocConfirmState::Rejected;
    return;
  }
  rivalCount_ = 0;
  for (std::size_t i = 0; i < found.refutedRivals; ++i) {
    rivals_[rivalCount_++] = found.rivals[i];
  }
  bool secondKnown = !found.hasSecond || !poseFinite(found.secondPose);
  for (std::size_t i = 0; i < rivalCount_ && !secondKnown; ++i) {
    secondKnown = !distinctPoses(rivals_[i], found.secondPose, search);
  }
  if (!secondKnown) {
    rivals_[rivalCount_++] = found.secondPose;
  }
  mine_ = Evidence{};
  accumulate(mine_, map, observations, scan, pose_);
  for (std::size_t i = 0; i < rivalCount_; ++i) {
    rivalEvidence_[i] = Evidence{};
    accumulate(rivalEvidence_[i], map, observations, scan, rivals_[i]);
  }
}

long RelocConfirmer::Evidence::score(std::size_t& missed) const noexcept {
  missed = (expected & ~explained).count();
  return static_cast<long>(explained.count()) - static_cast<long>(missed);
}

void RelocConfirmer::accumulate(Evidence& e, const LandmarkMap& map, Span<const PointObservation> observations,
                                const LaserScan& scan, const Pose2d& pose) const noexcept {
  const Pose2d laser = pose.compose(search_.laserMount);
  const double gate = search_.inlierGate;
  for (std::size_t j = 0; j < observations.size(); ++j) {  // the landmark each observation lands on
    const PointObservation& o = observations[j];
    if (!finite(o.x) || !finite(o.y)) {
      continue;
    }
    const Eigen::Vector2d w = laser.transformPoint(Eigen::Vector2d(o.x, o.y));
    double bestD2 = gate * gate;
    LandmarkIndex nearest = kNoLandmark;
    map.forEachNear(w.x(), w.y(), gate, [&](LandmarkIndex index, const Landmark& l) {
      const double d2 = (Eigen::Vector2d(l.x, l.y) - w).squaredNorm();
      if (l.kind == o.kind && d2 <= bestD2) {
        bestD2 = d2;
        nearest = index;
      }
    });
    if (nearest < kMaxLandmarks) {
      e.explained[nearest] = true;
    }
  }
  forEachExpected(search_, pose, observations, scan, landmarksOf(map), [&](std::size_t index, bool explained) {
    if (index < kMaxLandmarks) {
      e.expected[index] = true;
      e.explained[index] = e.explained[index] || explained;
    }
  });
}

bool RelocConfirmer::rivalsRefuted() const noexcept {
  std::size_t myMissed = 0;
  const long myScore = mine_.score(myMissed);
  const auto margin = static_cast<long>(search_.ambiguityMargin);
  const auto refutedMargin = static_cast<long>(std::min(search_.refutedMargin, search_.ambiguityMargin));
  for (std::size_t i = 0; i < rivalCount_; ++i) {
    std::size_t missed = 0;
    const long score = rivalEvidence_[i].score(missed);
    if (score + (missed > 0 ? refutedMargin : margin) >= myScore) {
      return false;  // the search's rule on the evidence so far: ambiguous
    }
  }
  return true;
}

RelocConfirmState RelocConfirmer::step(const Pose2d& odometry, const LandmarkMap& map,
                                       Span<const PointObservation> observations, const Pose2d& laserMount,
                                       const LaserScan* scan) noexcept {
  if (state_ != RelocConfirmState::Pending) {
    return state_;  // Idle, Rejected and Confirmed stay until start()
  }
  if (!poseFinite(odometry) || observations.size() == 0) {
    state_ = RelocConfirmState::Rejected;
    return state_;
  }
  pose_ = pose_.compose(odometry).normalized();
  const PoseCheck c = checkPose(map, observations, laserMount, pose_, params_.inlierGate);
  const double fraction = static_cast<double>(c.inliers) / static_cast<double>(observations.size());
  if (c.inliers < params_.minInliers || fraction < params_.minInlierFraction) {
    state_ = RelocConfirmState::Rejected;
    return state_;
  }
  pose_ = c.refit.normalized();
  if (rivalCount_ > 0) {
    // Every place passed over by its refutation must stay refuted on the evidence of all sweeps.
    if (scan == nullptr) {
      state_ = RelocConfirmState::Rejected;
      return state_;
    }
    accumulate(mine_, map, observations, *scan, pose_);
    for (std::size_t i = 0; i < rivalCount_; ++i) {
      rivals_[i] = refitOnce(map, observations, search_, rivals_[i].compose(odometry)).pose;
      accumulate(rivalEvidence_[i], map, observations, *scan, rivals_[i]);
    }
    if (!rivalsRefuted()) {
      state_ = RelocConfirmState::Rejected;
      return state_;
    }
  }
  ++confirmed_;
  state_ = confirmed_ >= params_.scansToConfirm ? RelocConfirmState::Confirmed : RelocConfirmState::Pending;
  return state_;
}

}  // namespace agv
