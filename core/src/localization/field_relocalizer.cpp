#include "agv/localization/field_relocalizer.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "agv/core/angle.hpp"

namespace agv {

Status FieldRelocalizerParams::validate() const noexcept {
  const double values[] = {positionStep,  rotationStep,   minClearance,       minInlierFraction, maxRms,
                           closeDistance, ambiguityRatio, ambiguityDistance,  ambiguityAngle,    confirmDistance,
                           confirmAngle,  confirmSigmas,  confirmMaxDistance, confirmMaxAngle,   confirmTravel,
                           confirmTurn};
  for (const double v : values) {
    if (!std::isfinite(v)) {
      return Status::NonFiniteInput;
    }
  }
  if (!(positionStep > 0.0) || !(rotationStep > 0.0) || minClearance < 0.0 || maxPoints == 0 || maxPoses == 0 ||
      candidates == 0 || candidates > FieldRelocalizer::kMaxCandidates || !(minInlierFraction > 0.0) ||
      minInlierFraction > 1.0 || !(maxRms > 0.0) || !(closeDistance > 0.0) || !(ambiguityRatio > 0.0) ||
      ambiguityRatio > 1.0 || !(ambiguityDistance > 0.0) || !(ambiguityAngle > 0.0) || !(confirmDistance > 0.0) ||
      !(confirmAngle > 0.0) || confirmSigmas < 0.0 || confirmMaxDistance < confirmDistance ||
      confirmMaxAngle < confirmAngle || confirmTravel < 0.0 || confirmTurn < 0.0 || confirmMaxScans == 0) {
    return Status::InvalidArgument;
  }
  return match.validate();
}

const char* toString(FieldRelocOutcome outcome) noexcept {
  switch (outcome) {
    case FieldRelocOutcome::Found:
      return "found";
    case FieldRelocOutcome::InvalidInput:
      return "invalid_input";
    case FieldRelocOutcome::NoPoints:
      return "no_points";
    case FieldRelocOutcome::NoCandidate:
      return "no_candidate";
    case FieldRelocOutcome::WeakSupport:
      return "weak_support";
    case FieldRelocOutcome::Ambiguous:
      return "ambiguous";
    case FieldRelocOutcome::WorkBoundHit:
      return "work_bound_hit";
  }
  return "?";
}

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

bool FieldRelocalizer::cellDistance(double x, double y, double& d) const noexcept {
  const LikelihoodFieldBase& field = *field_;
  const double res = field.params().resolution;
  const double fx = (x - field.originX()) / res;
  const double fy = (y - field.originY()) / res;
  if (!(fx >= 0.0 && fy >= 0.0 && fx < static_cast<double>(field.width()) &&
        fy < static_cast<double>(field.height()))) {
    return false;
  }
  d = field.cellDistance(static_cast<std::size_t>(fx), static_cast<std::size_t>(fy));
  return true;
}

bool FieldRelocalizer::candidatePosition(double x, double y) const noexcept {
  if (region_.radius > 0.0 && std::hypot(x - region_.x, y - region_.y) > region_.radius) {
    return false;
  }
  double d = 0.0;
  return cellDistance(x, y, d) && d >= params_.minClearance;
}

void FieldRelocalizer::rotate() noexcept {
  theta_ = normalizeAngle(static_cast<double>(it_) * params_.rotationStep);
  const double c = std::cos(theta_);
  const double s = std::sin(theta_);
  for (std::size_t k = 0; k < coarse_.size(); ++k) {
    const double px = static_cast<double>(coarse_[k].x);
    const double py = static_cast<double>(coarse_[k].y);
    rotated_[k] = MatchPoint{static_cast<float>(c * px - s * py), static_cast<float>(s * px + c * py)};
  }
}

void FieldRelocalizer::end(Status status, FieldRelocOutcome outcome) noexcept {
  result_.status = status;
  result_.outcome = outcome;
  stage_ = Stage::Done;
  field_ = nullptr;
}

void FieldRelocalizer::cancel() noexcept {
  if (searching()) {
    result_ = FieldRelocResult{};
    result_.scored = scored_;
    result_.visited = visited_;
    end(Status::NotFound, FieldRelocOutcome::NoCandidate);
  }
}

Status FieldRelocalizer::start(const MatchPoints& points, const Pose2d& laser, const LikelihoodFieldBase& field,
                               const RelocRegion& region) noexcept {
  result_ = FieldRelocResult{};
  scored_ = 0;
  visited_ = 0;
  kept_ = 0;
  refinedCount_ = 0;
  field_ = &field;
  const Status valid = params_.validate();
  if (valid != Status::Ok) {
    end(valid, FieldRelocOutcome::InvalidInput);
    return result_.status;
  }
  if (!laser.isFinite() || !std::isfinite(region.x) || !std::isfinite(region.y) || !std::isfinite(region.radius) ||
      region.radius < 0.0) {
    end(Status::NonFiniteInput, FieldRelocOutcome::InvalidInput);
    return result_.status;
  }
  if (!field.built()) {
    end(Status::NotInitialized, FieldRelocOutcome::InvalidInput);
    return result_.status;
  }
  laser_ = laser;
  region_ = region;
  // The scan (laser frame, for the refinement) and the coarse points (vehicle frame), spread evenly
  // over the scan's finite points.
  std::size_t finite = 0;
  scan_.clear();
  for (const MatchPoint& p : points) {
    (void)scan_.push_back(p);  // same capacity: cannot overflow
    finite += std::isfinite(p.x) && std::isfinite(p.y) ? 1U : 0U;
  }
  if (finite == 0) {
    end(Status::EmptyInput, FieldRelocOutcome::NoPoints);
    return result_.status;
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
  // The grid: the field's area, or the part of it around the region's disc.
  const double res = field.params().resolution;
  x0_ = field.originX();
  y0_ = field.originY();
  double x1 = x0_ + static_cast<double>(field.width()) * res;
  double y1 = y0_ + static_cast<double>(field.height()) * res;
  if (region.radius > 0.0) {
    x0_ = region.x - region.radius > x0_ ? region.x - region.radius : x0_;
    y0_ = region.y - region.radius > y0_ ? region.y - region.radius : y0_;
    x1 = region.x + region.radius < x1 ? region.x + region.radius : x1;
    y1 = region.y + region.radius < y1 ? region.y + region.radius : y1;
  }
  const double spanX = x1 - x0_;
  const double spanY = y1 - y0_;
  nx_ = static_cast<std::uint64_t>(spanX > 0.0 ? std::floor(spanX / params_.positionStep) : 0.0);
  ny_ = static_cast<std::uint64_t>(spanY > 0.0 ? std::floor(spanY / params_.positionStep) : 0.0);
  nt_ = static_cast<std::uint64_t>(std::ceil(kTwoPi<double> / params_.rotationStep));
  if (nx_ == 0U || ny_ == 0U) {
    end(Status::NotFound, FieldRelocOutcome::NoCandidate);
    return result_.status;
  }
  // Free positions first (their count bounds the work).
  std::uint64_t free = 0;
  for (std::uint64_t ix = 0; ix < nx_; ++ix) {
    for (std::uint64_t iy = 0; iy < ny_; ++iy) {
      free += candidatePosition(x0_ + (static_cast<double>(ix) + 0.5) * params_.positionStep,
                                y0_ + (static_cast<double>(iy) + 0.5) * params_.positionStep)
                  ? 1U
                  : 0U;
    }
  }
  if (free == 0U) {
    end(Status::NotFound, FieldRelocOutcome::NoCandidate);
    return result_.status;
  }
  if (free * nt_ > params_.maxPoses) {
    end(Status::NotConverged, FieldRelocOutcome::WorkBoundHit);
    return result_.status;
  }
  it_ = 0;
  ix_ = 0;
  iy_ = 0;
  rotate();
  stage_ = Stage::Coarse;
  return Status::Ok;
}

bool FieldRelocalizer::advance(std::uint32_t budget) noexcept {
  if (stage_ == Stage::Coarse) {
    // Coarse scoring, heading by heading (the points are rotated once per heading), resumed where
    // the previous call stopped.
    const double band = field_->params().maxDistance;
    const std::size_t np = coarse_.size();
    std::uint32_t done = 0;
    const std::uint32_t limit = budget > 0U ? budget : 1U;
    while (it_ < nt_ && done < limit) {
      const double x = x0_ + (static_cast<double>(ix_) + 0.5) * params_.positionStep;
      const double y = y0_ + (static_cast<double>(iy_) + 0.5) * params_.positionStep;
      ++done;  // every grid pose visited counts: a call is bounded also where few positions are free
      ++visited_;
      if (candidatePosition(x, y)) {
        ++scored_;
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
          if (cellDistance(x + static_cast<double>(rotated_[k].x), y + static_cast<double>(rotated_[k].y), d)) {
            const double a = std::fabs(d);
            score += a < band ? 1.0 - a / band : 0.0;
          }
          if (score + static_cast<double>(np - k - 1U) <= bar) {
            abandoned = true;  // cannot beat the worst kept any more
            break;
          }
        }
        if (!abandoned && score > 0.0) {
          offer(Candidate{Pose2d(x, y, theta_), score});
        }
      }
      // Next position; next heading after the last one.
      if (++iy_ == ny_) {
        iy_ = 0;
        if (++ix_ == nx_) {
          ix_ = 0;
          if (++it_ < nt_) {
            rotate();
          }
        }
      }
    }
    if (it_ < nt_) {
      return false;
    }
    result_.scored = scored_;
    result_.visited = visited_;
    if (kept_ == 0) {
      end(Status::NotFound, FieldRelocOutcome::NoCandidate);
      return true;
    }
    matcher_.setParams(params_.match);
    refinedCount_ = 0;
    stage_ = Stage::Refine;
    return false;
  }
  if (stage_ == Stage::Refine) {
    if (refinedCount_ < kept_) {
      // Refinement of one kept candidate in a window of one grid step.
      const SearchWindow window{params_.positionStep, params_.positionStep, params_.rotationStep};
      const std::size_t k = refinedCount_++;
      refined_[k] = matcher_.match(scan_, laser_, best_[k].pose, window, *field_);
      close_[k] =
          refined_[k].status == Status::Ok ? closePoints(scan_, laser_, refined_[k].pose, *field_) : std::uint16_t{0};
      return false;
    }
    decide();
    return true;
  }
  return true;
}

void FieldRelocalizer::decide() noexcept {
  std::size_t best = kMaxCandidates;
  for (std::size_t k = 0; k < kept_; ++k) {
    if (fits(refined_[k]) && (best == kMaxCandidates || close_[k] > close_[best])) {
      best = k;
    }
  }
  if (best == kMaxCandidates) {
    end(Status::NotEnoughData, FieldRelocOutcome::WeakSupport);
    return;
  }
  const ScanMatchResult& b = refined_[best];
  result_.pose = b.pose;
  result_.covariance = b.covariance;
  result_.inliers = b.inliers;
  result_.points = b.points;
  result_.rmsResidual = b.rmsResidual;
  result_.close = close_[best];
  for (std::size_t k = 0; k < kept_; ++k) {
    const ScanMatchResult& o = refined_[k];
    if (k == best || o.status != Status::Ok) {
      continue;
    }
    const bool distinct = !withinWindow(
        o.pose, b.pose, SearchWindow{params_.ambiguityDistance, params_.ambiguityDistance, params_.ambiguityAngle});
    if (distinct && close_[k] > result_.runnerUp) {
      result_.runnerUp = close_[k];
    }
  }
  if (static_cast<double>(result_.runnerUp) >= params_.ambiguityRatio * static_cast<double>(result_.close)) {
    end(Status::Rejected, FieldRelocOutcome::Ambiguous);
    return;
  }
  end(Status::Ok, FieldRelocOutcome::Found);
}

FieldRelocResult FieldRelocalizer::localize(const MatchPoints& points, const Pose2d& laser,
                                            const LikelihoodFieldBase& field, const RelocRegion& region) noexcept {
  if (start(points, laser, field, region) == Status::Ok) {
    // Bounded: one call visits the whole grid (its free poses are at most maxPoses, checked by
    // start), then kept_ + 1 calls.
    while (!advance(std::numeric_limits<std::uint32_t>::max())) {
    }
  }
  return result_;
}

bool FieldRelocalizer::confirm(const MatchPoints& points, const Pose2d& laser, const Pose2d& carried,
                               const LikelihoodFieldBase& field, Pose2d& refined) noexcept {
  return confirm(points, laser, carried, field, Eigen::Matrix3d::Zero(), refined);
}

SearchWindow FieldRelocalizer::confirmWindow(const Eigen::Matrix3d& carryCovariance) const noexcept {
  const double a = carryCovariance(0, 0);
  const double b = carryCovariance(0, 1);
  const double c = carryCovariance(1, 1);
  const double t = carryCovariance(2, 2);
  if (!carryCovariance.allFinite() || a < 0.0 || c < 0.0 || t < 0.0) {
    return SearchWindow{};
  }
  // The largest eigenvalue of the position block: the window does not depend on the frame.
  const double half = 0.5 * (a - c);
  const double positionVariance = 0.5 * (a + c) + std::sqrt(half * half + b * b);
  const double d = std::min(params_.confirmMaxDistance,
                            std::max(params_.confirmDistance, params_.confirmSigmas * std::sqrt(positionVariance)));
  const double th =
      std::min(params_.confirmMaxAngle, std::max(params_.confirmAngle, params_.confirmSigmas * std::sqrt(t)));
  return SearchWindow{d, d, th};
}

bool FieldRelocalizer::withinWindow(const Pose2d& pose, const Pose2d& carried, const SearchWindow& window) noexcept {
  return std::hypot(pose.x - carried.x, pose.y - carried.y) <= window.x &&
         std::fabs(normalizeAngle(pose.theta - carried.theta)) <= window.theta;
}

bool FieldRelocalizer::confirm(const MatchPoints& points, const Pose2d& laser, const Pose2d& carried,
                               const LikelihoodFieldBase& field, const Eigen::Matrix3d& carryCovariance,
                               Pose2d& refined) noexcept {
  if (params_.validate() != Status::Ok || !carried.isFinite()) {
    return false;
  }
  const SearchWindow window = confirmWindow(carryCovariance);
  if (!(window.x > 0.0)) {
    return false;  // a non-finite or negative covariance
  }
  matcher_.setParams(params_.match);
  const ScanMatchResult m = matcher_.match(points, laser, carried, window, field);
  if (!fits(m) || !withinWindow(m.pose, carried, window)) {
    return false;
  }
  refined = m.pose;
  return true;
}

void FieldConfirmation::add(const Pose2d& step) noexcept {
  ++scans_;
  const double d = std::hypot(step.x, step.y);
  const double a = std::fabs(normalizeAngle(step.theta));
  travel_ += std::isfinite(d) ? d : 0.0;
  turn_ += std::isfinite(a) ? a : 0.0;
}

bool FieldConfirmation::complete(std::uint32_t minScans, const FieldRelocalizerParams& params) const noexcept {
  if (scans_ < minScans) {
    return false;
  }
  const bool noMotionAsked = !(params.confirmTravel > 0.0) && !(params.confirmTurn > 0.0);
  return noMotionAsked || scans_ >= params.confirmMaxScans ||
         (params.confirmTravel > 0.0 && travel_ >= params.confirmTravel) ||
         (params.confirmTurn > 0.0 && turn_ >= params.confirmTurn);
}

}  // namespace agv
