#include "agv/calib/calibration.hpp"

#include "agv/calib/equal_norm_fit.hpp"

#include <Eigen/Core>
#include <cmath>
#include <complex>
#include <limits>

namespace agv {
namespace {

using Complex = std::complex<double>;

bool hasTravel(const CalibSegment& s, std::int64_t minTicks) noexcept {
  return s.ticks >= minTicks || s.ticks <= -minTicks;
}

/// Steering offset that applies to a segment's direction.
double offsetFor(const CalibSegment& s, const TricycleParams& p) noexcept {
  return s.ticks >= 0 ? p.steerOffsetForward : p.steerOffsetBackward;
}

/// Direction filter of a sum: all segments, forward only, backward only.
enum class Dir : std::uint8_t { All, Forward, Backward };

bool inDir(const CalibSegment& s, Dir dir, std::int64_t minTicks) noexcept {
  if (!hasTravel(s, minTicks)) {
    return false;
  }
  switch (dir) {
    case Dir::All:
      return true;
    case Dir::Forward:
      return s.ticks > 0;
    case Dir::Backward:
      return s.ticks < 0;
  }
  return false;
}

/// Two segments of direction `dir` with travel whose steering angles do not differ by k*pi.
/// O(n^2) with n <= kMaxCalibSegments.
bool steeringDiverse(Span<const CalibSegment> segs, Dir dir, const CalibrationOptions& opt) noexcept {
  const double minSin = std::sin(opt.minSteeringSeparation);
  for (std::size_t i = 0; i < segs.size(); ++i) {
    if (!inDir(segs[i], dir, opt.minTicks)) {
      continue;
    }
    for (std::size_t j = i + 1; j < segs.size(); ++j) {
      if (inDir(segs[j], dir, opt.minTicks) && std::fabs(std::sin(segs[i].steering - segs[j].steering)) >= minSin) {
        return true;
      }
    }
  }
  return false;
}

/// Normal equations of the rotation fit theta^k = n^k (sin a^k, cos a^k) . J over `dir`.
void rotationNormalEquations(Span<const CalibSegment> segs, Dir dir, const CalibrationOptions& opt, Eigen::Matrix2d& m,
                             Eigen::Vector2d& g) noexcept {
  m.setZero();
  g.setZero();
  for (const CalibSegment& s : segs) {
    if (!inDir(s, dir, opt.minTicks)) {
      continue;
    }
    const double n = static_cast<double>(s.ticks);
    const Eigen::Vector2d row(n * std::sin(s.steering), n * std::cos(s.steering));
    m.noalias() += row * row.transpose();
    g += row * unwrappedSegmentRotation(s, opt);
  }
}

/// max/min eigenvalue of a symmetric positive semi-definite 2x2 matrix (inf when singular).
double conditionNumber2(const Eigen::Matrix2d& m) noexcept {
  const double tr = 0.5 * (m(0, 0) + m(1, 1));
  const double diff = 0.5 * (m(0, 0) - m(1, 1));
  const double rad = std::sqrt(diff * diff + m(0, 1) * m(0, 1));
  const double hi = tr + rad;
  const double lo = tr - rad;
  if (!(hi > 0.0)) {
    return std::numeric_limits<double>::infinity();
  }
  if (!(lo > hi * 1e-15)) {
    return std::numeric_limits<double>::infinity();
  }
  return hi / lo;
}

double odometryCondition(Span<const CalibSegment> segs, Dir dir, const CalibrationOptions& opt) noexcept {
  Eigen::Matrix2d m;
  Eigen::Vector2d g;
  rotationNormalEquations(segs, dir, opt, m, g);
  return conditionNumber2(m);
}

Status refuse(CalibrationReport& report, Status status, CalibCondition condition) noexcept {
  report.status = status;
  report.failed = condition;
  return status;
}

/// RMS of theta^k - predicted rotation over segments with travel.
double rotationRms(Span<const CalibSegment> segs, const TricycleParams& p, const CalibrationOptions& opt) noexcept {
  double sum = 0.0;
  std::size_t count = 0;
  for (const CalibSegment& s : segs) {
    if (!hasTravel(s, opt.minTicks)) {
      continue;
    }
    const double pred =
        p.driveScale * static_cast<double>(s.ticks) * std::sin(s.steering + offsetFor(s, p)) / p.wheelbase;
    const double e = unwrappedSegmentRotation(s, opt) - pred;
    sum += e * e;
    ++count;
  }
  return count > 0 ? std::sqrt(sum / static_cast<double>(count)) : 0.0;
}

bool validOptions(const CalibrationOptions& opt) noexcept {
  return std::isfinite(opt.nominal.wheelbase) && opt.nominal.wheelbase > 0.0 && std::isfinite(opt.nominal.driveScale) &&
         opt.nominal.driveScale > 0.0 && std::isfinite(opt.nominal.steerOffsetForward) &&
         std::isfinite(opt.nominal.steerOffsetBackward) && opt.minTicks >= 1 && opt.minSteeringSeparation > 0.0 &&
         opt.minSteeringSeparation < kPi<double> / 2.0 && opt.minRotation > 0.0 && opt.minRotation < kPi<double> &&
         opt.minTranslation > 0.0 && opt.maxConditionNumber > 1.0;
}

}  // namespace

const char* toString(CalibCondition condition) noexcept {
  switch (condition) {
    case CalibCondition::None:
      return "none";
    case CalibCondition::SegmentCount:
      return "segment count";
    case CalibCondition::FiniteInput:
      return "finite input";
    case CalibCondition::SteeringDiversity:
      return "steering diversity";
    case CalibCondition::ForwardSteeringDiversity:
      return "forward steering diversity";
    case CalibCondition::BackwardSteeringDiversity:
      return "backward steering diversity";
    case CalibCondition::LaserRotation:
      return "laser rotation";
    case CalibCondition::LaserTranslation:
      return "laser translation";
    case CalibCondition::OdometryConditioning:
      return "odometry conditioning";
    case CalibCondition::LaserConditioning:
      return "laser conditioning";
    case CalibCondition::PositiveScale:
      return "positive scale";
  }
  return "unknown condition";
}

double unwrappedSegmentRotation(const CalibSegment& segment, const CalibrationOptions& options) noexcept {
  const TricycleParams& nom = options.nominal;
  const double nominal = nom.driveScale * static_cast<double>(segment.ticks) *
                         std::sin(segment.steering + offsetFor(segment, nom)) / nom.wheelbase;
  return nominal + angleDiff(segment.egomotion.theta, nominal);
}

Pose2d predictedEgomotion(const CalibSegment& segment, const TricycleParams& params, const Pose2d& laserPose) noexcept {
  const Pose2d arc = tricycleArc(params.driveScale * static_cast<double>(segment.ticks),
                                 segment.steering + offsetFor(segment, params), params.wheelbase);
  return laserPose.inverse().compose(arc).compose(laserPose);
}

Status checkCalibrationObservability(Span<const CalibSegment> segments, CalibModel model, const CalibrationOptions& opt,
                                     CalibrationReport& report) noexcept {
  report = CalibrationReport{};
  report.segmentCount = segments.size();
  if (!validOptions(opt)) {
    report.status = Status::InvalidArgument;
    return Status::InvalidArgument;
  }
  if (segments.size() > kMaxCalibSegments) {
    return refuse(report, Status::CapacityExceeded, CalibCondition::SegmentCount);
  }
  if (segments.size() < 2) {
    return refuse(report, Status::NotEnoughData, CalibCondition::SegmentCount);
  }
  for (std::size_t i = 0; i < segments.size(); ++i) {
    const CalibSegment& s = segments[i];
    if (!std::isfinite(s.steering) || !s.egomotion.isFinite()) {
      report.firstNonFinite = i;
      return refuse(report, Status::NonFiniteInput, CalibCondition::FiniteInput);
    }
    if (s.ticks >= opt.minTicks) {
      ++report.forwardCount;
    } else if (s.ticks <= -opt.minTicks) {
      ++report.backwardCount;
    }
    const double rot = s.egomotion.theta;  // in (-pi, pi]: a multiple of 2 pi shows as ~0
    if (std::fabs(std::sin(0.5 * rot)) >= std::sin(0.5 * opt.minRotation)) {
      report.laserRotationObserved = true;
    }
    if (std::hypot(s.egomotion.x, s.egomotion.y) >= opt.minTranslation) {
      report.laserTranslationObserved = true;
    }
  }
  report.steeringDiverse = steeringDiverse(segments, Dir::All, opt);
  report.forwardSteeringDiverse = steeringDiverse(segments, Dir::Forward, opt);
  report.backwardSteeringDiverse = steeringDiverse(segments, Dir::Backward, opt);
  report.conditionStc = odometryCondition(segments, Dir::All, opt);
  if (model == CalibModel::Atc) {
    report.conditionForward = odometryCondition(segments, Dir::Forward, opt);
    report.conditionBackward = odometryCondition(segments, Dir::Backward, opt);
  }

  if (model == CalibModel::Stc) {
    if (!report.steeringDiverse) {
      return refuse(report, Status::Unobservable, CalibCondition::SteeringDiversity);
    }
  } else {
    if (!report.forwardSteeringDiverse) {
      return refuse(report, Status::Unobservable, CalibCondition::ForwardSteeringDiversity);
    }
    if (!report.backwardSteeringDiverse) {
      return refuse(report, Status::Unobservable, CalibCondition::BackwardSteeringDiversity);
    }
  }
  if (!report.laserRotationObserved) {
    return refuse(report, Status::Unobservable, CalibCondition::LaserRotation);
  }
  if (!report.laserTranslationObserved) {
    return refuse(report, Status::Unobservable, CalibCondition::LaserTranslation);
  }
  const double worst =
      model == CalibModel::Stc ? report.conditionStc : std::fmax(report.conditionForward, report.conditionBackward);
  if (!(worst <= opt.maxConditionNumber)) {
    return refuse(report, Status::IllConditioned, CalibCondition::OdometryConditioning);
  }
  report.status = Status::Ok;
  return Status::Ok;
}

Status estimateLaserPose(Span<const CalibSegment> segments, const TricycleParams& params, const CalibrationOptions& opt,
                         Pose2d& laserPose, CalibrationReport& report) noexcept {
  if (segments.size() > kMaxCalibSegments) {
    return refuse(report, Status::CapacityExceeded, CalibCondition::SegmentCount);
  }
  if (!std::isfinite(params.driveScale) || !std::isfinite(params.wheelbase) || !(params.wheelbase > 0.0) ||
      !std::isfinite(params.steerOffsetForward) || !std::isfinite(params.steerOffsetBackward)) {
    return refuse(report, Status::NonFiniteInput, CalibCondition::FiniteInput);
  }
  // Complex form of the translation part of l ⊕ s^k = r^k ⊕ l (docs/calibration.md):
  //   w_k l + u s_k = r_k,  w_k = 1 - e^{i theta_k},  u = e^{i ltheta}.
  double a = 0.0;    // sum |w|^2
  double css = 0.0;  // sum |s|^2
  Complex pSum{};    // sum conj(w) r
  Complex qSum{};    // sum conj(w) s
  Complex srSum{};   // sum conj(s) r
  bool rotation = false;
  bool translation = false;
  const double minHalfSin = std::sin(0.5 * opt.minRotation);
  for (const CalibSegment& s : segments) {
    if (!std::isfinite(s.steering) || !s.egomotion.isFinite()) {
      return refuse(report, Status::NonFiniteInput, CalibCondition::FiniteInput);
    }
    const Pose2d r = tricycleArc(params.driveScale * static_cast<double>(s.ticks), s.steering + offsetFor(s, params),
                                 params.wheelbase);
    const Complex w = 1.0 - std::polar(1.0, r.theta);
    const Complex rt(r.x, r.y);
    const Complex st(s.egomotion.x, s.egomotion.y);
    a += std::norm(w);
    css += std::norm(st);
    pSum += std::conj(w) * rt;
    qSum += std::conj(w) * st;
    srSum += std::conj(st) * rt;
    rotation = rotation || std::fabs(std::sin(0.5 * s.egomotion.theta)) >= minHalfSin;
    translation = translation || std::abs(st) >= opt.minTranslation;
  }
  report.laserRotationObserved = rotation;
  report.laserTranslationObserved = translation;
  if (!rotation || !(a > 0.0)) {
    return refuse(report, Status::Unobservable, CalibCondition::LaserRotation);
  }
  if (!translation) {
    return refuse(report, Status::Unobservable, CalibCondition::LaserTranslation);
  }
  // Condition of the Hermitian normal matrix [[a, Q], [conj(Q), css]] of the unknowns (l, u).
  {
    const double mean = 0.5 * (a + css);
    const double half = 0.5 * (a - css);
    const double rad = std::sqrt(half * half + std::norm(qSum));
    const double lo = mean - rad;
    report.conditionLaser = lo > 0.0 ? (mean + rad) / lo : std::numeric_limits<double>::infinity();
  }
  // Eliminating l = (P - u Q) / a leaves cost(u) = const - 2 Re(conj(u) H) on |u| = 1, with
  // H = sum conj(s) r - conj(Q) P / a: stationary points u = +-H/|H|. Keep the cheaper one.
  const Complex h = srSum - std::conj(qSum) * pSum / a;
  const double hNorm = std::abs(h);
  if (!(hNorm > 0.0) || !std::isfinite(hNorm)) {
    return refuse(report, Status::Unobservable, CalibCondition::LaserTranslation);
  }
  if (!(report.conditionLaser <= opt.maxConditionNumber)) {
    return refuse(report, Status::IllConditioned, CalibCondition::LaserConditioning);
  }
  Complex best{};
  double bestCost = std::numeric_limits<double>::infinity();
  Complex bestL{};
  for (int sign = 1; sign >= -1; sign -= 2) {
    const Complex u = (static_cast<double>(sign) / hNorm) * h;
    const Complex l = (pSum - u * qSum) / a;
    double cost = 0.0;
    for (const CalibSegment& s : segments) {
      const Pose2d r = tricycleArc(params.driveScale * static_cast<double>(s.ticks), s.steering + offsetFor(s, params),
                                   params.wheelbase);
      const Complex e =
          (1.0 - std::polar(1.0, r.theta)) * l + u * Complex(s.egomotion.x, s.egomotion.y) - Complex(r.x, r.y);
      cost += std::norm(e);
    }
    if (cost < bestCost) {
      bestCost = cost;
      best = u;
      bestL = l;
    }
  }
  laserPose = Pose2d{bestL.real(), bestL.imag(), std::arg(best)};
  report.translationRms = segments.empty() ? 0.0 : std::sqrt(bestCost / static_cast<double>(segments.size()));
  return Status::Ok;
}

namespace {

/// The odometry closed form of `model` into `p` (wheelbase from the options): STC solves the 2x2
/// normal equations of all segments, ATC the equal-norm quadratic program of the forward and
/// backward blocks. False when the solve fails.
bool solveOdometry(Span<const CalibSegment> segments, CalibModel model, const CalibrationOptions& options,
                   TricycleParams& p, CalibrationReport& report) noexcept {
  p.wheelbase = options.nominal.wheelbase;
  if (model == CalibModel::Stc) {
    Eigen::Matrix2d m;
    Eigen::Vector2d g;
    rotationNormalEquations(segments, Dir::All, options, m, g);
    const double det = m(0, 0) * m(1, 1) - m(0, 1) * m(1, 0);
    // J = (s_w / L) (cos alpha, sin alpha) = M^-1 g (2x2 inverse by cofactors).
    const Eigen::Vector2d j((m(1, 1) * g(0) - m(0, 1) * g(1)) / det, (m(0, 0) * g(1) - m(1, 0) * g(0)) / det);
    p.driveScale = p.wheelbase * j.norm();
    p.steerOffsetForward = std::atan2(j(1), j(0));
    p.steerOffsetBackward = p.steerOffsetForward;
    return true;
  }
  Eigen::Matrix2d mf;
  Eigen::Vector2d gf;
  Eigen::Matrix2d mb;
  Eigen::Vector2d gb;
  rotationNormalEquations(segments, Dir::Forward, options, mf, gf);
  rotationNormalEquations(segments, Dir::Backward, options, mb, gb);
  // min ||A_F psi_F - theta_F||^2 + ||A_B psi_B - theta_B||^2  s.t.  |psi_F|^2 - |psi_B|^2 = 0.
  // Stationarity: (M_F + lambda) psi_F = g_F, (M_B - lambda) psi_B = g_B; the minimiser has both
  // matrices positive semi-definite, i.e. lambda in [A, B], A = -min eig M_F, B = min eig M_B.
  EqualNormFit fit;
  if (solveEqualNormFit(mf, gf, mb, gb, fit) != Status::Ok) {
    return false;
  }
  report.lambda = fit.lambda;
  p.driveScale = 0.5 * p.wheelbase * (fit.psiF.norm() + fit.psiB.norm());
  p.steerOffsetForward = std::atan2(fit.psiF(1), fit.psiF(0));
  p.steerOffsetBackward = std::atan2(fit.psiB(1), fit.psiB(0));
  return true;
}

/// Observability, odometry closed form of `model`, then the laser pose: the common path of the
/// STC and ATC solves.
Status calibrate(Span<const CalibSegment> segments, CalibModel model, const CalibrationOptions& options,
                 CalibrationResult& result) noexcept {
  result = CalibrationResult{};
  CalibrationReport& report = result.report;
  const Status obs = checkCalibrationObservability(segments, model, options, report);
  if (obs != Status::Ok) {
    return obs;
  }
  TricycleParams& p = result.params;
  if (!solveOdometry(segments, model, options, p, report) || !std::isfinite(p.driveScale) || !(p.driveScale > 0.0) ||
      !std::isfinite(p.steerOffsetForward) || !std::isfinite(p.steerOffsetBackward)) {
    return refuse(report, Status::Unobservable, CalibCondition::PositiveScale);
  }
  report.rotationRms = rotationRms(segments, p, options);
  const Status laser = estimateLaserPose(segments, p, options, result.laserPose, report);
  report.status = laser;
  return laser;
}

}  // namespace

Status calibrateStc(Span<const CalibSegment> segments, const CalibrationOptions& options,
                    CalibrationResult& result) noexcept {
  return calibrate(segments, CalibModel::Stc, options, result);
}

Status calibrateAtc(Span<const CalibSegment> segments, const CalibrationOptions& options,
                    CalibrationResult& result) noexcept {
  return calibrate(segments, CalibModel::Atc, options, result);
}

}  // namespace agv
