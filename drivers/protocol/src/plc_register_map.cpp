#include "agv/drivers/protocol/plc/plc_register_map.hpp"

#include <cmath>
#include <initializer_list>
#include <limits>

#include "agv/core/angle.hpp"

namespace agv::drivers::plc {
namespace {
// Offsets inside the command block.
constexpr std::uint16_t kCmdCode = 0;
constexpr std::uint16_t kCmdSequence = 1;
constexpr std::uint16_t kCmdX = 2;
constexpr std::uint16_t kCmdY = 4;
constexpr std::uint16_t kCmdTheta = 6;
constexpr std::uint16_t kCmdPlcHeartbeat = 8;
constexpr std::uint16_t kMaxCommandCode = static_cast<std::uint16_t>(PlcCommandCode::Stop);

/// Publishes a double as float; out-of-float-range values become +-inf, NaN stays NaN.
float toFloat(double v) noexcept {
  return static_cast<float>(v);
}
}  // namespace

Status PlcRegisterMap::encodeStatus(const PlcStatus& s, Span<std::uint16_t> table) const noexcept {
  if (table.size() < static_cast<std::size_t>(kStatusBase) + kStatusCount) {
    return Status::InvalidArgument;
  }
  std::uint16_t* r = table.data() + kStatusBase;
  const WordOrder o = config_.wordOrder;
  r[0] = s.heartbeat;
  r[1] = static_cast<std::uint16_t>(s.mode);
  r[2] = s.health;
  r[3] = static_cast<std::uint16_t>(s.lastStatus);
  packFloat(toFloat(s.pose.x), o, r + 4);
  packFloat(toFloat(s.pose.y), o, r + 6);
  packFloat(toFloat(s.pose.theta), o, r + 8);
  for (std::size_t i = 0; i < 6; ++i) {
    packFloat(toFloat(s.covariance[i]), o, r + 10 + 2 * i);
  }
  // Milliseconds modulo 2^32 (wraps after 49.7 days; the PLC uses differences).
  const auto ms = static_cast<std::uint64_t>(s.stamp.ns / 1000000);
  packU32(static_cast<std::uint32_t>(ms & 0xFFFFFFFFULL), o, r + 22);
  r[24] = s.matchedLandmarks;
  r[25] = s.visibleReflectors;
  packFloat(toFloat(s.calibration.driveScale), o, r + 26);
  packFloat(toFloat(s.calibration.steerOffsetForward), o, r + 28);
  packFloat(toFloat(s.calibration.steerOffsetBackward), o, r + 30);
  packFloat(toFloat(s.calibration.laserMount.x), o, r + 32);
  packFloat(toFloat(s.calibration.laserMount.y), o, r + 34);
  packFloat(toFloat(s.calibration.laserMount.theta), o, r + 36);
  packFloat(toFloat(s.calibration.wheelbase), o, r + 38);
  r[40] = s.reflectorsFused;
  r[41] = s.reflectorsRejected;
  r[42] = s.cornersFused;
  r[43] = s.cornersRejected;
  r[44] = s.routine.state;
  r[45] = s.routine.phase;
  r[46] = s.routine.segment;
  r[47] = s.routine.total;
  r[48] = static_cast<std::uint16_t>(s.routine.lastRefusal);
  r[49] = s.routine.driveFault;
  return Status::Ok;
}

Result<PlcCommand> PlcRegisterMap::decodeCommandBlock(const std::uint16_t* b) const noexcept {
  const WordOrder o = config_.wordOrder;
  if (b[kCmdCode] > kMaxCommandCode) {
    return Status::InvalidArgument;
  }
  const double x = static_cast<double>(unpackFloat(b + kCmdX, o));
  const double y = static_cast<double>(unpackFloat(b + kCmdY, o));
  const double th = static_cast<double>(unpackFloat(b + kCmdTheta, o));
  const double lim = config_.maxAbsPosition;
  // Written as negated "inside" tests so that NaN is refused too.
  if (!(std::fabs(x) <= lim) || !(std::fabs(y) <= lim) || !(std::fabs(th) <= kPi<double> + 1e-6)) {
    return Status::InvalidArgument;
  }
  PlcCommand c;
  c.code = static_cast<PlcCommandCode>(b[kCmdCode]);
  c.sequence = b[kCmdSequence];
  c.pose = Pose2d(x, y, normalizeAngle(th));
  c.plcHeartbeat = b[kCmdPlcHeartbeat];
  return c;
}

Result<PlcCommand> PlcRegisterMap::decodeCommand(Span<const std::uint16_t> table) const noexcept {
  if (table.size() < static_cast<std::size_t>(kCommandBase) + kCommandCount) {
    return Status::InvalidArgument;
  }
  return decodeCommandBlock(table.data() + kCommandBase);
}

Status PlcRegisterMap::checkWrite(std::uint16_t address, Span<const std::uint16_t> values,
                                  Span<const std::uint16_t> table) const noexcept {
  if (values.empty()) {
    return Status::InvalidArgument;
  }
  const std::size_t first = address;
  const std::size_t last = first + values.size();  // one past
  if (first < kCommandBase || last > static_cast<std::size_t>(kCommandBase) + kCommandCount) {
    return Status::OutOfRange;
  }
  // 32-bit fields must be written whole.
  for (const std::uint16_t field : {kCmdX, kCmdY, kCmdTheta}) {
    const std::size_t lo = kCommandBase + field;
    const bool hasLo = lo >= first && lo < last;
    const bool hasHi = lo + 1 >= first && lo + 1 < last;
    if (hasLo != hasHi) {
      return Status::Malformed;
    }
  }
  std::uint16_t block[kCommandCount] = {};
  if (table.size() >= static_cast<std::size_t>(kCommandBase) + kCommandCount) {
    for (std::size_t i = 0; i < kCommandCount; ++i) {
      block[i] = table[kCommandBase + i];
    }
  }
  for (std::size_t i = 0; i < values.size(); ++i) {
    block[first - kCommandBase + i] = values[i];
  }
  return decodeCommandBlock(block).ok() ? Status::Ok : Status::InvalidArgument;
}

}  // namespace agv::drivers::plc
