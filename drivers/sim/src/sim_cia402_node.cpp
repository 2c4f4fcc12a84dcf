#include "agv/sim/sim_cia402_node.hpp"

#include <cmath>

namespace agv::sim {

using drivers::CanFrame;
using namespace drivers::canopen;
using namespace drivers::canopen::cia402;

namespace {
constexpr std::uint32_t kHeartbeatBase = 0x700;
constexpr std::uint16_t kDeviceType = 0x1000;
constexpr std::uint16_t kErrorRegister = 0x1001;
constexpr std::uint32_t kAbortNone = 0;

std::uint32_t code(SdoAbortCode c) noexcept {
  return static_cast<std::uint32_t>(c);
}

double rampTo(double v, double target, double rate, double dt) noexcept {
  const double step = rate * dt;
  if (std::fabs(target - v) <= step) {
    return target;
  }
  return v + (target > v ? step : -step);
}

bool isRpdoMappable(std::uint16_t index) noexcept {
  return index == kControlword || index == kTargetVelocity || index == kTargetPosition;
}

bool isTpdoMappable(std::uint16_t index) noexcept {
  return index == kStatusword || index == kPositionActual || index == kVelocityActual || index == kModesDisplay ||
         index == kErrorCode;
}
}  // namespace

SimCia402Node::SimCia402Node(const SimCia402NodeParams& params) noexcept : params_(params) {
  position_ = static_cast<double>(params.initialPosition);
  activeTarget_ = params.initialPosition;
  resetDictionary();
}

void SimCia402Node::add(std::uint16_t index, std::uint8_t sub, std::uint8_t size, bool writable,
                        std::uint32_t value) noexcept {
  if (entries_ < kEntries) {
    od_[entries_++] = Entry{index, sub, size, writable, value};
  }
}

void SimCia402Node::resetDictionary() noexcept {
  entries_ = 0;
  const std::uint32_t n = params_.nodeId;
  add(kDeviceType, 0, 4, false, 0x00020192U);  // CiA 402 drive, servo
  add(kErrorRegister, 0, 1, false, 0);
  add(kConsumerHeartbeat, 0, 1, false, 1);
  add(kConsumerHeartbeat, 1, 4, true, 0);
  add(kProducerHeartbeat, 0, 2, true, 0);
  // Defaults as a drive leaves the factory: RPDO1 maps the controlword only, TPDO1 the statusword
  // (no event timer), TPDO2 disabled. The controller must map what it needs.
  add(kRpdoCommunication, 1, 4, true, kRpdo1Base + n);
  add(kRpdoCommunication, 2, 1, true, kPdoEventDriven);
  add(kRpdoMapping, 0, 1, true, 1);
  add(kRpdoMapping, 1, 4, true, mappingEntry(kControlword, 0, 16));
  add(kRpdoMapping, 2, 4, true, 0);
  add(kRpdoMapping, 3, 4, true, 0);
  add(kRpdoMapping, 4, 4, true, 0);
  for (std::uint16_t p = 0; p < 2U; ++p) {
    const std::uint32_t cob = p == 0U ? kTpdo1Base + n : kPdoInvalid | (kTpdo2Base + n);
    add(static_cast<std::uint16_t>(kTpdoCommunication + p), 1, 4, true, cob);
    add(static_cast<std::uint16_t>(kTpdoCommunication + p), 2, 1, true, kPdoEventDriven);
    add(static_cast<std::uint16_t>(kTpdoCommunication + p), 5, 2, true, 0);
    add(static_cast<std::uint16_t>(kTpdoMapping + p), 0, 1, true, p == 0U ? 1U : 0U);
    add(static_cast<std::uint16_t>(kTpdoMapping + p), 1, 4, true, p == 0U ? mappingEntry(kStatusword, 0, 16) : 0U);
    add(static_cast<std::uint16_t>(kTpdoMapping + p), 2, 4, true, 0);
    add(static_cast<std::uint16_t>(kTpdoMapping + p), 3, 4, true, 0);
    add(static_cast<std::uint16_t>(kTpdoMapping + p), 4, 4, true, 0);
  }
  add(kErrorCode, 0, 2, false, errorCode_);
  add(kControlword, 0, 2, true, 0);
  add(kStatusword, 0, 2, false, 0);
  add(kModesOfOperation, 0, 1, true, 0);
  add(kModesDisplay, 0, 1, false, 0);
  add(kPositionActual, 0, 4, false, 0);
  add(kVelocityActual, 0, 4, false, 0);
  add(kTargetPosition, 0, 4, true, static_cast<std::uint32_t>(params_.initialPosition));
  add(kProfileVelocity, 0, 4, true, 1000);
  add(kProfileAcceleration, 0, 4, true, 1000);
  add(kProfileDeceleration, 0, 4, true, 1000);
  add(kQuickStopDeceleration, 0, 4, true, 5000);
  add(kTargetVelocity, 0, 4, true, 0);
  // The drive's reactions as it leaves the factory: no reaction to a lost controller (the
  // controller must configure one: the tests show its write is what faults a silent-controller
  // drive), quick stop as `params_.options` says, fault reaction on the quick-stop ramp.
  add(kAbortConnectionOption, 0, 2, true, 0);
  add(kQuickStopOption, 0, 2, true, params_.options.quickStopToOperationEnabled ? 6U : 2U);
  add(kFaultReactionOption, 0, 2, true, 2);
  modeDisplay_ = 0;
  controlword_ = 0;
  controllerSeen_ = false;
  controllerLost_ = false;
}

void SimCia402Node::resetCommunication() noexcept {
  // Keep the application objects (0x6000..), reset the communication ones to their defaults.
  Entry keep[kEntries];
  std::size_t k = 0;
  for (std::size_t i = 0; i < entries_; ++i) {
    if (od_[i].index >= 0x2000U) {
      keep[k++] = od_[i];
    }
  }
  const std::uint16_t cw = controlword_;
  const std::int8_t mode = modeDisplay_;
  resetDictionary();
  for (std::size_t i = 0; i < k; ++i) {
    Entry* e = find(keep[i].index, keep[i].sub);
    if (e != nullptr) {
      e->value = keep[i].value;
    }
  }
  controlword_ = cw;
  modeDisplay_ = mode;
}

SimCia402Node::Entry* SimCia402Node::find(std::uint16_t index, std::uint8_t sub) noexcept {
  for (std::size_t i = 0; i < entries_; ++i) {
    if (od_[i].index == index && od_[i].sub == sub) {
      return &od_[i];
    }
  }
  return nullptr;
}

const SimCia402Node::Entry* SimCia402Node::find(std::uint16_t index, std::uint8_t sub) const noexcept {
  for (std::size_t i = 0; i < entries_; ++i) {
    if (od_[i].index == index && od_[i].sub == sub) {
      return &od_[i];
    }
  }
  return nullptr;
}

bool SimCia402Node::indexExists(std::uint16_t index) const noexcept {
  for (std::size_t i = 0; i < entries_; ++i) {
    if (od_[i].index == index) {
      return true;
    }
  }
  return false;
}

std::uint32_t SimCia402Node::read(std::uint16_t index, std::uint8_t sub) const noexcept {
  if (index == kStatusword && sub == 0U) {
    return statusword();
  }
  if (index == kPositionActual && sub == 0U) {
    if (feedback_) {
      return static_cast<std::uint32_t>(feedbackCounts_);
    }
    return static_cast<std::uint32_t>(static_cast<std::int32_t>(std::lround(position_)));
  }
  if (index == kVelocityActual && sub == 0U) {
    return static_cast<std::uint32_t>(static_cast<std::int32_t>(std::lround(velocity_)));
  }
  if (index == kModesDisplay && sub == 0U) {
    return static_cast<std::uint8_t>(modeDisplay_);
  }
  const Entry* e = find(index, sub);
  return e != nullptr ? e->value : 0U;
}

std::uint16_t SimCia402Node::statusword() const noexcept {
  std::uint16_t sw = static_cast<std::uint16_t>(statuswordBits(state_) | kSwRemote);
  if (state_ == PowerState::OperationEnabled) {
    if (modeDisplay_ == static_cast<std::int8_t>(OperationMode::ProfilePosition)) {
      if (setPointAck_) {
        sw = static_cast<std::uint16_t>(sw | kSwSetPointAcknowledge);
      }
      if (targetReached_) {
        sw = static_cast<std::uint16_t>(sw | kSwTargetReached);
      }
    } else if (modeDisplay_ == static_cast<std::int8_t>(OperationMode::ProfileVelocity)) {
      if (std::fabs(velocity_) < 1.0) {
        sw = static_cast<std::uint16_t>(sw | kSwSpeedZero);
      }
      if (std::fabs(velocity_ - static_cast<double>(targetVelocity())) < 1.0) {
        sw = static_cast<std::uint16_t>(sw | kSwTargetReached);
      }
    }
  }
  return sw;
}

bool SimCia402Node::pdoValid(std::uint16_t commIndex, std::uint32_t& cobId) const noexcept {
  const Entry* e = find(commIndex, 1);
  if (e == nullptr || (e->value & kPdoInvalid) != 0U) {
    return false;
  }
  cobId = e->value & 0x7FFU;
  return true;
}

std::uint32_t SimCia402Node::checkMapping(std::uint16_t mappingIndex, std::uint8_t count) const noexcept {
  if (count > 4U) {
    return code(SdoAbortCode::PdoLengthExceeded);
  }
  const bool rpdo = mappingIndex < kTpdoCommunication;
  unsigned bits = 0;
  for (std::uint8_t s = 1; s <= count; ++s) {
    const std::uint32_t m = read(mappingIndex, s);
    const std::uint16_t idx = static_cast<std::uint16_t>(m >> 16U);
    const std::uint8_t sub = static_cast<std::uint8_t>((m >> 8U) & 0xFFU);
    const std::uint8_t len = static_cast<std::uint8_t>(m & 0xFFU);
    const Entry* e = find(idx, sub);
    if (e == nullptr) {
      return code(SdoAbortCode::ObjectDoesNotExist);
    }
    if (rpdo ? !isRpdoMappable(idx) : !isTpdoMappable(idx)) {
      return code(SdoAbortCode::ObjectNotMappable);
    }
    if (len != 8U * e->size) {
      return code(SdoAbortCode::ParameterIncompatible);
    }
    bits += len;
  }
  if (bits > 64U) {
    return code(SdoAbortCode::PdoLengthExceeded);
  }
  return kAbortNone;
}

std::uint32_t SimCia402Node::write(std::uint16_t index, std::uint8_t sub, std::uint32_t value,
                                   std::uint8_t size) noexcept {
  Entry* e = find(index, sub);
  if (e == nullptr) {
    return indexExists(index) ? code(SdoAbortCode::SubIndexDoesNotExist) : code(SdoAbortCode::ObjectDoesNotExist);
  }
  if (!e->writable) {
    return code(SdoAbortCode::WriteOfReadOnly);
  }
  if (size != 0U && size != e->size) {
    return size > e->size ? code(SdoAbortCode::LengthTooHigh) : code(SdoAbortCode::LengthTooLow);
  }
  const bool mapping =
      (index >= kRpdoMapping && index < kRpdoMapping + 4U) || (index >= kTpdoMapping && index < kTpdoMapping + 4U);
  if (mapping) {
    const std::uint16_t comm = static_cast<std::uint16_t>(index - 0x200U);
    std::uint32_t cob = 0;
    if (pdoValid(comm, cob)) {
      return code(SdoAbortCode::CannotTransferDeviceState);  // the PDO must be disabled first
    }
    if (sub == 0U) {
      const std::uint32_t abort = checkMapping(index, static_cast<std::uint8_t>(value));
      if (abort != kAbortNone) {
        return abort;
      }
    } else if (read(index, 0) != 0U) {
      return code(SdoAbortCode::CannotTransferDeviceState);  // sub 0 must be 0 while mapping
    }
  }
  if ((index == kRpdoCommunication || index == kTpdoCommunication || index == kTpdoCommunication + 1U) && sub == 1U) {
    std::uint32_t cob = 0;
    if (pdoValid(index, cob) && (value & kPdoInvalid) == 0U && (value & 0x7FFU) != cob) {
      return code(SdoAbortCode::InvalidValue);  // a valid PDO's COB-ID cannot change
    }
  }
  const std::int16_t option = static_cast<std::int16_t>(value & 0xFFFFU);
  if ((index == kAbortConnectionOption && (option < 0 || option > 3)) ||
      (index == kQuickStopOption && option != 1 && option != 2 && option != 5 && option != 6) ||
      (index == kFaultReactionOption && option != 1 && option != 2)) {
    return code(SdoAbortCode::InvalidValue);  // the reactions this drive implements (header)
  }
  if (index == kModesOfOperation) {
    const std::int8_t mode = static_cast<std::int8_t>(value & 0xFFU);
    if (mode != static_cast<std::int8_t>(OperationMode::ProfilePosition) &&
        mode != static_cast<std::int8_t>(OperationMode::ProfileVelocity)) {
      return code(SdoAbortCode::InvalidValue);
    }
    modeDisplay_ = mode;
    activeTarget_ = static_cast<std::int32_t>(std::lround(position_));
  }
  e->value = value;
  if (index == kControlword) {
    onControlword(static_cast<std::uint16_t>(value));
  } else if (index == kProducerHeartbeat) {
    nextHeartbeat_ = last_;
  } else if (index == kConsumerHeartbeat) {
    controllerSeen_ = false;
    controllerLost_ = false;
  } else if (index == kTpdoCommunication || index == kTpdoCommunication + 1U) {
    nextTpdo_[index - kTpdoCommunication] = last_;
  }
  return kAbortNone;
}

void SimCia402Node::queue(const CanFrame& frame) noexcept {
  if (outbox_.tryPush(frame) != Status::Ok) {
    ++counters_.outboxDropped;
  }
}

void SimCia402Node::enterFault(std::uint16_t errorCode) noexcept {
  errorCode_ = errorCode;
  Entry* e = find(kErrorCode, 0);
  if (e != nullptr) {
    e->value = errorCode;
  }
  Entry* reg = find(kErrorRegister, 0);
  if (reg != nullptr) {
    reg->value = 0x01;  // generic error
  }
  if (state_ == PowerState::OperationEnabled || state_ == PowerState::QuickStopActive ||
      state_ == PowerState::SwitchedOn || state_ == PowerState::ReadyToSwitchOn) {
    state_ = PowerState::FaultReactionActive;  // 13: stop, then Fault
  } else if (state_ != PowerState::FaultReactionActive) {
    state_ = PowerState::Fault;
  }
  queue(encodeEmcy(params_.nodeId, errorCode, 0x01, last_));
  ++counters_.emcys;
}

void SimCia402Node::onConnectionLost() noexcept {
  // CiA 301: the heartbeat error is signalled by EMCY whatever the reaction; CiA 402 0x6007 says
  // what the drive does about it.
  switch (read(kAbortConnectionOption, 0)) {
    case 1:  // fault signal
      enterFault(params_.heartbeatErrorCode);
      return;
    case 2:  // disable voltage: the power stage off, the brake holds
      if (state_ != PowerState::Fault && state_ != PowerState::FaultReactionActive) {
        state_ = PowerState::SwitchOnDisabled;
        velocity_ = 0.0;
      }
      break;
    case 3:  // quick stop
      if (state_ == PowerState::OperationEnabled) {
        state_ = PowerState::QuickStopActive;
      }
      break;
    default:  // 0: no action
      break;
  }
  queue(encodeEmcy(params_.nodeId, params_.heartbeatErrorCode, 0x00, last_));
  ++counters_.emcys;
}

Cia402Options SimCia402Node::options() const noexcept {
  const std::uint32_t quickStop = read(kQuickStopOption, 0);
  Cia402Options o;
  o.quickStopToOperationEnabled = quickStop >= 5U && quickStop <= 8U;
  return o;
}

void SimCia402Node::injectFault(std::uint16_t errorCode) noexcept {
  enterFault(errorCode);
}

void SimCia402Node::powerCycle() noexcept {
  errorCode_ = 0;
  resetDictionary();
  state_ = PowerState::SwitchOnDisabled;  // 0, 1 after the self-test
  velocity_ = 0.0;
  setPointAck_ = false;
  nmt_ = NmtState::BootUp;
  bootUpPending_ = true;
}

void SimCia402Node::onControlword(std::uint16_t cw) noexcept {
  const std::uint16_t prev = controlword_;
  controlword_ = cw;
  Entry* e = find(kControlword, 0);
  if (e != nullptr) {
    e->value = cw;
  }
  const Cia402Command cmd = decodeControlword(prev, cw);
  const Result<PowerState> next = nextState(state_, cmd, options());
  if (next.ok()) {
    const PowerState from = state_;
    state_ = next.value();
    if (from != PowerState::OperationEnabled && state_ == PowerState::OperationEnabled) {
      activeTarget_ = static_cast<std::int32_t>(std::lround(position_));  // hold where it stands
      targetReached_ = true;
      setPointAck_ = false;
    }
    if (from == PowerState::Fault && state_ == PowerState::SwitchOnDisabled) {
      Entry* reg = find(kErrorRegister, 0);
      if (reg != nullptr) {
        reg->value = 0;
      }
      queue(encodeEmcy(params_.nodeId, 0x0000, 0x00, last_));  // error reset
      ++counters_.emcys;
    }
  } else if (prev != cw) {
    ++counters_.rejectedCommands;
  }
  // Profile position set-point handshake.
  if (modeDisplay_ == static_cast<std::int8_t>(OperationMode::ProfilePosition)) {
    const bool rising = (cw & kCwNewSetPoint) != 0U && (prev & kCwNewSetPoint) == 0U;
    if ((cw & kCwNewSetPoint) == 0U) {
      setPointAck_ = false;
    } else if (rising && !setPointAck_ && state_ == PowerState::OperationEnabled) {
      activeTarget_ = static_cast<std::int32_t>(read(kTargetPosition, 0));
      setPointAck_ = true;
      targetReached_ = false;
      ++counters_.setPointsAccepted;
    }
  }
}

void SimCia402Node::onSdo(const CanFrame& frame) noexcept {
  SdoMessage m;
  const Status s = decodeSdoRequest(frame, params_.nodeId, m);
  if (s == Status::NotFound) {
    return;
  }
  if (s == Status::Truncated) {
    ++counters_.malformed;
    return;
  }
  ++counters_.sdoRequests;
  SdoMessage answer;
  answer.index = m.index;
  answer.subIndex = m.subIndex;
  std::uint32_t abort = kAbortNone;
  if (s != Status::Ok) {
    abort = code(SdoAbortCode::CommandSpecifierInvalid);
    answer.index = static_cast<std::uint16_t>(frame.data[1] | (frame.data[2] << 8U));
    answer.subIndex = frame.data[3];
  } else if (m.kind == SdoKind::Abort) {
    return;  // nothing to answer
  } else if (m.kind == SdoKind::UploadRequest) {
    const Entry* e = find(m.index, m.subIndex);
    if (e == nullptr) {
      abort = indexExists(m.index) ? code(SdoAbortCode::SubIndexDoesNotExist) : code(SdoAbortCode::ObjectDoesNotExist);
    } else {
      answer.kind = SdoKind::UploadResponse;
      answer.size = e->size;
      answer.value = read(m.index, m.subIndex);
      if (e->size < 4U) {
        answer.value &= (1U << (8U * e->size)) - 1U;
      }
    }
  } else {
    abort = write(m.index, m.subIndex, m.value, m.size);
    answer.kind = SdoKind::DownloadResponse;
  }
  if (abort != kAbortNone) {
    answer.kind = SdoKind::Abort;
    answer.abortCode = abort;
    ++counters_.sdoAborts;
  }
  CanFrame out;
  if (encodeSdoResponse(params_.nodeId, answer, out) == Status::Ok) {
    queue(out);
  }
}

void SimCia402Node::onRpdo(std::uint16_t pdo, const CanFrame& frame) noexcept {
  const std::uint16_t mapIndex = static_cast<std::uint16_t>(kRpdoMapping + pdo);
  const std::uint32_t count = read(mapIndex, 0);
  std::uint32_t values[4] = {};
  std::uint16_t indices[4] = {};
  std::uint8_t subs[4] = {};
  unsigned offset = 0;
  for (std::uint8_t s = 1; s <= count && s <= 4U; ++s) {
    const std::uint32_t m = read(mapIndex, s);
    const unsigned bytes = (m & 0xFFU) / 8U;
    if (offset + bytes > frame.dlc || bytes > 4U) {
      ++counters_.malformed;  // shorter than the mapping: the whole PDO is discarded
      return;
    }
    std::uint32_t v = 0;
    for (unsigned i = 0; i < bytes; ++i) {
      v |= static_cast<std::uint32_t>(frame.data[offset + i]) << (8U * i);
    }
    values[s - 1] = v;
    indices[s - 1] = static_cast<std::uint16_t>(m >> 16U);
    subs[s - 1] = static_cast<std::uint8_t>((m >> 8U) & 0xFFU);
    offset += bytes;
  }
  ++counters_.rpdos;
  // The set-points first, the controlword last: a new set-point bit takes the target of the same PDO.
  std::int32_t cwSlot = -1;
  for (std::uint32_t i = 0; i < count && i < 4U; ++i) {
    if (indices[i] == kControlword) {
      cwSlot = static_cast<std::int32_t>(i);
      continue;
    }
    Entry* e = find(indices[i], subs[i]);
    if (e != nullptr) {
      e->value = values[i];
    }
  }
  if (cwSlot >= 0) {
    onControlword(static_cast<std::uint16_t>(values[cwSlot]));
  }
}

void SimCia402Node::receive(const CanFrame& frame, Timestamp now) noexcept {
  if (frame.extended || frame.rtr || frame.error) {
    return;
  }
  const std::uint32_t n = params_.nodeId;
  if (frame.id == 0x000U) {
    if (frame.dlc < 2U) {
      ++counters_.malformed;
      return;
    }
    if (frame.data[1] != 0U && frame.data[1] != n) {
      return;
    }
    switch (static_cast<NmtCommand>(frame.data[0])) {
      case NmtCommand::Start:
        nmt_ = NmtState::Operational;
        nextTpdo_[0] = last_;
        nextTpdo_[1] = last_;
        break;
      case NmtCommand::Stop:
        nmt_ = NmtState::Stopped;
        break;
      case NmtCommand::EnterPreOperational:
        nmt_ = NmtState::PreOperational;
        break;
      case NmtCommand::ResetNode:
        powerCycle();
        break;
      case NmtCommand::ResetCommunication:
        resetCommunication();
        nmt_ = NmtState::BootUp;
        bootUpPending_ = true;
        break;
    }
    return;
  }
  if (frame.id == kSdoRequestBase + n) {
    if (nmt_ == NmtState::PreOperational || nmt_ == NmtState::Operational) {
      onSdo(frame);
    }
    return;
  }
  std::uint32_t cob = 0;
  if (pdoValid(kRpdoCommunication, cob) && frame.id == cob) {
    if (nmt_ == NmtState::Operational) {
      onRpdo(0, frame);
    }
    return;
  }
  const std::uint32_t consumer = read(kConsumerHeartbeat, 1);
  const std::uint32_t producer = (consumer >> 16U) & 0x7FU;
  if (producer != 0U && frame.id == kHeartbeatBase + producer && frame.dlc >= 1U) {
    controllerSeen_ = true;
    controllerLost_ = false;
    lastControllerHeartbeat_ = now;
  }
}

void SimCia402Node::move(double dt) noexcept {
  const double accel = static_cast<double>(read(kProfileAcceleration, 0));
  const double decel = static_cast<double>(read(kProfileDeceleration, 0));
  const double quick = static_cast<double>(read(kQuickStopDeceleration, 0));
  const bool halt = (controlword_ & kCwHalt) != 0U;
  if (state_ == PowerState::QuickStopActive || state_ == PowerState::FaultReactionActive) {
    // Option codes 1 and 5 (quick stop) and 1 (fault reaction) ramp on the profile deceleration,
    // the others on the quick-stop deceleration.
    const bool quickStop = state_ == PowerState::QuickStopActive;
    const std::uint32_t option = read(quickStop ? kQuickStopOption : kFaultReactionOption, 0);
    velocity_ = rampTo(velocity_, 0.0, option == 1U || option == 5U ? decel : quick, dt);
    position_ += velocity_ * dt;
    if (velocity_ == 0.0) {
      // Quick stop 1, 2: Switch on disabled once stopped (5, 6 stay in Quick stop active);
      // the fault reaction done: Fault.
      if (!quickStop) {
        state_ = PowerState::Fault;
      } else if (option == 1U || option == 2U) {
        state_ = PowerState::SwitchOnDisabled;
      }
    }
    return;
  }
  if (state_ != PowerState::OperationEnabled) {
    velocity_ = 0.0;  // power stage off or not enabled: the brake holds
    return;
  }
  if (modeDisplay_ == static_cast<std::int8_t>(OperationMode::ProfileVelocity)) {
    const double target = halt ? 0.0 : static_cast<double>(targetVelocity());
    const bool speeding = std::fabs(target) > std::fabs(velocity_) && target * velocity_ >= 0.0;
    velocity_ = rampTo(velocity_, target, speeding ? accel : decel, dt);
    position_ += velocity_ * dt;
  } else if (modeDisplay_ == static_cast<std::int8_t>(OperationMode::ProfilePosition)) {
    const double err = static_cast<double>(activeTarget_) - position_;
    const double vmax = static_cast<double>(read(kProfileVelocity, 0));
    double want = halt ? 0.0 : std::sqrt(2.0 * decel * std::fabs(err));
    want = want < vmax ? want : vmax;
    want = err < 0.0 ? -want : want;
    const bool speeding = std::fabs(want) > std::fabs(velocity_) && want * velocity_ >= 0.0;
    velocity_ = rampTo(velocity_, want, speeding ? accel : decel, dt);
    const double stepLen = velocity_ * dt;
    if (std::fabs(err) <= std::fabs(stepLen) || std::fabs(err) < 0.5) {
      position_ = static_cast<double>(activeTarget_);
      velocity_ = 0.0;
      targetReached_ = true;
    } else {
      position_ += stepLen;
    }
  }
}

CanFrame SimCia402Node::tpdoFrame(std::uint16_t pdo, std::uint32_t cobId) const noexcept {
  CanFrame f;
  f.id = cobId;
  const std::uint16_t mapIndex = static_cast<std::uint16_t>(kTpdoMapping + pdo);
  const std::uint32_t count = read(mapIndex, 0);
  unsigned offset = 0;
  for (std::uint8_t s = 1; s <= count && s <= 4U; ++s) {
    const std::uint32_t m = read(mapIndex, s);
    const unsigned bytes = (m & 0xFFU) / 8U;
    const std::uint32_t v = read(static_cast<std::uint16_t>(m >> 16U), static_cast<std::uint8_t>((m >> 8U) & 0xFFU));
    for (unsigned i = 0; i < bytes && offset < 8U; ++i) {
      f.data[offset++] = static_cast<std::uint8_t>(v >> (8U * i));
    }
  }
  f.dlc = static_cast<std::uint8_t>(offset);
  f.stamp = last_;
  return f;
}

std::size_t SimCia402Node::step(Timestamp now, Span<CanFrame> out) noexcept {
  if (!started_) {
    started_ = true;
    last_ = now;
  }
  const double dt = (now - last_).seconds();
  last_ = now;
  if (dt > 0.0) {
    move(dt);
  }
  // Heartbeat consumer: a silent controller faults the drive (once per loss).
  const std::uint32_t consumer = read(kConsumerHeartbeat, 1);
  const Duration consumerTime = Duration::fromMilliseconds(consumer & 0xFFFFU);
  if (controllerSeen_ && !controllerLost_ && consumerTime.ns > 0 && now - lastControllerHeartbeat_ > consumerTime) {
    controllerLost_ = true;
    onConnectionLost();
  }
  std::size_t n = 0;
  auto emit = [&](const CanFrame& f) {
    if (silent_) {
      return;
    }
    if (n < out.size()) {
      out[n++] = f;
    } else {
      ++counters_.outboxDropped;
    }
  };
  if (bootUpPending_) {
    bootUpPending_ = false;
    emit(encodeHeartbeat(params_.nodeId, NmtState::BootUp, now));
    nmt_ = NmtState::PreOperational;
  }
  while (!outbox_.empty()) {
    emit(outbox_.front());
    outbox_.pop_front();
  }
  const std::uint32_t hbMs = read(kProducerHeartbeat, 0);
  if (hbMs != 0U && now >= nextHeartbeat_) {
    emit(encodeHeartbeat(params_.nodeId, nmt_, now));
    ++counters_.heartbeats;
    nextHeartbeat_ = now + Duration::fromMilliseconds(hbMs);
  }
  if (nmt_ == NmtState::Operational) {
    for (std::uint16_t p = 0; p < 2U; ++p) {
      std::uint32_t cob = 0;
      const std::uint32_t timerMs = read(static_cast<std::uint16_t>(kTpdoCommunication + p), 5);
      if (pdoValid(static_cast<std::uint16_t>(kTpdoCommunication + p), cob) && timerMs != 0U && now >= nextTpdo_[p]) {
        emit(tpdoFrame(p, cob));
        ++counters_.tpdos;
        nextTpdo_[p] = now + Duration::fromMilliseconds(timerMs);
      }
    }
  }
  return n;
}

}  // namespace agv::sim
