#pragma once
/// @file hall_scans.hpp
/// Calibration scans from the simulator's calibration hall (drivers/sim calibration_hall.hpp) in
/// the form `calibrateIntrinsics` takes, and the comparison of a result with the simulated truth.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "agv/lidar3d/laser_intrinsics.hpp"
#include "agv/lidar_calibration/intrinsic_calibration.hpp"
#include "agv/sim/calibration_hall.hpp"

namespace agv::lidar_calibration {

/// The simulated protocol.
struct HallScansConfig {
  sim::CalibrationHallConfig hall;
  std::vector<sim::HallPlacement> placements = sim::hallProtocol();  ///< 9 distances x 5 tilts
  sim::ModelSensorConfig sensor;
  std::uint64_t seed = 1;  ///< noise stream
};

/// One revolution per placement with `truth` as the sensor's intrinsics; `surfaces` (optional)
/// receives per scan what each return hit (`targetSurface` of the hall = the target).
std::vector<CalibrationScan> simulateHallScans(const HallScansConfig& config, const LaserIntrinsics& truth,
                                               std::vector<std::vector<int>>* surfaces = nullptr);

/// Errors of a result against the truth, per laser (estimate - truth), with the held common
/// offsets (the mean alpha error over the estimated lasers; the mean theta error when
/// `holdMeanTheta`; the common z shift D_corr += c sin(theta), V_o += c cos(theta) when both are
/// estimated) removed first: the calibration fixes them at the start values by constraint.
struct TruthComparison {
  std::vector<Eigen::Matrix<double, kLaserParamCount, 1>> error;  ///< per laser (zero for held lasers)
  Eigen::Matrix<double, kLaserParamCount, 1> maxAbs = Eigen::Matrix<double, kLaserParamCount, 1>::Zero();
  Eigen::Matrix<double, kLaserParamCount, 1> rms = Eigen::Matrix<double, kLaserParamCount, 1>::Zero();
  Eigen::Matrix<double, kLaserParamCount, 1> maxAbsStart =
      Eigen::Matrix<double, kLaserParamCount, 1>::Zero();     ///< start - truth, same gauge
  double commonAlpha = 0.0;                                   ///< [rad] removed gauge offset
  double commonTheta = 0.0;                                   ///< [rad] removed near-gauge offset
  double commonZ = 0.0;                                       ///< [m] removed common z shift (D_corr and V_o estimated)
  double maxSigmaRatio = 0.0;                                 ///< largest |error| / sigma over the estimated parameters
  std::size_t beyondThreeSigma = 0;                           ///< estimated parameters with |error| > 3 sigma
  std::size_t compared = 0;                                   ///< estimated parameters compared
  std::array<std::size_t, kLaserParamCount> beyondByParam{};  ///< the same per parameter kind
  std::array<std::size_t, kLaserParamCount> comparedByParam{};  ///< the same per parameter kind
};

/// Compares `result` with `truth` (estimated lasers only).
TruthComparison compareWithTruth(const IntrinsicCalibrationResult& result, const LaserIntrinsics& truth,
                                 const IntrinsicCalibrationConfig& config);

}  // namespace agv::lidar_calibration
