#include "agv/drivers/protocol/ouster/ouster_packet.hpp"

#include <cmath>

namespace agv::drivers::ouster {

namespace {
constexpr std::size_t kHeaderBytes = 32;  // non-legacy packet header and footer
constexpr std::size_t kLegacyColumnHeader = 16;
constexpr std::size_t kLegacyColumnFooter = 4;
constexpr std::size_t kColumnHeader = 12;
constexpr std::uint32_t kLegacyValid = 0xFFFFFFFFU;
constexpr float kTwoPi = 6.283185307179586F;

std::uint16_t le16(const std::uint8_t* p) noexcept {
  return static_cast<std::uint16_t>(p[0] | (static_cast<unsigned>(p[1]) << 8U));
}
std::uint32_t le32(const std::uint8_t* p) noexcept {
  return static_cast<std::uint32_t>(p[0]) | (static_cast<std::uint32_t>(p[1]) << 8U) |
         (static_cast<std::uint32_t>(p[2]) << 16U) | (static_cast<std::uint32_t>(p[3]) << 24U);
}
std::uint64_t le64(const std::uint8_t* p) noexcept {
  return static_cast<std::uint64_t>(le32(p)) | (static_cast<std::uint64_t>(le32(p + 4)) << 32U);
}

std::size_t columnBytes(const Format& f) noexcept {
  const bool legacy = f.profile == Profile::Legacy;
  return (legacy ? kLegacyColumnHeader + kLegacyColumnFooter : kColumnHeader) +
         f.pixelsPerColumn * pixelBytes(f.profile);
}

struct Pixel {
  std::uint32_t range[2] = {0, 0};
  std::uint16_t reflectivity[2] = {0, 0};
  std::uint16_t signal = 0;
  std::uint16_t nearIr = 0;
};

Pixel readPixel(Profile profile, const std::uint8_t* p) noexcept {
  Pixel px;
  switch (profile) {
    case Profile::Legacy:
      px.range[0] = le32(p) & 0xFFFFFU;
      px.reflectivity[0] = le16(p + 4);
      px.signal = le16(p + 6);
      px.nearIr = le16(p + 8);
      break;
    case Profile::Rng19Rfl8Sig16Nir16:
      px.range[0] = le32(p) & 0x7FFFFU;
      px.reflectivity[0] = p[4];
      px.signal = le16(p + 6);
      px.nearIr = le16(p + 8);
      break;
    case Profile::Rng19Rfl8Sig16Nir16Dual:
      px.range[0] = le32(p) & 0x7FFFFU;
      px.reflectivity[0] = p[3];
      px.range[1] = le32(p + 4) & 0x7FFFFU;
      px.reflectivity[1] = p[7];
      px.signal = le16(p + 8);
      px.nearIr = le16(p + 12);
      break;
    case Profile::Rng15Rfl8Nir8:
      px.range[0] = static_cast<std::uint32_t>(le16(p) & 0x7FFFU) * 8U;
      px.reflectivity[0] = p[2];
      px.nearIr = static_cast<std::uint16_t>(p[3] * 16U);
      break;
  }
  return px;
}
}  // namespace

std::size_t pixelBytes(Profile profile) noexcept {
  switch (profile) {
    case Profile::Legacy:
    case Profile::Rng19Rfl8Sig16Nir16:
      return 12;
    case Profile::Rng19Rfl8Sig16Nir16Dual:
      return 16;
    case Profile::Rng15Rfl8Nir8:
      return 4;
  }
  return 0;
}

Status validate(const Format& f) noexcept {
  if (f.columnsPerPacket == 0 || f.columnsPerPacket > kMaxColumnsPerPacket || f.pixelsPerColumn == 0 ||
      f.pixelsPerColumn > kMaxPixelsPerColumn || f.columnsPerFrame == 0 || f.columnsPerFrame > kMaxColumnsPerFrame ||
      pixelBytes(f.profile) == 0) {
    return Status::InvalidArgument;
  }
  return Status::Ok;
}

std::size_t packetBytes(const Format& f) noexcept {
  if (validate(f) != Status::Ok) {
    return 0;
  }
  const std::size_t frame = f.profile == Profile::Legacy ? 0 : 2 * kHeaderBytes;
  return frame + f.columnsPerPacket * columnBytes(f);
}

std::uint16_t columnAzimuth(std::uint16_t m, std::uint16_t w) noexcept {
  if (w == 0) {
    return 0;
  }
  const std::uint32_t az = (static_cast<std::uint32_t>(m % w) * velodyne::kAzimuthTurn + w / 2U) / w;
  return static_cast<std::uint16_t>(az % velodyne::kAzimuthTurn);
}

std::uint16_t measurementId(std::uint16_t azimuth, std::uint16_t w) noexcept {
  if (w == 0) {
    return 0;
  }
  const std::uint32_t m =
      (static_cast<std::uint32_t>(azimuth) * w + velodyne::kAzimuthTurn / 2U) / velodyne::kAzimuthTurn;
  return static_cast<std::uint16_t>(m % w);
}

Status OusterDecoder::decode(Span<const std::uint8_t> packet, Span<FiringRecord> out, std::size_t& written,
                             PacketInfo* info, Span<PixelExtra> extra) noexcept {
  written = 0;
  const Format& f = config_.format;
  const std::size_t want = packetBytes(f);
  if (want == 0 || (extra.size() != 0 && extra.size() < out.size())) {
    return Status::InvalidArgument;
  }
  if (packet.size() < want) {
    ++counters_.truncated;
    return Status::Truncated;
  }
  if (packet.size() > want) {
    ++counters_.oversized;
    return Status::Malformed;
  }
  const std::uint8_t* p = packet.data();
  const bool legacy = f.profile == Profile::Legacy;
  std::uint16_t packetType = 0;
  std::uint16_t frameId = 0;
  if (!legacy) {
    packetType = le16(p);
    frameId = le16(p + 2);
    if (packetType != 1U) {
      ++counters_.badPacketType;
      return Status::Unsupported;
    }
  }
  ++counters_.packets;
  if (info != nullptr) {
    info->packetType = packetType;
    info->frameId = legacy ? le16(p + 10) : frameId;
    info->columnCount = f.columnsPerPacket;
  }
  const std::size_t colBytes = columnBytes(f);
  const std::size_t pxBytes = pixelBytes(f.profile);
  const std::size_t first = legacy ? 0 : kHeaderBytes;
  const std::uint64_t t0 = le64(p + first);
  const bool dual = f.profile == Profile::Rng19Rfl8Sig16Nir16Dual;
  const unsigned returns = dual && config_.emitSecondReturn ? 2U : 1U;
  bool skipped = false;
  bool full = false;
  for (std::size_t c = 0; c < f.columnsPerPacket; ++c) {
    const std::uint8_t* col = p + first + c * colBytes;
    ColumnHeader h;
    h.timestampNs = le64(col);
    h.measurementId = le16(col + 8);
    if (legacy) {
      h.frameId = le16(col + 10);
      h.encoderCount = le32(col + 12);
      h.status = le32(col + colBytes - kLegacyColumnFooter);
      h.valid = h.status == kLegacyValid;
    } else {
      h.frameId = frameId;
      h.status = le16(col + 10);
      h.valid = (h.status & 1U) != 0U;
    }
    if (info != nullptr) {
      info->columns[c] = h;
    }
    if (!h.valid) {
      ++counters_.invalidColumns;
      skipped = true;
      continue;
    }
    if (h.measurementId >= f.columnsPerFrame) {
      ++counters_.badMeasurementId;
      skipped = true;
      continue;
    }
    ++counters_.validColumns;
    const std::uint16_t az = columnAzimuth(h.measurementId, f.columnsPerFrame);
    const std::uint64_t dt = h.timestampNs >= t0 ? h.timestampNs - t0 : 0U;
    const std::uint32_t timeNs = dt > 0xFFFFFFFFULL ? 0xFFFFFFFFU : static_cast<std::uint32_t>(dt);
    const std::uint8_t* px0 = col + (legacy ? kLegacyColumnHeader : kColumnHeader);
    for (std::size_t row = 0; row < f.pixelsPerColumn; ++row) {
      const Pixel px = readPixel(f.profile, px0 + row * pxBytes);
      for (unsigned k = 0; k < returns; ++k) {
        const std::uint32_t mm = px.range[k];
        if (mm == 0U && !config_.keepNoReturn) {
          ++counters_.noReturn;
          continue;
        }
        if (mm > kMaxRecordRangeMm) {
          ++counters_.beyondRecordRange;
          continue;
        }
        if (written >= out.size()) {
          ++counters_.outputFull;
          full = true;
          continue;
        }
        FiringRecord& r = out[written];
        r.timeNs = timeNs;
        r.azimuth = az;
        r.distance = static_cast<std::uint16_t>((mm + 1U) / 2U > 65535U ? 65535U : (mm + 1U) / 2U);
        r.laser = static_cast<std::uint8_t>(row);
        r.intensity = static_cast<std::uint8_t>(px.reflectivity[k] > 255U ? 255U : px.reflectivity[k]);
        r.block = static_cast<std::uint8_t>(c);
        r.secondReturn = static_cast<std::uint8_t>(k);
        if (extra.size() != 0) {
          PixelExtra& e = extra[written];
          e.rangeMm = mm;
          e.signal = px.signal;
          e.nearIr = px.nearIr;
          e.reflectivity = px.reflectivity[k];
        }
        ++written;
      }
    }
  }
  if (full) {
    return Status::CapacityExceeded;
  }
  return skipped ? Status::Malformed : Status::Ok;
}

Status ousterPoint(const OusterIntrinsics& in, const FiringRecord& r, bool sensorFrame, float xyz[3]) noexcept {
  if (r.laser >= in.beams || in.beams > kMaxPixelsPerColumn) {
    return Status::OutOfRange;
  }
  if (r.distance == 0U) {
    return Status::NotFound;
  }
  const std::uint16_t m = measurementId(r.azimuth, in.columnsPerFrame);
  const float thetaE = kTwoPi * (1.0F - static_cast<float>(m) / static_cast<float>(in.columnsPerFrame));
  const float theta = thetaE - in.azimuthRad[r.laser];
  const float phi = in.altitudeRad[r.laser];
  const float rangeM = static_cast<float>(r.distance) * 0.002F;
  const float n = in.beamOriginM;
  const float d = rangeM - n;
  const float x = d * std::cos(theta) * std::cos(phi) + n * std::cos(thetaE);
  const float y = d * std::sin(theta) * std::cos(phi) + n * std::sin(thetaE);
  const float z = d * std::sin(phi) + in.beamZOffsetM;
  if (!sensorFrame) {
    xyz[0] = x;
    xyz[1] = y;
    xyz[2] = z;
    return Status::Ok;
  }
  const float* t = in.lidarToSensor;
  xyz[0] = t[0] * x + t[1] * y + t[2] * z + t[3];
  xyz[1] = t[4] * x + t[5] * y + t[6] * z + t[7];
  xyz[2] = t[8] * x + t[9] * y + t[10] * z + t[11];
  return Status::Ok;
}

Status toFiringReturns(Span<const FiringRecord> records, const OusterIntrinsics& in, Span<FiringReturn> out,
                       std::size_t& written) noexcept {
  written = 0;
  if (in.columnsPerFrame == 0) {
    return Status::InvalidArgument;
  }
  // ousterPoint() with its six sines and cosines per point factored: per beam those of its
  // altitude and azimuth (computed at the beam's first record of the call), per column those of
  // theta_e (a packet's records come column by column), and theta = theta_e - az by the angle
  // difference identities. The same model; the points agree with ousterPoint() to float rounding.
  float cosAlt[kMaxPixelsPerColumn];
  float sinAlt[kMaxPixelsPerColumn];
  float cosAz[kMaxPixelsPerColumn];
  float sinAz[kMaxPixelsPerColumn];
  bool beamReady[kMaxPixelsPerColumn] = {};
  std::uint16_t lastM = 0;
  bool haveColumn = false;
  float cosE = 1.0F;
  float sinE = 0.0F;
  const float n = in.beamOriginM;
  const float* t = in.lidarToSensor;
  const std::int32_t w = in.columnsPerFrame;
  const std::uint16_t beams = in.beams <= kMaxPixelsPerColumn ? in.beams : std::uint16_t{0};  // beyond capacity: none
  Status st = Status::Ok;
  for (std::size_t i = 0; i < records.size(); ++i) {
    const FiringRecord& r = records[i];
    if (r.secondReturn != 0U) {
      continue;
    }
    if (r.laser >= beams) {
      st = Status::OutOfRange;
      continue;
    }
    if (r.distance == 0U) {
      continue;
    }
    if (written >= out.size()) {
      return Status::CapacityExceeded;
    }
    const std::uint16_t m = measurementId(r.azimuth, in.columnsPerFrame);
    if (!haveColumn || m != lastM) {
      const float thetaE = kTwoPi * (1.0F - static_cast<float>(m) / static_cast<float>(in.columnsPerFrame));
      cosE = std::cos(thetaE);
      sinE = std::sin(thetaE);
      lastM = m;
      haveColumn = true;
    }
    const std::size_t b = r.laser;
    if (!beamReady[b]) {
      cosAlt[b] = std::cos(in.altitudeRad[b]);
      sinAlt[b] = std::sin(in.altitudeRad[b]);
      cosAz[b] = std::cos(in.azimuthRad[b]);
      sinAz[b] = std::sin(in.azimuthRad[b]);
      beamReady[b] = true;
    }
    const float cosTheta = cosE * cosAz[b] + sinE * sinAz[b];  // cos(theta_e - az)
    const float sinTheta = sinE * cosAz[b] - cosE * sinAz[b];  // sin(theta_e - az)
    const float d = static_cast<float>(r.distance) * 0.002F - n;
    const float x = d * cosTheta * cosAlt[b] + n * cosE;
    const float y = d * sinTheta * cosAlt[b] + n * sinE;
    const float z = d * sinAlt[b] + in.beamZOffsetM;
    const std::int32_t col = (static_cast<std::int32_t>(m) + in.pixelShift[b] % w + w) % w;
    FiringReturn& o = out[written++];
    o.point = Eigen::Vector3f(t[0] * x + t[1] * y + t[2] * z + t[3], t[4] * x + t[5] * y + t[6] * z + t[7],
                              t[8] * x + t[9] * y + t[10] * z + t[11]);
    o.laser = r.laser;
    o.firing = static_cast<std::uint32_t>(col);
  }
  return st;
}

}  // namespace agv::drivers::ouster
