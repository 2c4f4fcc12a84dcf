#pragma once
/// @file vehicle_navigation.hpp
/// agvnav-vehicle's navigation: the one pipeline (`agv::nav::Pipeline`, apps/lib/navigation) set up
/// from the vehicle's configuration, calibration and map files, on devices owned by the caller.
///
/// `VehicleRuntime` (vehicle_runtime.hpp) owns the real devices with the Modbus PLC link and cycles
/// this; it needs no libmodbus itself, so a test can link it statically and give it any PLC link
/// (the vcan VM test does).

#include <memory>
#include <string>
#include <vector>

#include "agv/calib/calibration_file.hpp"
#include "agv/drivers/linux/canopen_encoder_source.hpp"
#include "agv/nav/pipeline.hpp"
#include "vehicle_config.hpp"

namespace agv::vehicle {

/// The loaded calibration and map, checked (see `loadVehicleFiles`).
struct VehicleFiles {
  VehicleCalibration calibration{};
  std::unique_ptr<LandmarkMap> map;
  /// What the program should log about files it accepted: one line per file of format version 1
  /// (no `end` line, so a cut cannot be detected), naming the file and how to convert it.
  std::vector<std::string> warnings;
};

/// Reads the calibration file and the map file named by `config`. False with `error` naming the
/// file, the line and the key (or the landmark field) when one cannot be read or is refused: a
/// version-2 file cut short (no `end <count>` line, or cut inside a line) names the line where the
/// text ends. Files of format version 1 are accepted with a warning in `files.warnings`.
bool loadVehicleFiles(const VehicleConfig& config, VehicleFiles& files, ConfigError& error);

/// The encoder source's configuration from `config`, with the interface name pointing into
/// `config.canInterface` (the source copies it: `config` only has to outlive the constructor call).
drivers::CanopenEncoderSourceConfig encoderSourceConfig(const VehicleConfig& config);

/// The pipeline's parameters from the configuration and the calibration: the calibrated
/// kinematics and laser pose, the laser model's range and field of view, reflectors when the laser
/// reports them, FALKO corners when `localization.corners` is on, `loop.publish_period`.
nav::PipelineParams pipelineParams(const VehicleConfig& config, const VehicleCalibration& calibration);

/// A `nav::PipelineLogSink` printing "agvnav-vehicle: <line>" on stderr.
void logToStderr(void* context, const char* line);

/// The pipeline with its map, configured and active; the configured initial pose (if any) is
/// applied in the first cycle. Allocates in the constructor only.
class VehicleNavigation {
 public:
  VehicleNavigation(const VehicleConfig& config, VehicleFiles&& files, const nav::PipelineDevices& devices);
  nav::Pipeline& pipeline() noexcept { return *pipeline_; }
  const nav::Pipeline& pipeline() const noexcept { return *pipeline_; }
  /// The calibration the pipeline runs with.
  const VehicleCalibration& calibration() const noexcept { return calibration_; }
  /// `Ok`, or why the pipeline refused its configuration (it then publishes nothing).
  Status status() const noexcept { return status_; }

 private:
  VehicleCalibration calibration_;
  std::unique_ptr<LandmarkMap> map_;
  std::unique_ptr<nav::Pipeline> pipeline_;
  Status status_ = Status::NotInitialized;
};

}  // namespace agv::vehicle
