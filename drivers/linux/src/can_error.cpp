#include "agv/drivers/linux/can_error.hpp"

#include <linux/can.h>
#include <linux/can/error.h>

namespace agv::drivers {

const char* toString(CanControllerState state) noexcept {
  switch (state) {
    case CanControllerState::ErrorActive:
      return "error-active";
    case CanControllerState::ErrorWarning:
      return "error-warning";
    case CanControllerState::ErrorPassive:
      return "error-passive";
    case CanControllerState::BusOff:
      return "bus-off";
  }
  return "unknown";
}

namespace {
constexpr bool has(std::uint32_t bits, std::uint32_t flag) noexcept {
  return (bits & flag) != 0U;
}
constexpr bool has8(std::uint8_t bits, unsigned flag) noexcept {
  return (static_cast<unsigned>(bits) & flag) != 0U;
}
}  // namespace

Status decodeCanError(const CanFrame& frame, CanErrorReport& out) noexcept {
  out = CanErrorReport{};
  if (!frame.error) {
    return Status::InvalidArgument;
  }
  // Bytes the frame did not carry count as zero ("unspecified" in every field).
  std::uint8_t d[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  const std::uint8_t n = frame.dlc < 8U ? frame.dlc : static_cast<std::uint8_t>(8U);
  for (std::uint8_t i = 0; i < n; ++i) {
    d[i] = frame.data[i];
  }

  const std::uint32_t c = frame.id & CAN_ERR_MASK;
  out.classes = c;
  out.txTimeout = has(c, CAN_ERR_TX_TIMEOUT);
  out.lostArbitration = has(c, CAN_ERR_LOSTARB);
  out.controllerProblem = has(c, CAN_ERR_CRTL);
  out.protocolViolation = has(c, CAN_ERR_PROT);
  out.transceiverProblem = has(c, CAN_ERR_TRX);
  out.noAck = has(c, CAN_ERR_ACK);
  out.busOff = has(c, CAN_ERR_BUSOFF);
  out.busError = has(c, CAN_ERR_BUSERROR);
  out.restarted = has(c, CAN_ERR_RESTARTED);
  out.countersValid = has(c, CAN_ERR_CNT);

  if (out.lostArbitration) {
    out.arbitrationBit = d[0];
  }
  if (out.controllerProblem) {
    out.controllerDetail = d[1];
    out.rxOverflow = has8(d[1], CAN_ERR_CRTL_RX_OVERFLOW);
    out.txOverflow = has8(d[1], CAN_ERR_CRTL_TX_OVERFLOW);
  }
  if (out.protocolViolation) {
    out.protocolType = d[2];
    out.protocolLocation = d[3];
  }
  if (out.transceiverProblem) {
    out.transceiverStatus = d[4];
  }
  if (out.countersValid) {
    out.txErrorCounter = d[6];
    out.rxErrorCounter = d[7];
  }

  // The worst state the frame names wins.
  if (out.busOff) {
    out.stateKnown = true;
    out.state = CanControllerState::BusOff;
  } else if (out.controllerProblem && has8(d[1], CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE)) {
    out.stateKnown = true;
    out.state = CanControllerState::ErrorPassive;
  } else if (out.controllerProblem && has8(d[1], CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING)) {
    out.stateKnown = true;
    out.state = CanControllerState::ErrorWarning;
  } else if (out.restarted || (out.controllerProblem && has8(d[1], CAN_ERR_CRTL_ACTIVE))) {
    out.stateKnown = true;
    out.state = CanControllerState::ErrorActive;
  }
  return Status::Ok;
}

}  // namespace agv::drivers
