#pragma once
/// @file cia402_drive.hpp
/// Control of the vehicle's two CiA 402 drives over CANopen, portable and heap-free:
/// - `Cia402Axis`: one drive node. Bring-up (NMT pre-operational, SDO configuration of the mode,
///   heartbeats, profile limits and PDO mappings, mode confirmed by reading 0x6061, NMT start,
///   shutdown -> switch on -> enable operation), the set-point RPDO, the statusword / actual-value
///   TPDOs, heartbeat supervision, EMCY, fault read-back (0x603F) and fault reset.
/// - `Cia402DriveController`: the traction axis (profile velocity) and the steering axis (profile
///   position with the set-point handshake) behind `hal::DriveControl`, SI units scaled and
///   limited at this edge, the controller's own heartbeat, and the safe-state reactions (traction
///   quick stop on a drive heartbeat loss, an EMCY or drive fault, a CAN bus-off, a PLC stop, a
///   stale set-point, shutdown and destruction).
///
/// Both are polled with a timestamp, take received frames (`onFrame`) and put the frames to send
/// in a bounded outbox (`takeFrames`); they never block and never touch an OS. The transport (the
/// SocketCAN bus on Linux, a CAN peripheral on an MCU) moves the frames. docs/drives.md lists every
/// CAN object, the PDO layouts and the reactions.

#include <cstddef>
#include <cstdint>

#include "agv/core/fixed_ring.hpp"
#include "agv/core/span.hpp"
#include "agv/core/status.hpp"
#include "agv/core/timestamp.hpp"
#include "agv/drivers/protocol/can_frame.hpp"
#include "agv/drivers/protocol/canopen/canopen_encoders.hpp"
#include "agv/drivers/protocol/canopen/cia402.hpp"
#include "agv/drivers/protocol/canopen/sdo.hpp"
#include "agv/hal/drive_control.hpp"

namespace agv::drivers::canopen {

/// Frames waiting to be sent, oldest first; bounded. A full outbox refuses ordinary frames
/// (counted); `pushUrgent` (quick stop) drops the oldest frame instead.
class CanOutbox {
 public:
  static constexpr std::size_t kCapacity = 32;
  /// `CapacityExceeded` (and counted) when full.
  Status push(const CanFrame& frame) noexcept;
  /// Always queued; the oldest frame is dropped (and counted) when full.
  void pushUrgent(const CanFrame& frame) noexcept;
  /// Moves up to `out.size()` frames into `out`, oldest first; returns their count.
  std::size_t take(Span<CanFrame> out) noexcept;
  std::size_t size() const noexcept { return ring_.size(); }
  std::uint32_t dropped() const noexcept { return dropped_; }

 private:
  FixedRing<CanFrame, kCapacity> ring_;
  std::uint32_t dropped_ = 0;
};

/// Something that sends a frame at once (the transport). Used only by the controller's
/// destructor for its last quick stop, when nobody will drain the outbox any more.
class CanFrameSink {
 public:
  /// True when the frame was handed to the bus.
  virtual bool send(const CanFrame& frame) noexcept = 0;

