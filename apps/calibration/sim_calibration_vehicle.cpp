#include "sim_calibration_vehicle.hpp"

namespace agv::calibration {

SimCalibrationVehicle::SimCalibrationVehicle(const sim::RayCaster& caster, const sim::SimVehicleParams& vehicle,
                                             const sim::SimLaserParams& laser, std::uint64_t seed, const Pose2d& start)
    : vehicle_(vehicle, seed * 7919U + 17U), laser_(caster, laser, seed * 104729U + 3U) {
  vehicle_.reset(start, Timestamp{});
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
