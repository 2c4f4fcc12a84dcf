// libFuzzer target: the CANopen encoder decoder fed arbitrary frames and service times. The first
// 16 bytes choose the configuration (mapping, sizes, directions, zero, SYNC/heartbeat periods);
// each following 14 bytes are one frame: id (2), dlc (1), flags (1), data (8), time step (2).
// Invariants: no crash or sanitizer report, service() writes within its span, the steering angle
// stays within half a revolution when the encoder wraps per revolution.
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "agv/drivers/protocol/canopen/canopen_encoders.hpp"
#include "fuzz_support.hpp"

using namespace agv::drivers;
using namespace agv::drivers::canopen;

namespace {
using agv::fuzz::check;
using agv::fuzz::u16le;
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 16) {
    return 0;
  }
  CanopenEncodersConfig cfg;
  cfg.drive.nodeId = static_cast<std::uint8_t>(data[0] & 0x7F);
  cfg.steering.nodeId = static_cast<std::uint8_t>(data[1] & 0x7F);
  cfg.drive.pdo = {static_cast<std::uint16_t>(u16le(data + 2) & 0x7FF), static_cast<std::uint8_t>(data[4] % 8),
                   static_cast<std::uint8_t>(data[5] % 5)};
  cfg.steering.pdo = {static_cast<std::uint16_t>(u16le(data + 6) & 0x7FF), static_cast<std::uint8_t>(data[8] % 8),
                      static_cast<std::uint8_t>(data[9] % 5)};
  cfg.drive.direction = (data[10] & 1) ? 1 : -1;
  cfg.steering.direction = (data[10] & 2) ? 1 : -1;
  cfg.steering.countsPerRevolution = (data[10] & 4) ? (1U << (data[11] % 17)) : 0U;
  cfg.steering.zeroCount = u16le(data + 12);
  cfg.steering.radiansPerCount = 1e-4;
  cfg.trigger = (data[10] & 8) ? SampleTrigger::BothUpdated : SampleTrigger::DriveUpdated;
  cfg.syncPeriod = agv::Duration::fromMicroseconds(data[14] * 100);
  cfg.heartbeatTimeout = agv::Duration::fromMicroseconds(data[15] * 1000);
  CanopenEncoders decoder(cfg);
  CanopenEncoders* dec = &decoder;
  if (dec->validate() != agv::Status::Ok) {
    return 0;
  }
  CanFrame out[3];
  agv::Timestamp now{};
  for (std::size_t pos = 16; pos + 14 <= size; pos += 14) {
    const std::uint8_t* p = data + pos;
    CanFrame f = agv::fuzz::canFrameFromBytes(p);
    now = now + agv::Duration::fromMicroseconds(u16le(p + 12));
    f.stamp = now;
    (void)dec->onFrame(f);
    const std::size_t n = dec->service(now, agv::Span<CanFrame>(out, 1 + (p[3] >> 6)));
    check(n <= 3U);
    agv::hal::EncoderSample s;
    (void)dec->takeSample(s);
    EmcyRecord r;
    (void)dec->takeEmcy(r);
    (void)dec->health();
    if (cfg.steering.countsPerRevolution > 0U) {
      check(std::fabs(dec->steeringAngle()) <= 0.5 * cfg.steering.countsPerRevolution * 1e-4 + 1e-9);
    }
  }
  return 0;
}