 protected:
  CanFrameSink() = default;
  CanFrameSink(const CanFrameSink&) = default;
  CanFrameSink& operator=(const CanFrameSink&) = default;
  ~CanFrameSink() = default;
};

/// PDO layout the controller writes into each drive (fixed; docs/drives.md):
/// RPDO1 (0x200 + node): controlword (u16) + target (i32: 0x60FF target velocity in profile
/// velocity mode, 0x607A target position in profile position mode), 6 bytes.
/// TPDO1 (0x180 + node): statusword (u16) + position actual value 0x6064 (i32), 6 bytes.
/// TPDO2 (0x280 + node): velocity actual value 0x606C (i32), 4 bytes.
/// (COB-ID bases: `kRpdo1Base`, `kTpdo1Base`, `kTpdo2Base` in cia402.hpp.)

/// Device-level set-up of one axis (device units; `Cia402DriveController` fills it from SI).
struct Cia402AxisConfig {
  std::uint8_t nodeId = 1;
  OperationMode mode = OperationMode::ProfileVelocity;
  /// Profile velocity 0x6081 [velocity units] written in profile position mode (the steering
  /// rate limit); not written in profile velocity mode.
  std::uint32_t profileVelocity = 0;
  std::uint32_t profileAcceleration = 1000;    ///< 0x6083 [acceleration units]
  std::uint32_t profileDeceleration = 1000;    ///< 0x6084 [acceleration units]
  std::uint32_t quickStopDeceleration = 4000;  ///< 0x6085 [acceleration units]
  /// Event timer of TPDO1 / TPDO2 (0x1800/0x1801 sub 5) [ms resolution], 1..65535 ms.
  Duration tpdoPeriod = Duration::fromMilliseconds(10);
  /// Heartbeat producer time of the drive (0x1017) [ms resolution], 1..65535 ms.
  Duration heartbeatPeriod = Duration::fromMilliseconds(50);
  /// No heartbeat from the drive for this long (once started) = heartbeat lost.
  Duration heartbeatTimeout = Duration::fromMilliseconds(150);
  /// Node id of the controller's heartbeat and the drive's consumer time for it (0x1016 sub 1):
  /// a controller silent this long faults the drive. 1..65535 ms.
  std::uint8_t controllerNodeId = 127;
  Duration controllerHeartbeatTimeout = Duration::fromMilliseconds(200);
  /// An SDO request without answer for this long fails the bring-up (`Timeout`).
  Duration sdoTimeout = Duration::fromMilliseconds(100);
  /// A state of the bring-up (first TPDO after NMT start, each power-state step) not reached within
  /// this time fails the bring-up (`Timeout`).
  Duration stateTimeout = Duration::fromMilliseconds(1000);
};

/// Where an axis is.
enum class AxisPhase : std::uint8_t {
  Idle,            ///< not started
  Configuring,     ///< NMT pre-operational sent; SDO configuration under way
  ConfirmingMode,  ///< reading 0x6061
  Starting,        ///< NMT start sent; waiting for the first statusword
  Enabling,        ///< stepping the power state machine to Operation enabled
  Enabled,         ///< Operation enabled: set-points flow
  QuickStopping,   ///< quick stop commanded (held until the next start)
  Faulted,         ///< started, and the drive reports a fault (statusword, EMCY) or its heartbeat was lost
  Failed,          ///< the bring-up failed (`lastError()`, `lastAbortCode()`)
  Released,        ///< disable operation commanded (held until the next start): the drive in Switched on
};

/// Name of a phase (e.g. "enabled"). Never null.
const char* toString(AxisPhase phase) noexcept;

/// Counters of one axis.
struct AxisCounters {
  std::uint32_t sdoRequests = 0;
  std::uint32_t sdoAborts = 0;
  std::uint32_t tpdos = 0;
  std::uint32_t heartbeats = 0;
  std::uint32_t emcys = 0;
  std::uint32_t rpdos = 0;
  std::uint32_t setPointsAcknowledged = 0;  ///< profile position handshakes completed
  std::uint32_t malformed = 0;              ///< frames of this node too short or undecodable
};

/// One CiA 402 drive node; see the file comment. Frames go into the `CanOutbox` given at
/// construction (shared by the axes of one bus; it must outlive the axis).
class Cia402Axis {
 public:
  /// Most SDO writes of a bring-up.
  static constexpr std::size_t kMaxConfigWrites = 40;

  Cia402Axis(const Cia402AxisConfig& config, CanOutbox& outbox) noexcept;

  /// InvalidArgument: node id outside 1..127 or equal to the controller's, a mode other than
  /// profile velocity / position, a period or timeout outside its range.
  Status validate() const noexcept;

  /// Starts (or restarts) the bring-up at `now`: NMT pre-operational, then the configuration.
  /// Clears a previous quick stop, fault or failure record (not the error code).
  void start(Timestamp now) noexcept;
  /// Handles a received frame; true when it was this node's (SDO response, TPDO, heartbeat, EMCY).
  /// A heartbeat counts as received at the frame's `stamp` when that lies after the previous
  /// poll (the transport's receive stamp, on the clock of `poll`'s `now`; a later `poll` clamps a
  /// stamp ahead of its `now` to it), else at the previous poll: a controller held up between
  /// two polls does not take the heartbeats queued meanwhile for late ones.
  bool onFrame(const CanFrame& frame) noexcept;
  /// Advances the bring-up, the set-point handshake and the supervision at `now`; emits the SDO
  /// request due and, once the node is started, the RPDO with the current controlword and target.
  void poll(Timestamp now) noexcept;

