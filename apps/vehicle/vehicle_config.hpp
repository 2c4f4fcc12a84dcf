#pragma once
/// @file vehicle_config.hpp
/// The configuration file of `agvnav-vehicle` (format and keys in docs/vehicle.md): one
/// `key = value` per line, `#` comments, every key checked for its type and range. A bad file is
/// refused with a message naming the file, the line and the key.
///
/// Start-up code: it may allocate (strings); nothing here runs in the vehicle loop.

#include <cstdint>
#include <string>

#include "agv/calibration/calibration_routine.hpp"
#include "agv/core/pose2.hpp"
#include "agv/drivers/linux/canopen_encoder_source.hpp"
#include "agv/drivers/linux/modbus_plc_link.hpp"
#include "agv/drivers/linux/sick_laser_source.hpp"
#include "agv/drivers/protocol/canopen/cia402_drive.hpp"
#include "agv/localization/landmark_map.hpp"

namespace agv::vehicle {

/// Everything `agvnav-vehicle` needs to run, from the configuration file.
struct VehicleConfig {
  std::string canInterface;  ///< can.interface
  drivers::CanopenEncoderSourceConfig can;
  drivers::SickLaserSourceConfig laser;
  drivers::ModbusPlcLinkConfig modbus;
  std::string calibrationFile;  ///< calibration.file (relative paths: to the configuration file's folder)
  std::string mapFile;          ///< map.file (same)
  MapMode mapMode = MapMode::Static;
  bool useCorners = false;  ///< localization.corners: FALKO corners as observations too
  /// localization.surface_map: scan matching against the surfaces of the earlier sweeps (map-less
  /// natural navigation from the set-pose, `nav::ObservationParams::surfaceMap`)
  bool useSurfaceMap = false;
  bool relocalize = true;  ///< localization.relocalize: search the map when lost or without a set-pose
  bool haveInitialPose = false;
  Pose2d initialPose{};                                     ///< localization.initial_pose
  Duration cyclePeriod = Duration::fromMilliseconds(2);     ///< loop.period
  Duration publishPeriod = Duration::fromMilliseconds(20);  ///< loop.publish_period
  /// drives.*: the CiA 402 traction and steering drives on `canInterface` (docs/drives.md), which
  /// the calibration routine commands. Without them the PLC's Calibrate is refused.
  bool drivesEnabled = false;  ///< drives.enabled
  drivers::canopen::Cia402DriveConfig drives;
  /// calibration.*: the routine on the PLC's Calibrate (docs/vehicle.md, "Calibration on the
  /// PLC's request"): the free area, the plan's shape, the speed; `start` is the pose at the
  /// request. Without `calibration.area` the PLC's Calibrate is refused.
  bool calibrationAreaSet = false;
  calibration::PlanRequest calibrationPlan;
  double calibrationSpeed = 0.5;  ///< calibration.speed [m/s]
  calibration::EgomotionSource calibrationEgomotion = calibration::EgomotionSource::Reflectors;
};

/// Why a configuration was refused: `where` is "file:line" (or the file alone), `key` the key
/// concerned (empty when none), `message` what is wrong. `text()` joins them for the user.
struct ConfigError {
  std::string where;
  std::string key;
  std::string message;
  std::string text() const;
};

/// Parses the configuration text `text` read from `path` (used in messages and to resolve
/// relative file paths). True on success; false with `error` filled.
bool parseVehicleConfig(const std::string& text, const std::string& path, VehicleConfig& out, ConfigError& error);

/// Reads and parses the file `path`. A missing or unreadable file is an error too.
bool loadVehicleConfig(const std::string& path, VehicleConfig& out, ConfigError& error);

}  // namespace agv::vehicle
