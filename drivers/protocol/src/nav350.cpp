#include "agv/drivers/protocol/sick/nav350.hpp"

#include <cmath>
#include <cstring>
#include <limits>

#include "agv/core/angle.hpp"
#include "protocol_detail.hpp"

namespace agv::drivers::sick {
namespace {
using detail::BeReader;

constexpr char kRequest[] = "sMN mNPOSGetData ";
constexpr char kReply[] = "sAN mNPOSGetData ";

double mdegToRad(double mdeg) noexcept {
  return deg2rad(mdeg * 1e-3);
}

Status parsePose(BeReader& r, Nav350PoseReply& reply) noexcept {
  std::uint16_t valid = 0;
  AGV_TRY(r.u16(valid));
  reply.poseValid = valid != 0U;
  if (!reply.poseValid) {
    return Status::Ok;
  }
  std::int32_t x = 0;
  std::int32_t y = 0;
  std::uint32_t phi = 0;
  AGV_TRY(r.i32(x));
  AGV_TRY(r.i32(y));
  AGV_TRY(r.u32(phi));
  reply.pose = Pose2d(static_cast<double>(x) * 1e-3, static_cast<double>(y) * 1e-3,
                      normalizeAngle(mdegToRad(static_cast<double>(phi))));
  AGV_TRY(r.u16(valid));
  reply.poseDetailsValid = valid != 0U;
  if (reply.poseDetailsValid) {
    std::int32_t meanDev = 0;
    AGV_TRY(r.u8(reply.outputMode));
    AGV_TRY(r.u32(reply.poseTimestampMs));
    AGV_TRY(r.i32(meanDev));
    AGV_TRY(r.u8(reply.navigationMode));
    AGV_TRY(r.u32(reply.infoState));
    AGV_TRY(r.u8(reply.usedReflectors));
    reply.meanDeviation = static_cast<double>(meanDev) * 1e-3;
  }
  return Status::Ok;
}

Status parseReflector(BeReader& r, const Nav350Config& config, Nav350Reflector& f) noexcept {
  std::uint16_t valid = 0;
  AGV_TRY(r.u16(valid));
  f.hasCartesian = valid != 0U;
  if (f.hasCartesian) {
    std::int32_t x = 0;
    std::int32_t y = 0;
    AGV_TRY(r.i32(x));
    AGV_TRY(r.i32(y));
    f.x = static_cast<double>(x) * 1e-3;
    f.y = static_cast<double>(y) * 1e-3;
  }
  AGV_TRY(r.u16(valid));
  f.hasPolar = valid != 0U;
  if (f.hasPolar) {
    std::uint32_t dist = 0;
    std::uint32_t phi = 0;
    AGV_TRY(r.u32(dist));
    AGV_TRY(r.u32(phi));
    f.range = static_cast<double>(dist) * 1e-3;
    f.bearing = normalizeAngle(mdegToRad(static_cast<double>(phi)) + config.angleOffset);
  }
  AGV_TRY(r.u16(valid));
  f.hasDetails = valid != 0U;
  if (f.hasDetails) {
    std::uint16_t size = 0;
    AGV_TRY(r.u16(f.localId));
    AGV_TRY(r.u16(f.globalId));
    AGV_TRY(r.u8(f.type));
    AGV_TRY(r.u16(f.subType));
    AGV_TRY(r.u16(f.quality));
    AGV_TRY(r.u32(f.timestampMs));
    AGV_TRY(r.u16(size));
    AGV_TRY(r.u16(f.hitCount));
    AGV_TRY(r.u16(f.meanEcho));
    AGV_TRY(r.u16(f.startIndex));
    AGV_TRY(r.u16(f.endIndex));
    f.size = static_cast<double>(size) * 1e-3;
  }
  return Status::Ok;
}

Status parseLandmarks(BeReader& r, const Nav350Config& config, Nav350PoseReply& reply, bool& overflow) noexcept {
  std::uint16_t valid = 0;
  AGV_TRY(r.u16(valid));
  reply.landmarksValid = valid != 0U;
  if (!reply.landmarksValid) {
    return Status::Ok;
  }
  AGV_TRY(r.u8(reply.landmarkFilter));
  AGV_TRY(r.u16(reply.reflectorCount));
  for (std::uint32_t i = 0; i < reply.reflectorCount; ++i) {
    Nav350Reflector f;
    AGV_TRY(parseReflector(r, config, f));
    if (reply.reflectors.push_back(f) != Status::Ok) {
      overflow = true;
    }
  }
  return Status::Ok;
}

/// Records the newest device instant of a decoded reply (the device clock wraps: "newer" is a
/// positive difference modulo 2^32).
void noteDeviceTimes(Nav350PoseReply& reply) noexcept {
  auto note = [&reply](std::uint32_t ms) {
    if (!reply.hasDeviceTime || static_cast<std::int32_t>(ms - reply.newestDeviceMs) > 0) {
      reply.newestDeviceMs = ms;
    }
    reply.hasDeviceTime = true;
  };
  if (reply.poseValid && reply.poseDetailsValid) {
    note(reply.poseTimestampMs);
  }
  if (reply.landmarksValid) {
    for (std::size_t i = 0; i < reply.reflectors.size(); ++i) {
      if (reply.reflectors[i].hasDetails) {
        note(reply.reflectors[i].timestampMs);
      }
    }
  }
  if (reply.scanValid) {
    note(reply.scanTimestampMs);
  }
}

/// One scan or remission channel header; `valueBytes` is 4 for DIST1/ANGL1, 2 for RSSI1.
struct ChannelHead {
  char name[6] = {};
  float scale = 0.0F;
  float offset = 0.0F;
  std::int32_t startMdeg = 0;
  std::uint16_t stepMdeg = 0;
  std::uint32_t timestampMs = 0;
  std::uint16_t count = 0;
};

Status parseChannelHead(BeReader& r, ChannelHead& ch) noexcept {
  const std::uint8_t* name = nullptr;
  AGV_TRY(r.bytes(5, name));
  std::memcpy(ch.name, name, 5);
  AGV_TRY(r.f32(ch.scale));
  AGV_TRY(r.f32(ch.offset));
  AGV_TRY(r.i32(ch.startMdeg));
  AGV_TRY(r.u16(ch.stepMdeg));
  AGV_TRY(r.u32(ch.timestampMs));
  AGV_TRY(r.u16(ch.count));
  return Status::Ok;
}

Status parseScan(BeReader& r, const Nav350Config& config, Timestamp receivedAt, Nav350PoseReply& reply,
                 bool& overflow) noexcept {
  std::uint16_t channels = 0;
  AGV_TRY(r.u16(channels));
  if (channels > 2U) {
    return Status::Malformed;
  }
  for (std::uint32_t c = 0; c < channels; ++c) {
    ChannelHead ch;
    AGV_TRY(parseChannelHead(r, ch));
    const bool dist = std::strcmp(ch.name, "DIST1") == 0;
    if (!dist && std::strcmp(ch.name, "ANGL1") != 0) {
      return Status::Malformed;
    }
    if (!dist) {
      const std::uint8_t* skipped = nullptr;
      AGV_TRY(r.bytes(4U * static_cast<std::size_t>(ch.count), skipped));
      continue;
    }
    if (!std::isfinite(ch.scale) || !(ch.scale > 0.0F) || !std::isfinite(ch.offset) || ch.stepMdeg == 0U) {
      return Status::Malformed;
    }
    if (!detail::plausibleScanChannel(static_cast<double>(ch.scale), static_cast<double>(ch.offset),
                                      static_cast<double>(ch.startMdeg) * 1e-3, static_cast<double>(ch.stepMdeg) * 1e-3,
                                      ch.count)) {
      return Status::OutOfRange;
    }
    LaserScan& scan = reply.scan;
    scan.angleMin =
        static_cast<float>(normalizeAngle(mdegToRad(static_cast<double>(ch.startMdeg)) + config.angleOffset));
    scan.angleIncrement = static_cast<float>(mdegToRad(static_cast<double>(ch.stepMdeg)));
    scan.rangeMin = config.rangeMin;
    scan.rangeMax = config.rangeMax;
    scan.stamp = receivedAt;
    reply.scanTimestampMs = ch.timestampMs;
    for (std::uint32_t i = 0; i < ch.count; ++i) {
      std::uint32_t raw = 0;
      AGV_TRY(r.u32(raw));
      float m = std::numeric_limits<float>::infinity();
      if (raw != 0U) {
        m = static_cast<float>(
            (static_cast<double>(raw) * static_cast<double>(ch.scale) + static_cast<double>(ch.offset)) * 1e-3);
      }
      if (scan.ranges.push_back(m) != Status::Ok) {
        overflow = true;
      }
    }
    reply.scanValid = true;
  }
  std::uint16_t remission = 0;
  AGV_TRY(r.u16(remission));
  if (remission != 0U) {
    ChannelHead ch;
    AGV_TRY(parseChannelHead(r, ch));
    if (std::strcmp(ch.name, "RSSI1") != 0) {
      return Status::Malformed;
    }
    const std::uint8_t* skipped = nullptr;
    AGV_TRY(r.bytes(2U * static_cast<std::size_t>(ch.count), skipped));
  }
  return Status::Ok;
}

}  // namespace

std::size_t encodeNav350PoseRequest(bool waitForNextScan, Nav350Mask mask, Span<std::uint8_t> out) noexcept {
  const std::size_t n = sizeof(kRequest) - 1;
  if (out.size() < n + 2) {
    return 0;
  }
  std::memcpy(out.data(), kRequest, n);
  out[n] = waitForNextScan ? 1U : 0U;
  out[n + 1] = static_cast<std::uint8_t>(mask);
  return n + 2;
}

std::size_t encodeColaB(Span<const std::uint8_t> payload, Span<std::uint8_t> out) noexcept {
  const std::size_t n = payload.size();
  if (out.size() < n + 9 || n > 0xFFFFFFFFU) {
    return 0;
  }
  out[0] = out[1] = out[2] = out[3] = 0x02;
  const auto len = static_cast<std::uint32_t>(n);
  out[4] = static_cast<std::uint8_t>(len >> 24U);
  out[5] = static_cast<std::uint8_t>(len >> 16U);
  out[6] = static_cast<std::uint8_t>(len >> 8U);
  out[7] = static_cast<std::uint8_t>(len);
  std::uint8_t x = 0;
  for (std::size_t i = 0; i < n; ++i) {
    out[8 + i] = payload[i];
    x = static_cast<std::uint8_t>(x ^ payload[i]);
  }
  out[8 + n] = x;
  return n + 9;
}

Status parseNav350PoseReply(Span<const std::uint8_t> payload, const Nav350Config& config, Timestamp receivedAt,
                            Nav350PoseReply& reply) noexcept {
  reply.version = 0;
  reply.errorCode = 0;
  reply.wait = 0;
  reply.mask = 0;
  reply.poseValid = false;
  reply.pose = Pose2d();
  reply.poseDetailsValid = false;
  reply.landmarksValid = false;
  reply.reflectorCount = 0;
  reply.reflectors.clear();
  reply.reflectors.resetRefusedCount();
  reply.scanValid = false;
  reply.scan.ranges.clear();
  reply.scan.ranges.resetRefusedCount();
  reply.scan.sweepDuration = Duration{};
  reply.receivedAt = receivedAt;
  reply.hasDeviceTime = false;
  reply.newestDeviceMs = 0;

  BeReader r(payload);
  bool overflow = false;
  Status s = r.literal(kReply);
  if (s == Status::Ok) {
    s = r.u16(reply.version);
  }
  if (s == Status::Ok) {
    s = r.u8(reply.errorCode);
  }
  if (s == Status::Ok) {
    s = r.u8(reply.wait);
  }
  if (s == Status::Ok) {
    s = r.u8(reply.mask);
  }
  if (s == Status::Ok && reply.errorCode != 0U && r.remaining() == 0U) {
    return Status::Ok;  // an error reply may stop after its header
  }
  if (s == Status::Ok) {
    s = parsePose(r, reply);
  }
  if (s == Status::Ok) {
    s = parseLandmarks(r, config, reply, overflow);
  }
  if (s == Status::Ok) {
    s = parseScan(r, config, receivedAt, reply, overflow);
  }
  if (s != Status::Ok) {
    reply.poseValid = false;
    reply.landmarksValid = false;
    reply.scanValid = false;
    reply.reflectors.clear();
    reply.scan.ranges.clear();
    return s;
  }
  noteDeviceTimes(reply);
  return overflow ? Status::CapacityExceeded : Status::Ok;
}

bool nav350VehicleTime(const Nav350PoseReply& reply, std::uint32_t deviceMs, Timestamp& out) noexcept {
  if (!reply.hasDeviceTime) {
    return false;
  }
  const std::uint32_t before = reply.newestDeviceMs - deviceMs;  // modulo 2^32: the clock may wrap
  if (before > kNav350MaxSpanMs) {
    return false;  // after the newest instant (a huge difference), or implausibly old
  }
  out = reply.receivedAt - Duration::fromMilliseconds(static_cast<std::int64_t>(before));
  return true;
}

}  // namespace agv::drivers::sick