  /// Profile velocity: the target velocity [velocity units] sent while enabled.
  void setTargetVelocity(std::int32_t velocity) noexcept { targetVelocity_ = velocity; }
  /// Profile position: the target position [position units]; given to the drive with the
  /// set-point handshake (new set-point bit 4 until the drive acknowledges with bit 12, change
  /// set immediately bit 5), the newest target when the drive is ready for another.
  void setTargetPosition(std::int32_t position) noexcept { targetPosition_ = position; }
  /// Quick stop: the controlword "quick stop" is held from now on, and its RPDO is queued at once
  /// (urgently) when the node has been started. Left only by `start()`.
  void quickStop() noexcept;
  /// Disable operation: from Operation enabled the drive goes to Switched on (powered, no torque
  /// demand, target velocity 0 in the RPDO); held until the next `start()`. Supervision (heartbeat,
  /// faults) goes on. Only in `Enabled`; `Rejected` otherwise.
  Status release() noexcept;
  /// Fault reset: bit 7 cleared for one poll, then set (the rising edge), then the power state
  /// machine is stepped to Operation enabled again. Only in `Faulted` with the drive in Fault;
  /// `Rejected` otherwise.
  Status faultReset(Timestamp now) noexcept;

  AxisPhase phase() const noexcept { return phase_; }
  /// A fault reset is under way (`Faulted` until the drive reports Switch on disabled).
  bool resetting() const noexcept { return faultResetStep_ != 0; }
  /// The drive's state from its last statusword (`Unknown` before the first).
  PowerState powerState() const noexcept { return decodeStatusword(statusword_); }
  std::uint16_t statusword() const noexcept { return statusword_; }
  bool haveActuals() const noexcept { return haveTpdo1_; }
  std::int32_t positionActual() const noexcept { return positionActual_; }
  std::int32_t velocityActual() const noexcept { return velocityActual_; }
  Timestamp lastTpdo() const noexcept { return lastTpdo_; }
  /// The heartbeat was lost (no heartbeat within the timeout, or a boot-up after start).
  bool heartbeatLost() const noexcept { return heartbeatLost_; }
  NmtState nmtState() const noexcept { return nmt_; }
  /// Error code of the drive's fault: from its EMCY or read back from 0x603F (0 = none known).
  std::uint16_t errorCode() const noexcept { return errorCode_; }
  /// Last EMCY received with a non-zero code (its node, code, register, vendor bytes).
  const EmcyRecord& lastEmcy() const noexcept { return lastEmcy_; }
  /// An EMCY with a non-zero code came since the last start.
  bool emcyActive() const noexcept { return emcyActive_; }
  /// Why the bring-up failed: `Timeout` (no SDO answer, a state not reached), `DeviceFault` (SDO
  /// abort: `lastAbortCode()`, or the drive faulted), `Rejected` (0x6061 confirmed another mode),
  /// `Malformed` (an answer for another object). `Ok` otherwise.
  Status lastError() const noexcept { return lastError_; }
  std::uint32_t lastAbortCode() const noexcept { return lastAbort_; }
  /// Index / sub-index of the SDO that failed.
  std::uint16_t lastErrorIndex() const noexcept { return lastErrorIndex_; }
  std::uint8_t lastErrorSubIndex() const noexcept { return lastErrorSub_; }
  /// The controlword the last RPDO carried.
  std::uint16_t controlword() const noexcept { return controlword_; }
  const AxisCounters& counters() const noexcept { return counters_; }
  const Cia402AxisConfig& config() const noexcept { return config_; }

 private:
  struct SdoWrite {
    std::uint16_t index;
    std::uint8_t sub;
    std::uint8_t size;
    std::uint32_t value;
  };
  enum class SdoPurpose : std::uint8_t { None, Config, ConfirmMode, ErrorCode };

