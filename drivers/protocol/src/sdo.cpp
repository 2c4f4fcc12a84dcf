#include "agv/drivers/protocol/canopen/sdo.hpp"

namespace agv::drivers::canopen {
namespace {

// Command specifiers (bits 7..5 of byte 0).
constexpr std::uint8_t kCcsDownloadInitiate = 1;
constexpr std::uint8_t kCcsUploadInitiate = 2;
constexpr std::uint8_t kScsUploadInitiate = 2;
constexpr std::uint8_t kScsDownloadInitiate = 3;
constexpr std::uint8_t kCsAbort = 4;
constexpr std::uint8_t kCsReserved = 7;
constexpr std::uint8_t kExpedited = 0x02;      // e
constexpr std::uint8_t kSizeIndicated = 0x01;  // s

bool validNode(std::uint8_t node) noexcept {
  return node >= 1U && node <= 127U;
}

bool fitsSize(std::uint32_t value, std::uint8_t size) noexcept {
  return size == 0U || size >= 4U || (value >> (8U * size)) == 0U;
}

void putU32(std::uint8_t* p, std::uint32_t v) noexcept {
  for (unsigned i = 0; i < 4U; ++i) {
    p[i] = static_cast<std::uint8_t>(v >> (8U * i));
  }
}

std::uint32_t getU32(const std::uint8_t* p) noexcept {
  return static_cast<std::uint32_t>(p[0]) | (static_cast<std::uint32_t>(p[1]) << 8U) |
         (static_cast<std::uint32_t>(p[2]) << 16U) | (static_cast<std::uint32_t>(p[3]) << 24U);
}

void frameHead(CanFrame& f, std::uint32_t id, std::uint8_t command, const SdoMessage& m) noexcept {
  f = CanFrame{};
  f.id = id;
  f.dlc = 8;
  f.data[0] = command;
  f.data[1] = static_cast<std::uint8_t>(m.index & 0xFFU);
  f.data[2] = static_cast<std::uint8_t>(m.index >> 8U);
  f.data[3] = m.subIndex;
}

/// Expedited transfer command byte with the size bits: scs/ccs, n = 4 - size, e, s.
std::uint8_t expeditedCommand(std::uint8_t cs, std::uint8_t size) noexcept {
  std::uint8_t c = static_cast<std::uint8_t>((cs << 5U) | kExpedited);
  if (size != 0U) {
    c = static_cast<std::uint8_t>(c | ((4U - size) << 2U) | kSizeIndicated);
  }
  return c;
}

/// The value of an expedited transfer: size from the n/s bits, bytes past it cleared.
void expeditedValue(const CanFrame& f, SdoMessage& m) noexcept {
  const std::uint8_t c = f.data[0];
  m.size = (c & kSizeIndicated) != 0U ? static_cast<std::uint8_t>(4U - ((c >> 2U) & 0x3U)) : 0U;
  std::uint32_t v = getU32(f.data + 4);
  if (m.size != 0U && m.size < 4U) {
    v &= (1U << (8U * m.size)) - 1U;
  }
  m.value = v;
}

Status encodeCommon(std::uint32_t id, std::uint8_t node, const SdoMessage& m, bool server, CanFrame& out) noexcept {
  if (!validNode(node) || m.size > 4U) {
    return Status::InvalidArgument;
  }
  switch (m.kind) {
    case SdoKind::DownloadRequest:
      if (server || !fitsSize(m.value, m.size)) {
        return Status::InvalidArgument;
      }
      frameHead(out, id, expeditedCommand(kCcsDownloadInitiate, m.size), m);
      putU32(out.data + 4, m.value);
      return Status::Ok;
    case SdoKind::UploadRequest:
      if (server) {
        return Status::InvalidArgument;
      }
      frameHead(out, id, static_cast<std::uint8_t>(kCcsUploadInitiate << 5U), m);
      return Status::Ok;
    case SdoKind::DownloadResponse:
      if (!server) {
        return Status::InvalidArgument;
      }
      frameHead(out, id, static_cast<std::uint8_t>(kScsDownloadInitiate << 5U), m);
      return Status::Ok;
    case SdoKind::UploadResponse:
      if (!server || !fitsSize(m.value, m.size)) {
        return Status::InvalidArgument;
      }
      frameHead(out, id, expeditedCommand(kScsUploadInitiate, m.size), m);
      putU32(out.data + 4, m.value);
      return Status::Ok;
    case SdoKind::Abort:
      frameHead(out, id, static_cast<std::uint8_t>(kCsAbort << 5U), m);
      putU32(out.data + 4, m.abortCode);
      return Status::Ok;
  }
  return Status::InvalidArgument;
}

/// Common checks of a received SDO frame: our COB-ID, a data frame of 8 bytes; index and
/// sub-index filled in.
Status decodeHead(const CanFrame& f, std::uint32_t id, SdoMessage& m) noexcept {
  if (f.extended || f.rtr || f.error || f.id != id) {
    return Status::NotFound;
  }
  if (f.dlc < 8U) {
    return Status::Truncated;
  }
  m = SdoMessage{};
  m.index = static_cast<std::uint16_t>(f.data[1] | (f.data[2] << 8U));
  m.subIndex = f.data[3];
  return Status::Ok;
}

}  // namespace

const char* sdoAbortName(std::uint32_t code) noexcept {
  switch (static_cast<SdoAbortCode>(code)) {
    case SdoAbortCode::ToggleBitNotAlternated:
      return "toggle bit not alternated";
    case SdoAbortCode::ProtocolTimedOut:
      return "SDO protocol timed out";
    case SdoAbortCode::CommandSpecifierInvalid:
      return "command specifier not valid or unknown";
    case SdoAbortCode::InvalidBlockSize:
      return "invalid block size";
    case SdoAbortCode::InvalidSequenceNumber:
      return "invalid sequence number";
    case SdoAbortCode::CrcError:
      return "CRC error";
    case SdoAbortCode::OutOfMemory:
      return "out of memory";
    case SdoAbortCode::UnsupportedAccess:
      return "unsupported access to an object";
    case SdoAbortCode::ReadOfWriteOnly:
      return "read of a write-only object";
    case SdoAbortCode::WriteOfReadOnly:
      return "write of a read-only object";
    case SdoAbortCode::ObjectDoesNotExist:
      return "object does not exist";
    case SdoAbortCode::ObjectNotMappable:
      return "object cannot be mapped to a PDO";
    case SdoAbortCode::PdoLengthExceeded:
      return "mapped objects exceed the PDO length";
    case SdoAbortCode::ParameterIncompatible:
      return "general parameter incompatibility";
    case SdoAbortCode::InternalIncompatible:
      return "general internal incompatibility in the device";
    case SdoAbortCode::HardwareError:
      return "access failed: hardware error";
    case SdoAbortCode::LengthMismatch:
      return "data type does not match: length";
    case SdoAbortCode::LengthTooHigh:
      return "data type does not match: length too high";
    case SdoAbortCode::LengthTooLow:
      return "data type does not match: length too low";
    case SdoAbortCode::SubIndexDoesNotExist:
      return "sub-index does not exist";
    case SdoAbortCode::InvalidValue:
      return "invalid value";
    case SdoAbortCode::ValueTooHigh:
      return "value too high";
    case SdoAbortCode::ValueTooLow:
      return "value too low";
    case SdoAbortCode::MaxBelowMin:
      return "maximum below minimum";
    case SdoAbortCode::ResourceNotAvailable:
      return "resource not available: SDO connection";
    case SdoAbortCode::GeneralError:
      return "general error";
    case SdoAbortCode::CannotTransfer:
      return "data cannot be transferred or stored";
    case SdoAbortCode::CannotTransferLocalControl:
      return "data cannot be transferred: local control";
    case SdoAbortCode::CannotTransferDeviceState:
      return "data cannot be transferred: device state";
    case SdoAbortCode::NoObjectDictionary:
      return "no object dictionary";
    case SdoAbortCode::NoDataAvailable:
      return "no data available";
  }
  return "unknown abort code";
}

Status encodeSdoRequest(std::uint8_t nodeId, const SdoMessage& message, CanFrame& out) noexcept {
  return encodeCommon(kSdoRequestBase + nodeId, nodeId, message, false, out);
}

Status encodeSdoResponse(std::uint8_t nodeId, const SdoMessage& message, CanFrame& out) noexcept {
  return encodeCommon(kSdoResponseBase + nodeId, nodeId, message, true, out);
}

Status decodeSdoRequest(const CanFrame& frame, std::uint8_t nodeId, SdoMessage& out) noexcept {
  SdoMessage m;
  const Status head = decodeHead(frame, kSdoRequestBase + nodeId, m);
  if (head != Status::Ok) {
    return head;
  }
  const std::uint8_t ccs = static_cast<std::uint8_t>(frame.data[0] >> 5U);
  if (ccs == kCcsDownloadInitiate) {
    if ((frame.data[0] & kExpedited) == 0U) {
      return Status::Unsupported;  // segmented download
    }
    m.kind = SdoKind::DownloadRequest;
    expeditedValue(frame, m);
  } else if (ccs == kCcsUploadInitiate) {
    m.kind = SdoKind::UploadRequest;
  } else if (ccs == kCsAbort) {
    m.kind = SdoKind::Abort;
    m.abortCode = getU32(frame.data + 4);
  } else if (ccs == kCsReserved) {
    return Status::Malformed;
  } else {
    return Status::Unsupported;  // segments, block transfers
  }
  out = m;
  return Status::Ok;
}

Status decodeSdoResponse(const CanFrame& frame, std::uint8_t nodeId, SdoMessage& out) noexcept {
  SdoMessage m;
  const Status head = decodeHead(frame, kSdoResponseBase + nodeId, m);
  if (head != Status::Ok) {
    return head;
  }
  const std::uint8_t scs = static_cast<std::uint8_t>(frame.data[0] >> 5U);
  if (scs == kScsDownloadInitiate) {
    m.kind = SdoKind::DownloadResponse;
  } else if (scs == kScsUploadInitiate) {
    if ((frame.data[0] & kExpedited) == 0U) {
      return Status::Unsupported;  // normal (segmented) upload: the value does not fit one frame
    }
    m.kind = SdoKind::UploadResponse;
    expeditedValue(frame, m);
  } else if (scs == kCsAbort) {
    m.kind = SdoKind::Abort;
    m.abortCode = getU32(frame.data + 4);
  } else if (scs == kCsReserved) {
    return Status::Malformed;
  } else {
    return Status::Unsupported;
  }
  out = m;
  return Status::Ok;
}

}  // namespace agv::drivers::canopen
