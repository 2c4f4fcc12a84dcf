#include "agv/drivers/protocol/canopen/canopen_encoders.hpp"

#include <cmath>
#include <initializer_list>

namespace agv::drivers::canopen {
namespace {
constexpr std::uint32_t kNmtId = 0x000;
constexpr std::uint32_t kSyncId = 0x080;
constexpr std::uint32_t kEmcyBase = 0x080;
constexpr std::uint32_t kHeartbeatBase = 0x700;

std::uint32_t mask(std::uint8_t size) noexcept {
  return size >= 4 ? 0xFFFFFFFFU : ((1U << (8U * size)) - 1U);
}

/// Sign-extends the low 8*size bits of `v`.
std::int64_t signExtend(std::uint32_t v, std::uint8_t size) noexcept {
  const unsigned bits = 8U * size;
  const std::uint64_t m = std::uint64_t{1} << (bits - 1U);
  const std::uint64_t x = static_cast<std::uint64_t>(v & mask(size));
  return static_cast<std::int64_t>((x ^ m)) - static_cast<std::int64_t>(m);
}

/// Little-endian read of the mapped value; false when the PDO is too short.
bool readPdo(const CanFrame& f, const PdoMapping& m, std::uint32_t& v) noexcept {
  if (static_cast<unsigned>(m.byteOffset) + m.size > f.dlc || m.size < 1 || m.size > 4) {
    return false;
  }
  std::uint32_t r = 0;
  for (unsigned i = 0; i < m.size; ++i) {
    r |= static_cast<std::uint32_t>(f.data[m.byteOffset + i]) << (8U * i);
  }
  v = r;
  return true;
}

CanFrame pdoFrame(const PdoMapping& m, std::uint32_t raw, Timestamp stamp) noexcept {
  CanFrame f;
  f.id = m.cobId;
  const unsigned end = static_cast<unsigned>(m.byteOffset) + m.size;
  f.dlc = static_cast<std::uint8_t>(end > 8U ? 8U : end);
  for (unsigned i = 0; i < m.size && m.byteOffset + i < 8U; ++i) {
    f.data[m.byteOffset + i] = static_cast<std::uint8_t>(raw >> (8U * i));
  }
  f.stamp = stamp;
  return f;
}

/// Signed steering count relative to the zero, wrapped into half a revolution when the encoder
/// wraps per revolution. False for a raw value outside the revolution.
bool steeringCounts(const SteeringEncoderConfig& c, std::uint32_t raw, std::int64_t& counts) noexcept {
  if (c.countsPerRevolution > 0U) {
    const std::int64_t cpr = c.countsPerRevolution;
    if (raw >= c.countsPerRevolution) {
      return false;
    }
    std::int64_t d = (static_cast<std::int64_t>(raw) - static_cast<std::int64_t>(c.zeroCount)) % cpr;
    if (d < 0) {
      d += cpr;
    }
    if (d > cpr / 2) {
      d -= cpr;
    }
    counts = d;
    return true;
  }
  counts = signExtend(raw, c.pdo.size) - signExtend(c.zeroCount, c.pdo.size);
  return true;
}

bool pdoValid(const PdoMapping& m) noexcept {
  return m.size >= 1 && m.size <= 4 && static_cast<unsigned>(m.byteOffset) + m.size <= 8U && m.cobId > kSyncId &&
         m.cobId <= 0x7FFU;
}
}  // namespace

Status decodeEmcy(const CanFrame& f, EmcyRecord& record) noexcept {
  if (f.extended || f.rtr || f.error || f.id <= kEmcyBase || f.id > kEmcyBase + 127U) {
    return Status::NotFound;
  }
  if (f.dlc < 3U) {
    return Status::Truncated;
  }
  EmcyRecord r;
  r.nodeId = static_cast<std::uint8_t>(f.id - kEmcyBase);
  r.errorCode = static_cast<std::uint16_t>(f.data[0] | (f.data[1] << 8U));
  r.errorRegister = f.data[2];
  for (unsigned i = 0; i < 5U; ++i) {
    r.vendor[i] = 3U + i < f.dlc ? f.data[3 + i] : 0U;  // bytes past dlc are unspecified
  }
  r.stamp = f.stamp;
  record = r;
  return Status::Ok;
}

CanFrame encodeNmt(NmtCommand command, std::uint8_t nodeId) noexcept {
  CanFrame f;
  f.id = kNmtId;
  f.dlc = 2;
  f.data[0] = static_cast<std::uint8_t>(command);
  f.data[1] = nodeId;
  return f;
}

CanFrame encodeSync(Timestamp stamp) noexcept {
  CanFrame f;
  f.id = kSyncId;
  f.dlc = 0;
  f.stamp = stamp;
  return f;
}

CanFrame encodeHeartbeat(std::uint8_t nodeId, NmtState state, Timestamp stamp) noexcept {
  CanFrame f;
  f.id = kHeartbeatBase + nodeId;
  f.dlc = 1;
  f.data[0] = static_cast<std::uint8_t>(state);
  f.stamp = stamp;
  return f;
}

CanFrame encodeEmcy(std::uint8_t nodeId, std::uint16_t errorCode, std::uint8_t errorRegister,
                    Timestamp stamp) noexcept {
  CanFrame f;
  f.id = kEmcyBase + nodeId;
  f.dlc = 8;
  f.data[0] = static_cast<std::uint8_t>(errorCode & 0xFFU);
  f.data[1] = static_cast<std::uint8_t>(errorCode >> 8U);
  f.data[2] = errorRegister;
  f.stamp = stamp;
  return f;
}

CanFrame encodeDrivePdo(const DriveEncoderConfig& c, std::int64_t trueTicks, Timestamp stamp) noexcept {
  const std::int64_t counts = c.direction < 0 ? -trueTicks : trueTicks;
  const auto raw = static_cast<std::uint32_t>(static_cast<std::uint64_t>(counts) & mask(c.pdo.size));
  return pdoFrame(c.pdo, raw, stamp);
}

CanFrame encodeSteeringPdo(const SteeringEncoderConfig& c, double angle, Timestamp stamp) noexcept {
  const double perCount = c.radiansPerCount > 0.0 ? c.radiansPerCount : 1.0;
  const std::int64_t counts = std::llround((c.direction < 0 ? -angle : angle) / perCount);
  std::uint32_t raw = 0;
  if (c.countsPerRevolution > 0U) {
    const std::int64_t cpr = c.countsPerRevolution;
    std::int64_t r = (static_cast<std::int64_t>(c.zeroCount) + counts) % cpr;
    if (r < 0) {
      r += cpr;
    }
    raw = static_cast<std::uint32_t>(r);
  } else {
    const std::int64_t r = signExtend(c.zeroCount, c.pdo.size) + counts;
    raw = static_cast<std::uint32_t>(static_cast<std::uint64_t>(r) & mask(c.pdo.size));
  }
  return pdoFrame(c.pdo, raw, stamp);
}

CanopenEncoders::CanopenEncoders(const CanopenEncodersConfig& config) noexcept : config_(config) {}

Status CanopenEncoders::validate() const noexcept {
  const DriveEncoderConfig& d = config_.drive;
  const SteeringEncoderConfig& s = config_.steering;
  const auto nodeOk = [](std::uint8_t n) noexcept { return n >= 1U && n <= 127U; };
  if (!nodeOk(d.nodeId) || !nodeOk(s.nodeId) || d.nodeId == s.nodeId) {
    return Status::InvalidArgument;
  }
  if (!pdoValid(d.pdo) || !pdoValid(s.pdo) || d.pdo.cobId == s.pdo.cobId) {
    return Status::InvalidArgument;
  }
  for (const std::uint16_t cob : {d.pdo.cobId, s.pdo.cobId}) {
    for (const std::uint8_t n : {d.nodeId, s.nodeId}) {
      if (cob == kEmcyBase + n || cob == kHeartbeatBase + n) {
        return Status::InvalidArgument;
      }
    }
  }
  if ((d.direction != 1 && d.direction != -1) || (s.direction != 1 && s.direction != -1)) {
    return Status::InvalidArgument;
  }
  if (!std::isfinite(s.radiansPerCount) || !(s.radiansPerCount > 0.0)) {
    return Status::InvalidArgument;
  }
  if (s.countsPerRevolution > 0U &&
      (s.zeroCount >= s.countsPerRevolution || s.countsPerRevolution - 1U > mask(s.pdo.size))) {
    return Status::InvalidArgument;
  }
  if (config_.heartbeatTimeout.ns < 0 || config_.syncPeriod.ns < 0 || config_.pairingWindow.ns < 0) {
    return Status::InvalidArgument;
  }
  return Status::Ok;
}

std::size_t CanopenEncoders::startupFrames(Span<CanFrame> out) const noexcept {
  std::size_t n = 0;
  for (const std::uint8_t node : {config_.drive.nodeId, config_.steering.nodeId}) {
    if (n < out.size()) {
      out[n++] = encodeNmt(NmtCommand::Start, node);
    }
  }
  return n;
}

void CanopenEncoders::emit(Timestamp stamp) noexcept {
  sample_.stamp = stamp;
  sample_.driveTicks = ticks_;
  sample_.steeringAngle = angle_;
  sampleReady_ = true;
  driveUpdated_ = false;
  steerUpdated_ = false;
}

void CanopenEncoders::pair(bool& ownUpdated, Timestamp& ownStamp, bool& otherUpdated, Timestamp otherStamp,
                           Timestamp stamp) noexcept {
  if (config_.trigger != SampleTrigger::BothUpdated) {
    ownUpdated = true;
    ownStamp = stamp;
    return;
  }
  if (ownUpdated) {
    ++incomplete_;  // our previous position never got its partner
  }
  ownUpdated = true;
  ownStamp = stamp;
  const Duration gap = stamp > otherStamp ? stamp - otherStamp : otherStamp - stamp;
  if (otherUpdated && config_.pairingWindow.ns > 0 && gap > config_.pairingWindow) {
    otherUpdated = false;  // the other position belongs to an earlier cycle whose partner was lost
    ++incomplete_;
  }
}

void CanopenEncoders::onHeartbeat(NodeHealth& h, const CanFrame& f, bool& needStart) noexcept {
  const auto state = static_cast<std::uint8_t>(f.data[0] & 0x7FU);
  h.state = static_cast<NmtState>(state);
  h.lastHeartbeat = f.stamp;
  h.heartbeatSeen = true;
  h.heartbeatTimedOut = false;
  if (state == static_cast<std::uint8_t>(NmtState::BootUp)) {
    ++h.bootUps;
    needStart = true;  // a restarted node comes up pre-operational: start it again
  }
}

void CanopenEncoders::onEmcy(NodeHealth& h, std::uint8_t node, const CanFrame& f) noexcept {
  EmcyRecord r;
  (void)decodeEmcy(f, r);  // the caller checked the identifier and the length
  r.nodeId = node;
  ++h.emcyCount;
  h.emcyActive = r.errorCode != 0U;
  if (emcy_.tryPush(r) != Status::Ok) {
    ++emcyDropped_;  // full: keep the oldest (the first fault explains the rest)
  }
}

FrameKind CanopenEncoders::onFrame(const CanFrame& f) noexcept {
  if (f.extended || f.rtr || f.error) {
    return FrameKind::Ignored;
  }
  const std::uint8_t dn = config_.drive.nodeId;
  const std::uint8_t sn = config_.steering.nodeId;
  if (f.id == config_.drive.pdo.cobId) {
    std::uint32_t raw = 0;
    if (!readPdo(f, config_.drive.pdo, raw)) {
      ++malformed_;
      return FrameKind::Malformed;
    }
    const std::uint8_t size = config_.drive.pdo.size;
    const std::int64_t sign = config_.drive.direction < 0 ? -1 : 1;
    if (!haveDrive_) {
      ticks_ = sign * signExtend(raw, size);  // the drive's absolute position
      haveDrive_ = true;
    } else {
      ticks_ += sign * signExtend(raw - lastRaw_, size);  // modular difference: wraps unwrapped
    }
    lastRaw_ = raw & mask(size);
    ++drive_.pdoCount;
    pair(driveUpdated_, driveStamp_, steerUpdated_, steerStamp_, f.stamp);
    if ((config_.trigger == SampleTrigger::DriveUpdated && haveSteer_) ||
        (config_.trigger == SampleTrigger::BothUpdated && steerUpdated_)) {
      emit(f.stamp);
    }
    return FrameKind::DrivePosition;
  }
  if (f.id == config_.steering.pdo.cobId) {
    std::uint32_t raw = 0;
    std::int64_t counts = 0;
    if (!readPdo(f, config_.steering.pdo, raw) || !steeringCounts(config_.steering, raw, counts)) {
      ++malformed_;
      return FrameKind::Malformed;
    }
    const double sign = config_.steering.direction < 0 ? -1.0 : 1.0;
    angle_ = sign * static_cast<double>(counts) * config_.steering.radiansPerCount;
    haveSteer_ = true;
    ++steer_.pdoCount;
    pair(steerUpdated_, steerStamp_, driveUpdated_, driveStamp_, f.stamp);
    if (config_.trigger == SampleTrigger::BothUpdated && driveUpdated_) {
      emit(f.stamp);
    }
    return FrameKind::SteeringPosition;
  }
  if (f.id == kHeartbeatBase + dn || f.id == kHeartbeatBase + sn) {
    if (f.dlc < 1U) {
      ++malformed_;
      return FrameKind::Malformed;
    }
    if (f.id == kHeartbeatBase + dn) {
      onHeartbeat(drive_, f, driveStartPending_);
    } else {
      onHeartbeat(steer_, f, steerStartPending_);
    }
    return FrameKind::Heartbeat;
  }
  if (f.id == kEmcyBase + dn || f.id == kEmcyBase + sn) {
    if (f.dlc < 3U) {
      ++malformed_;
      return FrameKind::Malformed;
    }
    if (f.id == kEmcyBase + dn) {
      onEmcy(drive_, dn, f);
    } else {
      onEmcy(steer_, sn, f);
    }
    return FrameKind::Emcy;
  }
  return FrameKind::Ignored;
}

std::size_t CanopenEncoders::service(Timestamp now, Span<CanFrame> out) noexcept {
  std::size_t n = 0;
  if (!syncStarted_) {  // supervision starts with the first service call
    syncStarted_ = true;
    nextSync_ = now;
    if (!drive_.heartbeatSeen) {
      drive_.lastHeartbeat = now;
    }
    if (!steer_.heartbeatSeen) {
      steer_.lastHeartbeat = now;
    }
  }
  if (config_.heartbeatTimeout.ns > 0) {
    for (NodeHealth* h : {&drive_, &steer_}) {
      if (now - h->lastHeartbeat > config_.heartbeatTimeout) {
        h->heartbeatTimedOut = true;
      }
    }
  }
  if (driveStartPending_ && n < out.size()) {
    out[n++] = encodeNmt(NmtCommand::Start, config_.drive.nodeId);
    driveStartPending_ = false;
  }
  if (steerStartPending_ && n < out.size()) {
    out[n++] = encodeNmt(NmtCommand::Start, config_.steering.nodeId);
    steerStartPending_ = false;
  }
  if (config_.syncPeriod.ns > 0 && now >= nextSync_ && n < out.size()) {
    out[n++] = encodeSync(now);
    if (config_.trigger == SampleTrigger::BothUpdated && (driveUpdated_ || steerUpdated_)) {
      ++incomplete_;  // a new cycle: the half of the last one that came stays unpaired
      driveUpdated_ = false;
      steerUpdated_ = false;
    }
    nextSync_ = nextSync_ + config_.syncPeriod;
    if (now - nextSync_ >= config_.syncPeriod) {  // late by more than a period: no burst of SYNCs
      nextSync_ = now + config_.syncPeriod;
    }
  }
  return n;
}

bool CanopenEncoders::takeSample(hal::EncoderSample& sample) noexcept {
  if (!sampleReady_) {
    return false;
  }
  sample = sample_;
  sampleReady_ = false;
  return true;
}

bool CanopenEncoders::takeEmcy(EmcyRecord& record) noexcept {
  if (emcy_.empty()) {
    return false;
  }
  record = emcy_.front();
  emcy_.pop_front();
  return true;
}

Status CanopenEncoders::health() const noexcept {
  if (drive_.heartbeatTimedOut || steer_.heartbeatTimedOut) {
    return Status::Timeout;
  }
  for (const NodeHealth* h : {&drive_, &steer_}) {
    if (h->emcyActive || (h->state != NmtState::Unknown && h->state != NmtState::Operational)) {
      return Status::DeviceFault;
    }
  }
  if (!haveDrive_ || !haveSteer_) {
    return Status::NotInitialized;
  }
  return Status::Ok;
}

}  // namespace agv::drivers::canopen