  void buildConfig() noexcept;
  void addWrite(std::uint16_t index, std::uint8_t sub, std::uint8_t size, std::uint32_t value) noexcept;
  void sendSdo(const SdoMessage& m, SdoPurpose purpose, Timestamp now) noexcept;
  void onSdo(const SdoMessage& m) noexcept;
  void fail(Status why, Timestamp now) noexcept;
  void enterFaulted() noexcept;
  void sendRpdo(bool urgent) noexcept;
  void stepEnabling(Timestamp now) noexcept;
  void stepHandshake() noexcept;

  Cia402AxisConfig config_;
  CanOutbox& out_;
  AxisPhase phase_ = AxisPhase::Idle;
  Timestamp phaseSince_{};
  Timestamp now_{};
  // Configuration list.
  SdoWrite writes_[kMaxConfigWrites] = {};
  std::size_t writeCount_ = 0;
  std::size_t nextWrite_ = 0;
  // SDO client: one request outstanding.
  SdoPurpose sdoPurpose_ = SdoPurpose::None;
  SdoMessage sdoRequest_{};
  Timestamp sdoDeadline_{};
  bool errorCodeWanted_ = false;
  // Drive state.
  std::uint16_t statusword_ = 0xFFFFU;  // decodes as Unknown (bits 0-3 and 6 all set: no state)
  bool haveTpdo1_ = false;
  std::int32_t positionActual_ = 0;
  std::int32_t velocityActual_ = 0;
  Timestamp lastTpdo_{};
  NmtState nmt_ = NmtState::Unknown;
  Timestamp lastHeartbeat_{};
  bool heartbeatLost_ = false;
  bool supervised_ = false;  // the drive's heartbeat producer is configured: supervise it
  bool started_ = false;     // NMT start sent: RPDOs flow
  std::uint16_t errorCode_ = 0;
  EmcyRecord lastEmcy_{};
  bool emcyActive_ = false;
  Status lastError_ = Status::Ok;
  std::uint32_t lastAbort_ = 0;
  std::uint16_t lastErrorIndex_ = 0;
  std::uint8_t lastErrorSub_ = 0;
  // Command.
  std::uint16_t controlword_ = 0;
  Cia402Command lastStep_ = Cia402Command::DisableVoltage;
  bool quickStop_ = false;
  int faultResetStep_ = 0;  // 0 none, 1 bit 7 low sent, 2 bit 7 high sent
  std::int32_t targetVelocity_ = 0;
  std::int32_t targetPosition_ = 0;
  // Profile position handshake.
  std::int32_t sentPosition_ = 0;
  bool newSetPoint_ = false;
  bool positionGiven_ = false;  // a set-point was acknowledged since enabling
  std::int32_t acceptedPosition_ = 0;
  AxisCounters counters_{};
};

/// Traction axis in SI units (profile velocity mode).
struct TractionAxisConfig {
  std::uint8_t nodeId = 1;
  /// Position units of the drive (0x6064) per metre of drive-wheel surface travel (> 0).
  double countsPerMetre = 10000.0;
  /// Velocity units (0x60FF, 0x606C) per m/s; with the common default of position units per
  /// second, equal to `countsPerMetre`. Acceleration units (0x6083..0x6085) are taken as velocity
  /// units per second.
  double velocityUnitsPerMps = 10000.0;
  std::int8_t direction = 1;           ///< +1 or -1: the sign that makes forward travel positive
  double maxSpeed = 1.0;               ///< [m/s] set-points beyond are refused
  double acceleration = 0.5;           ///< [m/s^2] profile acceleration and deceleration
  double quickStopDeceleration = 2.0;  ///< [m/s^2]
  double standstillSpeed = 0.005;      ///< [m/s] below this the wheel is at rest
};

/// Steering axis in SI units (profile position mode).
struct SteeringAxisConfig {
  /// Node 3 by default: node 2 is the steering encoder of `CanopenEncodersConfig` on the same bus.
  std::uint8_t nodeId = 3;
  double countsPerRadian = 10000.0;    ///< position units per radian of the measured angle (> 0)
  std::int32_t zeroCount = 0;          ///< position at straight ahead
  std::int8_t direction = 1;           ///< +1 or -1: the sign that makes a left turn positive
  double maxAngle = 1.4;               ///< [rad] |set-point| beyond is refused
  double maxRate = 0.8;                ///< [rad/s] profile velocity
  double acceleration = 2.0;           ///< [rad/s^2] profile acceleration and deceleration
  double quickStopDeceleration = 8.0;  ///< [rad/s^2]
};

/// The whole drive set-up, SI units and times; defaults for a 10 ms control cycle.
struct Cia402DriveConfig {
  TractionAxisConfig traction;
  SteeringAxisConfig steering;
  std::uint8_t controllerNodeId = 127;  ///< our heartbeat: 0x700 + id
  Duration controllerHeartbeatPeriod = Duration::fromMilliseconds(50);
  /// The drives' consumer time for our heartbeat (0x1016): > 2 x our period.
  Duration controllerHeartbeatTimeout = Duration::fromMilliseconds(200);
  Duration driveHeartbeatPeriod = Duration::fromMilliseconds(50);    ///< 0x1017 of the drives
  Duration driveHeartbeatTimeout = Duration::fromMilliseconds(150);  ///< our consumer time
  Duration tpdoPeriod = Duration::fromMilliseconds(10);
  Duration sdoTimeout = Duration::fromMilliseconds(100);
  Duration stateTimeout = Duration::fromMilliseconds(1000);
  /// Watchdog: while enabled, no `command()` / `stop()` for this long = stale set-point.
  Duration setpointTimeout = Duration::fromMilliseconds(200);
};

/// The axis configurations `Cia402DriveController` derives from `config` (device units).
void deriveAxisConfigs(const Cia402DriveConfig& config, Cia402AxisConfig& traction,
                       Cia402AxisConfig& steering) noexcept;

/// State of the drive controller.
enum class DriveControllerState : std::uint8_t {
  Idle,        ///< not started
  BringingUp,  ///< the axes are being configured and enabled
  Enabled,     ///< both axes in Operation enabled: `command()` accepted
  SafeStop,    ///< traction quick-stopped after a trigger (`safeStopReason()`); `start()` to resume
  Failed,      ///< a bring-up failed (see the axes' `lastError()`)
  Released,    ///< both axes handed back by `release()` (Switched on); no watchdog; `start()` to enable again
};

/// Why the controller quick-stopped the traction axis.
enum class SafeStopReason : std::uint8_t {
  None,
  DriveHeartbeatLost,  ///< a drive's heartbeat timed out (or it booted again)
  DriveFault,          ///< an EMCY with an error code, or a drive reports Fault
  BusOff,              ///< the transport reported CAN bus-off
  PlcStop,             ///< `quickStop(PlcStop)` (the PLC's Stop)
  SetpointTimeout,     ///< no set-point for `setpointTimeout`
  Shutdown,            ///< `shutdown()` (process exiting)
  Requested,           ///< `quickStop(Requested)` by the application
};

const char* toString(DriveControllerState state) noexcept;
const char* toString(SafeStopReason reason) noexcept;

/// The traction and steering drives as a `hal::DriveControl`; see the file comment.
class Cia402DriveController final : public hal::DriveControl {
 public:
  explicit Cia402DriveController(const Cia402DriveConfig& config) noexcept;
  /// Sends a last traction quick stop through the sink (`setEmergencySink`) when the drives were
  /// started; the drives' heartbeat consumers stop them anyway when this controller falls silent.
  ~Cia402DriveController();
  Cia402DriveController(const Cia402DriveController&) = delete;
  Cia402DriveController& operator=(const Cia402DriveController&) = delete;

