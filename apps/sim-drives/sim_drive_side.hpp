#pragma once
/// @file sim_drive_side.hpp
/// The simulated vehicle's side of the CAN bus, shared by `agvnav-sim-drives --vehicle`,
/// vehicle.calibration (in-process) and the vcan VM's calibration cases: the CiA 406 steering
/// encoder (node 2) and the motors of the simulated CiA 402 drives moving the simulated tricycle.
#include <cmath>
#include <cstdint>

#include "agv/core/angle.hpp"
#include "agv/drivers/protocol/can_frame.hpp"
#include "agv/drivers/protocol/canopen/cia402_drive.hpp"
#include "agv/hal/drive_command.hpp"
#include "agv/hal/encoder_source.hpp"
#include "agv/sim/sim_cia402_node.hpp"

namespace agv::simdrives {

/// Steering encoder resolution: 14 bits per turn.
inline constexpr double kSteerEncoderRadPerCount = 2.0 * kPi<double> / 16384.0;

/// The steering encoder's frames at `now` for the measured `angle`: its heartbeat (0x702,
/// operational) and TPDO1 (0x182, the angle in counts, 4 bytes little-endian).
inline void steeringEncoderFrames(double angle, Timestamp now, drivers::CanFrame (&out)[2]) {
  out[0] = drivers::CanFrame{};
  out[0].id = 0x702;
  out[0].dlc = 1;
  out[0].data[0] = 0x05;
  out[0].stamp = now;
  out[1] = drivers::CanFrame{};
  out[1].id = 0x182;
  out[1].dlc = 4;
  const auto counts = static_cast<std::int32_t>(std::lround(angle / kSteerEncoderRadPerCount));
  for (unsigned b = 0; b < 4U; ++b) {
    out[1].data[b] = static_cast<std::uint8_t>((static_cast<std::uint32_t>(counts) >> (8U * b)) & 0xFFU);
  }
  out[1].stamp = now;
}

/// Drains `wheel` (the simulated vehicle's own encoder measurements), keeping the newest counts in
/// `ticks` and angle in `steer`, and gives the counts to `traction` as its position actual value.
inline void feedWheel(hal::EncoderSource& wheel, sim::SimCia402Node& traction, std::int64_t& ticks, double& steer) {
  hal::EncoderSample m;
  while (wheel.read(m) == Status::Ok) {
    ticks = m.driveTicks;
    steer = m.steeringAngle;
  }
  traction.setPositionFeedback(static_cast<std::int32_t>(ticks));
}

/// What the motors do to the vehicle: the traction node's velocity [counts/s] times the wheel's
/// true metres per count, and the steering node's position as an angle.
inline hal::DriveCommand motorsToVehicle(const sim::SimCia402Node& traction, const sim::SimCia402Node& steering,
                                         const drivers::canopen::Cia402DriveConfig& d, double trueDriveScale,
                                         Timestamp now) {
  const double steer = (steering.position() - d.steering.zeroCount) / d.steering.countsPerRadian;
  return hal::DriveCommand{now, traction.velocity() * trueDriveScale, steer};
}

}  // namespace agv::simdrives
