#include "agv/localization/localizer.hpp"

#include <algorithm>
#include <cmath>

#include "agv/localization/beam_lookup.hpp"
#include "agv/localization/surface_map.hpp"

namespace agv {

namespace {
/// The soft gate puts a match this far inside the gate (d^2 = 0.95 gate after the scaling).
constexpr double kSoftGateMargin = 0.95;

double largestEigen2(double a, double b, double c) noexcept {
  // symmetric [[a, b], [b, c]]
  const double h = 0.5 * (a - c);
  return 0.5 * (a + c) + std::sqrt(h * h + b * b);
}
std::uint32_t bit(LocalizerFlag f) noexcept {
  return static_cast<std::uint32_t>(f);
}
std::uint16_t sat16(std::size_t v) noexcept {
  return v > 0xFFFFU ? static_cast<std::uint16_t>(0xFFFFU) : static_cast<std::uint16_t>(v);
}
}  // namespace

Localizer::Localizer(const LocalizerParams& params) noexcept : params_(params), ekf_(params.ekf), hyp_(params.ekf) {}

Timestamp Localizer::stamp() const noexcept {
  if (history_.empty()) {
    return Timestamp{};
  }
  return history_.back().stamp;
}

Status Localizer::reset(Timestamp stamp, const Pose2d& pose, const Eigen::Matrix3d& covariance) noexcept {
  PoseEkf fresh(params_.ekf);
  const Status s = fresh.reset(pose, covariance);
  if (s != Status::Ok) {
    return s;
  }
  ekf_ = fresh;
  gatedRun_ = 0;
  failedRun_ = 0;
  HistoryEntry e;
  e.stamp = stamp;
  e.delta = Pose2d{};
  e.deltaCov.setZero();
  e.pose = ekf_.pose();
  e.cov = ekf_.covariance();
  e.odo = odo_;
  e.odoCov = odoCov_;
  fixOdoCov_ = odoCov_;
  history_.clear();
  (void)history_.push(e);
  initialized_ = true;
  lost_ = false;
  badCycles_ = 0;
  pendingFlags_ = 0;
  haveScan_ = false;
  return Status::Ok;
}

Status Localizer::predict(const OdometryIncrement& inc) noexcept {
  if (!initialized_) {
    return Status::NotInitialized;
  }
  if (!inc.isValid()) {
    pendingFlags_ |= bit(LocalizerFlag::OdometryRejected);
    return Status::NonFiniteInput;
  }
  if (inc.stamp <= stamp()) {
    pendingFlags_ |= bit(LocalizerFlag::OdometryRejected);
    return Status::InvalidArgument;
  }
  const Status s = ekf_.predict(inc);
  if (s != Status::Ok) {
    pendingFlags_ |= bit(LocalizerFlag::OdometryRejected);
    return s;
  }
  odo_ = odo_.compose(inc.delta);
  odo_.theta = normalizeAngle(odo_.theta);
  odoCov_ += inc.covariance;
  HistoryEntry e;
  e.stamp = inc.stamp;
  e.delta = inc.delta;
  e.deltaCov = inc.covariance;
  e.pose = ekf_.pose();
  e.cov = ekf_.covariance();
  e.odo = odo_;
  e.odoCov = odoCov_;
  (void)history_.push(e);  // when full, the oldest increment makes room
  return Status::Ok;
}

Localizer::Visibility Localizer::visibility(const Pose2d& laserWorld, const Landmark& lm,
                                            const LaserScan* beams) const noexcept {
  const Eigen::Vector2d p = laserWorld.inverseTransformPoint(Eigen::Vector2d(lm.x, lm.y));
  const LaserModel& L = params_.laser;
  const double r = p.norm();
  if (r < L.rangeMin + params_.occlusion.viewRangeMargin || r > L.rangeMax - params_.occlusion.viewRangeMargin) {
    return Visibility::OutOfLimits;
  }
  const double b = std::atan2(p.y(), p.x());
  if (b < L.angleMin + params_.occlusion.viewAngleMargin || b > L.angleMax - params_.occlusion.viewAngleMargin) {
    return Visibility::OutOfLimits;
  }
  if (beams == nullptr) {
    return Visibility::InView;
  }
  const Result<double> measured = farthestReturnNear(*beams, b);
  if (!measured.ok()) {
    return Visibility::NoReturn;
  }
  // Standard deviation of measured minus predicted range for a visible landmark: sensor, kind,
  // landmark and the pose covariance projected on the ray. The range from the laser origin
  // t_l = t + R(theta) l_t to m has gradient -u with respect to t and -u . R'(theta) l_t with
  // respect to theta (u: unit ray in the world frame).
  const Pose2d& x = ekf_.pose();
  const Eigen::Matrix3d& P = ekf_.covariance();
  const double ux = (lm.x - laserWorld.x) / r;
  const double uy = (lm.y - laserWorld.y) / r;
  const double lx = laserWorld.x - x.x;  // R(theta) l_t
  const double ly = laserWorld.y - x.y;
  const Eigen::Vector3d g(-ux, -uy, -(ux * -ly + uy * lx));
  const std::size_t kind = static_cast<std::size_t>(lm.kind) % kLandmarkKindCount;
  const double ks = L.kindSigma[kind];
  const double var = L.rangeSigma * L.rangeSigma + ks * ks + lm.variance + g.dot(P * g);
  const double tolerance = params_.occlusion.sigmas * std::sqrt(var > 0.0 ? var : 0.0) +
                           params_.occlusion.kindDepth[kind] + r * static_cast<double>(beams->angleIncrement);
  if (measured.value() < r - tolerance) {
    return Visibility::Occluded;
  }
  const double support = params_.occlusion.supportRadius[kind];
  if (support > 0.0 && params_.occlusion.supportPoints > 0U) {
    const Result<SideSupport> sides = sideSupport(*beams, r, b, support, params_.occlusion.supportPoints);
    if (!sides.ok() || sides.value().before < params_.occlusion.supportPoints ||
        sides.value().after < params_.occlusion.supportPoints) {
      return Visibility::InViewUnsupported;
    }
  }
  return Visibility::InView;
}

Localizer::ViewCount Localizer::countInView(std::uint8_t kinds, const LandmarkMap& map, const LaserScan* beams,
                                            LandmarkMap* mutableMap) const noexcept {
  const Pose2d laserWorld = ekf_.pose().compose(params_.laser.mounting);
  ViewCount count;
  map.forEachNear(laserWorld.x, laserWorld.y, params_.laser.rangeMax, [&](LandmarkIndex idx, const Landmark& lm) {
    if ((landmarkKindBit(lm.kind) & kinds) == 0U) {
      return;
    }
    const bool confirmed = lm.surveyed || lm.hits >= params_.map.minHitsConfirmed;
    switch (visibility(laserWorld, lm, beams)) {
      case Visibility::OutOfLimits:
        return;
      case Visibility::Occluded:
        ++count.occluded;
        if (confirmed) {
          return;  // hidden: no evidence either way
        }
        break;  // a young landmark that disappears behind something is more likely a transient
      case Visibility::NoReturn:
        ++count.noReturn;
        return;
      case Visibility::InViewUnsupported:
        ++count.unsupported;
        break;
      case Visibility::InView:
        if (confirmed) {
          ++count.inView;
          count.detections += params_.health.detectionRate[static_cast<std::size_t>(lm.kind) % kLandmarkKindCount];
        }
        break;
    }
    if (mutableMap != nullptr && !lm.surveyed && lm.lastMatchedCycle != cycle_) {
      (void)mutableMap->weaken(idx);
    }
  });
  return count;
}

void Localizer::associate(const ScanObservations& scan, const LandmarkMap& map) noexcept {
  const LaserModel& L = params_.laser;
  const Pose2d laserWorld = ekf_.pose().compose(L.mounting);
  const double cl = std::cos(laserWorld.theta);
  const double sl = std::sin(laserWorld.theta);
  const std::size_t n = scan.points.size();
  for (std::size_t i = 0; i < n; ++i) {
    Scratch& s = scratch_[i];
    s = Scratch{};
    const PointObservation& o = scan.points[i];
    if (!std::isfinite(o.x) || !std::isfinite(o.y)) {
      s.state = Assoc::NonFinite;
      continue;
    }
    const double r = std::hypot(o.x, o.y);
    const double b = std::atan2(o.y, o.x);
    if (r < L.rangeMin || r > L.rangeMax || b < L.angleMin || b > L.angleMax) {
      s.state = Assoc::OutOfView;
      continue;
    }
    const double ks = L.kindSigma[static_cast<std::size_t>(o.kind) % kLandmarkKindCount];
    s.R = polarToCartesianCovariance(o.x, o.y, L.rangeSigma, L.bearingSigma);
    s.R(0, 0) += ks * ks;
    s.R(1, 1) += ks * ks;
    const Eigen::Vector2d z(o.x, o.y);
    const Eigen::Vector2d w = laserWorld.transformPoint(z);
    const PointInnovation base = ekf_.innovation(z, w, s.R, L.mounting);
    if (!base.valid) {
      s.state = Assoc::Gate;
      continue;
    }
    const double lambda =
        largestEigen2(base.S(0, 0), base.S(0, 1), base.S(1, 1)) + params_.association.searchLandmarkVariance;
    double radius = std::sqrt(params_.association.gate * lambda);
    if (radius > params_.association.maxSearchRadius) {
      radius = params_.association.maxSearchRadius;
    }
    const double r2 = radius * radius;
    double best = INFINITY;
    double second = INFINITY;
    LandmarkIndex bestIdx = kNoLandmark;
    bool anyCandidate = false;
    map.forEachNear(w.x(), w.y(), radius, [&](LandmarkIndex idx, const Landmark& lm) {
      if (lm.kind != o.kind) {
        return;
      }
      const double ex = w.x() - lm.x;
      const double ey = w.y() - lm.y;
      if (ex * ex + ey * ey > r2) {
        return;
      }
      anyCandidate = true;
      // innovation z - h(m) in the laser frame = R(laser)^T (w - m)
      const double nx = cl * ex + sl * ey;
      const double ny = -sl * ex + cl * ey;
      const double a = base.S(0, 0) + lm.variance;
      const double c = base.S(1, 1) + lm.variance;
      const double bb = base.S(0, 1);
      const double det = a * c - bb * bb;
      if (!(det > 0.0)) {
        return;
      }
      const double d2 = (c * nx * nx - 2.0 * bb * nx * ny + a * ny * ny) / det;
      if (d2 < best) {
        second = best;
        best = d2;
        bestIdx = idx;
      } else if (d2 < second) {
        second = d2;
      }
    });
    s.d2 = best;
    if (bestIdx != kNoLandmark && best <= params_.association.gate && second <= params_.association.gate &&
        second - best < params_.association.ambiguityMargin) {
      s.state = Assoc::Ambiguous;
    } else if (bestIdx != kNoLandmark && best <= params_.association.gate) {
      s.state = Assoc::Matched;
      s.landmark = bestIdx;
    } else if (anyCandidate) {
      s.state = Assoc::Gate;
    } else {
      s.state = Assoc::None;
    }
  }
  // One landmark, one observation: keep the closer (Mahalanobis) claim.
  for (std::size_t i = 0; i < n; ++i) {
    if (scratch_[i].state != Assoc::Matched) {
      continue;
    }
    for (std::size_t j = i + 1; j < n; ++j) {
      if (scratch_[j].state == Assoc::Matched && scratch_[j].landmark == scratch_[i].landmark) {
        if (scratch_[j].d2 < scratch_[i].d2) {
          scratch_[i].state = Assoc::Duplicate;
          break;
        }
        scratch_[j].state = Assoc::Duplicate;
      }
    }
  }
}

void Localizer::orderMatches(const ScanObservations& scan) noexcept {
  // Orders the matched observations by Mahalanobis distance (insertion sort, n <= kMaxObservations)
  // so that the sequential updates apply the most certain association first.
  std::size_t m = 0;
  const std::size_t n = scan.points.size();
  for (std::size_t i = 0; i < n; ++i) {
    if (scratch_[i].state == Assoc::Matched) {
      std::size_t k = m++;
      while (k > 0 && scratch_[order_[k - 1]].d2 > scratch_[i].d2) {
        order_[k] = order_[k - 1];
        --k;
      }
      order_[k] = static_cast<std::uint16_t>(i);
    }
  }
}

void Localizer::maintainMap(const ScanObservations& scan, const LaserScan* beams, LandmarkMap& map) noexcept {
  const Pose2d& x = ekf_.pose();
  const Eigen::Matrix3d& P = ekf_.covariance();
  const Pose2d laserWorld = x.compose(params_.laser.mounting);
  const std::size_t n = scan.points.size();
  const std::uint32_t deletedBefore = map.counters().deleted;
  for (std::size_t i = 0; i < n; ++i) {
    const Scratch& s = scratch_[i];
    if (s.state != Assoc::Used && s.state != Assoc::Tentative && s.state != Assoc::None) {
      continue;
    }
    const PointObservation& o = scan.points[i];
    const Eigen::Vector2d w = laserWorld.transformPoint(Eigen::Vector2d(o.x, o.y));
    // Variance of the observation's world position: sensor (rotation invariant) + pose.
    Eigen::Matrix<double, 2, 3> J;
    J << 1.0, 0.0, -(w.y() - x.y), 0.0, 1.0, w.x() - x.x;
    const double var = 0.5 * (s.R.trace() + (J * P * J.transpose()).trace());
    if (s.state == Assoc::Used || s.state == Assoc::Tentative) {
      (void)map.reinforce(s.landmark, w.x(), w.y(), var, cycle_);
    }
  }
  // In view and not matched: -1 (deleted at 0).
  (void)countInView(scan.kindsDetected, map, beams, &map);
  health_.deleted = sat16(map.counters().deleted - deletedBefore);
  // Unmatched observations become landmarks, unless one of the same kind is already close.
  for (std::size_t i = 0; i < n; ++i) {
    const Scratch& s = scratch_[i];
    if (s.state != Assoc::None) {
      continue;
    }
    const PointObservation& o = scan.points[i];
    const Eigen::Vector2d w = laserWorld.transformPoint(Eigen::Vector2d(o.x, o.y));
    bool crowded = false;
    const double sep2 = params_.map.insertSeparation * params_.map.insertSeparation;
    map.forEachNear(w.x(), w.y(), params_.map.insertSeparation, [&](LandmarkIndex, const Landmark& lm) {
      const double ex = lm.x - w.x();
      const double ey = lm.y - w.y();
      if (lm.kind == o.kind && ex * ex + ey * ey < sep2) {
        crowded = true;
      }
    });
    if (crowded) {
      continue;
    }
    Eigen::Matrix<double, 2, 3> J;
    J << 1.0, 0.0, -(w.y() - x.y), 0.0, 1.0, w.x() - x.x;
    const double var = 0.5 * (s.R.trace() + (J * P * J.transpose()).trace());
    const Result<LandmarkIndex> r = map.insert(o.kind, w.x(), w.y(), var);
    if (r.ok()) {
      ++health_.inserted;
    } else if (r.status() == Status::CapacityExceeded) {
      ++health_.insertRefused;
      health_.flags |= bit(LocalizerFlag::MapInsertRefused);
    }
  }
}

void Localizer::finishHealth() noexcept {
  const Eigen::Matrix3d& P = ekf_.covariance();
  health_.positionSigma = std::sqrt(largestEigen2(P(0, 0), P(0, 1), P(1, 1)));
  health_.headingSigma = std::sqrt(P(2, 2));
  health_.consecutiveBadCycles = badCycles_;
  health_.lost = lost_;
  if (lost_) {
    health_.flags |= bit(LocalizerFlag::Lost);
    health_.status = Status::Lost;
  }
}

const LocalizerHealth& Localizer::correct(const ScanObservations& scan, LandmarkMap& map) noexcept {
  return correctWith(scan, nullptr, map, nullptr, nullptr, Fallback{});
}

const LocalizerHealth& Localizer::correct(const ScanObservations& scan, const LaserScan& beams,
                                          LandmarkMap& map) noexcept {
  return correctWith(scan, &beams, map, nullptr, nullptr, Fallback{});
}

const LocalizerHealth& Localizer::correct(const ScanObservations& scan, const LaserScan& beams, LandmarkMap& map,
                                          const LikelihoodFieldBase& field) noexcept {
  return correctWith(scan, &beams, map, &field, nullptr, Fallback{});
}

const LocalizerHealth& Localizer::correct(const ScanObservations& scan, const LaserScan& beams,
                                          const MatchPoints& points, LandmarkMap& map,
                                          const LikelihoodFieldBase& field) noexcept {
  return correctWith(scan, &beams, map, &field, &points, Fallback{});
}

const LocalizerHealth& Localizer::correct(const ScanObservations& scan, const LaserScan& beams,
                                          const MatchPoints& points, LandmarkMap& map, const LikelihoodFieldBase& field,
                                          const MatchPoints& fallbackPoints,
                                          const LikelihoodFieldBase& fallback) noexcept {
  return correctWith(scan, &beams, map, &field, &points, Fallback{&fallback, &fallbackPoints});
}

void Localizer::odometryAt(const Rewind& at, Pose2d& odo, Eigen::Matrix3d& odoCov) const noexcept {
  const HistoryEntry& e = history_[at.k];
  odo = e.odo;
  odoCov = e.odoCov;
  if (at.split) {
    odo = odo.compose(at.part);
    odoCov += at.f * history_[at.k + 1U].deltaCov;
  }
}

void Localizer::matchScan(const Rewind& at, const LaserScan& beams, const MatchPoints* points,
                          const LikelihoodFieldBase& field) noexcept {
  ScanMatchHealth& h = health_.scanMatch;
  h.attempted = true;
  const ScanMatchParams& sp = params_.scanMatch;
  matcher_.setParams(sp);
  SearchWindow window = matcher_.searchWindow(ekf_.covariance());
  if (sp.widenAfter > 0U && failedRun_ >= sp.widenAfter) {
    // Recovery: the window doubles per failed cycle beyond widenAfter, from the recovery sizes.
    const unsigned run = static_cast<unsigned>(failedRun_) - sp.widenAfter;
    const unsigned doublings = run < 16U ? run : 16U;
    const double f = static_cast<double>(1U << doublings);
    const double t =
        sp.recoveryTranslation * f < sp.maxRecoveryTranslation ? sp.recoveryTranslation * f : sp.maxRecoveryTranslation;
    const double r =
        sp.recoveryRotation * f < sp.maxRecoveryRotation ? sp.recoveryRotation * f : sp.maxRecoveryRotation;
    window.x = window.x > t ? window.x : t;
    window.y = window.y > t ? window.y : t;
    window.theta = window.theta > r ? window.theta : r;
    h.widened = true;
  }
  h.window = window.x > window.y ? window.x : window.y;
  const Pose2d before = ekf_.pose();
  const ScanMatchResult m = points != nullptr ? matcher_.match(*points, params_.laser.mounting, before, window, field)
                                              : matcher_.match(beams, params_.laser.mounting, before, window, field);
  // A cycle whose match is not fused adds to the run that widens the next search.
  failedRun_ = failedRun_ < 255U ? static_cast<std::uint8_t>(failedRun_ + 1U) : failedRun_;
  h.status = m.status;
  h.pose = m.pose;
  h.points = m.points;
  h.inliers = m.inliers;
  h.rmsResidual = m.rmsResidual;
  if (m.status == Status::Ok) {
    Eigen::Matrix3d R = m.covariance;
    if (sp.fitScatter > 0.0 && m.lever > 0.0) {
      const double e2 = sp.fitScatter * sp.fitScatter * m.rmsResidual * m.rmsResidual;
      R(0, 0) += e2;
      R(1, 1) += e2;
      R(2, 2) += e2 / (m.lever * m.lever);
    }
    h.mahalanobis2 = ekf_.poseMahalanobis2(m.pose, R);
    const Status u = ekf_.updatePose(m.pose, R, params_.scanMatchGate);
    if (u == Status::Ok) {
      h.fused = true;
      h.correction = std::hypot(ekf_.pose().x - before.x, ekf_.pose().y - before.y);
      gatedRun_ = 0;
      failedRun_ = 0;
      return;
    }
    if (u == Status::Rejected && sp.softGate && m.rmsResidual <= sp.resyncMaxRms && h.mahalanobis2 > 0.0) {
      // The innovation covariance scaled so that the match lies just inside the gate:
      // S' = k S, i.e. R' = k R + (k - 1) P.
      const double k = h.mahalanobis2 / (kSoftGateMargin * params_.scanMatchGate);
      const Eigen::Matrix3d soft = k * R + (k - 1.0) * ekf_.covariance();
      if (ekf_.updatePose(m.pose, soft, params_.scanMatchGate) == Status::Ok) {
        h.fused = true;
        h.softGated = true;
        h.correction = std::hypot(ekf_.pose().x - before.x, ekf_.pose().y - before.y);
        gatedRun_ = 0;
        failedRun_ = 0;
        return;
      }
    }
    h.status = u;
  }
  if (sp.resyncAfter > 0U) {
    resync(m, before, at, beams, points, field);
  }
  if (!h.resynced) {
    health_.flags |= bit(LocalizerFlag::ScanMatchRejected);
  }
}

void Localizer::resync(const ScanMatchResult& m, const Pose2d& before, const Rewind& at, const LaserScan& beams,
                       const MatchPoints* points, const LikelihoodFieldBase& field) noexcept {
  const ScanMatchParams& sp = params_.scanMatch;
  ScanMatchHealth& h = health_.scanMatch;
  const bool gatedGood =
      h.status == Status::Rejected && m.rmsResidual <= sp.resyncMaxRms && m.inliers >= sp.resyncMinInliers;
  Pose2d odo;
  Eigen::Matrix3d odoCov;
  odometryAt(at, odo, odoCov);
  // A match's covariance says how well its points fit the map, not how well the map fits the
  // world: real matches scatter around the truth by more (`resyncMatchSigma*`).
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  scatter.diagonal() << sp.resyncMatchSigma * sp.resyncMatchSigma, sp.resyncMatchSigma * sp.resyncMatchSigma,
      sp.resyncMatchSigmaAngle * sp.resyncMatchSigmaAngle;
  bool confirmed = false;
  if (gatedRun_ > 0U) {
    // The hypothesis carried to this scan by the odometry since its last scan (not by the
    // filter, whose corrections in between are no motion), with the odometry's own uncertainty.
    OdometryIncrement inc;
    inc.stamp = health_.stamp;
    inc.delta = between(hypOdo_, odo);
    inc.covariance = odoCov - hypOdoCov_;
    inc.covariance = (0.5 * (inc.covariance + inc.covariance.transpose())).eval();
    if (hyp_.predict(inc) != Status::Ok) {
      gatedRun_ = 0U;
    }
  }
  if (gatedRun_ > 0U) {
    if (gatedGood && hyp_.updatePose(m.pose, m.covariance + scatter, params_.scanMatchGate) == Status::Ok) {
      confirmed = true;
      h.pose = hyp_.pose();
    } else {
      // The tracking search ran around the filter's estimate, which is off by the hypothesis'
      // offset: look again where the hypothesis says the vehicle is, over its own window.
      const Pose2d carried = hyp_.pose();
      const SearchWindow window = matcher_.searchWindow(hyp_.covariance());
      const ScanMatchResult c = points != nullptr
                                    ? matcher_.match(*points, params_.laser.mounting, carried, window, field)
                                    : matcher_.match(beams, params_.laser.mounting, carried, window, field);
      h.hypothesisChecked = true;
      const bool consistent =
          c.status == Status::Ok && hyp_.poseMahalanobis2(c.pose, c.covariance + scatter) <= params_.scanMatchGate;
      if (consistent && c.rmsResidual <= sp.resyncMaxRms && c.inliers >= sp.resyncMinInliers &&
          hyp_.updatePose(c.pose, c.covariance + scatter, params_.scanMatchGate) == Status::Ok) {
        confirmed = true;
        h.pose = c.pose;
      } else if ((c.status != Status::Ok || consistent) && !gatedGood) {
        // The matcher could not tell (too few points, a scan off the map), or the match agrees
        // but fits too loosely to count: the hypothesis is neither confirmed nor contradicted;
        // it is carried on to the next scan.
        hypOdo_ = odo;
        hypOdoCov_ = odoCov;
        h.consecutiveGated = gatedRun_;
        return;
      }
    }
  }
  if (confirmed) {
    gatedRun_ = static_cast<std::uint8_t>(gatedRun_ < 255U ? gatedRun_ + 1U : gatedRun_);
  } else if (gatedGood && hyp_.reset(m.pose, m.covariance + scatter) == Status::Ok) {
    gatedRun_ = 1U;  // a new hypothesis
  } else {
    gatedRun_ = 0U;  // contradicted (or none), and no new one
    return;
  }
  hypOdo_ = odo;
  hypOdoCov_ = odoCov;
  h.consecutiveGated = gatedRun_;
  if (gatedRun_ >= sp.resyncAfter && ekf_.reset(hyp_.pose(), hyp_.covariance()) == Status::Ok) {
    h.resynced = true;
    h.fused = true;
    h.pose = hyp_.pose();
    h.correction = std::hypot(hyp_.pose().x - before.x, hyp_.pose().y - before.y);
    health_.flags |= bit(LocalizerFlag::ScanMatchResync);
    gatedRun_ = 0;
    failedRun_ = 0;
  }
}

void Localizer::matchFallback(const Rewind& at, const Fallback& fallback) noexcept {
  ScanMatchHealth& h = health_.fallbackMatch;
  h.attempted = true;
  Pose2d odo;
  Eigen::Matrix3d odoCov;
  odometryAt(at, odo, odoCov);
  // The fallback's surfaces were placed with the estimates up to the last fix: relative to them
  // the prior is as uncertain as the odometry since.
  Eigen::Matrix3d relative = odoCov - fixOdoCov_;
  relative = (0.5 * (relative + relative.transpose())).eval();
  for (int i = 0; i < 3; ++i) {
    relative(i, i) = relative(i, i) > 0.0 ? relative(i, i) : 0.0;  // rounding of the two sums
  }
  const ScanMatchParams sp = surfaceMapMatching(params_.scanMatch);
  matcher_.setParams(sp);
  SearchWindow window = matcher_.searchWindow(relative);
  // The odometry's model does not cover its worst steps (a slip in a turn): search at least the
  // recovery window, the gate below still weighs the match against the odometry.
  window.x = window.x > sp.recoveryTranslation ? window.x : sp.recoveryTranslation;
  window.y = window.y > sp.recoveryTranslation ? window.y : sp.recoveryTranslation;
  window.theta = window.theta > sp.recoveryRotation ? window.theta : sp.recoveryRotation;
  h.window = window.x > window.y ? window.x : window.y;
  const Pose2d before = ekf_.pose();
  const ScanMatchResult m = matcher_.match(*fallback.points, params_.laser.mounting, before, window, *fallback.field);
  h.status = m.status;
  h.pose = m.pose;
  h.points = m.points;
  h.inliers = m.inliers;
  h.rmsResidual = m.rmsResidual;
  if (m.status != Status::Ok) {
    return;
  }
  // A filter of the relative uncertainty alone moves the mean; the covariance stays the prior's.
  PoseEkf rel(params_.ekf);
  if (rel.reset(before, relative) != Status::Ok) {
    h.status = Status::IllConditioned;
    return;
  }
  h.mahalanobis2 = rel.poseMahalanobis2(m.pose, m.covariance);
  const Status u = rel.updatePose(m.pose, m.covariance, params_.scanMatchGate);
  if (u != Status::Ok || ekf_.reset(rel.pose(), ekf_.covariance()) != Status::Ok) {
    h.status = u != Status::Ok ? u : Status::IllConditioned;
    return;
  }
  h.fused = true;
  h.correction = std::hypot(ekf_.pose().x - before.x, ekf_.pose().y - before.y);
  fixOdoCov_ = odoCov;
  health_.flags |= bit(LocalizerFlag::FallbackMatchFused);
}

const LocalizerHealth& Localizer::correctWith(const ScanObservations& scan, const LaserScan* beams, LandmarkMap& map,
                                              const LikelihoodFieldBase* field, const MatchPoints* points,
                                              Fallback fallback) noexcept {
  ++cycle_;
  health_ = LocalizerHealth{};
  health_.cycle = cycle_;
  health_.stamp = scan.stamp;
  health_.flags = pendingFlags_;
  pendingFlags_ = 0;
  health_.observations = sat16(scan.points.size());
  if (!initialized_) {
    health_.flags |= bit(LocalizerFlag::NotInitialized);
    health_.status = Status::NotInitialized;
    return health_;
  }
  if (lost_) {
    finishHealth();
    return health_;
  }
  Rewind at;
  if (!rewindToScan(scan, at)) {
    finishHealth();
    return health_;
  }
  const Pose2d prior = ekf_.pose();
  // The scan match first: it moves the prior the landmarks are associated against.
  if (field != nullptr && beams != nullptr) {
    matchScan(at, *beams, points, *field);
    if (health_.scanMatch.fused) {
      Pose2d odo;
      odometryAt(at, odo, fixOdoCov_);
    } else if (fallback.field != nullptr && fallback.points != nullptr && fallback.field->built() &&
               !health_.scanMatch.resynced) {
      matchFallback(at, fallback);
    }
  }
  // Association against the prior at the scan time, and what the check expects to see.
  associate(scan, map);
  if (!params_.occlusion.enabled) {
    beams = nullptr;
  } else if (beams != nullptr && checkBeamGeometry(*beams) != Status::Ok) {
    health_.flags |= bit(LocalizerFlag::OcclusionUnchecked);
    beams = nullptr;
  }
  const ViewCount view = countInView(scan.kindsDetected, map, beams, nullptr);
  health_.expectedInView = sat16(view.inView);
  health_.expectedDetections = view.detections;
  health_.occluded = sat16(view.occluded);
  health_.noReturn = sat16(view.noReturn);
  health_.unsupported = sat16(view.unsupported);

  const PoseEkf beforeLandmarks = ekf_;
  fuseMatches(scan, map);
  if (field != nullptr && beams != nullptr && !health_.scanMatch.fused) {
    checkAgainstField(beforeLandmarks, scan, *beams, points, *field);
  }
  health_.correction = std::hypot(ekf_.pose().x - prior.x, ekf_.pose().y - prior.y);
  health_.headingCorrection = std::fabs(normalizeAngle(ekf_.pose().theta - prior.theta));
  tallyObservations(scan);
  const bool bad = judgeCycle(map.mode());
  // Map lifecycle, on good cycles only (a suspect pose must not write the map).
  if (!bad && map.mode() == MapMode::Dynamic) {
    maintainMap(scan, beams, map);
  }
  storeAndReplay(at);
  lastScanStamp_ = scan.stamp;
  haveScan_ = true;
  finishHealth();
  return health_;
}

bool Localizer::rewindToScan(const ScanObservations& scan, Rewind& at) noexcept {
  const std::size_t n = history_.size();
  const Timestamp newest = history_[n - 1U].stamp;
  const bool tooOld = scan.stamp < history_[0].stamp || (haveScan_ && scan.stamp < lastScanStamp_);
  const bool tooNew = scan.stamp > newest && (scan.stamp - newest) > params_.maxScanLead;
  if (tooOld || tooNew) {
    health_.flags |=
        bit(LocalizerFlag::ScanRejected) | bit(tooOld ? LocalizerFlag::ScanTooOld : LocalizerFlag::ScanTooNew);
    health_.status = Status::Rejected;
    return false;
  }
  std::size_t k = n - 1U;
  while (k > 0 && history_[k].stamp > scan.stamp) {
    --k;
  }
  const PoseEkf atNewest = ekf_;
  if (ekf_.reset(history_[k].pose, history_[k].cov) != Status::Ok) {
    // A stored state that does not validate cannot be rewound to; keep the newest state.
    ekf_ = atNewest;
    health_.flags |= bit(LocalizerFlag::ScanRejected);
    health_.status = Status::Rejected;
    return false;
  }
  at = Rewind{};
  at.k = k;
  if (k + 1U < n && scan.stamp > history_[k].stamp) {
    const HistoryEntry& next = history_[k + 1U];
    at.split = true;
    at.f = static_cast<double>((scan.stamp - history_[k].stamp).ns) /
           static_cast<double>((next.stamp - history_[k].stamp).ns);
    OdometryIncrement p;
    p.stamp = scan.stamp;
    p.delta = partialIncrement(next.delta, at.f);
    p.covariance = at.f * next.deltaCov;
    at.part = p.delta;
    (void)ekf_.predict(p);
  }
  return true;
}

void Localizer::fuseMatches(const ScanObservations& scan, const LandmarkMap& map) noexcept {
  orderMatches(scan);
  std::size_t matched = 0;
  const std::size_t nObs = scan.points.size();
  for (std::size_t i = 0; i < nObs; ++i) {
    if (scratch_[i].state == Assoc::Matched) {
      ++matched;
    }
  }
  const LaserModel& L = params_.laser;
  // Minimum support while uncertain: count the matches that may correct.
  const AssociationParams& ap = params_.association;
  const Eigen::Matrix3d& P0 = ekf_.covariance();
  const bool fieldOnly = ap.fieldSupport && health_.scanMatch.attempted && map.mode() == MapMode::Static;
  if (ap.minSupport > 1U && !health_.scanMatch.fused &&
      (fieldOnly || std::sqrt(largestEigen2(P0(0, 0), P0(0, 1), P0(1, 1))) > ap.supportSigma)) {
    std::size_t correctable = 0;
    for (std::size_t q = 0; q < matched; ++q) {
      const Landmark* lm = map.at(scratch_[order_[q]].landmark);
      correctable += lm != nullptr && (lm->surveyed || lm->hits >= params_.map.minHitsToCorrect) ? 1U : 0U;
    }
    if (correctable > 0U && correctable < ap.minSupport) {
      for (std::size_t q = 0; q < matched; ++q) {
        const Landmark* lm = map.at(scratch_[order_[q]].landmark);
        if (lm != nullptr && (lm->surveyed || lm->hits >= params_.map.minHitsToCorrect)) {
          scratch_[order_[q]].state = Assoc::Unsupported;
        }
      }
    }
  }
  for (std::size_t q = 0; q < matched; ++q) {
    Scratch& s = scratch_[order_[q]];
    if (s.state != Assoc::Matched) {
      continue;
    }
    const Landmark* lm = map.at(s.landmark);
    if (lm == nullptr) {
      s.state = Assoc::UpdateRejected;
      continue;
    }
    if (!lm->surveyed && lm->hits < params_.map.minHitsToCorrect) {
      s.state = Assoc::Tentative;  // matched for the map lifecycle, not used by the filter
      continue;
    }
    const PointObservation& o = scan.points[order_[q]];
    Eigen::Matrix2d R = s.R;
    R(0, 0) += lm->variance;
    R(1, 1) += lm->variance;
    const PointInnovation in = ekf_.innovation(Eigen::Vector2d(o.x, o.y), Eigen::Vector2d(lm->x, lm->y), R, L.mounting);
    if (ekf_.update(in, params_.association.gate) == Status::Ok) {
      s.state = Assoc::Used;
      s.ratio = in.mahalanobis2 / params_.association.gate;
      s.innovation2 = in.innovation.squaredNorm();
    } else {
      s.state = Assoc::UpdateRejected;
    }
  }
}

void Localizer::checkAgainstField(const PoseEkf& before, const ScanObservations& scan, const LaserScan& beams,
                                  const MatchPoints* points, const LikelihoodFieldBase& field) noexcept {
  const double gate = params_.association.fieldCheckGate;
  const std::size_t nObs = scan.points.size();
  bool used = false;
  for (std::size_t i = 0; i < nObs; ++i) {
    used = used || scratch_[i].state == Assoc::Used;
  }
  if (!(gate > 0.0) || !used) {
    return;
  }
  const ScanMatchParams& sp = params_.scanMatch;
  matcher_.setParams(sp);  // the fallback's match runs with its own
  const Pose2d& laser = params_.laser.mounting;
  const double c0 = points != nullptr ? matcher_.costAt(*points, laser, before.pose(), field)
                                      : matcher_.costAt(beams, laser, before.pose(), field);
  const double c1 = points != nullptr ? matcher_.costAt(*points, laser, ekf_.pose(), field)
                                      : matcher_.costAt(beams, laser, ekf_.pose(), field);
  if (!std::isfinite(c0) || !std::isfinite(c1)) {
    return;
  }
  const double scale = sp.huber * sp.huber * sp.covarianceInflation;
  if (2.0 * (c1 - c0) / scale <= gate) {
    return;
  }
  ekf_ = before;
  for (std::size_t i = 0; i < nObs; ++i) {
    if (scratch_[i].state == Assoc::Used) {
      scratch_[i].state = Assoc::FieldRejected;
    }
  }
  health_.flags |= bit(LocalizerFlag::LandmarksContradictField);
}

void Localizer::tallyObservations(const ScanObservations& scan) noexcept {
  double ratioSum = 0.0;
  double ratioSumKind[kLandmarkKindCount] = {};
  double innovation2Kind[kLandmarkKindCount] = {};
  const std::size_t nObs = scan.points.size();
  for (std::size_t i = 0; i < nObs; ++i) {
    const Scratch& s = scratch_[i];
    const std::size_t kind = static_cast<std::size_t>(scan.points[i].kind) % kLandmarkKindCount;
    SourceHealth& src = health_.sources[kind];
    ++src.observed;
    switch (s.state) {
      case Assoc::Used:
        ++health_.used;
        ++src.fused;
        ratioSum += s.ratio;
        ratioSumKind[kind] += s.ratio;
        innovation2Kind[kind] += s.innovation2;
        health_.maxTestRatio = std::max(health_.maxTestRatio, s.ratio);
        src.maxTestRatio = std::max(src.maxTestRatio, s.ratio);
        break;
      case Assoc::Tentative:
        ++health_.tentative;
        ++src.tentative;
        break;
      case Assoc::NonFinite:
        ++health_.rejectedNonFinite;
        ++src.rejected;
        break;
      case Assoc::OutOfView:
        ++health_.rejectedOutOfView;
        ++src.unmatched;
        break;
      case Assoc::Gate:
        ++health_.rejectedGate;
        ++src.rejected;
        break;
      case Assoc::Duplicate:
        ++health_.rejectedDuplicate;
        ++src.rejected;
        break;
      case Assoc::UpdateRejected:
        ++health_.rejectedUpdate;
        ++src.rejected;
        break;
      case Assoc::Ambiguous:
        ++health_.rejectedAmbiguous;
        ++src.rejected;
        break;
      case Assoc::Unsupported:
        ++health_.rejectedSupport;
        ++src.rejected;
        break;
      case Assoc::FieldRejected:
        ++health_.rejectedField;
        ++src.rejected;
        break;
      case Assoc::None:
        ++health_.unmatched;
        ++src.unmatched;
        break;
      case Assoc::Matched:
        break;
    }
  }
  if (health_.used > 0) {
    health_.meanTestRatio = ratioSum / static_cast<double>(health_.used);
  }
  for (std::size_t k = 0; k < kLandmarkKindCount; ++k) {
    SourceHealth& src = health_.sources[k];
    if (src.fused > 0) {
      src.meanTestRatio = ratioSumKind[k] / static_cast<double>(src.fused);
      src.innovationRms = std::sqrt(innovation2Kind[k] / static_cast<double>(src.fused));
    }
  }
  const auto flagIf = [this](bool condition, LocalizerFlag flag) {
    if (condition) {
      health_.flags |= bit(flag);
    }
  };
  flagIf(health_.rejectedNonFinite > 0, LocalizerFlag::ObservationNonFinite);
  flagIf(health_.rejectedOutOfView > 0, LocalizerFlag::ObservationOutOfView);
  flagIf(health_.rejectedGate > 0, LocalizerFlag::GateRejected);
  flagIf(health_.rejectedDuplicate > 0, LocalizerFlag::DuplicateRejected);
  flagIf(health_.rejectedUpdate > 0, LocalizerFlag::UpdateRejected);
  flagIf(health_.rejectedAmbiguous > 0, LocalizerFlag::AmbiguityRejected);
  flagIf(health_.rejectedSupport > 0, LocalizerFlag::SupportRejected);
  flagIf(health_.used < params_.health.minMatchesForFix && !health_.scanMatch.fused, LocalizerFlag::NoFix);
}

bool Localizer::judgeCycle(MapMode mode) noexcept {
  const LocalizerHealthParams& hp = params_.health;
  bool bad = false;
  if (!health_.scanMatch.fused && health_.expectedDetections >= static_cast<double>(hp.minExpectedForCheck)) {
    double need = std::ceil(hp.minMatchedFraction * health_.expectedDetections);
    if (need < static_cast<double>(hp.minMatchesForFix)) {
      need = static_cast<double>(hp.minMatchesForFix);
    }
    // A tentative match confirms the landmark is there as well as a used one.
    if (static_cast<double>(health_.used) + static_cast<double>(health_.tentative) < need) {
      bad = true;
    }
  }
  if (mode == MapMode::Static && !health_.scanMatch.fused) {
    for (std::size_t k = 0; k < kLandmarkKindCount; ++k) {
      const SourceHealth& src = health_.sources[k];
      const double fraction = hp.minObservedMatchedFraction[k];
      if (fraction > 0.0 && src.observed >= hp.minExpectedForCheck &&
          static_cast<double>(src.fused) + static_cast<double>(src.tentative) <
              std::ceil(fraction * static_cast<double>(src.observed))) {
        bad = true;
      }
    }
  }
  const ScanMatchHealth& sm = health_.scanMatch;
  if (mode == MapMode::Static && sm.attempted && !sm.fused && !health_.fallbackMatch.attempted &&
      hp.minFieldInlierFraction > 0.0 && sm.points >= params_.scanMatch.minInliers &&
      static_cast<double>(sm.inliers) < hp.minFieldInlierFraction * static_cast<double>(sm.points)) {
    health_.flags |= bit(LocalizerFlag::FieldContradicted);
    bad = true;
  }
  const Eigen::Matrix3d& P = ekf_.covariance();
  const double ps = std::sqrt(largestEigen2(P(0, 0), P(0, 1), P(1, 1)));
  if (!(ps <= hp.maxPositionSigma) || !(std::sqrt(P(2, 2)) <= hp.maxHeadingSigma)) {
    health_.flags |= bit(LocalizerFlag::CovarianceLimit);
    // Against a static map the limit makes the pose untrusted. A dynamic map has no absolute
    // reference: the pose's uncertainty about the map's origin grows with the distance travelled by
    // construction, and nothing could be reset to. There it is dead reckoning relative to its own
    // map, said by the flag, not a bad cycle: only the matched/expected check judges it.
    bad = bad || mode == MapMode::Static;
  }
  if (bad) {
    health_.flags |= bit(LocalizerFlag::BadCycle);
    if (badCycles_ < 255U) {
      ++badCycles_;
    }
    if (badCycles_ >= hp.lostAfterBadCycles) {
      lost_ = true;
    }
  } else {
    badCycles_ = 0;
  }
  return bad;
}

void Localizer::storeAndReplay(const Rewind& at) noexcept {
  health_.scanPose = ekf_.pose();
  const std::size_t n = history_.size();
  const std::size_t k = at.k;
  if (at.split) {
    HistoryEntry& here = history_[k];
    here.stamp = health_.stamp;  // scans come in order: nothing before this is replayed again
    here.pose = ekf_.pose();
    here.cov = ekf_.covariance();
    HistoryEntry& next = history_[k + 1U];
    next.delta = between(at.part, next.delta);
    next.deltaCov = (1.0 - at.f) * next.deltaCov;
  } else {
    history_[k].pose = ekf_.pose();
    history_[k].cov = ekf_.covariance();
  }
  for (std::size_t j = k + 1U; j < n; ++j) {
    HistoryEntry& e = history_[j];
    OdometryIncrement inc;
    inc.stamp = e.stamp;
    inc.delta = e.delta;
    inc.covariance = e.deltaCov;
    (void)ekf_.predict(inc);
    e.pose = ekf_.pose();
    e.cov = ekf_.covariance();
  }
}

}  // namespace agv
