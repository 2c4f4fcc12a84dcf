#pragma once
/// @file sim_cia402_node.hpp
/// A simulated CiA 402 drive node on CANopen (heap-free, no OS): NMT state machine, the CiA 402
/// power state machine driven by the controlword (transition table of
/// `agv/drivers/protocol/canopen/cia402.hpp`), profile velocity and profile position modes with
/// acceleration-limited ramps and the set-point handshake, an SDO server for the objects the drive
/// controller uses (aborts for unknown objects and sub-indices, read-only objects, bad lengths or
/// values, mappings that do not fit), PDOs as mapped through 0x1400/0x1600/0x1800/0x1A00 (the RPDO
/// written into the object dictionary, TPDOs sent every event-timer period), a heartbeat producer
/// (0x1017) and a heartbeat consumer (0x1016) whose timeout is met with the reaction of the abort
/// connection option code 0x6007 (0 none, 1 fault, 2 disable voltage, 3 quick stop; 0 as the node
/// leaves the factory, so only a controller that configures it gets a drive that stops when the
/// controller falls silent). Quick stop (0x605A: 1, 2, 5, 6) and fault reaction (0x605E: 1, 2) end
/// on the slow-down or quick-stop ramp as their option codes say; other values are refused.
/// Faults can be injected (EMCY + Fault with an error code) and the node silenced (a dead node).
///
/// Used by the drive-controller tests in-process and by `agvnav-sim-drives` on a CAN interface.

#include <cstddef>
#include <cstdint>

#include "agv/core/fixed_ring.hpp"
#include "agv/core/span.hpp"
#include "agv/core/timestamp.hpp"
#include "agv/drivers/protocol/can_frame.hpp"
#include "agv/drivers/protocol/canopen/canopen_encoders.hpp"
#include "agv/drivers/protocol/canopen/cia402.hpp"
#include "agv/drivers/protocol/canopen/sdo.hpp"

namespace agv::sim {

/// Set-up of one simulated drive.
struct SimCia402NodeParams {
  std::uint8_t nodeId = 1;
  /// Position at power-on [position units].
  std::int32_t initialPosition = 0;
  /// Error code of the heartbeat-consumer fault (CiA 301: 0x8130, life guard / heartbeat error).
  std::uint16_t heartbeatErrorCode = 0x8130;
  /// The quick-stop option code as the node leaves the factory: 6 (transition 16 allowed) when
  /// `quickStopToOperationEnabled`, else 2. A write of 0x605A replaces it.
  drivers::canopen::Cia402Options options;
};

/// Counters of one simulated node.
struct SimCia402Counters {
  std::uint32_t sdoRequests = 0;
  std::uint32_t sdoAborts = 0;
  std::uint32_t rpdos = 0;
  std::uint32_t tpdos = 0;
  std::uint32_t heartbeats = 0;
  std::uint32_t emcys = 0;
  std::uint32_t setPointsAccepted = 0;  ///< profile position set-points taken (handshake)
  std::uint32_t rejectedCommands = 0;   ///< controlword commands the state machine refused
  std::uint32_t malformed = 0;          ///< frames for this node too short or undecodable
  std::uint32_t outboxDropped = 0;
};

/// One simulated drive; see the file comment.
class SimCia402Node {
 public:
  /// Most frames queued between two `step()` calls (SDO answers, EMCYs).
  static constexpr std::size_t kOutbox = 16;

  explicit SimCia402Node(const SimCia402NodeParams& params) noexcept;

  /// A frame on the bus at `now` (NMT, SDO request, RPDO, the controller's heartbeat; others
  /// ignored). SDO answers are queued for the next `step()`.
  void receive(const drivers::CanFrame& frame, Timestamp now) noexcept;
  /// Advances the drive to `now` (motion ramps, quick stop and fault reactions, the heartbeat
  /// consumer) and writes the frames it sends (queued answers, boot-up, heartbeat, TPDOs) into
  /// `out`; returns their count (frames beyond `out` are dropped and counted).
  std::size_t step(Timestamp now, Span<drivers::CanFrame> out) noexcept;

  /// Injects a drive fault: EMCY with `errorCode` (error register bit 0), 0x603F = `errorCode`,
  /// Fault reaction active (the motor stops on the quick-stop ramp), then Fault.
  void injectFault(std::uint16_t errorCode) noexcept;
  /// A silent node sends nothing (no heartbeat, PDO, SDO answer or EMCY; a dead transmitter or a
  /// cut cable from the node) but still receives and acts on what it hears.
  void setSilent(bool silent) noexcept { silent_ = silent; }
  /// The motor's position as a physical model measures it (e.g. the simulated vehicle's wheel
  /// encoder, with slip and ramps the node does not model): from now on the position actual value
  /// 0x6064 (SDO and TPDOs) reports `counts` instead of the node's own integration of its profile
  /// velocity, which keeps driving the ramps (`velocity()`, 0x606C).
  void setPositionFeedback(std::int32_t counts) noexcept {
    feedback_ = true;
    feedbackCounts_ = counts;
  }
  /// Power cycle: object dictionary back to defaults, boot-up message, pre-operational.
  void powerCycle() noexcept;

