#include "agv/sim/sim_laser.hpp"

#include <algorithm>
#include <cmath>

namespace agv::sim {

Status SimLaserParams::validate() const noexcept {
  const double v[] = {fieldOfView, angularResolution,    scanRate,         rangeNoiseStdDev, rangeMin,
                      rangeMax,    reflectorNoiseStdDev, reflectorMaxRange};
  for (double x : v) {
    if (!std::isfinite(x)) {
      return Status::NonFiniteInput;
    }
  }
  if (fieldOfView <= 0.0 || fieldOfView > kTwoPi<double> + 1e-9 || angularResolution <= 0.0 || scanRate <= 0.0 ||
      rangeNoiseStdDev < 0.0 || rangeMin < 0.0 || rangeMax <= rangeMin || reflectorNoiseStdDev < 0.0 ||
      reflectorMaxRange <= 0.0) {
    return Status::InvalidArgument;
  }
  const double r = static_cast<double>(noReturnValue);
  if (std::isfinite(r) && r >= rangeMin && r < rangeMax) {
    return Status::InvalidArgument;  // a no-return must not look like a valid reading
  }
  const std::size_t n = beamCount();
  if (n < 2) {
    return Status::InvalidArgument;
  }
  if (n > kMaxScanBeams) {
    return Status::CapacityExceeded;
  }
  return Status::Ok;
}

std::size_t SimLaserParams::beamCount() const noexcept {
  if (!(angularResolution > 0.0) || !(fieldOfView > 0.0)) {
    return 0;
  }
  const double n = std::round(fieldOfView / angularResolution);
  return n < 1e7 ? static_cast<std::size_t>(n) : 0U;
}

SimLaser::SimLaser(const RayCaster& caster, const SimLaserParams& params, std::uint64_t seed)
    : caster_(&caster), params_(params), status_(params.validate()), rng_(seed) {}

Duration SimLaser::period() const noexcept {
  return Duration::fromSeconds(1.0 / params_.scanRate);
}

Duration SimLaser::sweepDuration() const noexcept {
  const double n = static_cast<double>(params_.beamCount());
  // One revolution per period; the beams of the field of view take their share of it.
  return Duration::fromSeconds(params_.fieldOfView / kTwoPi<double> * (n - 1.0) / n / params_.scanRate);
}

Pose2d SimLaser::poseAt(const Pose2d& a, const Pose2d& b, double f) const noexcept {
  return Pose2d{a.x + f * (b.x - a.x), a.y + f * (b.y - a.y),
                normalizeAngle(a.theta + f * angleDiff(b.theta, a.theta))};
}

Status SimLaser::scan(const Pose2d& poseFirstBeam, const Pose2d& poseLastBeam, Timestamp stamp,
                      hal::LaserMeasurement& out) noexcept {
  if (status_ != Status::Ok) {
    return status_;
  }
  if (!poseFirstBeam.isFinite() || !poseLastBeam.isFinite()) {
    return Status::NonFiniteInput;
  }
  const std::size_t n = params_.beamCount();
  const double inc = params_.fieldOfView / static_cast<double>(n);
  const double angleMin = -0.5 * params_.fieldOfView;
  LaserScan& s = out.scan;
  s.stamp = stamp;
  s.sweepDuration = sweepDuration();
  s.angleMin = static_cast<float>(angleMin);
  s.angleIncrement = static_cast<float>(inc);
  s.rangeMin = static_cast<float>(params_.rangeMin);
  s.rangeMax = static_cast<float>(params_.rangeMax);
  s.ranges.clear();
  const double denom = n > 1 ? static_cast<double>(n - 1) : 1.0;
  // poseAt() per beam, the heading difference taken once per sweep (the same values: the
  // reduction to [-pi, pi] is the identity inside it, so it is applied only outside).
  const Pose2d& a0 = poseFirstBeam;
  const Pose2d& a1 = poseLastBeam;
  const double turn = angleDiff(a1.theta, a0.theta);
  for (std::size_t i = 0; i < n; ++i) {
    const double f = static_cast<double>(i) / denom;
    double theta = a0.theta + f * turn;
    if (!(std::fabs(theta) < kPi<double>)) {
      theta = normalizeAngle(theta);
    }
    const Point2 origin{a0.x + f * (a1.x - a0.x), a0.y + f * (a1.y - a0.y)};
    const double a = theta + angleMin + static_cast<double>(i) * inc;
    const RayHit hit = caster_->cast(origin, a, params_.rangeMax + 5.0 * params_.rangeNoiseStdDev);
    float value = params_.noReturnValue;
    if (hit.hit) {
      const double r = hit.range + params_.rangeNoiseStdDev * normal_(rng_);
      if (r >= params_.rangeMin && r < params_.rangeMax) {
        value = static_cast<float>(r);
      }
    }
    static_cast<void>(s.ranges.push_back(value));  // n <= kMaxScanBeams by validate()
  }

  out.reflectors.clear();
  out.reflectors.resetRefusedCount();
  out.hasReflectors = params_.reportsReflectors;
  if (!params_.reportsReflectors) {
    return Status::Ok;
  }
  const World& w = caster_->world();
  for (std::size_t k = 0; k < w.circles.size(); ++k) {
    const Circle& c = w.circles[k];
    if (c.kind != ObstacleKind::Reflector) {
      continue;
    }
    // Pose when the beam sweeps over the reflector: bearing from the first-beam pose, refined once.
    Pose2d p = poseFirstBeam;
    double sweptAt = 0.0;  // fraction of the sweep
    for (int iter = 0; iter < 2; ++iter) {
      const Pose2d::Vector2 v = p.inverseTransformPoint(Pose2d::Vector2(c.centre.x, c.centre.y));
      sweptAt = std::clamp((std::atan2(v.y(), v.x()) - angleMin) / params_.fieldOfView, 0.0, 1.0);
      p = poseAt(poseFirstBeam, poseLastBeam, sweptAt);
    }
    const Pose2d::Vector2 v = p.inverseTransformPoint(Pose2d::Vector2(c.centre.x, c.centre.y));
    const double bearing = std::atan2(v.y(), v.x());
    if (std::fabs(bearing) > 0.5 * params_.fieldOfView) {
      continue;
    }
    const double dist = v.norm();
    if (dist - c.radius > params_.reflectorMaxRange || dist - c.radius < params_.rangeMin) {
      continue;
    }
    // Line of sight: the ray towards the centre must hit this pole first.
    const RayHit hit = caster_->cast(Point2{p.x, p.y}, p.theta + bearing, dist);
    if (!hit.hit || !hit.circle || hit.index != k) {
      continue;
    }
    hal::ReflectorObservation o;
    o.x = static_cast<float>(v.x() + params_.reflectorNoiseStdDev * normal_(rng_));
    o.y = static_cast<float>(v.y() + params_.reflectorNoiseStdDev * normal_(rng_));
    o.positionStdDev = static_cast<float>(params_.reflectorNoiseStdDev);
    if (params_.stampsReflectors) {  // the instant of the pose the reflector was seen from
      o.stamp = stamp + Duration::fromSeconds(sweptAt * sweepDuration().seconds());
      o.stamped = true;
    }
    static_cast<void>(out.reflectors.push_back(o));  // a full list counts the refusal
  }
  return Status::Ok;
}

Status SimLaser::capture(const Pose2d& poseFirstBeam, const Pose2d& poseLastBeam, Timestamp stamp) noexcept {
  const Status s = scan(poseFirstBeam, poseLastBeam, stamp, pending_);
  hasPending_ = s == Status::Ok;
  return s;
}

Status SimLaser::read(hal::LaserMeasurement& out) noexcept {
  if (!hasPending_) {
    return Status::NotFound;
  }
  out = pending_;
  hasPending_ = false;
  return Status::Ok;
}

}  // namespace agv::sim
