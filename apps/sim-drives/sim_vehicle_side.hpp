#pragma once
/// @file sim_vehicle_side.hpp
/// `agvnav-sim-drives --vehicle`: the simulated tricycle (`sim::SimVehicle`) moved by the two
/// simulated drives' set-points, its wheel counts reported by the traction node, the steering
/// encoder (node 2) on the bus, and its NAV350 (`sim::SimLaser`) served on a TCP port of 127.0.0.1
/// speaking the binary CoLa `mNPOSGetData` request and reply that `agvnav-vehicle` polls with
/// `laser.model = nav350` (docs/drives.md, "agvnav-sim-drives --vehicle"). All in real time on the
/// caller's monotonic clock.

#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "agv/core/pose2.hpp"
#include "agv/core/span.hpp"
#include "agv/core/status.hpp"
#include "agv/core/timestamp.hpp"
#include "agv/drivers/linux/loopback_server.hpp"
#include "agv/drivers/protocol/can_frame.hpp"
#include "agv/drivers/protocol/canopen/cia402_drive.hpp"
#include "agv/sim/ray_caster.hpp"
#include "agv/sim/sim_laser.hpp"
#include "agv/sim/sim_vehicle.hpp"
#include "agv/sim/world.hpp"
#include "sim_drives.hpp"

namespace agv::simdrives {

/// A drive set-point given to the vehicle directly between two instants (a test aid for a run
/// without a CAN interface): `SPEED:STEER@FROM-TO`, m/s and degrees, seconds after the start.
struct DirectMove {
  double speed = 0.0;  ///< [m/s]
  double steer = 0.0;  ///< [rad]
  double from = 0.0;   ///< [s]
  double to = 0.0;     ///< [s]
};

/// Parses `SPEED:STEER@FROM-TO` (steer in degrees). False with `error` set when it does not parse.
bool parseDirectMove(const std::string& text, DirectMove& out, std::string& error);

struct SimVehicleSideOptions {
  std::string worldFile;                       ///< empty: the built-in warehouse (`sim::defaultWorldText`)
  Pose2d start{10.0, 12.5, 0.0};               ///< logical point at power-on, world frame
  std::uint16_t laserPort = 2112;              ///< 0: an ephemeral port (printed)
  double laserResolutionDeg = 1.0;             ///< beam spacing of the simulated NAV350
  double laserRate = 8.0;                      ///< [Hz] sweeps per second (a NAV350 turns at 8 Hz)
  std::uint64_t seed = 1;                      ///< noise of the vehicle and the laser
  drivers::canopen::Cia402DriveConfig drives;  ///< the steering axis' scaling (as agvnav-vehicle's)
  std::vector<DirectMove> moves;
};

/// See the file comment. Construct, check `status()`, then call `step()` from the program's loop.
class SimVehicleSide {
 public:
  SimVehicleSide(const SimVehicleSideOptions& options, Timestamp now, std::FILE* log);
  ~SimVehicleSide();
  SimVehicleSide(const SimVehicleSide&) = delete;
  SimVehicleSide& operator=(const SimVehicleSide&) = delete;

  /// Ok, or why the world, the laser or the port was refused (`error()` says more).
  Status status() const noexcept { return status_; }
  const std::string& error() const noexcept { return error_; }
  /// The laser's TCP port on 127.0.0.1.
  std::uint16_t laserPort() const noexcept { return server_ ? server_->port() : 0; }

  /// Every 10 ms of `now`: the vehicle integrated to `now`, its wheel counts given to the traction
  /// node, the motors' set-points (or a due direct move) commanded, and the steering encoder's
  /// heartbeat and TPDO1 appended to `out` (from `count`; returns the new count). Every laser
  /// period a sweep is taken and handed to the laser's connection.
  std::size_t step(Timestamp now, SimDrives& drives, Span<drivers::CanFrame> out, std::size_t count);

  const sim::SimVehicle& vehicle() const noexcept { return *vehicle_; }
  std::uint64_t sweeps() const noexcept { return sweeps_; }
  std::uint64_t replies() const;

 private:
  void serve(drivers::LoopbackServer& server);
  void publishSweep(Timestamp start, Timestamp end);
  std::uint32_t deviceMs(Timestamp t) const noexcept;

  SimVehicleSideOptions options_;
  std::FILE* log_;
  Status status_ = Status::Ok;
  std::string error_;
  sim::World world_;
  std::unique_ptr<sim::RayCaster> caster_;
  std::unique_ptr<sim::SimVehicle> vehicle_;
  std::unique_ptr<sim::SimLaser> laser_;
  Timestamp start_{};
  Timestamp nextDrive_{};
  Timestamp nextSweep_{};
  Pose2d sweepStartPose_;
  std::int64_t wheelTicks_ = 0;
  double wheelSteer_ = 0.0;
  std::uint64_t sweeps_ = 0;

  // The laser's connection thread waits for the next sweep's reply (binary CoLa, framed).
  mutable std::mutex mutex_;
  std::condition_variable newSweep_;
  std::vector<std::uint8_t> reply_;
  std::uint64_t replySeq_ = 0;
  std::uint64_t replies_ = 0;
  bool stopping_ = false;
  std::unique_ptr<drivers::LoopbackServer> server_;
};

}  // namespace agv::simdrives