  drivers::canopen::PowerState state() const noexcept { return state_; }
  drivers::canopen::NmtState nmtState() const noexcept { return nmt_; }
  std::int8_t modeDisplay() const noexcept { return modeDisplay_; }
  std::uint16_t statusword() const noexcept;
  std::uint16_t controlword() const noexcept { return controlword_; }
  std::uint16_t errorCode() const noexcept { return errorCode_; }
  double position() const noexcept { return position_; }  ///< [position units] (own integration)
  double velocity() const noexcept { return velocity_; }  ///< [velocity units]
  /// Profile position: the set-point being moved to.
  std::int32_t activeTargetPosition() const noexcept { return activeTarget_; }
  std::int32_t targetVelocity() const noexcept { return static_cast<std::int32_t>(read(0x60FF, 0)); }
  /// The controller's heartbeat timed out (the drive reacted as 0x6007 says).
  bool controllerLost() const noexcept { return controllerLost_; }
  const SimCia402Counters& counters() const noexcept { return counters_; }
  std::uint8_t nodeId() const noexcept { return params_.nodeId; }
  /// Value of an object dictionary entry (0 when it does not exist).
  std::uint32_t read(std::uint16_t index, std::uint8_t sub) const noexcept;

 private:
  struct Entry {
    std::uint16_t index;
    std::uint8_t sub;
    std::uint8_t size;  // bytes
    bool writable;
    std::uint32_t value;
  };
  static constexpr std::size_t kEntries = 52;

  void resetDictionary() noexcept;
  void resetCommunication() noexcept;
  void add(std::uint16_t index, std::uint8_t sub, std::uint8_t size, bool writable, std::uint32_t value) noexcept;
  Entry* find(std::uint16_t index, std::uint8_t sub) noexcept;
  const Entry* find(std::uint16_t index, std::uint8_t sub) const noexcept;
  bool indexExists(std::uint16_t index) const noexcept;
  /// SDO download: 0 on success, else the abort code.
  std::uint32_t write(std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size) noexcept;
  std::uint32_t checkMapping(std::uint16_t mappingIndex, std::uint8_t count) const noexcept;
  void onSdo(const drivers::CanFrame& frame) noexcept;
  void onRpdo(std::uint16_t pdo, const drivers::CanFrame& frame) noexcept;
  void onControlword(std::uint16_t cw) noexcept;
  void queue(const drivers::CanFrame& frame) noexcept;
  void enterFault(std::uint16_t code) noexcept;
  void onConnectionLost() noexcept;
  drivers::canopen::Cia402Options options() const noexcept;
  void move(double dt) noexcept;
  bool pdoValid(std::uint16_t commIndex, std::uint32_t& cobId) const noexcept;
  drivers::CanFrame tpdoFrame(std::uint16_t pdo, std::uint32_t cobId) const noexcept;

  SimCia402NodeParams params_;
  Entry od_[kEntries] = {};
  std::size_t entries_ = 0;
  drivers::canopen::NmtState nmt_ = drivers::canopen::NmtState::BootUp;
  bool bootUpPending_ = true;
  drivers::canopen::PowerState state_ = drivers::canopen::PowerState::SwitchOnDisabled;
  std::uint16_t controlword_ = 0;
  std::int8_t modeDisplay_ = 0;
  std::uint16_t errorCode_ = 0;
  double position_ = 0.0;
  double velocity_ = 0.0;
  std::int32_t activeTarget_ = 0;
  bool setPointAck_ = false;
  bool targetReached_ = true;
  bool silent_ = false;
  bool feedback_ = false;
  std::int32_t feedbackCounts_ = 0;
  // Time.
  bool started_ = false;
  Timestamp last_{};
  Timestamp nextHeartbeat_{};
  Timestamp nextTpdo_[2] = {};
  // Heartbeat consumer.
  bool controllerSeen_ = false;
  bool controllerLost_ = false;
  Timestamp lastControllerHeartbeat_{};
  FixedRing<drivers::CanFrame, kOutbox> outbox_;
  SimCia402Counters counters_{};
};

}  // namespace agv::sim
