#pragma once
/// @file sim_calibration_vehicle.hpp
/// The simulated vehicle (drivers/sim) as a `CalibrationVehicle`: `wait` advances the simulation,
/// and the laser takes a sweep every laser period while the vehicle stands still (the routine uses
/// only standstill sweeps; sweeps while driving are not simulated to save time). With CAN
/// parameters the encoder samples reach the routine only as CAN frames decoded by the vehicle's
/// CANopen decoder (`sim::CanEncoderSource`), as on the real vehicle.

#include <cstdint>
#include <memory>

#include "agv/calibration/calibration_routine.hpp"
#include "agv/sim/can_encoder_source.hpp"
#include "agv/sim/ray_caster.hpp"
#include "agv/sim/sim_laser.hpp"
#include "agv/sim/sim_vehicle.hpp"

namespace agv::calibration {

class SimCalibrationVehicle final : public CalibrationVehicle {
 public:
  /// The vehicle starts at rest at `start` (logical point, world frame) at time 0. `caster` must
  /// outlive this object. `can`: the encoders' CAN bus (nullptr: samples straight from the
  /// simulated vehicle). Check `status()` for the laser and bus parameters.
  SimCalibrationVehicle(const sim::RayCaster& caster, const sim::SimVehicleParams& vehicle,
                        const sim::SimLaserParams& laser, std::uint64_t seed, const Pose2d& start,
                        const sim::SimCanEncodersParams* can = nullptr);

  /// Ok, or why the laser or CAN parameters were refused.
  Status status() const noexcept;
  /// Frames of the encoders' CAN bus so far (zero without CAN).
  sim::CanBusCounters canCounters() const noexcept;
  const sim::SimVehicle& vehicle() const noexcept { return vehicle_; }

  hal::DriveControl& drive() override { return vehicle_; }
  hal::EncoderSource& encoders() override;
  hal::LaserSource& laser() override { return laser_; }
  Timestamp now() override { return vehicle_.now(); }
  void wait(Duration period) override;

 private:
  sim::SimVehicle vehicle_;
  sim::SimLaser laser_;
  std::unique_ptr<sim::CanEncoderSource> can_;
  Timestamp nextSweep_{};
};

}  // namespace agv::calibration