  /// InvalidArgument when an axis is unusable (`Cia402Axis::validate`), the node ids collide, a
  /// scale is not finite > 0, a direction not +-1, a limit not finite > 0, the controller's
  /// heartbeat timeout not above twice its period, or a period is not positive.
  Status validate() const noexcept;
  /// The sink the destructor sends its last quick stop through (may be null).
  void setEmergencySink(CanFrameSink* sink) noexcept { sink_ = sink; }

  /// Starts the bring-up of both axes (also to resume after a safe stop or a failure); the
  /// controller's heartbeat is produced from now on. `InvalidArgument` for a bad configuration,
  /// `DeviceFault` while the bus is off.
  Status start(Timestamp now) noexcept;
  /// Handles a received frame (any identifier; others are ignored and counted).
  void onFrame(const CanFrame& frame) noexcept;
  /// The transport reports the controller bus-off (`busOff` true) or back (false).
  void onBusState(bool busOff, Timestamp now) noexcept;
  /// One control cycle at `now`: supervision (heartbeats, faults, watchdog) with the reactions,
  /// the axes' bring-up and set-points, our heartbeat. A trigger found here quick-stops the
  /// traction axis in this call.
  void poll(Timestamp now) noexcept;
  /// Moves the frames to send (oldest first) into `out`; returns their count.
  std::size_t takeFrames(Span<CanFrame> out) noexcept { return outbox_.take(out); }

