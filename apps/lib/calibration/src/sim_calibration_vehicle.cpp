#include "agv/calibration/sim_calibration_vehicle.hpp"

namespace agv::calibration {

SimCalibrationVehicle::SimCalibrationVehicle(const sim::RayCaster& caster, const sim::SimVehicleParams& vehicle,
                                             const sim::SimLaserParams& laser, std::uint64_t seed, const Pose2d& start,
                                             const sim::SimCanEncodersParams* can)
    : vehicle_(vehicle, seed * 7919U + 17U), laser_(caster, laser, seed * 104729U + 3U) {
  vehicle_.reset(start, Timestamp{});
  if (can != nullptr) {
    can_ = std::make_unique<sim::CanEncoderSource>(vehicle_, *can);
  }
}

Status SimCalibrationVehicle::status() const noexcept {
  if (laser_.status() != Status::Ok) {
    return laser_.status();
  }
  return can_ ? can_->validate() : Status::Ok;
}

sim::CanBusCounters SimCalibrationVehicle::canCounters() const noexcept {
  return can_ ? can_->counters() : sim::CanBusCounters{};
}

hal::EncoderSource& SimCalibrationVehicle::encoders() {
  if (can_) {
    return *can_;
  }
  return vehicle_;
}

void SimCalibrationVehicle::wait(Duration period) {
  const Timestamp until = vehicle_.now() + period;
  vehicle_.advanceTo(until);
  if (laser_.status() != Status::Ok) {
    return;
  }
  while (nextSweep_ <= until) {
    if (vehicle_.isStandstill()) {
      const Pose2d pose = vehicle_.trueLaserPose();
      static_cast<void>(laser_.capture(pose, pose, nextSweep_));
    }
    nextSweep_ = nextSweep_ + laser_.period();
  }
}

}  // namespace agv::calibration
