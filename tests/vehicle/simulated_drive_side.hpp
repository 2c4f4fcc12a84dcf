#pragma once
// The simulated vehicle's side of the CAN bus (apps/sim-drives/sim_drive_side.hpp), under the
// names the tests use.
#include "sim_drive_side.hpp"

namespace agv::test {
using simdrives::feedWheel;
using simdrives::kSteerEncoderRadPerCount;
using simdrives::motorsToVehicle;
using simdrives::steeringEncoderFrames;
}  // namespace agv::test