  /// Quick stop of the traction axis now (the frame is queued at once): PLC Stop, or the
  /// application's own reason. The steering axis holds its position.
  void quickStop(SafeStopReason reason) noexcept;
  /// The end of a motion task (the calibration routine done, the vehicle standing): the traction
  /// target goes to 0 and both axes get "disable operation" (Operation enabled -> Switched on), so
  /// the set-point watchdog does not quick-stop a vehicle that was told to stop. The heartbeats and
  /// faults stay supervised (a trigger then quick-stops as in any state). Only while `Enabled`
  /// with the traction at standstill (`isStandstill()`: a drive's reaction to "disable operation",
  /// 0x605C, may be to coast); `Rejected` otherwise, changing nothing (a safe stop stays a safe
  /// stop; a moving vehicle is left to `stop()`, the quick stop or the set-point watchdog).
  Status release() noexcept;
  /// The process is exiting: quick stop (reason `Shutdown`).
  void shutdown() noexcept { quickStop(SafeStopReason::Shutdown); }
  /// Fault reset of the axes in Fault, then re-enabling (`Rejected` when no axis is in Fault).
  Status faultReset(Timestamp now) noexcept;

  // hal::DriveControl
  /// Scales the set-point to device units (speed -> 0x60FF, angle -> 0x607A). `NonFiniteInput`
  /// for NaN/inf, `InvalidArgument` beyond `maxSpeed` / `maxAngle` (the previous set-point
  /// stays), `DeviceFault` unless enabled. Feeds the watchdog.
  Status command(const hal::DriveCommand& cmd) noexcept override;
  /// Target velocity 0 (the drive ramps down with its profile deceleration); steering kept.
  /// `DeviceFault` while the bus is off; otherwise `Ok` (also in a safe stop). Feeds the watchdog.
  Status stop() noexcept override;
  /// True when the traction drive reports a velocity below `standstillSpeed` in a TPDO of the
  /// last 3 TPDO periods.
  bool isStandstill() const noexcept override;

  DriveControllerState state() const noexcept { return state_; }
  SafeStopReason safeStopReason() const noexcept { return reason_; }
  const Cia402Axis& traction() const noexcept { return traction_; }
  const Cia402Axis& steering() const noexcept { return steering_; }
  /// Measured traction speed [m/s] and steering angle [rad] from the last TPDOs.
  double speedActual() const noexcept;
  double steeringAngleActual() const noexcept;
  /// Frames received that belong to no axis.
  std::uint32_t ignoredFrames() const noexcept { return ignored_; }
  std::uint32_t outboxDropped() const noexcept { return outbox_.dropped(); }
  const Cia402DriveConfig& config() const noexcept { return config_; }

 private:
  void trigger(SafeStopReason reason) noexcept;

  Cia402DriveConfig config_;
  CanOutbox outbox_;
  Cia402Axis traction_;
  Cia402Axis steering_;
  CanFrameSink* sink_ = nullptr;
  DriveControllerState state_ = DriveControllerState::Idle;
  SafeStopReason reason_ = SafeStopReason::None;
  bool busOff_ = false;
  bool heartbeatOn_ = false;
  Timestamp nextHeartbeat_{};
  Timestamp now_{};
  bool commandSeen_ = false;
  Timestamp lastCommand_{};
  std::uint32_t ignored_ = 0;
};

}  // namespace agv::drivers::canopen
