#pragma once
/// @file vehicle_runtime.hpp
/// The vehicle's navigation loop on the real drivers: CANopen encoders (SocketCAN) -> tricycle
/// odometry -> EKF prediction; SICK laser -> reflectors (NAV350) and/or FALKO corners -> EKF
/// correction against the landmark map; pose, covariance, health and calibration -> PLC link
/// (Modbus TCP); PLC commands (localize from a set-pose, stop) -> localizer.
///
/// Everything is allocated by `create()`; the loop itself does not allocate. Not thread-safe.

#include <csignal>
#include <cstdint>
#include <memory>
#include <string>

#include "agv/calib/calibration_file.hpp"
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

/// Counters of one run, printed at the end.
struct RuntimeCounters {
  std::uint64_t cycles = 0;
  std::uint64_t encoderSamples = 0;
  std::uint64_t sweeps = 0;
  std::uint64_t corrections = 0;
  std::uint64_t publications = 0;
  std::uint64_t commands = 0;
};

class VehicleRuntime {
 public:
  /// Builds the drivers and the localizer (allocates here, once).
  VehicleRuntime(const VehicleConfig& config, VehicleFiles&& files);
  ~VehicleRuntime();
  VehicleRuntime(const VehicleRuntime&) = delete;
  VehicleRuntime& operator=(const VehicleRuntime&) = delete;

  /// Opens the links. Only a PLC link that cannot be set up (a server port that cannot be bound)
  /// is fatal; a missing CAN interface or laser is reported in the health registers and retried.
  /// Returns false with a message in `error`.
  bool open(std::string& error);

  /// Runs cycles until `stop` becomes non-zero (set by a signal handler), then closes the links.
  void run(const volatile std::sig_atomic_t& stop);

  /// One cycle at most: reads encoders and laser, corrects, publishes when due (no sleep).
  void cycle();

  const RuntimeCounters& counters() const noexcept { return counters_; }
  /// PlcHealthBit bits of the last publication.
  std::uint16_t healthBits() const noexcept { return healthBits_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  RuntimeCounters counters_{};
  std::uint16_t healthBits_ = 0;
};

}  // namespace agv::vehicle
