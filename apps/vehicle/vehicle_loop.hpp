#pragma once
/// @file vehicle_loop.hpp
/// One cycle of the vehicle's navigation, on devices owned by the caller: CANopen encoders ->
/// tricycle odometry -> EKF prediction; SICK laser -> reflectors (NAV350) and/or FALKO corners ->
/// EKF correction against the landmark map; pose, covariance and health -> any `hal::PlcLink`;
/// PLC commands (localize from a set-pose, stop) -> localizer.
///
/// `VehicleRuntime` (vehicle_runtime.hpp) owns the real devices with the Modbus PLC link and runs
/// this loop; the loop itself needs no libmodbus, so a test can link it statically and give it any
/// PLC link (the vcan VM test does).
///
/// Everything is allocated by the constructor; `cycle()` does not allocate. Not thread-safe.

#include <cstdint>
#include <memory>

#include "agv/calib/calibration_file.hpp"
#include "agv/drivers/linux/canopen_encoder_source.hpp"
#include "agv/drivers/linux/sick_laser_source.hpp"
#include "agv/hal/plc_link.hpp"
#include "vehicle_config.hpp"

namespace agv::vehicle {

/// The loaded calibration and map, checked (see `loadVehicleFiles`).
struct VehicleFiles {
  VehicleCalibration calibration{};
  std::unique_ptr<LandmarkMap> map;
};

/// Reads the calibration file and the map file named by `config`. False with `error` naming the
/// file, the line and the key (or the landmark field) when one cannot be read or is refused.
bool loadVehicleFiles(const VehicleConfig& config, VehicleFiles& files, ConfigError& error);

/// The encoder source's configuration from `config`, with the interface name pointing into
/// `config.canInterface` (the source copies it: `config` only has to outlive the constructor call).
drivers::CanopenEncoderSourceConfig encoderSourceConfig(const VehicleConfig& config);

/// Counters of one run, printed at the end.
struct RuntimeCounters {
  std::uint64_t cycles = 0;
  std::uint64_t encoderSamples = 0;
  std::uint64_t sweeps = 0;
  std::uint64_t corrections = 0;
  std::uint64_t publications = 0;
  std::uint64_t commands = 0;         ///< PLC commands read
  std::uint64_t refusedCommands = 0;  ///< of which not carried out (Calibrate)
};

/// The devices the loop reads and publishes to; the caller owns them, opens them and keeps them
/// alive as long as the loop.
struct VehicleDevices {
  drivers::CanopenEncoderSource& encoders;
  drivers::SickLaserSource& laser;
  /// Receives a `hal::PoseReport` every `loop.publish_period`. The health bits of the status
  /// block (`plc::PlcHealthBit`, not part of the report) are `VehicleLoop::healthBits()`, set
  /// before each `publish()`.
  hal::PlcLink& plc;
};

class VehicleLoop {
 public:
  /// Builds the odometry, the localizer and the detector (allocates here, once).
  /// `config.initialPose`, when given, is applied in the first cycle.
  VehicleLoop(const VehicleConfig& config, VehicleFiles&& files, const VehicleDevices& devices);
  ~VehicleLoop();
  VehicleLoop(const VehicleLoop&) = delete;
  VehicleLoop& operator=(const VehicleLoop&) = delete;

  /// One cycle: reads the encoders (up to 32 samples) and the PLC commands, reads a laser sweep
  /// and corrects with it, publishes when due. Never sleeps or blocks; does not allocate.
  void cycle() noexcept;

  const RuntimeCounters& counters() const noexcept;
  /// `plc::PlcHealthBit` bits of the last (or the current) publication.
  std::uint16_t healthBits() const noexcept;
  /// The calibration the loop runs with.
  const VehicleCalibration& calibration() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace agv::vehicle
