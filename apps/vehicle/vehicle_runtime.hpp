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

#include "agv/drivers/linux/modbus_plc_link.hpp"
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
  ///
  /// One wait per cycle: after each cycle the loop waits in one `ppoll` on every device descriptor
  /// (CAN socket, laser connection, Modbus listener and connections) until the next cycle's
  /// absolute deadline on CLOCK_MONOTONIC (deadline += loop.period; a late cycle resynchronizes and
  /// is counted). Input before the deadline runs one extra cycle at once (at most one per period;
  /// the rest of the period is waited without descriptors), so a chatty peer costs at most a second
  /// cycle per period. The wait unblocks SIGINT and SIGTERM (ppoll's signal mask): a caller that
  /// blocks them before `run()` (main.cpp does) gets a race-free stop within one cycle.
  void run(const volatile std::sig_atomic_t& stop);

  /// Figures of the loop since `run()` started.
  struct LoopStats {
    std::uint64_t cycles = 0;
    std::uint64_t inputWakes = 0;     ///< waits ended by device input before the deadline
    std::uint64_t overruns = 0;       ///< cycles that ended past the next deadline
    std::int64_t longestCycleNs = 0;  ///< longest pipeline cycle (wait excluded)
  };
  const LoopStats& loopStats() const noexcept;
  /// The Modbus link's counters (connections, refusals, timeouts, evictions).
  const drivers::PlcLinkCounters& plcCounters() const noexcept;

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
