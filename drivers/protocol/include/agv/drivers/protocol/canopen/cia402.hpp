#pragma once
/// @file cia402.hpp
/// CiA 402 (IEC 61800-7-201) drive profile, heap-free: the power state machine of a drive as the
/// statusword (0x6041) reports it, the device-control commands of the controlword (0x6040), the
/// transition table between the states, the object indices and the operation-mode bits the drive
/// controller uses. Shared by the controller (`Cia402Axis`, `Cia402DriveController`) and the
/// simulated drive (`agv::sim::SimCia402Node`). docs/drives.md describes every object.

#include <cstdint>

#include "agv/core/result.hpp"

namespace agv::drivers::canopen {

/// COB-IDs of the CiA 301 pre-defined connection set used for the drives' PDOs (+ node id).
inline constexpr std::uint32_t kTpdo1Base = 0x180;
inline constexpr std::uint32_t kRpdo1Base = 0x200;
inline constexpr std::uint32_t kTpdo2Base = 0x280;

/// Objects of the drive profile and of CiA 301 the drive controller reads or writes.
namespace cia402 {
inline constexpr std::uint16_t kErrorCode = 0x603F;              ///< u16, last fault's error code
inline constexpr std::uint16_t kControlword = 0x6040;            ///< u16
inline constexpr std::uint16_t kStatusword = 0x6041;             ///< u16
inline constexpr std::uint16_t kModesOfOperation = 0x6060;       ///< i8
inline constexpr std::uint16_t kModesDisplay = 0x6061;           ///< i8
inline constexpr std::uint16_t kPositionActual = 0x6064;         ///< i32 [position units]
inline constexpr std::uint16_t kVelocityActual = 0x606C;         ///< i32 [velocity units]
inline constexpr std::uint16_t kTargetPosition = 0x607A;         ///< i32 [position units]
inline constexpr std::uint16_t kProfileVelocity = 0x6081;        ///< u32 [velocity units] (pp)
inline constexpr std::uint16_t kProfileAcceleration = 0x6083;    ///< u32 [acceleration units]
inline constexpr std::uint16_t kProfileDeceleration = 0x6084;    ///< u32 [acceleration units]
inline constexpr std::uint16_t kQuickStopDeceleration = 0x6085;  ///< u32 [acceleration units]
inline constexpr std::uint16_t kTargetVelocity = 0x60FF;         ///< i32 [velocity units] (pv)
/// i16: the drive's reaction to a lost connection (its heartbeat consumer timing out).
inline constexpr std::uint16_t kAbortConnectionOption = 0x6007;
inline constexpr std::uint16_t kQuickStopOption = 0x605A;      ///< i16: how a quick stop ends
inline constexpr std::uint16_t kFaultReactionOption = 0x605E;  ///< i16: how the drive stops on a fault
inline constexpr std::uint16_t kConsumerHeartbeat = 0x1016;    ///< u32 per sub-index: node << 16 | ms
inline constexpr std::uint16_t kProducerHeartbeat = 0x1017;    ///< u16 [ms]
inline constexpr std::uint16_t kRpdoCommunication = 0x1400;    ///< + PDO number - 1
inline constexpr std::uint16_t kRpdoMapping = 0x1600;
inline constexpr std::uint16_t kTpdoCommunication = 0x1800;
inline constexpr std::uint16_t kTpdoMapping = 0x1A00;
/// Bit 31 of a PDO COB-ID entry (sub-index 1): the PDO does not exist (disabled while mapping).
inline constexpr std::uint32_t kPdoInvalid = 0x80000000U;
/// PDO transmission type 255: event-driven (a TPDO is sent every event-timer period).
inline constexpr std::uint8_t kPdoEventDriven = 0xFF;

/// A PDO mapping entry (sub-index 1..8 of 0x1600.. / 0x1A00..): index << 16 | sub << 8 | bits.
constexpr std::uint32_t mappingEntry(std::uint16_t index, std::uint8_t subIndex, std::uint8_t bits) noexcept {
  return (static_cast<std::uint32_t>(index) << 16U) | (static_cast<std::uint32_t>(subIndex) << 8U) | bits;
}

/// Values of the option codes above that the drive controller writes at every bring-up, so that
/// the drives' own reactions are the documented safe states whatever their factory settings
/// (docs/drives.md, "Safe state"):
/// - abort connection 1 = fault signal: a silent controller is a drive fault (fault reaction, then
///   Fault; only a fault reset by a live controller leaves it);
/// - quick stop 2 = slow down on the quick-stop ramp (0x6085), then Switch on disabled;
/// - fault reaction 2 = slow down on the quick-stop ramp, then Fault (never coast).
inline constexpr std::int16_t kAbortConnectionFaultSignal = 1;
inline constexpr std::int16_t kQuickStopRampThenDisabled = 2;
inline constexpr std::int16_t kFaultReactionQuickStopRamp = 2;

// Statusword bits.
inline constexpr std::uint16_t kSwReadyToSwitchOn = 1U << 0U;
inline constexpr std::uint16_t kSwSwitchedOn = 1U << 1U;
inline constexpr std::uint16_t kSwOperationEnabled = 1U << 2U;
inline constexpr std::uint16_t kSwFault = 1U << 3U;
inline constexpr std::uint16_t kSwVoltageEnabled = 1U << 4U;
inline constexpr std::uint16_t kSwQuickStop = 1U << 5U;  ///< 0 = quick stop active (low active)
inline constexpr std::uint16_t kSwSwitchOnDisabled = 1U << 6U;
inline constexpr std::uint16_t kSwWarning = 1U << 7U;
inline constexpr std::uint16_t kSwRemote = 1U << 9U;
inline constexpr std::uint16_t kSwTargetReached = 1U << 10U;
/// Profile position: set-point acknowledge; profile velocity: speed is zero.
inline constexpr std::uint16_t kSwSetPointAcknowledge = 1U << 12U;
inline constexpr std::uint16_t kSwSpeedZero = 1U << 12U;

// Controlword bits.
inline constexpr std::uint16_t kCwSwitchOn = 1U << 0U;
inline constexpr std::uint16_t kCwEnableVoltage = 1U << 1U;
inline constexpr std::uint16_t kCwQuickStop = 1U << 2U;  ///< 0 = quick stop (low active)
inline constexpr std::uint16_t kCwEnableOperation = 1U << 3U;
/// Profile position: a new set-point (the drive takes it on the rising edge).
inline constexpr std::uint16_t kCwNewSetPoint = 1U << 4U;
/// Profile position: the new set-point replaces the one under way at once.
inline constexpr std::uint16_t kCwChangeSetImmediately = 1U << 5U;
inline constexpr std::uint16_t kCwRelative = 1U << 6U;
inline constexpr std::uint16_t kCwFaultReset = 1U << 7U;
inline constexpr std::uint16_t kCwHalt = 1U << 8U;
}  // namespace cia402

/// Modes of operation (0x6060 / 0x6061) the controller uses.
enum class OperationMode : std::int8_t {
  None = 0,
  ProfilePosition = 1,
  ProfileVelocity = 3,
};

/// The states of the CiA 402 power state machine.
enum class PowerState : std::uint8_t {
  NotReadyToSwitchOn,
  SwitchOnDisabled,
  ReadyToSwitchOn,
  SwitchedOn,
  OperationEnabled,
  QuickStopActive,
  FaultReactionActive,
  Fault,
  Unknown,  ///< a statusword whose state bits match no state (not a protocol state)
};

/// Name of a state as CiA 402 writes it (e.g. "Operation enabled"). Never null.
const char* toString(PowerState state) noexcept;

/// The state the statusword reports, by the masks of CiA 402: bits 0-3, 5, 6 (0x6F) for the
/// states with voltage applied, bits 0-3 and 6 (0x4F) for the others. `Unknown` for a pattern no
/// state has.
PowerState decodeStatusword(std::uint16_t statusword) noexcept;

/// The state bits of a statusword reporting `state` (bits 0-3, 5, 6; voltage-enabled bit 4 set in
/// the states with the power stage on). 0 for `Unknown`. Used by the simulated drive.
std::uint16_t statuswordBits(PowerState state) noexcept;

/// Device-control commands of the controlword.
enum class Cia402Command : std::uint8_t {
  Shutdown,          ///< x110: to Ready to switch on
  SwitchOn,          ///< 0111: to Switched on
  DisableOperation,  ///< 0111 (the same bits as SwitchOn): Operation enabled -> Switched on
  EnableOperation,   ///< 1111: to Operation enabled (also "switch on + enable operation")
  DisableVoltage,    ///< xx0x: power stage off, to Switch on disabled
  QuickStop,         ///< x01x: Operation enabled -> Quick stop active
  FaultReset,        ///< rising edge of bit 7: Fault -> Switch on disabled
};

/// Name of a command (e.g. "enable operation"). Never null.
const char* toString(Cia402Command command) noexcept;

/// The controlword bits 0-3 and 7 of `command` (the fault reset's word has bit 7 set; the
/// rising edge is what counts, so the word before it must have bit 7 clear). Mode bits 4-6, 8 are
/// the caller's.
std::uint16_t controlwordFor(Cia402Command command) noexcept;

/// The command a drive reads from `current` when the previous controlword was `previous`, by the
/// bit patterns of CiA 402: a 0 -> 1 edge of bit 7 is a fault reset, otherwise bits 0-3 decide.
/// The pattern 0111 is reported as `SwitchOn` (it is also "disable operation").
Cia402Command decodeControlword(std::uint16_t previous, std::uint16_t current) noexcept;

/// Options of the state machine a drive may choose.
struct Cia402Options {
  /// Transition 16 (Quick stop active -> Operation enabled on "enable operation"): allowed only
  /// by quick-stop option codes 5..8. Off by default (option code 2: slow down on the quick-stop
  /// ramp, then Switch on disabled).
  bool quickStopToOperationEnabled = false;
};

/// The transition table of CiA 402: the state a drive in `from` goes to on `command`.
/// - A command that keeps the state it leads to (e.g. "enable operation" in Operation enabled,
///   "shutdown" in Ready to switch on, "disable voltage" in Switch on disabled) returns `from`.
/// - Transitions: 2 shutdown SOD->RTSO, 3 switch on RTSO->SO, 3+4 enable operation RTSO->OE,
///   4 enable operation SO->OE, 5 disable operation OE->SO, 6 shutdown SO->RTSO, 7 disable
///   voltage / quick stop RTSO->SOD, 8 shutdown OE->RTSO, 9 disable voltage OE->SOD, 10 disable
///   voltage / quick stop SO->SOD, 11 quick stop OE->QSA, 12 disable voltage QSA->SOD, 15 fault
///   reset F->SOD, 16 enable operation QSA->OE (only with `quickStopToOperationEnabled`).
/// - Anything else is refused with `Status::Rejected` (the drive stays where it is): e.g. switch
///   on from Switch on disabled, any command in Not ready to switch on or Fault reaction active
///   (their exits are automatic), any command but fault reset in Fault, a fault reset outside
///   Fault. `InvalidArgument` for `Unknown`.
/// The automatic transitions (0, 1 at power-on, 13 on a fault, 14 when the fault reaction ends,
/// and QSA -> SOD when the quick stop is complete) are the drive's, not commands.
Result<PowerState> nextState(PowerState from, Cia402Command command, const Cia402Options& options = {}) noexcept;

/// The command that moves a drive in `state` one step towards Operation enabled (shutdown,
/// switch on, enable operation; a fault reset in Fault), or false when there is none (already
/// enabled, or a state left automatically).
bool commandTowardsEnabled(PowerState state, Cia402Command& command) noexcept;

}  // namespace agv::drivers::canopen
