#include "agv/drivers/protocol/canopen/cia402_drive.hpp"

#include <cmath>

namespace agv::drivers::canopen {

using namespace cia402;

namespace {
constexpr std::uint32_t kHeartbeatBase = 0x700;

std::int64_t milliseconds(Duration d) noexcept {
  return d.ns / 1000000;
}

bool msInRange(Duration d) noexcept {
  const std::int64_t ms = milliseconds(d);
  return ms >= 1 && ms <= 65535;
}

std::uint32_t u32ms(Duration d) noexcept {
  return static_cast<std::uint32_t>(milliseconds(d));
}

/// Rounds to int32, saturating (callers limit the value first; NaN -> 0).
std::int32_t roundSaturated(double v) noexcept {
  if (!(v == v)) {
    return 0;
  }
  if (v >= 2147483647.0) {
    return 2147483647;
  }
  if (v <= -2147483648.0) {
    return -2147483647 - 1;
  }
  return static_cast<std::int32_t>(std::lround(v));
}

/// A non-negative profile value in device units, rounded, at least 1, saturating.
std::uint32_t profileUnits(double v) noexcept {
  if (!(v >= 1.0)) {
    return 1U;
  }
  if (v >= 4294967295.0) {
    return 0xFFFFFFFFU;
  }
  return static_cast<std::uint32_t>(std::llround(v));
}

bool positiveFinite(double v) noexcept {
  return std::isfinite(v) && v > 0.0;
}

std::int32_t readI32(const std::uint8_t* p) noexcept {
  const std::uint32_t u = static_cast<std::uint32_t>(p[0]) | (static_cast<std::uint32_t>(p[1]) << 8U) |
                          (static_cast<std::uint32_t>(p[2]) << 16U) | (static_cast<std::uint32_t>(p[3]) << 24U);
  return static_cast<std::int32_t>(u);
}
}  // namespace

// ---------------------------------------------------------------------------------------------
// CanOutbox

Status CanOutbox::push(const CanFrame& frame) noexcept {
  if (ring_.tryPush(frame) != Status::Ok) {
    ++dropped_;
    return Status::CapacityExceeded;
  }
  return Status::Ok;
}

void CanOutbox::pushUrgent(const CanFrame& frame) noexcept {
  if (ring_.size() == ring_.capacity()) {
    ++dropped_;
  }
  (void)ring_.push(frame);
}

std::size_t CanOutbox::take(Span<CanFrame> out) noexcept {
  std::size_t n = 0;
  while (n < out.size() && !ring_.empty()) {
    out[n++] = ring_.front();
    ring_.pop_front();
  }
  return n;
}

// ---------------------------------------------------------------------------------------------
// Cia402Axis

const char* toString(AxisPhase phase) noexcept {
  switch (phase) {
    case AxisPhase::Idle:
      return "idle";
    case AxisPhase::Configuring:
      return "configuring";
    case AxisPhase::ConfirmingMode:
      return "confirming mode";
    case AxisPhase::Starting:
      return "starting";
    case AxisPhase::Enabling:
      return "enabling";
    case AxisPhase::Enabled:
      return "enabled";
    case AxisPhase::QuickStopping:
      return "quick stopping";
    case AxisPhase::Faulted:
      return "faulted";
    case AxisPhase::Failed:
      return "failed";
    case AxisPhase::Released:
      return "released";
  }
  return "unknown phase";
}

Cia402Axis::Cia402Axis(const Cia402AxisConfig& config, CanOutbox& outbox) noexcept : config_(config), out_(outbox) {}

Status Cia402Axis::validate() const noexcept {
  const Cia402AxisConfig& c = config_;
  if (c.nodeId < 1U || c.nodeId > 127U || c.controllerNodeId < 1U || c.controllerNodeId > 127U ||
      c.nodeId == c.controllerNodeId) {
    return Status::InvalidArgument;
  }
  if (c.mode != OperationMode::ProfileVelocity && c.mode != OperationMode::ProfilePosition) {
    return Status::InvalidArgument;
  }
  if (!msInRange(c.tpdoPeriod) || !msInRange(c.heartbeatPeriod) || !msInRange(c.controllerHeartbeatTimeout)) {
    return Status::InvalidArgument;
  }
  if (c.heartbeatTimeout <= c.heartbeatPeriod || c.sdoTimeout.ns <= 0 || c.stateTimeout.ns <= 0) {
    return Status::InvalidArgument;
  }
  if (c.mode == OperationMode::ProfilePosition && c.profileVelocity == 0U) {
    return Status::InvalidArgument;
  }
  return Status::Ok;
}

void Cia402Axis::addWrite(std::uint16_t index, std::uint8_t sub, std::uint8_t size, std::uint32_t value) noexcept {
  if (writeCount_ < kMaxConfigWrites) {
    writes_[writeCount_++] = SdoWrite{index, sub, size, value};
  }
}

void Cia402Axis::buildConfig() noexcept {
  const Cia402AxisConfig& c = config_;
  const std::uint32_t n = c.nodeId;
  writeCount_ = 0;
  // The heartbeat producer first: supervision of the drive starts when it is confirmed.
  addWrite(kProducerHeartbeat, 0, 2, u32ms(c.heartbeatPeriod));
  addWrite(kConsumerHeartbeat, 1, 4,
           (static_cast<std::uint32_t>(c.controllerNodeId) << 16U) | u32ms(c.controllerHeartbeatTimeout));
  // The drive's own reactions: a silent controller faults it, a quick stop and a fault both end
  // on the quick-stop ramp. A drive without these objects fails the bring-up (abort named).
  addWrite(kAbortConnectionOption, 0, 2, static_cast<std::uint16_t>(kAbortConnectionFaultSignal));
  addWrite(kQuickStopOption, 0, 2, static_cast<std::uint16_t>(kQuickStopRampThenDisabled));
  addWrite(kFaultReactionOption, 0, 2, static_cast<std::uint16_t>(kFaultReactionQuickStopRamp));
  addWrite(kModesOfOperation, 0, 1, static_cast<std::uint8_t>(c.mode));
  addWrite(kProfileAcceleration, 0, 4, c.profileAcceleration);
  addWrite(kProfileDeceleration, 0, 4, c.profileDeceleration);
  addWrite(kQuickStopDeceleration, 0, 4, c.quickStopDeceleration);
  if (c.mode == OperationMode::ProfilePosition) {
    addWrite(kProfileVelocity, 0, 4, c.profileVelocity);
  }
  const std::uint16_t target = c.mode == OperationMode::ProfilePosition ? kTargetPosition : kTargetVelocity;
  // RPDO1: controlword + target. Disabled while the mapping is written (CiA 301 procedure).
  addWrite(kRpdoCommunication, 1, 4, kPdoInvalid | (kRpdo1Base + n));
  addWrite(kRpdoMapping, 0, 1, 0);
  addWrite(kRpdoMapping, 1, 4, mappingEntry(kControlword, 0, 16));
  addWrite(kRpdoMapping, 2, 4, mappingEntry(target, 0, 32));
  addWrite(kRpdoMapping, 0, 1, 2);
  addWrite(kRpdoCommunication, 2, 1, kPdoEventDriven);
  addWrite(kRpdoCommunication, 1, 4, kRpdo1Base + n);
  // TPDO1: statusword + position actual value, event timer.
  addWrite(kTpdoCommunication, 1, 4, kPdoInvalid | (kTpdo1Base + n));
  addWrite(kTpdoMapping, 0, 1, 0);
  addWrite(kTpdoMapping, 1, 4, mappingEntry(kStatusword, 0, 16));
  addWrite(kTpdoMapping, 2, 4, mappingEntry(kPositionActual, 0, 32));
  addWrite(kTpdoMapping, 0, 1, 2);
  addWrite(kTpdoCommunication, 2, 1, kPdoEventDriven);
  addWrite(kTpdoCommunication, 5, 2, u32ms(c.tpdoPeriod));
  addWrite(kTpdoCommunication, 1, 4, kTpdo1Base + n);
  // TPDO2: velocity actual value.
  addWrite(kTpdoCommunication + 1U, 1, 4, kPdoInvalid | (kTpdo2Base + n));
  addWrite(kTpdoMapping + 1U, 0, 1, 0);
  addWrite(kTpdoMapping + 1U, 1, 4, mappingEntry(kVelocityActual, 0, 32));
  addWrite(kTpdoMapping + 1U, 0, 1, 1);
  addWrite(kTpdoCommunication + 1U, 2, 1, kPdoEventDriven);
  addWrite(kTpdoCommunication + 1U, 5, 2, u32ms(c.tpdoPeriod));
  addWrite(kTpdoCommunication + 1U, 1, 4, kTpdo2Base + n);
}

void Cia402Axis::start(Timestamp now) noexcept {
  now_ = now;
  phase_ = AxisPhase::Configuring;
  phaseSince_ = now;
  buildConfig();
  nextWrite_ = 0;
  sdoPurpose_ = SdoPurpose::None;
  errorCodeWanted_ = false;
  statusword_ = 0xFFFFU;
  haveTpdo1_ = false;
  heartbeatLost_ = false;
  supervised_ = false;
  started_ = false;
  emcyActive_ = false;
  lastError_ = Status::Ok;
  lastAbort_ = 0;
  quickStop_ = false;
  faultResetStep_ = 0;
  newSetPoint_ = false;
  positionGiven_ = false;
  targetVelocity_ = 0;
  (void)out_.push(encodeNmt(NmtCommand::EnterPreOperational, config_.nodeId));
}

void Cia402Axis::sendSdo(const SdoMessage& m, SdoPurpose purpose, Timestamp now) noexcept {
  CanFrame f;
  if (encodeSdoRequest(config_.nodeId, m, f) != Status::Ok) {
    fail(Status::InvalidArgument, now);
    return;
  }
  if (out_.push(f) != Status::Ok) {
    return;  // outbox full: tried again next poll
  }
  sdoRequest_ = m;
  sdoPurpose_ = purpose;
  sdoDeadline_ = now + config_.sdoTimeout;
  ++counters_.sdoRequests;
}

void Cia402Axis::fail(Status why, Timestamp now) noexcept {
  (void)now;
  phase_ = AxisPhase::Failed;
  lastError_ = why;
  lastErrorIndex_ = sdoRequest_.index;
  lastErrorSub_ = sdoRequest_.subIndex;
  sdoPurpose_ = SdoPurpose::None;
}

void Cia402Axis::enterFaulted() noexcept {
  // Before the NMT start (configuration), a fault is only recorded: the configuration goes on so
  // that the statusword can tell the drive's state once it is started.
  if (phase_ == AxisPhase::Idle || phase_ == AxisPhase::Failed || phase_ == AxisPhase::Faulted || !started_) {
    return;
  }
  if (phase_ != AxisPhase::Enabled && phase_ != AxisPhase::QuickStopping && phase_ != AxisPhase::Released) {
    lastError_ = Status::DeviceFault;  // during the bring-up
  }
  phase_ = AxisPhase::Faulted;
  if (!heartbeatLost_) {
    errorCodeWanted_ = true;  // read 0x603F back
  }
}

void Cia402Axis::onSdo(const SdoMessage& m) noexcept {
  if (sdoPurpose_ == SdoPurpose::None) {
    return;  // late answer to a request given up
  }
  const SdoPurpose purpose = sdoPurpose_;
  if (m.kind == SdoKind::Abort) {
    ++counters_.sdoAborts;
    sdoPurpose_ = SdoPurpose::None;
    if (purpose == SdoPurpose::ErrorCode) {
      errorCodeWanted_ = false;  // the EMCY's code, if any, stays
      return;
    }
    lastAbort_ = m.abortCode;
    fail(Status::DeviceFault, now_);
    lastErrorIndex_ = m.index;
    lastErrorSub_ = m.subIndex;
    return;
  }
  if (m.index != sdoRequest_.index || m.subIndex != sdoRequest_.subIndex) {
    ++counters_.malformed;
    if (purpose != SdoPurpose::ErrorCode) {
      fail(Status::Malformed, now_);
    }
    sdoPurpose_ = SdoPurpose::None;
    return;
  }
  sdoPurpose_ = SdoPurpose::None;
  switch (purpose) {
    case SdoPurpose::Config:
      if (m.kind != SdoKind::DownloadResponse) {
        fail(Status::Malformed, now_);
        return;
      }
      if (m.index == kProducerHeartbeat) {
        supervised_ = true;
        lastHeartbeat_ = now_;  // the first heartbeat is due one period from now
      }
      ++nextWrite_;
      break;
    case SdoPurpose::ConfirmMode:
      if (m.kind != SdoKind::UploadResponse) {
        fail(Status::Malformed, now_);
        return;
      }
      if (static_cast<std::int8_t>(m.value & 0xFFU) != static_cast<std::int8_t>(config_.mode)) {
        fail(Status::Rejected, now_);
        return;
      }
      (void)out_.push(encodeNmt(NmtCommand::Start, config_.nodeId));
      started_ = true;
      phase_ = AxisPhase::Starting;
      phaseSince_ = now_;
      break;
    case SdoPurpose::ErrorCode:
      if (m.kind == SdoKind::UploadResponse) {
        errorCode_ = static_cast<std::uint16_t>(m.value & 0xFFFFU);
      }
      errorCodeWanted_ = false;
      break;
    case SdoPurpose::None:
      break;
  }
}

bool Cia402Axis::onFrame(const CanFrame& f) noexcept {
  if (f.extended || f.rtr || f.error) {
    return false;
  }
  const std::uint32_t n = config_.nodeId;
  if (f.id == kSdoResponseBase + n) {
    SdoMessage m;
    const Status s = decodeSdoResponse(f, config_.nodeId, m);
    if (s != Status::Ok) {
      ++counters_.malformed;
      return true;
    }
    onSdo(m);
    return true;
  }
  if (f.id == kTpdo1Base + n) {
    if (f.dlc < 6U) {
      ++counters_.malformed;
      return true;
    }
    statusword_ = static_cast<std::uint16_t>(f.data[0] | (f.data[1] << 8U));
    positionActual_ = readI32(f.data + 2);
    haveTpdo1_ = true;
    lastTpdo_ = now_;
    ++counters_.tpdos;
    return true;
  }
  if (f.id == kTpdo2Base + n) {
    if (f.dlc < 4U) {
      ++counters_.malformed;
      return true;
    }
    velocityActual_ = readI32(f.data);
    ++counters_.tpdos;
    return true;
  }
  if (f.id == kHeartbeatBase + n) {
    if (f.dlc < 1U) {
      ++counters_.malformed;
      return true;
    }
    const std::uint8_t s = f.data[0] & 0x7FU;  // bit 7 is the toggle bit of node guarding
    if (s != 0x00U && s != 0x04U && s != 0x05U && s != 0x7FU) {
      ++counters_.malformed;
      return true;
    }
    ++counters_.heartbeats;
    nmt_ = static_cast<NmtState>(s);
    lastHeartbeat_ = f.stamp > now_ ? f.stamp : now_;  // the receive stamp, when the transport gave one
    if (nmt_ == NmtState::BootUp && started_) {
      heartbeatLost_ = true;  // the drive restarted under us: its configuration is gone
      enterFaulted();
    }
    return true;
  }
  EmcyRecord r;
  const Status e = decodeEmcy(f, r);
  if (e == Status::Ok && r.nodeId == config_.nodeId) {
    ++counters_.emcys;
    if (r.errorCode != 0U) {
      lastEmcy_ = r;
      errorCode_ = r.errorCode;
      emcyActive_ = true;
      enterFaulted();
    } else {
      emcyActive_ = false;
    }
    return true;
  }
  if (e == Status::Truncated && f.id == 0x080U + n) {
    ++counters_.malformed;
    return true;
  }
  return false;
}

void Cia402Axis::quickStop() noexcept {
  quickStop_ = true;
  if (phase_ != AxisPhase::Idle && phase_ != AxisPhase::Faulted && phase_ != AxisPhase::Failed) {
    phase_ = AxisPhase::QuickStopping;
  }
  if (started_) {
    sendRpdo(true);
  }
}

Status Cia402Axis::release() noexcept {
  if (phase_ != AxisPhase::Enabled) {
    return Status::Rejected;
  }
  phase_ = AxisPhase::Released;
  targetVelocity_ = 0;  // the RPDO of the next poll carries the controlword
  return Status::Ok;
}

Status Cia402Axis::faultReset(Timestamp now) noexcept {
  if (phase_ != AxisPhase::Faulted || powerState() != PowerState::Fault || heartbeatLost_) {
    return Status::Rejected;
  }
  faultResetStep_ = 1;
  quickStop_ = false;
  emcyActive_ = false;
  phaseSince_ = now;
  return Status::Ok;
}

void Cia402Axis::stepEnabling(Timestamp now) noexcept {
  const PowerState ps = powerState();
  if (ps == PowerState::OperationEnabled) {
    phase_ = AxisPhase::Enabled;
    targetPosition_ = positionActual_;  // hold where it stands until told otherwise
    sentPosition_ = positionActual_;
    acceptedPosition_ = positionActual_;
    newSetPoint_ = false;
    positionGiven_ = false;
    return;
  }
  Cia402Command c = lastStep_;
  if (ps != PowerState::Fault && commandTowardsEnabled(ps, c)) {
    lastStep_ = c;
  }
  if (now - phaseSince_ > config_.stateTimeout) {
    fail(Status::Timeout, now);
  }
}

void Cia402Axis::stepHandshake() noexcept {
  const bool ack = (statusword_ & kSwSetPointAcknowledge) != 0U;
  if (newSetPoint_) {
    if (ack) {  // the drive took the set-point: drop bit 4 so that it can clear bit 12
      newSetPoint_ = false;
      acceptedPosition_ = sentPosition_;
      positionGiven_ = true;
      ++counters_.setPointsAcknowledged;
    }
  } else if (!ack && (!positionGiven_ || targetPosition_ != acceptedPosition_)) {
    sentPosition_ = targetPosition_;
    newSetPoint_ = true;
  }
}

void Cia402Axis::sendRpdo(bool urgent) noexcept {
  std::uint16_t cw = controlword_;
  if (faultResetStep_ == 1) {
    cw = 0x0000U;  // bit 7 low first: the reset is the rising edge
  } else if (faultResetStep_ >= 2) {
    cw = controlwordFor(Cia402Command::FaultReset);
  } else if (quickStop_) {
    cw = controlwordFor(Cia402Command::QuickStop);
  } else if (phase_ == AxisPhase::Enabling) {
    cw = controlwordFor(lastStep_);
  } else if (phase_ == AxisPhase::Released) {
    cw = controlwordFor(Cia402Command::DisableOperation);
  } else if (phase_ == AxisPhase::Enabled) {
    cw = controlwordFor(Cia402Command::EnableOperation);
    if (config_.mode == OperationMode::ProfilePosition) {
      cw = static_cast<std::uint16_t>(cw | kCwChangeSetImmediately | (newSetPoint_ ? kCwNewSetPoint : 0U));
    }
  }
  controlword_ = cw;
  std::int32_t target = 0;
  if (config_.mode == OperationMode::ProfilePosition) {
    target = sentPosition_;
  } else if (phase_ == AxisPhase::Enabled && !quickStop_) {
    target = targetVelocity_;
  }
  CanFrame f;
  f.id = kRpdo1Base + config_.nodeId;
  f.dlc = 6;
  f.data[0] = static_cast<std::uint8_t>(cw & 0xFFU);
  f.data[1] = static_cast<std::uint8_t>(cw >> 8U);
  const std::uint32_t t = static_cast<std::uint32_t>(target);
  for (unsigned i = 0; i < 4U; ++i) {
    f.data[2 + i] = static_cast<std::uint8_t>(t >> (8U * i));
  }
  if (urgent) {
    out_.pushUrgent(f);
  } else if (out_.push(f) != Status::Ok) {
    return;
  }
  ++counters_.rpdos;
}

void Cia402Axis::poll(Timestamp now) noexcept {
  now_ = now;
  if (phase_ == AxisPhase::Idle) {
    return;
  }
  // Supervision of the drive's heartbeat, once its producer time is configured. A receive stamp
  // ahead of this poll (another clock, a wrong stamp) counts as received now, never later.
  if (lastHeartbeat_ > now) {
    lastHeartbeat_ = now;
  }
  if (supervised_ && !heartbeatLost_ && now - lastHeartbeat_ > config_.heartbeatTimeout) {
    heartbeatLost_ = true;
    enterFaulted();
  }
  if (sdoPurpose_ != SdoPurpose::None && now > sdoDeadline_) {
    if (sdoPurpose_ == SdoPurpose::ErrorCode) {
      sdoPurpose_ = SdoPurpose::None;
      errorCodeWanted_ = false;
    } else {
      fail(Status::Timeout, now);
    }
  }
  if (started_ && haveTpdo1_) {
    const PowerState ps = powerState();
    if (ps == PowerState::Fault || ps == PowerState::FaultReactionActive) {
      enterFaulted();
    }
  }
  switch (phase_) {
    case AxisPhase::Configuring:
      if (sdoPurpose_ == SdoPurpose::None) {
        if (nextWrite_ < writeCount_) {
          const SdoWrite& w = writes_[nextWrite_];
          SdoMessage m;
          m.kind = SdoKind::DownloadRequest;
          m.index = w.index;
          m.subIndex = w.sub;
          m.size = w.size;
          m.value = w.value;
          sendSdo(m, SdoPurpose::Config, now);
        } else {
          phase_ = AxisPhase::ConfirmingMode;
          SdoMessage m;
          m.kind = SdoKind::UploadRequest;
          m.index = kModesDisplay;
          sendSdo(m, SdoPurpose::ConfirmMode, now);
        }
      }
      break;
    case AxisPhase::Starting:
      if (haveTpdo1_) {
        phase_ = AxisPhase::Enabling;
        phaseSince_ = now;
        lastStep_ = Cia402Command::Shutdown;
        stepEnabling(now);
      } else if (now - phaseSince_ > config_.stateTimeout) {
        fail(Status::Timeout, now);
      }
      break;
    case AxisPhase::Enabling:
      stepEnabling(now);
      break;
    case AxisPhase::Enabled:
      if (powerState() != PowerState::OperationEnabled) {
        enterFaulted();  // the drive left Operation enabled by itself
      } else if (config_.mode == OperationMode::ProfilePosition) {
        stepHandshake();
      }
      break;
    case AxisPhase::Faulted:
      if (faultResetStep_ == 1) {
        sendRpdo(false);  // bit 7 low in this poll, high from the next one
        faultResetStep_ = 2;
        return;
      }
      if (faultResetStep_ >= 2 && powerState() == PowerState::SwitchOnDisabled) {
        faultResetStep_ = 0;
        heartbeatLost_ = false;
        phase_ = AxisPhase::Enabling;
        phaseSince_ = now;
        lastStep_ = Cia402Command::Shutdown;
      } else if (faultResetStep_ >= 2 && now - phaseSince_ > config_.stateTimeout) {
        faultResetStep_ = 0;
        fail(Status::Timeout, now);
      }
      break;
    default:
      break;
  }
  if (errorCodeWanted_ && sdoPurpose_ == SdoPurpose::None && phase_ != AxisPhase::Configuring) {
    SdoMessage m;
    m.kind = SdoKind::UploadRequest;
    m.index = kErrorCode;
    sendSdo(m, SdoPurpose::ErrorCode, now);
  }
  if (started_) {
    sendRpdo(false);
  }
}

// ---------------------------------------------------------------------------------------------
// Cia402DriveController

void deriveAxisConfigs(const Cia402DriveConfig& c, Cia402AxisConfig& traction, Cia402AxisConfig& steering) noexcept {
  Cia402AxisConfig common;
  common.tpdoPeriod = c.tpdoPeriod;
  common.heartbeatPeriod = c.driveHeartbeatPeriod;
  common.heartbeatTimeout = c.driveHeartbeatTimeout;
  common.controllerNodeId = c.controllerNodeId;
  common.controllerHeartbeatTimeout = c.controllerHeartbeatTimeout;
  common.sdoTimeout = c.sdoTimeout;
  common.stateTimeout = c.stateTimeout;

  traction = common;
  traction.nodeId = c.traction.nodeId;
  traction.mode = OperationMode::ProfileVelocity;
  const double vu = c.traction.velocityUnitsPerMps;
  traction.profileAcceleration = profileUnits(c.traction.acceleration * vu);
  traction.profileDeceleration = traction.profileAcceleration;
  traction.quickStopDeceleration = profileUnits(c.traction.quickStopDeceleration * vu);
  traction.profileVelocity = 0;

  steering = common;
  steering.nodeId = c.steering.nodeId;
  steering.mode = OperationMode::ProfilePosition;
  const double pu = c.steering.countsPerRadian;
  steering.profileVelocity = profileUnits(c.steering.maxRate * pu);
  steering.profileAcceleration = profileUnits(c.steering.acceleration * pu);
  steering.profileDeceleration = steering.profileAcceleration;
  steering.quickStopDeceleration = profileUnits(c.steering.quickStopDeceleration * pu);
}

namespace {
Cia402AxisConfig tractionOf(const Cia402DriveConfig& c) noexcept {
  Cia402AxisConfig t;
  Cia402AxisConfig s;
  deriveAxisConfigs(c, t, s);
  return t;
}
Cia402AxisConfig steeringOf(const Cia402DriveConfig& c) noexcept {
  Cia402AxisConfig t;
  Cia402AxisConfig s;
  deriveAxisConfigs(c, t, s);
  return s;
}
}  // namespace

const char* toString(DriveControllerState state) noexcept {
  switch (state) {
    case DriveControllerState::Idle:
      return "idle";
    case DriveControllerState::BringingUp:
      return "bringing up";
    case DriveControllerState::Enabled:
      return "enabled";
    case DriveControllerState::SafeStop:
      return "safe stop";
    case DriveControllerState::Failed:
      return "failed";
    case DriveControllerState::Released:
      return "released";
  }
  return "unknown state";
}

const char* toString(SafeStopReason reason) noexcept {
  switch (reason) {
    case SafeStopReason::None:
      return "none";
    case SafeStopReason::DriveHeartbeatLost:
      return "drive heartbeat lost";
    case SafeStopReason::DriveFault:
      return "drive fault";
    case SafeStopReason::BusOff:
      return "CAN bus-off";
    case SafeStopReason::PlcStop:
      return "PLC stop";
    case SafeStopReason::SetpointTimeout:
      return "stale set-point";
    case SafeStopReason::Shutdown:
      return "shutdown";
    case SafeStopReason::Requested:
      return "requested";
  }
  return "unknown reason";
}

Cia402DriveController::Cia402DriveController(const Cia402DriveConfig& config) noexcept
    : config_(config), traction_(tractionOf(config), outbox_), steering_(steeringOf(config), outbox_) {}

Cia402DriveController::~Cia402DriveController() {
  if (state_ == DriveControllerState::Idle) {
    return;
  }
  trigger(SafeStopReason::Shutdown);
  if (sink_ != nullptr) {
    CanFrame frames[CanOutbox::kCapacity];
    const std::size_t n = outbox_.take(Span<CanFrame>(frames));
    for (std::size_t i = 0; i < n; ++i) {
      (void)sink_->send(frames[i]);
    }
  }
}

Status Cia402DriveController::validate() const noexcept {
  const Cia402DriveConfig& c = config_;
  if (traction_.validate() != Status::Ok || steering_.validate() != Status::Ok ||
      c.traction.nodeId == c.steering.nodeId) {
    return Status::InvalidArgument;
  }
  const TractionAxisConfig& t = c.traction;
  const SteeringAxisConfig& s = c.steering;
  if (!positiveFinite(t.countsPerMetre) || !positiveFinite(t.velocityUnitsPerMps) || !positiveFinite(t.maxSpeed) ||
      !positiveFinite(t.acceleration) || !positiveFinite(t.quickStopDeceleration) ||
      !positiveFinite(t.standstillSpeed) || (t.direction != 1 && t.direction != -1)) {
    return Status::InvalidArgument;
  }
  if (!positiveFinite(s.countsPerRadian) || !positiveFinite(s.maxAngle) || !positiveFinite(s.maxRate) ||
      !positiveFinite(s.acceleration) || !positiveFinite(s.quickStopDeceleration) ||
      (s.direction != 1 && s.direction != -1)) {
    return Status::InvalidArgument;
  }
  // The scaled limits must fit the drives' 32-bit objects.
  if (t.maxSpeed * t.velocityUnitsPerMps >= 2.0e9 || s.maxAngle * s.countsPerRadian + std::fabs(s.zeroCount) >= 2.0e9) {
    return Status::InvalidArgument;
  }
  if (c.controllerHeartbeatPeriod.ns <= 0 || c.controllerHeartbeatTimeout.ns <= 2 * c.controllerHeartbeatPeriod.ns ||
      c.setpointTimeout.ns <= 0) {
    return Status::InvalidArgument;
  }
  return Status::Ok;
}

Status Cia402DriveController::start(Timestamp now) noexcept {
  if (validate() != Status::Ok) {
    return Status::InvalidArgument;
  }
  if (busOff_) {
    return Status::DeviceFault;
  }
  now_ = now;
  state_ = DriveControllerState::BringingUp;
  reason_ = SafeStopReason::None;
  heartbeatOn_ = true;
  nextHeartbeat_ = now;
  commandSeen_ = false;
  traction_.start(now);
  steering_.start(now);
  return Status::Ok;
}

void Cia402DriveController::onFrame(const CanFrame& frame) noexcept {
  if (!traction_.onFrame(frame) && !steering_.onFrame(frame)) {
    ++ignored_;
  }
}

void Cia402DriveController::onBusState(bool busOff, Timestamp now) noexcept {
  now_ = now;
  busOff_ = busOff;
  if (busOff && state_ != DriveControllerState::Idle) {
    trigger(SafeStopReason::BusOff);
  }
}

void Cia402DriveController::trigger(SafeStopReason reason) noexcept {
  if (state_ == DriveControllerState::SafeStop || state_ == DriveControllerState::Idle) {
    return;  // the first reason is kept
  }
  reason_ = reason;
  state_ = DriveControllerState::SafeStop;
  traction_.quickStop();
}

Status Cia402DriveController::release() noexcept {
  // Only a standing vehicle: how a drive leaves Operation enabled on "disable operation" is its
  // option code 0x605C (some coast), and a moving one is stopped by stop() or the quick stop.
  if (state_ != DriveControllerState::Enabled || !isStandstill()) {
    return Status::Rejected;
  }
  traction_.setTargetVelocity(0);
  static_cast<void>(traction_.release());
  static_cast<void>(steering_.release());
  state_ = DriveControllerState::Released;
  return Status::Ok;
}

void Cia402DriveController::quickStop(SafeStopReason reason) noexcept {
  trigger(reason == SafeStopReason::None ? SafeStopReason::Requested : reason);
}

Status Cia402DriveController::faultReset(Timestamp now) noexcept {
  const bool t = traction_.faultReset(now) == Status::Ok;
  const bool s = steering_.faultReset(now) == Status::Ok;
  if (!t && !s) {
    return Status::Rejected;
  }
  if (!t && traction_.phase() != AxisPhase::Enabled) {
    traction_.start(now);  // the axis that was not in Fault is brought up again
  }
  if (!s && steering_.phase() != AxisPhase::Enabled) {
    steering_.start(now);
  }
  state_ = DriveControllerState::BringingUp;
  reason_ = SafeStopReason::None;
  return Status::Ok;
}

void Cia402DriveController::poll(Timestamp now) noexcept {
  now_ = now;
  if (state_ == DriveControllerState::Idle) {
    return;
  }
  if (commandSeen_) {
    lastCommand_ = now;
    commandSeen_ = false;
  }
  traction_.poll(now);
  steering_.poll(now);
  const bool lost = traction_.heartbeatLost() || steering_.heartbeatLost();
  const bool faulted = (traction_.phase() == AxisPhase::Faulted && !traction_.resetting()) ||
                       (steering_.phase() == AxisPhase::Faulted && !steering_.resetting());
  switch (state_) {
    case DriveControllerState::BringingUp:
      if (lost) {
        trigger(SafeStopReason::DriveHeartbeatLost);
      } else if (faulted) {
        trigger(SafeStopReason::DriveFault);
      } else if (traction_.phase() == AxisPhase::Failed || steering_.phase() == AxisPhase::Failed) {
        state_ = DriveControllerState::Failed;
        traction_.quickStop();
      } else if (traction_.phase() == AxisPhase::Enabled && steering_.phase() == AxisPhase::Enabled) {
        state_ = DriveControllerState::Enabled;
        lastCommand_ = now;
      }
      break;
    case DriveControllerState::Enabled:
      if (lost) {
        trigger(SafeStopReason::DriveHeartbeatLost);
      } else if (faulted || traction_.phase() != AxisPhase::Enabled || steering_.phase() != AxisPhase::Enabled) {
        trigger(SafeStopReason::DriveFault);
      } else if (now - lastCommand_ > config_.setpointTimeout) {
        trigger(SafeStopReason::SetpointTimeout);
      }
      break;
    case DriveControllerState::Released:
      if (lost) {
        trigger(SafeStopReason::DriveHeartbeatLost);
      } else if (faulted) {
        trigger(SafeStopReason::DriveFault);
      }
      break;
    default:
      break;
  }
  if (heartbeatOn_ && now >= nextHeartbeat_) {
    (void)outbox_.push(encodeHeartbeat(config_.controllerNodeId, NmtState::Operational, now));
    nextHeartbeat_ = nextHeartbeat_ + config_.controllerHeartbeatPeriod;
    if (nextHeartbeat_ <= now) {
      nextHeartbeat_ = now + config_.controllerHeartbeatPeriod;  // no burst after a late poll
    }
  }
}

Status Cia402DriveController::command(const hal::DriveCommand& cmd) noexcept {
  if (!std::isfinite(cmd.speed) || !std::isfinite(cmd.steeringAngle)) {
    return Status::NonFiniteInput;
  }
  if (std::fabs(cmd.speed) > config_.traction.maxSpeed || std::fabs(cmd.steeringAngle) > config_.steering.maxAngle) {
    return Status::InvalidArgument;
  }
  if (state_ != DriveControllerState::Enabled) {
    return Status::DeviceFault;
  }
  const TractionAxisConfig& t = config_.traction;
  const SteeringAxisConfig& s = config_.steering;
  traction_.setTargetVelocity(roundSaturated(cmd.speed * t.velocityUnitsPerMps * t.direction));
  steering_.setTargetPosition(
      roundSaturated(static_cast<double>(s.zeroCount) + cmd.steeringAngle * s.countsPerRadian * s.direction));
  commandSeen_ = true;
  return Status::Ok;
}

Status Cia402DriveController::stop() noexcept {
  if (busOff_) {
    return Status::DeviceFault;
  }
  traction_.setTargetVelocity(0);
  commandSeen_ = true;
  return Status::Ok;
}

double Cia402DriveController::speedActual() const noexcept {
  const TractionAxisConfig& t = config_.traction;
  return static_cast<double>(traction_.velocityActual()) / t.velocityUnitsPerMps * t.direction;
}

double Cia402DriveController::steeringAngleActual() const noexcept {
  const SteeringAxisConfig& s = config_.steering;
  return (static_cast<double>(steering_.positionActual()) - static_cast<double>(s.zeroCount)) / s.countsPerRadian *
         s.direction;
}

bool Cia402DriveController::isStandstill() const noexcept {
  if (!traction_.haveActuals()) {
    return false;
  }
  if (now_ - traction_.lastTpdo() > Duration{3 * config_.tpdoPeriod.ns}) {
    return false;
  }
  return std::fabs(speedActual()) < config_.traction.standstillSpeed;
}

}  // namespace agv::drivers::canopen
