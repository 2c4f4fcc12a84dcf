#pragma once
/// @file socketcan_drive_control.hpp
/// The CiA 402 traction and steering drives on a SocketCAN bus (Linux only): a `hal::DriveControl`
/// made of a `SocketCanBus` and the portable `canopen::Cia402DriveController` (docs/drives.md).
///
/// `cycle(now)` is the control cycle (call it every 10 ms or so, with the same clock the set-points
/// are stamped on): it reads the frames waiting in the socket without waiting (at most
/// `maxFramesPerCycle`), reports the controller's bus-off / link loss to the drive controller
/// (which quick-stops the traction axis) and its return, polls the drive controller, and sends
/// what it queued. Frames the bus refuses are counted and dropped: the set-point RPDOs are
/// repeated every cycle, a lost SDO fails the bring-up by its timeout. The destructor quick-stops
/// the traction drive through the bus directly (the drive controller's emergency sink).
///
/// No heap after construction; not thread-safe (one loop owns it). On the kernel CAN stack it runs
/// in the vcan VM test (docs/vcan-testing.md); on the build hosts only its behaviour without a CAN
/// interface and `busStateReports` are tested.

#include <cstdint>

#include "agv/core/status.hpp"
#include "agv/core/timestamp.hpp"
#include "agv/drivers/linux/socketcan_bus.hpp"
#include "agv/drivers/protocol/canopen/cia402_drive.hpp"
#include "agv/hal/drive_control.hpp"

namespace agv::drivers {

/// Configuration of a `SocketCanDriveControl`.
struct SocketCanDriveControlConfig {
  /// Interface name (can0, vcan0 ...; at most 15 characters), copied by the constructor.
  const char* interfaceName = "can0";
  /// The drives: nodes, scaling, limits, heartbeats, timeouts (docs/drives.md).
  canopen::Cia402DriveConfig drives;
  /// Time between attempts to open a bus that could not be opened.
  Duration openRetryInterval = Duration::fromSeconds(1.0);
  /// Bound of the frames one `cycle()` reads (the rest wait in the socket for the next call).
  std::uint32_t maxFramesPerCycle = 64;
};

/// Running totals (the bus's own counters are in `busHealth()`).
struct SocketCanDriveControlCounters {
  std::uint64_t framesHandled = 0;  ///< data frames given to the drive controller
  std::uint64_t errorFrames = 0;    ///< CAN error frames seen (decoded by the bus)
  std::uint64_t framesSent = 0;     ///< frames the kernel accepted
  std::uint64_t sendFailures = 0;   ///< frames refused (bus-off, link down, queue full)
  std::uint64_t openAttempts = 0;
};

/// What one `cycle()` reports to the drive controller (`onBusState`): the bus off, then (or only)
/// back. `reportedOff`: the controller was told the bus is off and not yet that it is back;
/// `offSeen`: the bus counted a bus-off report while this cycle read (the transport takes a data
/// frame received after it as the CAN controller's return, so a read that goes on past the report
/// can end with the bus usable again: the bus-off is reported all the same); `usable`: the bus
/// after the read (open, link up, not bus-off).
struct BusStateReports {
  bool off = false;   ///< report the bus off (the traction quick stop)
  bool back = false;  ///< report it back, after `off` when both are set
};
BusStateReports busStateReports(bool reportedOff, bool offSeen, bool usable) noexcept;

/// See the file comment.
class SocketCanDriveControl final : public hal::DriveControl, private canopen::CanFrameSink {
 public:
  explicit SocketCanDriveControl(const SocketCanDriveControlConfig& config) noexcept;
  ~SocketCanDriveControl();
  SocketCanDriveControl(const SocketCanDriveControl&) = delete;
  SocketCanDriveControl& operator=(const SocketCanDriveControl&) = delete;

  /// Opens the bus (receiving every frame and the error frames). `InvalidArgument` for a bad
  /// configuration (no interface name or one above 15 characters, drives refused by
  /// `Cia402DriveController::validate`, no frames per cycle, no retry interval), else the bus's result (`NotFound`,
  /// `Unsupported`, `DeviceFault`); a failed open is retried by `cycle()` every `openRetryInterval`.
  Status open(Timestamp now) noexcept;
  /// Starts the drives' bring-up (`Cia402DriveController::start`); `NotInitialized` when the bus
  /// is not open.
  Status start(Timestamp now) noexcept;
  /// One control cycle at `now`; see the file comment. `Ok`, or `DeviceFault` while the bus is not
  /// usable (not open, link down, bus-off: the drive controller has been told).
  Status cycle(Timestamp now) noexcept;

  /// Traction quick stop (PLC Stop or the application's reason); sent at once when the bus takes it.
  void quickStop(canopen::SafeStopReason reason) noexcept;
  Status faultReset(Timestamp now) noexcept { return controller_.faultReset(now); }
  /// Hands the drives back at the end of a motion task (`Cia402DriveController::release`); the
  /// "disable operation" RPDOs are sent at once when the bus takes them.
  Status release() noexcept;

  // hal::DriveControl: forwarded to the drive controller (docs/drives.md).
  Status command(const hal::DriveCommand& cmd) noexcept override { return controller_.command(cmd); }
  Status stop() noexcept override { return controller_.stop(); }
  bool isStandstill() const noexcept override { return controller_.isStandstill(); }

  const canopen::Cia402DriveController& controller() const noexcept { return controller_; }
  const SocketCanHealth& busHealth() const noexcept { return bus_.health(); }
  const SocketCanDriveControlCounters& counters() const noexcept { return counters_; }

 private:
  bool send(const CanFrame& frame) noexcept override;
  void flush() noexcept;
  bool busUsable() const noexcept;

  SocketCanDriveControlConfig config_;
  char interfaceName_[16] = {};
  bool nameOk_ = false;
  // Declared before the controller: the controller's destructor sends through the bus.
  SocketCanBus bus_;
  canopen::Cia402DriveController controller_;
  Status openStatus_ = Status::NotInitialized;
  Timestamp nextOpen_{};
  bool reportedOff_ = false;
  SocketCanDriveControlCounters counters_{};
};

}  // namespace agv::drivers
