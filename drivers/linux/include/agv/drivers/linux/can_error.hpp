#pragma once
/// @file can_error.hpp
/// Decoding of SocketCAN error frames into facts a driver can act on.
///
/// A CAN controller driver in Linux reports bus problems as error frames (CAN_ERR_FLAG set in the
/// identifier): the identifier carries the error classes, the eight data bytes their details
/// (linux/can/error.h). `decodeCanError` turns one such frame into a `CanErrorReport`.

#include <cstdint>

#include "agv/core/status.hpp"
#include "agv/drivers/protocol/can_frame.hpp"

namespace agv::drivers {

/// Fault-confinement state of the CAN controller (ISO 11898-1), worst last.
enum class CanControllerState : std::uint8_t {
  ErrorActive = 0,   ///< normal operation
  ErrorWarning = 1,  ///< an error counter reached 96: the bus is disturbed
  ErrorPassive = 2,  ///< an error counter reached 128: the node no longer destroys frames
  BusOff = 3,        ///< transmit error counter above 255: the node is off the bus until restarted
};

/// Short stable name of a controller state ("error-active", ..., "bus-off"). Never null.
const char* toString(CanControllerState state) noexcept;

/// What one error frame says. Flags are false and numbers zero when the frame does not tell.
struct CanErrorReport {
  std::uint32_t classes = 0;        ///< raw error class bits (CAN_ERR_* of the identifier)
  bool txTimeout = false;           ///< the controller driver timed out a transmission
  bool lostArbitration = false;     ///< arbitration lost (bit position in `arbitrationBit`)
  bool controllerProblem = false;   ///< controller status change or buffer overflow (below)
  bool protocolViolation = false;   ///< bit, form, stuff ... error (`protocolType`, `protocolLocation`)
  bool transceiverProblem = false;  ///< wiring fault reported by the transceiver (`transceiverStatus`)
  bool noAck = false;               ///< a transmitted frame was not acknowledged: no other node listens
  bool busOff = false;              ///< the controller went bus-off
  bool busError = false;            ///< a bus error occurred (reported per error when enabled)
  bool restarted = false;           ///< the controller was restarted after bus-off
  bool rxOverflow = false;          ///< the controller's receive buffer overflowed: frames were lost
  bool txOverflow = false;          ///< the controller's transmit buffer overflowed
  bool countersValid = false;       ///< `txErrorCounter`/`rxErrorCounter` hold the controller's counters
  bool stateKnown = false;          ///< the frame tells the controller state (`state`)
  CanControllerState state = CanControllerState::ErrorActive;
  std::uint8_t arbitrationBit = 0;     ///< bit where arbitration was lost (0 = unspecified)
  std::uint8_t controllerDetail = 0;   ///< raw controller status byte (data[1])
  std::uint8_t protocolType = 0;       ///< raw protocol error type byte (data[2])
  std::uint8_t protocolLocation = 0;   ///< raw protocol error location byte (data[3])
  std::uint8_t transceiverStatus = 0;  ///< raw transceiver status byte (data[4])
  std::uint8_t txErrorCounter = 0;     ///< transmit error counter (data[6]) when `countersValid`
  std::uint8_t rxErrorCounter = 0;     ///< receive error counter (data[7]) when `countersValid`
};

/// Decodes the error frame `frame` into `out`.
///
/// Returns `InvalidArgument` (and leaves `out` reset) when `frame.error` is false. Data bytes
/// past `frame.dlc` count as zero, so a short report still yields its error classes.
/// The implied controller state is the worst one the frame names: bus-off, then passive, then
/// warning; a restart or a "back to error-active" report gives error-active.
Status decodeCanError(const CanFrame& frame, CanErrorReport& out) noexcept;

}  // namespace agv::drivers
