#pragma once
/// @file scenario.hpp
/// The HIL scenario: the simulated vehicle drives the world's paths while the navigation side
/// (today: dead reckoning) estimates its pose; results per run with the trajectories for plots.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "agv/core/pose2.hpp"
#include "agv/kinematics/tricycle.hpp"
#include "agv/sim/sim_laser.hpp"
#include "agv/sim/sim_vehicle.hpp"
#include "agv/sim/world.hpp"

namespace agv::hil {

/// What a vehicle's navigation believes about it before calibration (drawing values).
struct NominalVehicle {
  TricycleParams kinematics{1.5, 1.0e-4, 0.0, 0.0};
  Pose2d laserMount{1.6, 0.0, 0.0};
};

/// Settings of one HIL session.
struct ScenarioConfig {
  int runsPerPath = 6;
  std::uint64_t seed = 1;
  sim::SimVehicleParams vehicle;  ///< the truth
  NominalVehicle nominal;         ///< what the estimators start from (drawing values)
  NominalVehicle estimate;        ///< what the navigation uses: the calibration result, else nominal
  sim::SimLaserParams laser;
  double startPositionStdDev = 0.01;  ///< [m] how precisely the vehicle is placed at a path start
  double startHeadingStdDev = 0.002;  ///< [rad]
  Duration controlPeriod = Duration::fromMilliseconds(20);
  double maxRunSeconds = 120.0;  ///< a run not finished by then is an error
};

/// One sample of a run's history (every control period).
struct TrajectorySample {
  double distance = 0.0;  ///< [m] travelled by the logical point
  Pose2d truth;
  Pose2d withTruth;     ///< dead reckoning with the true parameters
  Pose2d withNominal;   ///< dead reckoning with the nominal (uncalibrated) parameters
  Pose2d withEstimate;  ///< dead reckoning with the parameters the navigation has (calibrated)
};

/// Result of one run along one path.
struct RunResult {
  std::string path;
  int run = 0;
  bool finished = false;  ///< reached the end point and stopped
  double simSeconds = 0.0;
  double distance = 0.0;  ///< [m] logical-point travel
  Pose2d finalTruth;
  Pose2d finalWithTruth;
  Pose2d finalWithNominal;
  Pose2d finalWithEstimate;  ///< the last pose published to the PLC
  std::size_t plcReports = 0;
  std::size_t scans = 0;
  double meanReflectorsPerScan = 0.0;
  std::size_t minReflectorsPerScan = 0;
  double meanValidBeamFraction = 0.0;
  std::vector<TrajectorySample> history;
};

/// Runs `config.runsPerPath` runs on every path of `world`; `progress` is called after each run.
/// Returns false (with `error`) on a setup problem (no path, invalid laser parameters).
bool runScenario(const sim::World& world, const ScenarioConfig& config,
                 const std::function<void(const RunResult&, int index, int total)>& progress,
                 std::vector<RunResult>* results, std::string* error);

/// Position error [m] and absolute heading error [rad] of `estimate` against `truth`.
double positionError(const Pose2d& estimate, const Pose2d& truth) noexcept;
double headingError(const Pose2d& estimate, const Pose2d& truth) noexcept;

}  // namespace agv::hil
