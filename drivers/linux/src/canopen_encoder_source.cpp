#include "agv/drivers/linux/canopen_encoder_source.hpp"

#include <cstring>

namespace agv::drivers {
namespace {

constexpr std::uint32_t kEmcyBase = 0x080;
constexpr std::uint32_t kHeartbeatBase = 0x700;
// NMT Start for two nodes, a SYNC and NMT Start again after a boot-up: service() never has more.
constexpr std::size_t kMaxOutFrames = 4;

bool isNmtStart(const CanFrame& f) noexcept {
  return f.id == 0x000U && f.dlc == 2U && f.data[0] == static_cast<std::uint8_t>(canopen::NmtCommand::Start);
}

}  // namespace

CanopenEncoderSource::CanopenEncoderSource(const CanopenEncoderSourceConfig& config) noexcept
    : config_(config), decoder_(config.canopen) {
  const char* name = config.interfaceName;
  std::size_t len = 0;
  while (name != nullptr && len < sizeof(name_) && name[len] != '\0') {
    ++len;
  }
  if (name == nullptr || len == 0 || len >= sizeof(name_)) {
    configStatus_ = Status::InvalidArgument;
  } else {
    std::memcpy(name_, name, len);
    name_[len] = '\0';
  }
  config_.interfaceName = name_;
  if (configStatus_ == Status::Ok) {
    configStatus_ = decoder_.validate();
  }
  if (config_.maxFramesPerRead == 0U || config_.openRetryInterval.ns <= 0 || config_.busOffReopenAfter.ns <= 0 ||
      config_.receiveBufferBytes < 0) {
    configStatus_ = Status::InvalidArgument;
  }
}

Status CanopenEncoderSource::open() noexcept {
  if (configStatus_ != Status::Ok) {
    openStatus_ = configStatus_;
    return configStatus_;
  }
  wanted_ = true;
  return tryOpen(monotonicNow());
}

void CanopenEncoderSource::close() noexcept {
  wanted_ = false;
  bus_.close();
  openStatus_ = Status::NotInitialized;
}

Status CanopenEncoderSource::tryOpen(Timestamp now) noexcept {
  SocketCanConfig c;
  c.interfaceName = name_;
  c.receiveBufferBytes = config_.receiveBufferBytes;
  c.busOffReopenAfter = config_.busOffReopenAfter;
  const canopen::CanopenEncodersConfig& co = config_.canopen;
  const std::uint32_t ids[] = {
      co.drive.pdo.cobId,
      co.steering.pdo.cobId,
      kEmcyBase + co.drive.nodeId,
      kEmcyBase + co.steering.nodeId,
      kHeartbeatBase + co.drive.nodeId,
      kHeartbeatBase + co.steering.nodeId,
  };
  for (const std::uint32_t id : ids) {
    (void)c.filters.push_back(CanFilter{id, 0x7FFU, false});  // 6 of kMaxCanFilters (>= 16)
  }
  ++counters_.openAttempts;
  nextOpen_ = now + config_.openRetryInterval;
  openStatus_ = bus_.open(c);
  if (openStatus_ != Status::Ok) {
    return openStatus_;
  }
  seenReopens_ = bus_.health().counters.reopens;
  wasBusOff_ = false;
  sendStartup();
  return Status::Ok;
}

void CanopenEncoderSource::sendFrame(const CanFrame& frame) noexcept {
  if (bus_.send(frame) != Status::Ok) {
    ++counters_.sendFailures;
    return;
  }
  if (isNmtStart(frame)) {
    ++counters_.nmtStartsSent;
  } else if (frame.id == 0x080U && frame.dlc == 0U) {
    ++counters_.syncsSent;
  }
}

void CanopenEncoderSource::sendStartup() noexcept {
  CanFrame frames[2];
  const std::size_t n = decoder_.startupFrames(Span<CanFrame>(frames, 2));
  for (std::size_t i = 0; i < n; ++i) {
    sendFrame(frames[i]);
  }
}

void CanopenEncoderSource::watchRecovery() noexcept {
  const SocketCanHealth& h = bus_.health();
  const bool busOff = h.controller == CanControllerState::BusOff;
  const bool reopened = h.counters.reopens != seenReopens_;
  if (bus_.isUp() && !busOff && (reopened || wasBusOff_)) {
    // Back on the bus: the nodes may have been reset or stopped meanwhile.
    ++counters_.recoveries;
    sendStartup();
  }
  seenReopens_ = h.counters.reopens;
  wasBusOff_ = busOff;
}

Status CanopenEncoderSource::read(hal::EncoderSample& out) noexcept {
  if (configStatus_ != Status::Ok) {
    return configStatus_;
  }
  if (!wanted_) {
    return Status::NotInitialized;
  }
  if (openStatus_ != Status::Ok) {
    const Timestamp now = monotonicNow();
    if (now < nextOpen_ || tryOpen(now) != Status::Ok) {
      return Status::DeviceFault;
    }
  }

  bool have = false;
  hal::EncoderSample sample{};
  for (std::uint32_t i = 0; i < config_.maxFramesPerRead; ++i) {
    CanFrame f;
    if (bus_.receive(f, Duration{}) != Status::Ok) {
      break;  // nothing waiting, or the link is down (the bus reopens it on later calls)
    }
    if (f.error) {
      ++counters_.errorFrames;  // already decoded into busHealth()
      watchRecovery();
      continue;
    }
    ++counters_.framesHandled;
    (void)decoder_.onFrame(f);
    watchRecovery();  // a frame after a bus-off means the controller is back
    if (decoder_.takeSample(sample)) {
      have = true;  // the next frames stay queued: no sample is overwritten
      break;
    }
  }
  bus_.maintain();
  watchRecovery();

  CanFrame due[kMaxOutFrames];
  const std::size_t n = decoder_.service(monotonicNow(), Span<CanFrame>(due, kMaxOutFrames));
  for (std::size_t i = 0; i < n; ++i) {
    sendFrame(due[i]);
  }

  if (have) {
    out = sample;
    ++counters_.samples;
    return Status::Ok;
  }
  const Status h = health();
  return h == Status::Ok || h == Status::NotInitialized ? Status::NotFound : h;
}

Status CanopenEncoderSource::health() const noexcept {
  if (configStatus_ != Status::Ok) {
    return configStatus_;
  }
  if (!wanted_) {
    return Status::NotInitialized;
  }
  if (openStatus_ != Status::Ok || !bus_.isUp() || bus_.health().controller == CanControllerState::BusOff) {
    return Status::DeviceFault;
  }
  return decoder_.health();
}

}  // namespace agv::drivers
