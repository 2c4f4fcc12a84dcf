#pragma once
/// @file canopen_encoders.hpp
/// CANopen (CiA 301) decoding of the vehicle's two encoders, heap-free: a CiA 406 steering encoder
/// (position value, object 0x6004) and a CiA 402 traction drive (position actual value, 0x6064),
/// each sending its position in a TPDO, plus the network management around them: NMT start
/// commands, optional SYNC production, heartbeat (0x700 + node) supervision with a timeout fault,
/// EMCY (0x080 + node) reporting, and unwrapping of the 32-bit (or narrower) drive counter into
/// int64 ticks. Output: `agv::hal::EncoderSample` in SI units.
///
/// The inverse (`encode*` functions) builds the same frames from true values, for the simulator.
/// Every CAN object used is listed in docs/drivers.md.

#include <cstddef>
#include <cstdint>

#include "agv/core/fixed_ring.hpp"
#include "agv/core/span.hpp"
#include "agv/core/status.hpp"
#include "agv/core/timestamp.hpp"
#include "agv/drivers/protocol/can_frame.hpp"
#include "agv/hal/encoder_sample.hpp"

namespace agv::drivers::canopen {

/// NMT command specifiers (CiA 301), sent in frame 0x000: [command, node id (0 = all)].
enum class NmtCommand : std::uint8_t {
  Start = 0x01,
  Stop = 0x02,
  EnterPreOperational = 0x80,
  ResetNode = 0x81,
  ResetCommunication = 0x82,
};

/// NMT states reported in heartbeat frames (CiA 301).
enum class NmtState : std::uint8_t {
  BootUp = 0x00,
  Stopped = 0x04,
  Operational = 0x05,
  PreOperational = 0x7F,
  Unknown = 0xFF,  ///< no heartbeat received yet (not a protocol value)
};

/// Where a position sits in a TPDO (from the device's PDO mapping, objects 0x1A00..).
struct PdoMapping {
  std::uint16_t cobId = 0;      ///< 11-bit COB-ID of the TPDO (default TPDO1 = 0x180 + node)
  std::uint8_t byteOffset = 0;  ///< first byte of the value in the PDO data
  std::uint8_t size = 4;        ///< bytes: 1..4 (little-endian, as CANopen sends)
};

/// CiA 402 traction drive: position actual value (0x6064) -> drive ticks.
struct DriveEncoderConfig {
  std::uint8_t nodeId = 1;
  PdoMapping pdo{0x181, 0, 4};
  std::int8_t direction = 1;  ///< +1 or -1: sign that makes forward travel count up
};

/// CiA 406 steering encoder: position value (0x6004) -> steering angle.
struct SteeringEncoderConfig {
  std::uint8_t nodeId = 2;
  PdoMapping pdo{0x182, 0, 4};
  std::int8_t direction = 1;     ///< +1 or -1: sign that makes a left turn positive
  double radiansPerCount = 0.0;  ///< [rad/count] at the steering axis (> 0)
  std::uint32_t zeroCount = 0;   ///< raw count at straight ahead
  /// Counts per encoder revolution when the encoder sits on the steering axis (the raw value
  /// wraps there, e.g. 8192 for 13 bits); 0 = the value is taken as a signed number of `size` bytes.
  std::uint32_t countsPerRevolution = 0;
};

/// When a sample is emitted.
enum class SampleTrigger : std::uint8_t {
  BothUpdated,   ///< when both positions were received since the last sample (SYNC-driven PDOs)
  DriveUpdated,  ///< on every drive position, with the latest steering angle
};

struct CanopenEncodersConfig {
  DriveEncoderConfig drive;
  SteeringEncoderConfig steering;
  SampleTrigger trigger = SampleTrigger::BothUpdated;
  /// Heartbeat consumer time per node (CiA 301 0x1016): no heartbeat for this long = fault.
  /// Typical: 3 x the producer time (0x1017). 0 disables the check.
  Duration heartbeatTimeout = Duration::fromMilliseconds(300);
  /// SYNC production period; 0 = no SYNC (the devices send cyclic/event-driven PDOs).
  Duration syncPeriod = Duration{};
  /// `BothUpdated`: the two positions of one sample must be received within this time of each
  /// other (the TPDOs of one SYNC or cycle arrive back to back; keep it below the TPDO period). A
  /// position whose partner was lost is dropped, not paired with the next cycle's, and counted in
  /// `incompleteCycles()`; with SYNC, each SYNC also ends the cycle. 0 = no time check.
  Duration pairingWindow = Duration::fromMilliseconds(3);
};

/// One EMCY message (CiA 301).
struct EmcyRecord {
  std::uint8_t nodeId = 0;
  std::uint16_t errorCode = 0;     ///< 0x0000 = error reset / no error
  std::uint8_t errorRegister = 0;  ///< object 0x1001
  std::uint8_t vendor[5] = {};
  Timestamp stamp;
};

/// Supervision state of one node.
struct NodeHealth {
  NmtState state = NmtState::Unknown;
  Timestamp lastHeartbeat;
  bool heartbeatSeen = false;
  bool heartbeatTimedOut = false;
  bool emcyActive = false;  ///< last EMCY had a non-zero error code
  std::uint32_t emcyCount = 0;
  std::uint32_t pdoCount = 0;
  std::uint32_t bootUps = 0;  ///< boot-up messages (node restarted; NMT start re-sent)
};

/// What a received frame was.
enum class FrameKind : std::uint8_t {
  Ignored,  ///< not for this decoder (other ids, extended, remote and error frames)
  DrivePosition,
  SteeringPosition,
  Heartbeat,
  Emcy,
  Malformed,  ///< one of our ids, but too short (or a steering value outside its revolution)
};

/// Builds the NMT frame `command` for `nodeId` (0 = all nodes).
CanFrame encodeNmt(NmtCommand command, std::uint8_t nodeId) noexcept;
/// Builds a SYNC frame (0x080, no data).
CanFrame encodeSync(Timestamp stamp) noexcept;
/// Heartbeat of `nodeId` in `state` (0x700 + node, 1 byte).
CanFrame encodeHeartbeat(std::uint8_t nodeId, NmtState state, Timestamp stamp) noexcept;
/// EMCY of `nodeId` (0x080 + node, 8 bytes).
CanFrame encodeEmcy(std::uint8_t nodeId, std::uint16_t errorCode, std::uint8_t errorRegister, Timestamp stamp) noexcept;
/// Decodes an EMCY frame (0x080 + node, node 1..127): error code, error register, vendor bytes
/// (those past `dlc` read as 0), stamp. `NotFound`: not an EMCY identifier (or an extended, remote or
/// error frame); `Truncated`: fewer than 3 data bytes (no error register). `record` is written only
/// on `Ok`.
Status decodeEmcy(const CanFrame& frame, EmcyRecord& record) noexcept;
/// Drive TPDO carrying the position for `trueTicks` (wrapped into the mapped size, direction applied).
CanFrame encodeDrivePdo(const DriveEncoderConfig& config, std::int64_t trueTicks, Timestamp stamp) noexcept;
/// Steering TPDO carrying the position for `angle` [rad] (rounded to a count, wrapped).
CanFrame encodeSteeringPdo(const SteeringEncoderConfig& config, double angle, Timestamp stamp) noexcept;

/// The decoder/supervisor of the two encoder nodes.
class CanopenEncoders {
 public:
  static constexpr std::size_t kEmcyQueue = 8;

