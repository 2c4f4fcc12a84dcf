#include "agv/localization/field_relocalizer.hpp"

#include <cmath>

#include "agv/core/angle.hpp"

namespace agv {

Status FieldRelocalizerParams::validate() const noexcept {
  const double values[] = {positionStep,   rotationStep,    minClearance,   minInlierFraction,
                           maxRms,         closeDistance,   ambiguityRatio, ambiguityDistance,
                           ambiguityAngle, confirmDistance, confirmAngle};
  for (const double v : values) {
    if (!std::isfinite(v)) {
      return Status::NonFiniteInput;
    }
  }
  if (!(positionStep > 0.0) || !(rotationStep > 0.0) || minClearance < 0.0 || maxPoints == 0 || maxPoses == 0 ||
      candidates == 0 || candidates > FieldRelocalizer::kMaxCandidates || !(minInlierFraction > 0.0) ||
      minInlierFraction > 1.0 || !(maxRms > 0.0) || !(closeDistance > 0.0) || !(ambiguityRatio > 0.0) ||
      ambiguityRatio > 1.0 || !(ambiguityDistance > 0.0) || !(ambiguityAngle > 0.0) || !(confirmDistance > 0.0) ||
      !(confirmAngle > 0.0)) {
    return Status::InvalidArgument;
  }
  return match.validate();
}

namespace {

FieldRelocResult finish(FieldRelocResult r, Status status, FieldRelocOutcome outcome) noexcept {
  r.status = status;
  r.outcome = outcome;
  return r;
}

}  // namespace

void FieldRelocalizer::offer(const Candidate& c) noexcept {
  const std::size_t cap = params_.candidates;
  // A kept candidate within one grid step (position and heading) is the same basin: keep the better.
  for (std::size_t k = 0; k < kept_; ++k) {
    Candidate& o = best_[k];
    if (std::fabs(o.pose.x - c.pose.x) <= params_.positionStep * 1.01 &&
        std::fabs(o.pose.y - c.pose.y) <= params_.positionStep * 1.01 &&
        std::fabs(normalizeAngle(o.pose.theta - c.pose.theta)) <= params_.rotationStep * 1.01) {
      if (c.score > o.score) {
        o = c;
      }
      return;
    }
  }
  if (kept_ < cap) {
    best_[kept_++] = c;
    return;
  }
  std::size_t worst = 0;
  for (std::size_t k = 1; k < kept_; ++k) {
    worst = best_[k].score < best_[worst].score ? k : worst;
  }
  if (c.score > best_[worst].score) {
    best_[worst] = c;
  }
}

bool FieldRelocalizer::fits(const ScanMatchResult& m) const noexcept {
  return m.status == Status::Ok && m.points > 0 && m.rmsResidual <= params_.maxRms &&
         static_cast<double>(m.inliers) >= params_.minInlierFraction * static_cast<double>(m.points);
}

std::uint16_t FieldRelocalizer::closePoints(const MatchPoints& points, const Pose2d& laser, const Pose2d& x,
                                            const LikelihoodFieldBase& field) const noexcept {
  const Pose2d l = x.compose(laser);
  std::uint32_t n = 0;
  for (const MatchPoint& p : points) {
    if (!(std::isfinite(p.x) && std::isfinite(p.y))) {
      continue;
    }
    const Eigen::Vector2d w = l.transformPoint(Eigen::Vector2d(static_cast<double>(p.x), static_cast<double>(p.y)));
    const FieldSample f = field.sample(w.x(), w.y());
    n += f.inside && std::fabs(f.distance) <= params_.closeDistance ? 1U : 0U;
  }
  return static_cast<std::uint16_t>(n > 65535U ? 65535U : n);
}

FieldRelocResult FieldRelocalizer::localize(const MatchPoints& points, const Pose2d& laser,
                                            const LikelihoodFieldBase& field, const RelocRegion& region) noexcept {
  FieldRelocResult r;
  const Status valid = params_.validate();
  if (valid != Status::Ok) {
    return finish(r, valid, FieldRelocOutcome::InvalidInput);
  }
  if (!laser.isFinite() || !std::isfinite(region.x) || !std::isfinite(region.y) || !std::isfinite(region.radius) ||
      region.radius < 0.0) {
    return finish(r, Status::NonFiniteInput, FieldRelocOutcome::InvalidInput);
  }
  if (!field.built()) {
    return finish(r, Status::NotInitialized, FieldRelocOutcome::InvalidInput);
  }
  // The coarse points, vehicle frame, spread evenly over the scan's finite points.
  std::size_t finite = 0;
  for (const MatchPoint& p : points) {
    finite += std::isfinite(p.x) && std::isfinite(p.y) ? 1U : 0U;
  }
  if (finite == 0) {
    return finish(r, Status::EmptyInput, FieldRelocOutcome::NoPoints);
  }
  coarse_.clear();
  const std::size_t stride = (finite + params_.maxPoints - 1U) / params_.maxPoints;
  std::size_t seen = 0;
  for (const MatchPoint& p : points) {
    if (!(std::isfinite(p.x) && std::isfinite(p.y))) {
      continue;
    }
    if (seen++ % stride == 0U) {
      const Eigen::Vector2d v =
          laser.transformPoint(Eigen::Vector2d(static_cast<double>(p.x), static_cast<double>(p.y)));
      (void)coarse_.push_back(MatchPoint{static_cast<float>(v.x()), static_cast<float>(v.y())});
    }
  }
  // The grid and its size.
  const double res = field.params().resolution;
  const double band = field.params().maxDistance;
  const double width = static_cast<double>(field.width()) * res;
  const double height = static_cast<double>(field.height()) * res;
  const auto cellOf = [&](double x, double y, double& d) noexcept {
    const double fx = (x - field.originX()) / res;
    const double fy = (y - field.originY()) / res;
    if (!(fx >= 0.0 && fy >= 0.0 && fx < static_cast<double>(field.width()) &&
          fy < static_cast<double>(field.height()))) {
      return false;
    }
    d = field.cellDistance(static_cast<std::size_t>(fx), static_cast<std::size_t>(fy));
    return true;
  };
  // The grid: the field's area, or the part of it around the region's disc.
  double x0 = field.originX();
  double y0 = field.originY();
  double x1 = x0 + width;
  double y1 = y0 + height;
  if (region.radius > 0.0) {
    x0 = region.x - region.radius > x0 ? region.x - region.radius : x0;
    y0 = region.y - region.radius > y0 ? region.y - region.radius : y0;
    x1 = region.x + region.radius < x1 ? region.x + region.radius : x1;
    y1 = region.y + region.radius < y1 ? region.y + region.radius : y1;
  }
  const double spanX = x1 - x0;
  const double spanY = y1 - y0;
  const auto nx = static_cast<std::uint64_t>(spanX > 0.0 ? std::floor(spanX / params_.positionStep) : 0.0);
  const auto ny = static_cast<std::uint64_t>(spanY > 0.0 ? std::floor(spanY / params_.positionStep) : 0.0);
  const auto gridX = [&](std::uint64_t ix) noexcept {
    return x0 + (static_cast<double>(ix) + 0.5) * params_.positionStep;
  };
  const auto gridY = [&](std::uint64_t iy) noexcept {
    return y0 + (static_cast<double>(iy) + 0.5) * params_.positionStep;
  };
  const auto candidatePosition = [&](double x, double y, double& d) noexcept {
    if (region.radius > 0.0 && std::hypot(x - region.x, y - region.y) > region.radius) {
      return false;
    }
    return cellOf(x, y, d) && d >= params_.minClearance;
  };
  const auto nt = static_cast<std::uint64_t>(std::ceil(kTwoPi<double> / params_.rotationStep));
  if (nx == 0U || ny == 0U) {
    return finish(r, Status::NotFound, FieldRelocOutcome::NoCandidate);
  }
  // Free positions first (their count bounds the work).
  std::uint64_t free = 0;
  for (std::uint64_t ix = 0; ix < nx; ++ix) {
    for (std::uint64_t iy = 0; iy < ny; ++iy) {
      double d = 0.0;
      free += candidatePosition(gridX(ix), gridY(iy), d) ? 1U : 0U;
    }
  }
  if (free == 0U) {
    return finish(r, Status::NotFound, FieldRelocOutcome::NoCandidate);
  }
  if (free * nt > params_.maxPoses) {
    r.scored = 0;
    return finish(r, Status::NotConverged, FieldRelocOutcome::WorkBoundHit);
  }
  // Coarse scoring, heading by heading (the points are rotated once per heading).
  kept_ = 0;
  const std::size_t np = coarse_.size();
  MatchPoint* rotated = rotated_;
  std::uint32_t scored = 0;
  for (std::uint64_t it = 0; it < nt; ++it) {
    const double theta = normalizeAngle(static_cast<double>(it) * params_.rotationStep);
    const double c = std::cos(theta);
    const double s = std::sin(theta);
    for (std::size_t k = 0; k < np; ++k) {
      const double px = static_cast<double>(coarse_[k].x);
      const double py = static_cast<double>(coarse_[k].y);
      rotated[k] = MatchPoint{static_cast<float>(c * px - s * py), static_cast<float>(s * px + c * py)};
    }
    for (std::uint64_t ix = 0; ix < nx; ++ix) {
      for (std::uint64_t iy = 0; iy < ny; ++iy) {
        const double x = gridX(ix);
        const double y = gridY(iy);
        double d0 = 0.0;
        if (!candidatePosition(x, y, d0)) {
          continue;
        }
        ++scored;
        // The bar to beat: the worst kept score once the list is full.
        double bar = 0.0;
        if (kept_ == params_.candidates) {
          bar = best_[0].score;
          for (std::size_t k = 1; k < kept_; ++k) {
            bar = best_[k].score < bar ? best_[k].score : bar;
          }
        }
        double score = 0.0;
        bool abandoned = false;
        for (std::size_t k = 0; k < np; ++k) {
          double d = band;
          if (cellOf(x + static_cast<double>(rotated[k].x), y + static_cast<double>(rotated[k].y), d)) {
            const double a = std::fabs(d);
            score += a < band ? 1.0 - a / band : 0.0;
          }
          if (score + static_cast<double>(np - k - 1U) <= bar) {
            abandoned = true;  // cannot beat the worst kept any more
            break;
          }
        }
        if (!abandoned && score > 0.0) {
          offer(Candidate{Pose2d(x, y, theta), score});
        }
      }
    }
  }
  r.scored = scored;
  if (kept_ == 0) {
    return finish(r, Status::NotFound, FieldRelocOutcome::NoCandidate);
  }
  // Refinement of each kept candidate in a window of one grid step.
  ScanMatchParams mp = params_.match;
  matcher_.setParams(mp);
  const SearchWindow window{params_.positionStep, params_.positionStep, params_.rotationStep};
  ScanMatchResult refined[kMaxCandidates];
  std::uint16_t close[kMaxCandidates] = {};
  std::size_t best = kMaxCandidates;
  for (std::size_t k = 0; k < kept_; ++k) {
    refined[k] = matcher_.match(points, laser, best_[k].pose, window, field);
    close[k] = refined[k].status == Status::Ok ? closePoints(points, laser, refined[k].pose, field) : std::uint16_t{0};
    if (fits(refined[k]) && (best == kMaxCandidates || close[k] > close[best])) {
      best = k;
    }
  }
  if (best == kMaxCandidates) {
    return finish(r, Status::NotEnoughData, FieldRelocOutcome::WeakSupport);
  }
  const ScanMatchResult& b = refined[best];
  r.pose = b.pose;
  r.covariance = b.covariance;
  r.inliers = b.inliers;
  r.points = b.points;
  r.rmsResidual = b.rmsResidual;
  r.close = close[best];
  for (std::size_t k = 0; k < kept_; ++k) {
    const ScanMatchResult& o = refined[k];
    if (k == best || o.status != Status::Ok) {
      continue;
    }
    const bool distinct = std::hypot(o.pose.x - b.pose.x, o.pose.y - b.pose.y) > params_.ambiguityDistance ||
                          std::fabs(normalizeAngle(o.pose.theta - b.pose.theta)) > params_.ambiguityAngle;
    if (distinct && close[k] > r.runnerUp) {
      r.runnerUp = close[k];
    }
  }
  if (static_cast<double>(r.runnerUp) >= params_.ambiguityRatio * static_cast<double>(r.close)) {
    return finish(r, Status::Rejected, FieldRelocOutcome::Ambiguous);
  }
  return finish(r, Status::Ok, FieldRelocOutcome::Found);
}

bool FieldRelocalizer::confirm(const MatchPoints& points, const Pose2d& laser, const Pose2d& carried,
                               const LikelihoodFieldBase& field, Pose2d& refined) noexcept {
  if (params_.validate() != Status::Ok || !carried.isFinite()) {
    return false;
  }
  matcher_.setParams(params_.match);
  const ScanMatchResult m =
      matcher_.match(points, laser, carried,
                     SearchWindow{params_.confirmDistance, params_.confirmDistance, params_.confirmAngle}, field);
  if (!fits(m) || std::hypot(m.pose.x - carried.x, m.pose.y - carried.y) > params_.confirmDistance ||
      std::fabs(normalizeAngle(m.pose.theta - carried.theta)) > params_.confirmAngle) {
    return false;
  }
  refined = m.pose;
  return true;
}

}  // namespace agv
