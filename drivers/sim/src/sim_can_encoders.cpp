#include "agv/sim/sim_can_encoders.hpp"

#include <cmath>

#include "agv/core/angle.hpp"

namespace agv::sim {

namespace canopen = drivers::canopen;
using drivers::CanFrame;

namespace {
constexpr std::uint32_t kNmtId = 0x000;
constexpr std::uint32_t kSyncId = 0x080;

/// `v` as a two's-complement field of `bits` bits holds it (the device's position value).
std::int64_t wrapSigned(std::int64_t v, unsigned bits) noexcept {
  const std::uint64_t mask = bits >= 64U ? ~std::uint64_t{0} : (std::uint64_t{1} << bits) - 1U;
  const std::uint64_t half = std::uint64_t{1} << (bits - 1U);
  const std::uint64_t u = static_cast<std::uint64_t>(v) & mask;
  return static_cast<std::int64_t>(u ^ half) - static_cast<std::int64_t>(half);
}
}  // namespace

SimCanEncodersParams defaultSimCanEncoders(std::uint32_t steerCountsPerRevolution) {
  SimCanEncodersParams p;
  p.bus.drive.nodeId = 1;
  p.bus.drive.pdo = canopen::PdoMapping{0x181, 0, 4};
  p.bus.drive.direction = -1;  // the motor counts down when the vehicle drives forward
  p.bus.steering.nodeId = 2;
  p.bus.steering.pdo = canopen::PdoMapping{0x182, 0, 4};
  p.bus.steering.direction = 1;
  p.bus.steering.countsPerRevolution = steerCountsPerRevolution;
  p.bus.steering.radiansPerCount = kTwoPi<double> / static_cast<double>(steerCountsPerRevolution);
  // Straight ahead 3/128 of a revolution (8.4 deg) below the encoder's wrap: left turns cross it.
  p.bus.steering.zeroCount = steerCountsPerRevolution - steerCountsPerRevolution / 128U * 3U;
  p.bus.trigger = canopen::SampleTrigger::BothUpdated;
  p.bus.heartbeatTimeout = Duration::fromMilliseconds(300);
  p.bus.syncPeriod = Duration{};
  return p;
}

Status validateSimCanEncoders(const SimCanEncodersParams& params) noexcept {
  if (canopen::CanopenEncoders(params.bus).validate() != Status::Ok) {
    return Status::InvalidArgument;
  }
  const std::int64_t limit = std::int64_t{1} << 31;
  return params.driveTicksAtZero >= -limit && params.driveTicksAtZero < limit ? Status::Ok : Status::InvalidArgument;
}

SimCanEncoders::SimCanEncoders(const SimCanEncodersParams& params) noexcept : params_(params) {}

void SimCanEncoders::nmt(canopen::NmtCommand command, Node& node) noexcept {
  switch (command) {
    case canopen::NmtCommand::Start:
      node.state = canopen::NmtState::Operational;
      break;
    case canopen::NmtCommand::Stop:
      node.state = canopen::NmtState::Stopped;
      break;
    case canopen::NmtCommand::EnterPreOperational:
      node.state = canopen::NmtState::PreOperational;
      break;
    case canopen::NmtCommand::ResetNode:
    case canopen::NmtCommand::ResetCommunication:
      node.state = canopen::NmtState::PreOperational;
      node.bootPending = true;
      break;
  }
}

void SimCanEncoders::receive(const CanFrame& frame) noexcept {
  if (frame.extended || frame.rtr || frame.error) {
    return;
  }
  if (frame.id == kSyncId) {
    ++counters_.syncsReceived;
    syncReceived_ = true;
    return;
  }
  if (frame.id == kNmtId && frame.dlc >= 2U) {
    ++counters_.nmtReceived;
    const auto command = static_cast<canopen::NmtCommand>(frame.data[0]);
    const std::uint8_t target = frame.data[1];
    if (target == 0U || target == params_.bus.drive.nodeId) {
      nmt(command, drive_);
    }
    if (target == 0U || target == params_.bus.steering.nodeId) {
      nmt(command, steer_);
    }
  }
}

std::size_t SimCanEncoders::measure(const hal::EncoderSample& truth, Span<CanFrame> out) noexcept {
  std::size_t n = 0;
  const auto put = [&](const CanFrame& f) noexcept {
    if (n < out.size()) {
      out[n++] = f;
    }
  };
  const Timestamp t = truth.stamp;
  const std::uint8_t nodes[2] = {params_.bus.drive.nodeId, params_.bus.steering.nodeId};
  Node* states[2] = {&drive_, &steer_};
  // Boot-up messages (power-on or reset), then the periodic heartbeats.
  bool booted = false;
  for (int i = 0; i < 2; ++i) {
    Node& node = *states[i];
    if (node.bootPending) {
      node.bootPending = false;
      put(canopen::encodeHeartbeat(nodes[i], canopen::NmtState::BootUp, t));
      ++counters_.heartbeats;
      booted = true;
    }
  }
  if (!heartbeatStarted_ || booted) {
    heartbeatStarted_ = true;
    nextHeartbeat_ = t + params_.heartbeatPeriod;
  } else if (params_.heartbeatPeriod.ns > 0 && t >= nextHeartbeat_) {
    for (int i = 0; i < 2; ++i) {
      put(canopen::encodeHeartbeat(nodes[i], states[i]->state, t));
      ++counters_.heartbeats;
    }
    nextHeartbeat_ = nextHeartbeat_ + params_.heartbeatPeriod;
    if (t >= nextHeartbeat_) {  // measurements further apart than the producer time
      nextHeartbeat_ = t + params_.heartbeatPeriod;
    }
  }
  // TPDOs: cyclic on every measurement, or synchronous on a SYNC received since the last one.
  const bool synchronous = params_.bus.syncPeriod.ns > 0;
  const bool send = !synchronous || syncReceived_;
  syncReceived_ = false;
  if (!send) {
    return n;
  }
  if (drive_.state == canopen::NmtState::Operational) {
    const canopen::DriveEncoderConfig& d = params_.bus.drive;
    const std::int64_t ticks = truth.driveTicks + params_.driveTicksAtZero;
    put(canopen::encodeDrivePdo(d, ticks, t));
    ++counters_.drivePdos;
    const std::int64_t value = wrapSigned(d.direction < 0 ? -ticks : ticks, 8U * d.pdo.size);
    const std::int64_t half = std::int64_t{1} << (8U * d.pdo.size - 1U);
    if (haveLastValue_ && (value - lastValue_ > half || lastValue_ - value > half)) {
      ++counters_.driveCounterWraps;
    }
    haveLastValue_ = true;
    lastValue_ = value;
  }
  if (steer_.state == canopen::NmtState::Operational) {
    put(canopen::encodeSteeringPdo(params_.bus.steering, truth.steeringAngle, t));
    ++counters_.steeringPdos;
  }
  return n;
}

hal::EncoderSample SimCanEncoders::expectedDecoded(const hal::EncoderSample& truth) const noexcept {
  const canopen::SteeringEncoderConfig& s = params_.bus.steering;
  const double sign = s.direction < 0 ? -1.0 : 1.0;
  hal::EncoderSample e = truth;
  e.driveTicks = truth.driveTicks + params_.driveTicksAtZero;
  e.steeringAngle =
      sign * static_cast<double>(std::llround(sign * truth.steeringAngle / s.radiansPerCount)) * s.radiansPerCount;
  return e;
}

}  // namespace agv::sim
