#pragma once
/// @file calibration_routine.hpp
/// The on-vehicle calibration routine run against the simulated vehicle: drives half-circle
/// segments at several steering angles forward and backward through `hal::DriveControl`, cuts
/// the encoder stream into segments (`CalibSegmentBuilder`), measures the laser egomotion of each
/// segment from the reflectors seen at its two standstills (`alignReflectors`), and solves the
/// ATC closed form (`calibrateAtc`).

#include <cstdint>
#include <string>

#include "agv/calib/calibration.hpp"
#include "agv/sim/ray_caster.hpp"
#include "scenario.hpp"

namespace agv::hil {

/// Plan of the routine.
struct CalibrationPlan {
  Pose2d home{10.0, 12.5, 0.0};  ///< start pose in the built-in warehouse's open area
  double steeringDeg[8] = {18.0, 26.0, 34.0, 42.0, 50.0, 0.0, 0.0, 0.0};  ///< |steering| set, both signs
  int steeringCount = 5;
  double speed = 0.5;                            ///< [m/s]
  double rotation = kPi<double>;                 ///< beta: rotation of each segment (nominal) [rad]
  Duration settle = Duration::fromSeconds(1.5);  ///< standstill before each observation
};

/// What the routine did and found.
struct CalibrationOutcome {
  Status status = Status::NotInitialized;  ///< of the solve (or of the data collection)
  std::string message;                     ///< the failure reason in words (empty on success)
  CalibrationResult result;                ///< estimate + observability report
  int segmentsDriven = 0;
  int segmentsUsed = 0;      ///< closed by the builder and aligned
  int segmentsRejected = 0;  ///< rejected by the segment builder or without a reflector alignment
  double simSeconds = 0.0;
  double meanAlignmentRms = 0.0;  ///< [m] reflector alignment residual
  sim::CanBusCounters can;        ///< the encoder frames of the routine
};

/// Runs the routine in `world` (through `caster`) with the vehicle and laser of `config`; the
/// solve starts from `config.nominal`.
CalibrationOutcome runCalibration(const sim::RayCaster& caster, const ScenarioConfig& config,
                                  const CalibrationPlan& plan);

}  // namespace agv::hil
