#include "agv/localization/scan_matcher.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "spd3.hpp"

namespace agv {

Status ScanMatchParams::validate() const noexcept {
  const double values[] = {pointSpacing,
                           inlierDistance,
                           huber,
                           minInlierFraction,
                           sigmaFloor,
                           covarianceInflation,
                           stepTranslation,
                           stepRotation,
                           maxCorrection,
                           maxRotation,
                           searchSigmas,
                           maxSearchTranslation,
                           maxSearchRotation,
                           searchStepTranslation,
                           searchStepRotation,
                           maxRmsResidual,
                           resyncMaxRms,
                           resyncMatchSigma,
                           resyncMatchSigmaAngle,
                           fitScatter,
                           recoveryTranslation,
                           recoveryRotation,
                           maxRecoveryTranslation,
                           maxRecoveryRotation};
  for (const double v : values) {
    if (!std::isfinite(v)) {
      return Status::NonFiniteInput;
    }
  }
  if (maxIterations == 0 || pointSpacing < 0.0 || !(inlierDistance > 0.0) || !(huber > 0.0) || !(sigmaFloor > 0.0) ||
      !(covarianceInflation > 0.0) || !(stepTranslation > 0.0) || !(stepRotation > 0.0) || !(maxCorrection > 0.0) ||
      !(maxRotation > 0.0) || searchSigmas < 0.0 || !(maxRmsResidual > 0.0) || !(resyncMaxRms > 0.0) ||
      resyncMatchSigma < 0.0 || resyncMatchSigmaAngle < 0.0 || fitScatter < 0.0 || maxSearchTranslation < 0.0 ||
      maxSearchRotation < 0.0 || !(searchStepTranslation > 0.0) || !(searchStepRotation > 0.0) || maxSearchPoses == 0 ||
      minInlierFraction < 0.0 || minInlierFraction > 1.0 || recoveryTranslation < 0.0 || recoveryRotation < 0.0 ||
      maxRecoveryTranslation < recoveryTranslation || maxRecoveryRotation < recoveryRotation) {
    return Status::InvalidArgument;
  }
  return Status::Ok;
}

namespace {

/// Normal equations of one linearisation at pose (x, y, theta).
struct Normal {
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  Eigen::Vector3d g = Eigen::Vector3d::Zero();
  double weightSum = 0.0;
  double weightedSquares = 0.0;
  double inlierSquares = 0.0;
  double cost = 0.0;  // sum of the robust costs, outliers at the cost of inlierDistance
  std::size_t inliers = 0;
};

/// Huber's cost of residual r with threshold k.
double huberCost(double r, double k) noexcept {
  return r <= k ? 0.5 * r * r : k * (r - 0.5 * k);
}

}  // namespace

void scanToMatchPoints(const LaserScan& scan, MatchPoints& out, double maxRange) noexcept {
  out.clear();
  for (std::size_t i = 0; i < scan.size(); ++i) {
    const double r = static_cast<double>(scan.ranges[i]);
    if (scan.isValid(i) && r <= maxRange) {
      const double a = static_cast<double>(scan.angle(i));
      static_cast<void>(
          out.push_back(MatchPoint{static_cast<float>(r * std::cos(a)), static_cast<float>(r * std::sin(a))}));
    }
  }
}

void ScanMatcher::keepPoint(const Eigen::Vector2d& p) noexcept {
  if (!p.allFinite()) {
    return;
  }
  if (!points_.empty()) {
    const double dx = p.x() - static_cast<double>(points_.back().x);
    const double dy = p.y() - static_cast<double>(points_.back().y);
    if (dx * dx + dy * dy < params_.pointSpacing * params_.pointSpacing) {
      return;
    }
  }
  static_cast<void>(points_.push_back(MatchPoint{static_cast<float>(p.x()), static_cast<float>(p.y())}));
}

bool ScanMatcher::collectPoints(const LaserScan& scan, const Pose2d& laser, ScanMatchResult& result) noexcept {
  points_.clear();
  for (std::size_t i = 0; i < scan.size(); ++i) {
    if (scan.isValid(i)) {
      const double a = static_cast<double>(scan.angle(i));
      const double r = static_cast<double>(scan.ranges[i]);
      keepPoint(laser.transformPoint(Eigen::Vector2d(r * std::cos(a), r * std::sin(a))));
    }
  }
  result.points = static_cast<std::uint16_t>(points_.size() > 65535U ? 65535U : points_.size());
  if (points_.empty()) {
    result.status = Status::EmptyInput;
    return false;
  }
  return true;
}

bool ScanMatcher::collectPoints(const MatchPoints& points, const Pose2d& laser, ScanMatchResult& result) noexcept {
  points_.clear();
  for (const MatchPoint& p : points) {
    keepPoint(laser.transformPoint(Eigen::Vector2d(static_cast<double>(p.x), static_cast<double>(p.y))));
  }
  result.points = static_cast<std::uint16_t>(points_.size() > 65535U ? 65535U : points_.size());
  if (points_.empty()) {
    result.status = Status::EmptyInput;
    return false;
  }
  return true;
}

double ScanMatcher::effectiveInlierDistance(const LikelihoodFieldBase& field) const noexcept {
  // The field cannot tell distances beyond its saturation apart.
  return params_.inlierDistance < field.params().maxDistance ? params_.inlierDistance : field.params().maxDistance;
}

double ScanMatcher::cost(const Pose2d& x, const LikelihoodFieldBase& field, double bound) const noexcept {
  const double inlierDistance = effectiveInlierDistance(field);
  const double outlierCost = huberCost(inlierDistance, params_.huber);
  const double c = std::cos(x.theta);
  const double s = std::sin(x.theta);
  double total = 0.0;
  for (const MatchPoint& pt : points_) {
    const double px = static_cast<double>(pt.x);
    const double py = static_cast<double>(pt.y);
    // Not inside the field: the saturated distance, at least the inlier distance (an outlier).
    const double ar = std::fabs(field.distance(x.x + c * px - s * py, x.y + s * px + c * py));
    total += ar < inlierDistance ? huberCost(ar, params_.huber) : outlierCost;
    if (total >= bound) {
      break;  // cannot beat the bound any more: the terms are non-negative
    }
  }
  return total;
}

Pose2d ScanMatcher::search(const Pose2d& prior, double wx, double wy, double wt, const LikelihoodFieldBase& field,
                           std::uint32_t& scored) const noexcept {
  // Steps per axis each way, grown together until the grid fits maxSearchPoses.
  double stepT = params_.searchStepTranslation;
  double stepR = params_.searchStepRotation;
  long nx = 0;
  long ny = 0;
  long nt = 0;
  for (int grow = 0; grow < 32; ++grow) {
    nx = static_cast<long>(std::floor(wx / stepT));
    ny = static_cast<long>(std::floor(wy / stepT));
    nt = static_cast<long>(std::floor(wt / stepR));
    const double poses =
        static_cast<double>(2 * nx + 1) * static_cast<double>(2 * ny + 1) * static_cast<double>(2 * nt + 1);
    if (poses <= static_cast<double>(params_.maxSearchPoses)) {
      break;
    }
    stepT *= 1.25;
    stepR *= 1.25;
  }
  Pose2d best = prior;
  double bestCost = cost(prior, field);
  scored = 1;
  // In the field's grid units (cell centres at whole values, `distanceAtGrid`): the rotation is
  // scaled to cells once per heading and the translation once per pose, so that a point costs
  // four products and four sums (no division by the resolution).
  const double res = field.params().resolution;
  const double inlierDistance = effectiveInlierDistance(field);
  const double outlierCost = huberCost(inlierDistance, params_.huber);
  for (long it = -nt; it <= nt; ++it) {
    const double theta = normalizeAngle(prior.theta + static_cast<double>(it) * stepR);
    const double c = std::cos(theta) / res;
    const double s = std::sin(theta) / res;
    for (long ix = -nx; ix <= nx; ++ix) {
      const double x = prior.x + static_cast<double>(ix) * stepT;
      const double u0 = (x - field.originX()) / res - 0.5;
      for (long iy = -ny; iy <= ny; ++iy) {
        if (it == 0 && ix == 0 && iy == 0) {
          continue;
        }
        const double y = prior.y + static_cast<double>(iy) * stepT;
        const double v0 = (y - field.originY()) / res - 0.5;
        // As `cost`: abandoned once the partial sum reaches the best pose's (it cannot win).
        double total = 0.0;
        for (const MatchPoint& pt : points_) {
          const double px = static_cast<double>(pt.x);
          const double py = static_cast<double>(pt.y);
          const double ar = std::fabs(field.distanceAtGrid(u0 + (c * px - s * py), v0 + (s * px + c * py)));
          total += ar < inlierDistance ? huberCost(ar, params_.huber) : outlierCost;
          if (total >= bestCost) {
            break;
          }
        }
        ++scored;
        if (total < bestCost) {
          bestCost = total;
          best = Pose2d(x, y, theta);
        }
      }
    }
  }
  return best;
}

bool ScanMatcher::checkInput(const Pose2d& laser, const Pose2d& prior, const Eigen::Matrix3d& priorCovariance,
                             const LikelihoodFieldBase& field, ScanMatchResult& result) const noexcept {
  result = ScanMatchResult{};
  result.pose = prior;
  if (!prior.isFinite() || !laser.isFinite() || !priorCovariance.allFinite()) {
    result.status = Status::NonFiniteInput;
    return false;
  }
  if (!field.built()) {
    result.status = Status::NotInitialized;
    return false;
  }
  return true;
}

ScanMatchResult ScanMatcher::match(const LaserScan& scan, const Pose2d& laser, const Pose2d& prior,
                                   const LikelihoodFieldBase& field) noexcept {
  ScanMatchResult result;
  if (!checkInput(laser, prior, Eigen::Matrix3d::Zero(), field, result) || !collectPoints(scan, laser, result)) {
    return result;
  }
  const std::uint16_t points = result.points;
  result = refine(prior, prior, params_.maxCorrection, params_.maxRotation, field);
  result.points = points;
  return result;
}

ScanMatchResult ScanMatcher::match(const LaserScan& scan, const Pose2d& laser, const Pose2d& prior,
                                   const Eigen::Matrix3d& priorCovariance, const LikelihoodFieldBase& field) noexcept {
  ScanMatchResult result;
  if (!checkInput(laser, prior, priorCovariance, field, result) || !collectPoints(scan, laser, result)) {
    return result;
  }
  return searchAndRefine(prior, searchWindow(priorCovariance), field, result);
}

ScanMatchResult ScanMatcher::match(const MatchPoints& points, const Pose2d& laser, const Pose2d& prior,
                                   const Eigen::Matrix3d& priorCovariance, const LikelihoodFieldBase& field) noexcept {
  ScanMatchResult result;
  if (!checkInput(laser, prior, priorCovariance, field, result) || !collectPoints(points, laser, result)) {
    return result;
  }
  return searchAndRefine(prior, searchWindow(priorCovariance), field, result);
}

namespace {
bool validWindow(const SearchWindow& w) noexcept {
  return std::isfinite(w.x) && std::isfinite(w.y) && std::isfinite(w.theta) && w.x >= 0.0 && w.y >= 0.0 &&
         w.theta >= 0.0;
}
}  // namespace

ScanMatchResult ScanMatcher::match(const LaserScan& scan, const Pose2d& laser, const Pose2d& prior,
                                   const SearchWindow& window, const LikelihoodFieldBase& field) noexcept {
  return matchInWindow(scan, laser, prior, window, field);
}

ScanMatchResult ScanMatcher::match(const MatchPoints& points, const Pose2d& laser, const Pose2d& prior,
                                   const SearchWindow& window, const LikelihoodFieldBase& field) noexcept {
  return matchInWindow(points, laser, prior, window, field);
}

template <typename Scan>
ScanMatchResult ScanMatcher::matchInWindow(const Scan& scan, const Pose2d& laser, const Pose2d& prior,
                                           const SearchWindow& window, const LikelihoodFieldBase& field) noexcept {
  ScanMatchResult result;
  if (!checkInput(laser, prior, Eigen::Matrix3d::Zero(), field, result)) {
    return result;
  }
  if (!validWindow(window)) {
    result.status = Status::InvalidArgument;
    return result;
  }
  if (!collectPoints(scan, laser, result)) {
    return result;
  }
  return searchAndRefine(prior, window, field, result);
}

template <typename Scan>
double ScanMatcher::costOf(const Scan& scan, const Pose2d& laser, const Pose2d& x,
                           const LikelihoodFieldBase& field) noexcept {
  ScanMatchResult result;
  if (!checkInput(laser, x, Eigen::Matrix3d::Zero(), field, result) || !collectPoints(scan, laser, result)) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  return cost(x, field);
}

double ScanMatcher::costAt(const LaserScan& scan, const Pose2d& laser, const Pose2d& x,
                           const LikelihoodFieldBase& field) noexcept {
  return costOf(scan, laser, x, field);
}

double ScanMatcher::costAt(const MatchPoints& points, const Pose2d& laser, const Pose2d& x,
                           const LikelihoodFieldBase& field) noexcept {
  return costOf(points, laser, x, field);
}

SearchWindow ScanMatcher::searchWindow(const Eigen::Matrix3d& priorCovariance) const noexcept {
  const auto half = [&](double variance, double cap) noexcept {
    const double w = params_.searchSigmas * std::sqrt(variance > 0.0 ? variance : 0.0);
    return std::isfinite(w) && w < cap ? w : (std::isfinite(w) ? cap : 0.0);
  };
  return SearchWindow{half(priorCovariance(0, 0), params_.maxSearchTranslation),
                      half(priorCovariance(1, 1), params_.maxSearchTranslation),
                      half(priorCovariance(2, 2), params_.maxSearchRotation)};
}

ScanMatchResult ScanMatcher::searchAndRefine(const Pose2d& prior, const SearchWindow& window,
                                             const LikelihoodFieldBase& field, ScanMatchResult result) noexcept {
  const double wx = window.x;
  const double wy = window.y;
  const double wt = window.theta;
  Pose2d start = prior;
  std::uint32_t scored = 0;
  if (wx >= params_.searchStepTranslation || wy >= params_.searchStepTranslation || wt >= params_.searchStepRotation) {
    start = search(prior, wx, wy, wt, field, scored);
  }
  const double allowedT = std::hypot(wx, wy) > params_.maxCorrection ? std::hypot(wx, wy) : params_.maxCorrection;
  const double allowedR = wt > params_.maxRotation ? wt : params_.maxRotation;
  const std::uint16_t points = result.points;
  result = refine(prior, start, allowedT, allowedR, field);
  result.points = points;
  result.searched = scored;
  return result;
}

ScanMatchResult ScanMatcher::refine(const Pose2d& prior, const Pose2d& start, double allowedTranslation,
                                    double allowedRotation, const LikelihoodFieldBase& field) noexcept {
  ScanMatchResult result;
  result.pose = prior;
  // Points within `band` of a surface are inliers (Huber-weighted), the others cost a constant.
  const auto linearise = [&](const Pose2d& x, double band) noexcept {
    const double outlierCost = huberCost(band, params_.huber);
    Normal n;
    const double c = std::cos(x.theta);
    const double s = std::sin(x.theta);
    for (const MatchPoint& pt : points_) {
      const double px = static_cast<double>(pt.x);
      const double py = static_cast<double>(pt.y);
      const double qx = x.x + c * px - s * py;
      const double qy = x.y + s * px + c * py;
      const FieldSample f = field.sample(qx, qy);
      if (!f.inside || !(std::fabs(f.distance) < band)) {
        n.cost += outlierCost;
        continue;
      }
      const double r = f.distance;  // signed: negative behind the surface
      const double ar = std::fabs(r);
      n.cost += huberCost(ar, params_.huber);
      const double w = ar <= params_.huber ? 1.0 : params_.huber / ar;
      const Eigen::Vector3d J(f.gradient.x(), f.gradient.y(),
                              f.gradient.x() * (-s * px - c * py) + f.gradient.y() * (c * px - s * py));
      n.H.noalias() += w * J * J.transpose();
      n.g.noalias() += w * r * J;
      n.weightSum += w;
      n.weightedSquares += w * r * r;
      n.inlierSquares += r * r;
      ++n.inliers;
    }
    return n;
  };
  // Rank check: det(H) against the product of its diagonal (scale-free per axis, spd3.hpp).
  constexpr double kRankTolerance = 1e-9;
  // Gauss-Newton with step halving: a step that does not lower the robust cost is halved (at most
  // kHalvings times); when none lowers it, x is the minimum the field resolves (converged).
  constexpr int kHalvings = 5;
  enum class Outcome { Converged, NotConverged, TooFew, Singular, NonFinite };
  const auto gaussNewton = [&](Pose2d& x, Normal& n, double band, std::size_t minInliers, std::uint8_t& it) noexcept {
    n = linearise(x, band);
    it = 0;
    while (it < params_.maxIterations) {
      ++it;
      if (n.inliers < minInliers) {
        return Outcome::TooFew;
      }
      Eigen::Matrix3d Hinv;
      if (!detail::invertSpd3(n.H, kRankTolerance, Hinv)) {
        return Outcome::Singular;
      }
      Eigen::Vector3d step = -(Hinv * n.g);
      if (!step.allFinite()) {
        return Outcome::NonFinite;
      }
      bool lowered = false;
      for (int h = 0; h <= kHalvings && !lowered; ++h) {
        const Pose2d candidate = Pose2d(x.x + step.x(), x.y + step.y(), x.theta + step.z()).normalized();
        const Normal m = linearise(candidate, band);
        if (m.cost < n.cost) {
          x = candidate;
          n = m;
          lowered = true;
        } else {
          step *= 0.5;
        }
      }
      if (!lowered ||
          (std::hypot(step.x(), step.y()) < params_.stepTranslation && std::fabs(step.z()) < params_.stepRotation)) {
        return Outcome::Converged;
      }
    }
    return Outcome::NotConverged;
  };
  const std::size_t minInliers = [&]() noexcept {
    const auto byFraction =
        static_cast<std::size_t>(std::ceil(params_.minInlierFraction * static_cast<double>(points_.size())));
    return byFraction > params_.minInliers ? byFraction : params_.minInliers;
  }();
  const double inlierDistance = effectiveInlierDistance(field);
  Pose2d x = start;
  Normal n;
  std::uint8_t it = 0;
  const Outcome o = gaussNewton(x, n, inlierDistance, minInliers, it);
  result.iterations = it;
  if (o == Outcome::TooFew) {
    result.status = Status::NotEnoughData;
    result.inliers = static_cast<std::uint16_t>(n.inliers > 65535U ? 65535U : n.inliers);
    return result;
  }
  if (o == Outcome::Singular || o == Outcome::NonFinite) {
    result.status = o == Outcome::Singular ? Status::Unobservable : Status::NonFiniteInput;
    return result;
  }
  result.pose = x;
  result.inliers = static_cast<std::uint16_t>(n.inliers > 65535U ? 65535U : n.inliers);
  result.rmsResidual = n.inliers > 0 ? std::sqrt(n.inlierSquares / static_cast<double>(n.inliers)) : 0.0;
  if (o == Outcome::NotConverged) {
    result.status = Status::NotConverged;
    return result;
  }
  if (result.rmsResidual > params_.maxRmsResidual) {
    result.status = Status::IllConditioned;
    return result;
  }
  if (params_.adaptiveBand) {
    // The residual scale of this scan against this map: where most surfaces are as mapped, the
    // points on them fit within the range noise, and the points 3 robust sigmas beyond are on
    // surfaces that moved or were never mapped (a pallet put next to a mapped one); in the wide
    // band they pull at Huber's constant force and bias the pose by centimetres.
    const double band = residualBand(x, field, inlierDistance);
    if (band < inlierDistance) {
      Pose2d y = x;
      Normal k;
      std::uint8_t jt = 0;
      if (gaussNewton(y, k, band, params_.minInliers, jt) == Outcome::Converged) {
        x = y;  // the covariance stays the wide band's (its scatter includes the changed surfaces)
        result.pose = x;
        result.iterations = static_cast<std::uint8_t>(it + jt < 255 ? it + jt : 255);
      }
    }
  }
  Eigen::Matrix3d Hinv;
  if (!detail::invertSpd3(n.H, kRankTolerance, Hinv)) {
    result.status = Status::Unobservable;
    return result;
  }
  if (std::hypot(x.x - prior.x, x.y - prior.y) > allowedTranslation ||
      std::fabs(normalizeAngle(x.theta - prior.theta)) > allowedRotation) {
    result.status = Status::OutOfRange;
    return result;
  }
  const double dof = n.weightSum > 4.0 ? n.weightSum - 3.0 : 1.0;
  double sigma2 = n.weightedSquares / dof;
  if (sigma2 < params_.sigmaFloor * params_.sigmaFloor) {
    sigma2 = params_.sigmaFloor * params_.sigmaFloor;
  }
  const Eigen::Matrix3d cov = sigma2 * params_.covarianceInflation * Hinv;
  if (params_.fitScatter > 0.0) {  // the lever is only read to apply the fit scatter
    double lever2 = 0.0;
    for (const MatchPoint& pt : points_) {
      lever2 +=
          static_cast<double>(pt.x) * static_cast<double>(pt.x) + static_cast<double>(pt.y) * static_cast<double>(pt.y);
    }
    result.lever = std::sqrt(lever2 / static_cast<double>(points_.size()));
  }
  if (!cov.allFinite()) {
    result.status = Status::NonFiniteInput;
    return result;
  }
  result.covariance = 0.5 * (cov + cov.transpose());
  result.status = Status::Ok;
  return result;
}

double ScanMatcher::residualBand(const Pose2d& x, const LikelihoodFieldBase& field, double inlierDistance) noexcept {
  residuals_.clear();
  const double c = std::cos(x.theta);
  const double s = std::sin(x.theta);
  for (const MatchPoint& pt : points_) {
    const double px = static_cast<double>(pt.x);
    const double py = static_cast<double>(pt.y);
    const FieldSample f = field.sample(x.x + c * px - s * py, x.y + s * px + c * py);
    if (f.inside && std::fabs(f.distance) < inlierDistance) {
      static_cast<void>(residuals_.push_back(static_cast<float>(std::fabs(f.distance))));
    }
  }
  if (residuals_.empty()) {
    return inlierDistance;
  }
  float* const mid = residuals_.begin() + residuals_.size() / 2U;
  std::nth_element(residuals_.begin(), mid, residuals_.end());
  // Median absolute residual -> sigma of a normal (1.4826), 3 sigmas; never below the floor of
  // the residual's sigma (the field's quantisation).
  const double band = 3.0 * 1.4826 * static_cast<double>(*mid);
  const double floor = 3.0 * params_.sigmaFloor;
  return band > floor ? band : floor;
}

}  // namespace agv
