#pragma once
// Start-up of agvnav-vehicle for in-process tests (tests/vehicle, and the vcan VM test of the loop):
// the test configuration, calibration and map written into a folder and loaded as the program does.
#include <string>

#include "vehicle_files.hpp"
#include "vehicle_navigation.hpp"

namespace agv::test {

/// Writes `configText` as vehicle.conf, `goodCalibration()` as calibration.txt and `mapText`
/// (default `goodMap()`) as landmarks.txt into `dir`, then loads them with `loadVehicleConfig` and
/// `loadVehicleFiles`. False with `error` filled when one is refused.
inline bool loadTestVehicle(TempFolder& dir, const std::string& configText, vehicle::VehicleConfig& config,
                            vehicle::VehicleFiles& files, vehicle::ConfigError& error,
                            const std::string& mapText = goodMap()) {
  const std::string conf = dir.write("vehicle.conf", configText);
  dir.write("calibration.txt", goodCalibration());
  dir.write("landmarks.txt", mapText);
  return vehicle::loadVehicleConfig(conf, config, error) && vehicle::loadVehicleFiles(config, files, error);
}

}  // namespace agv::test