namespace agv::drivers::sick {
namespace {
/// Big-endian writer into a bounded buffer; remembers an overflow.
class BeOut {
 public:
  explicit BeOut(Span<std::uint8_t> out) noexcept : out_(out) {}
  void u8(std::uint32_t v) noexcept {
    if (n_ < out_.size()) {
      out_[n_++] = static_cast<std::uint8_t>(v & 0xFFU);
    } else {
      overflow_ = true;
    }
  }
  void u16(std::uint32_t v) noexcept {
    u8(v >> 8U);
    u8(v);
  }
  void u32(std::uint32_t v) noexcept {
    u16(v >> 16U);
    u16(v & 0xFFFFU);
  }
  void i32(std::int64_t v) noexcept { u32(static_cast<std::uint32_t>(static_cast<std::int32_t>(v))); }
  void f32(float f) noexcept {
    std::uint32_t b = 0;
    std::memcpy(&b, &f, sizeof b);
    u32(b);
  }
  void text(const char* s) noexcept {
    for (; *s != '\0'; ++s) {
      u8(static_cast<std::uint8_t>(*s));
    }
  }
  std::size_t size() const noexcept { return overflow_ ? 0U : n_; }

 private:
  Span<std::uint8_t> out_;
  std::size_t n_ = 0;
  bool overflow_ = false;
};

std::int64_t toMm(double m) noexcept {
  const double mm = std::round(m * 1000.0);
  return mm > 2147483647.0 ? 2147483647 : (mm < -2147483648.0 ? -2147483647 - 1 : static_cast<std::int64_t>(mm));
}

/// Device angle [mdeg] in [0, 360000) of a sensor-frame angle.
std::uint32_t toMdeg(double rad, double offset) noexcept {
  double d = rad2deg(normalizeAngle(rad - offset)) * 1000.0;
  if (d < 0.0) {
    d += 360000.0;
  }
  const auto v = static_cast<std::uint32_t>(std::lround(d));
  return v >= 360000U ? v - 360000U : v;
}
}  // namespace

std::size_t encodeNav350PoseReply(const Nav350PoseReply& r, const Nav350Config& config,
                                  Span<std::uint8_t> out) noexcept {
  BeOut w(out);
  w.text(kReply);
  w.u16(r.version);
  w.u8(r.errorCode);
  w.u8(r.wait);
  w.u8(r.mask);
  w.u16(r.poseValid ? 1U : 0U);
  if (r.poseValid) {
    w.i32(toMm(r.pose.x));
    w.i32(toMm(r.pose.y));
    w.u32(toMdeg(r.pose.theta, 0.0));
    w.u16(r.poseDetailsValid ? 1U : 0U);
    if (r.poseDetailsValid) {
      w.u8(r.outputMode);
      w.u32(r.poseTimestampMs);
      w.i32(toMm(r.meanDeviation));
      w.u8(r.navigationMode);
      w.u32(r.infoState);
      w.u8(r.usedReflectors);
    }
  }
  w.u16(r.landmarksValid ? 1U : 0U);
  if (r.landmarksValid) {
    w.u8(r.landmarkFilter);
    w.u16(static_cast<std::uint32_t>(r.reflectors.size()));
    for (const Nav350Reflector& f : r.reflectors) {
      w.u16(f.hasCartesian ? 1U : 0U);
      if (f.hasCartesian) {
        w.i32(toMm(f.x));
        w.i32(toMm(f.y));
      }
      w.u16(f.hasPolar ? 1U : 0U);
      if (f.hasPolar) {
        w.u32(static_cast<std::uint32_t>(toMm(f.range < 0.0 ? 0.0 : f.range)));
        w.u32(toMdeg(f.bearing, config.angleOffset));
      }
      w.u16(f.hasDetails ? 1U : 0U);
      if (f.hasDetails) {
        w.u16(f.localId);
        w.u16(f.globalId);
        w.u8(f.type);
        w.u16(f.subType);
        w.u16(f.quality);
        w.u32(f.timestampMs);
        w.u16(static_cast<std::uint32_t>(toMm(f.size)) & 0xFFFFU);
        w.u16(f.hitCount);
        w.u16(f.meanEcho);
        w.u16(f.startIndex);
        w.u16(f.endIndex);
      }
    }
  }
  const LaserScan& scan = r.scan;
  w.u16(r.scanValid ? 1U : 0U);
  if (r.scanValid) {
    w.text("DIST1");
    w.f32(1.0F);
    w.f32(0.0F);
    w.i32(static_cast<std::int32_t>(toMdeg(static_cast<double>(scan.angleMin), config.angleOffset)));
    w.u16(static_cast<std::uint32_t>(std::lround(rad2deg(static_cast<double>(scan.angleIncrement)) * 1000.0)) &
          0xFFFFU);
    w.u32(r.scanTimestampMs);
    w.u16(static_cast<std::uint32_t>(scan.size()) & 0xFFFFU);
    for (std::size_t i = 0; i < scan.size(); ++i) {
      w.u32(scan.isValid(i) ? static_cast<std::uint32_t>(toMm(static_cast<double>(scan.ranges[i]))) : 0U);
    }
  }
  w.u16(0);  // no remission channel
  return w.size();
}

}  // namespace agv::drivers::sick
