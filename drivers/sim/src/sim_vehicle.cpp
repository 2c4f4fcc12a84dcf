#include "agv/sim/sim_vehicle.hpp"

#include <algorithm>
#include <cmath>

namespace agv::sim {

SimVehicle::SimVehicle(const SimVehicleParams& params, std::uint64_t seed) : params_(params), rng_(seed) {
  if (params_.substep.ns <= 0) {
    params_.substep = Duration::fromMilliseconds(1);
  }
  if (params_.encoderPeriod.ns <= 0) {
    params_.encoderPeriod = Duration::fromMilliseconds(10);
  }
}

void SimVehicle::reset(const Pose2d& pose, Timestamp t) noexcept {
  pose_ = pose.normalized();
  now_ = t;
  nextSample_ = t + params_.encoderPeriod;
  speed_ = 0.0;
  speedSet_ = 0.0;
  servoSet_ = servo_;
  queue_.clear();
}

Status SimVehicle::command(const hal::DriveCommand& cmd) noexcept {
  if (!std::isfinite(cmd.speed) || !std::isfinite(cmd.steeringAngle)) {
    return Status::NonFiniteInput;
  }
  if (std::fabs(cmd.speed) > params_.maxSpeed || std::fabs(cmd.steeringAngle) > params_.maxSteering) {
    return Status::InvalidArgument;
  }
  speedSet_ = cmd.speed;
  servoSet_ = cmd.steeringAngle;
  return Status::Ok;
}

Status SimVehicle::stop() noexcept {
  speedSet_ = 0.0;
  return Status::Ok;
}

bool SimVehicle::isStandstill() const noexcept {
  return std::fabs(speed_) < params_.standstillSpeed;
}

void SimVehicle::advanceTo(Timestamp t) noexcept {
  // Bounded: each pass advances by at least 1 ns and at most one sub-step.
  while (now_ < t) {
    Timestamp next = now_ + params_.substep;
    next = std::min(next, t);
    next = std::min(next, nextSample_);
    substep((next - now_).seconds());
    now_ = next;
    if (now_ >= nextSample_) {
      emitSample();
      nextSample_ = nextSample_ + params_.encoderPeriod;
    }
  }
}

void SimVehicle::substep(double dt) noexcept {
  // Servos: slew-limited towards their set-points.
  const double dv = std::clamp(speedSet_ - speed_, -params_.acceleration * dt, params_.acceleration * dt);
  const double v0 = speed_;
  speed_ += dv;
  const double da = std::clamp(servoSet_ - servo_, -params_.steeringRate * dt, params_.steeringRate * dt);
  const double a0 = servo_;
  servo_ += da;
  // Trapezoid over the sub-step for the wheel travel, midpoint for the steering.
  const double dsWheel = 0.5 * (v0 + speed_) * dt;
  if (dsWheel == 0.0) {
    return;
  }
  wheelTravel_ += dsWheel;
  if (da != 0.0) {
    backlashSide_ = da > 0.0 ? 1.0 : -1.0;
  }
  const double offset = dsWheel > 0.0 ? params_.truth.steerOffsetForward : params_.truth.steerOffsetBackward;
  double alpha = 0.5 * (a0 + servo_) + offset - 0.5 * params_.steerBacklash * backlashSide_;
  // Lateral slip: the wheel's travel lags its angle towards straight ahead.
  const double v = 0.5 * (v0 + speed_);
  const double lateral = v * v * std::sin(alpha) / params_.truth.wheelbase;
  alpha -= params_.turnSlip * lateral;
  // Traction slip against the acceleration along the travel.
  const double along = (dsWheel > 0.0 ? 1.0 : -1.0) * dv / dt;
  const double dsGround = dsWheel * (1.0 + params_.slipBias + params_.radiusChange - params_.accelSlip * along) +
                          params_.slipNoise * std::sqrt(std::fabs(dsWheel)) * normal_(rng_);
  odometer_ += std::fabs(dsGround);
  pose_ = pose_.compose(tricycleArc(dsGround, alpha, params_.truth.wheelbase));
}

void SimVehicle::emitSample() noexcept {
  hal::EncoderSample s;
  s.stamp = now_;
  s.driveTicks = static_cast<std::int64_t>(std::floor(wheelTravel_ / params_.truth.driveScale));
  const double quantum = kTwoPi<double> / std::exp2(params_.steerEncoderBits);
  const double measured = servo_ + params_.steerEncoderDrift + params_.steerNoiseStdDev * normal_(rng_);
  s.steeringAngle = std::round(measured / quantum) * quantum;
  if (queue_.size() >= params_.encoderQueue) {
    queue_.pop_front();
    ++dropped_;
  }
  queue_.push_back(s);
}

Status SimVehicle::read(hal::EncoderSample& out) noexcept {
  if (queue_.empty()) {
    return Status::NotFound;
  }
  out = queue_.front();
  queue_.pop_front();
  return Status::Ok;
}

}  // namespace agv::sim