  explicit CanopenEncoders(const CanopenEncodersConfig& config) noexcept;

  /// InvalidArgument when the configuration is unusable (node ids outside 1..127 or equal,
  /// PDO byte range outside 8 bytes, size not 1..4, same COB-ID twice, direction not +-1,
  /// radiansPerCount not finite > 0, zeroCount not below countsPerRevolution).
  Status validate() const noexcept;

  /// Frames to send once the bus is up: NMT Start for each node.
  std::size_t startupFrames(Span<CanFrame> out) const noexcept;

  /// Handles one received frame.
  FrameKind onFrame(const CanFrame& frame) noexcept;

  /// Periodic service at `now`: heartbeat timeouts; writes into `out` the frames due (SYNC when
  /// its period elapsed, NMT Start for a node that booted up again) and returns their count.
  std::size_t service(Timestamp now, Span<CanFrame> out) noexcept;

  /// The newest complete sample, once: true when a sample was produced since the last call.
  bool takeSample(hal::EncoderSample& sample) noexcept;

  /// Oldest unreported EMCY, once. Overflowing EMCYs are counted in `emcyDropped()`.
  bool takeEmcy(EmcyRecord& record) noexcept;
  std::uint32_t emcyDropped() const noexcept { return emcyDropped_; }

  /// Overall state: Ok; NotInitialized (no position from one of the nodes yet); Timeout (a
  /// heartbeat timed out); DeviceFault (an EMCY is active, or a node is not operational).
  Status health() const noexcept;
  const NodeHealth& driveHealth() const noexcept { return drive_; }
  const NodeHealth& steeringHealth() const noexcept { return steer_; }
  std::uint32_t malformedFrames() const noexcept { return malformed_; }
  /// `BothUpdated`: positions dropped because the other node's position of the same cycle never
  /// came (a lost TPDO); each such cycle produces no sample.
  std::uint32_t incompleteCycles() const noexcept { return incomplete_; }

  /// Unwrapped drive ticks so far (direction applied).
  std::int64_t driveTicks() const noexcept { return ticks_; }
  /// Latest steering angle [rad].
  double steeringAngle() const noexcept { return angle_; }

 private:
  void onHeartbeat(NodeHealth& h, const CanFrame& f, bool& needStart) noexcept;
  void onEmcy(NodeHealth& h, std::uint8_t node, const CanFrame& f) noexcept;
  void emit(Timestamp stamp) noexcept;
  void pair(bool& ownUpdated, Timestamp& ownStamp, bool& otherUpdated, Timestamp otherStamp, Timestamp stamp) noexcept;

  CanopenEncodersConfig config_;
  NodeHealth drive_{};
  NodeHealth steer_{};
  bool driveStartPending_ = false;
  bool steerStartPending_ = false;
  // Drive unwrapping.
  bool haveDrive_ = false;
  std::uint32_t lastRaw_ = 0;
  std::int64_t ticks_ = 0;
  // Steering.
  bool haveSteer_ = false;
  double angle_ = 0.0;
  bool driveUpdated_ = false;
  bool steerUpdated_ = false;
  Timestamp driveStamp_{};  // receive time of the pending drive / steering position
  Timestamp steerStamp_{};
  std::uint32_t incomplete_ = 0;
  // Output.
  bool sampleReady_ = false;
  hal::EncoderSample sample_{};
  // SYNC.
  bool syncStarted_ = false;
  Timestamp nextSync_{};
  // EMCY queue, oldest first.
  FixedRing<EmcyRecord, kEmcyQueue> emcy_;
  std::uint32_t emcyDropped_ = 0;
  std::uint32_t malformed_ = 0;
};

}  // namespace agv::drivers::canopen
