#pragma once
/// @file vehicle_runtime.hpp
/// The vehicle's navigation on the real drivers: owns the CANopen encoder source (SocketCAN), the
/// SICK laser source (TCP), the Modbus TCP PLC link and the monotonic clock, and cycles the
/// navigation pipeline (`VehicleNavigation`, vehicle_navigation.hpp) on them until a signal.
///
/// Everything is allocated by the constructor; the loop itself does not allocate. Not thread-safe.

#include <csignal>
#include <cstdint>
#include <memory>
#include <string>

#include "vehicle_navigation.hpp"

namespace agv::vehicle {

class VehicleRuntime {
 public:
  /// Builds the drivers and the loop (allocates here, once).
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

  const nav::PipelineCounters& counters() const noexcept;
  /// `hal::HealthBit` bits of the last publication.
  std::uint16_t healthBits() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace agv::vehicle
