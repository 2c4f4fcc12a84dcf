#pragma once
/// @file sdo.hpp
/// CANopen (CiA 301) expedited SDO transfers, heap-free: the frames a client sends to a node's
/// SDO server (COB-ID 0x600 + node) and the server's answers (0x580 + node). Only expedited
/// transfers (values of 1..4 bytes in one frame) are supported, which covers every object the
/// drive controller uses (docs/drives.md); a segmented or block transfer is refused as
/// `Unsupported`. Abort codes are decoded to a name (`sdoAbortName`).
///
/// Frame layout (8 data bytes always): byte 0 the command specifier, bytes 1-2 the object index
/// (little-endian), byte 3 the sub-index, bytes 4-7 the value (little-endian) or the abort code.

#include <cstdint>

#include "agv/core/status.hpp"
#include "agv/drivers/protocol/can_frame.hpp"

namespace agv::drivers::canopen {

/// COB-ID base of the client -> server SDO (request): 0x600 + node id.
inline constexpr std::uint32_t kSdoRequestBase = 0x600;
/// COB-ID base of the server -> client SDO (response): 0x580 + node id.
inline constexpr std::uint32_t kSdoResponseBase = 0x580;

/// SDO abort codes of CiA 301 (the 32-bit value in an abort frame). `sdoAbortName` names them.
enum class SdoAbortCode : std::uint32_t {
  ToggleBitNotAlternated = 0x05030000,
  ProtocolTimedOut = 0x05040000,
  CommandSpecifierInvalid = 0x05040001,
  InvalidBlockSize = 0x05040002,
  InvalidSequenceNumber = 0x05040003,
  CrcError = 0x05040004,
  OutOfMemory = 0x05040005,
  UnsupportedAccess = 0x06010000,
  ReadOfWriteOnly = 0x06010001,
  WriteOfReadOnly = 0x06010002,
  ObjectDoesNotExist = 0x06020000,
  ObjectNotMappable = 0x06040041,
  PdoLengthExceeded = 0x06040042,
  ParameterIncompatible = 0x06040043,
  InternalIncompatible = 0x06040047,
  HardwareError = 0x06060000,
  LengthMismatch = 0x06070010,
  LengthTooHigh = 0x06070012,
  LengthTooLow = 0x06070013,
  SubIndexDoesNotExist = 0x06090011,
  InvalidValue = 0x06090030,
  ValueTooHigh = 0x06090031,
  ValueTooLow = 0x06090032,
  MaxBelowMin = 0x06090036,
  ResourceNotAvailable = 0x060A0023,
  GeneralError = 0x08000000,
  CannotTransfer = 0x08000020,
  CannotTransferLocalControl = 0x08000021,
  CannotTransferDeviceState = 0x08000022,
  NoObjectDictionary = 0x08000023,
  NoDataAvailable = 0x08000024,
};

/// Every abort code `sdoAbortName` knows, in the order of the enum (for tests and tools).
inline constexpr SdoAbortCode kSdoAbortCodes[] = {
    SdoAbortCode::ToggleBitNotAlternated,
    SdoAbortCode::ProtocolTimedOut,
    SdoAbortCode::CommandSpecifierInvalid,
    SdoAbortCode::InvalidBlockSize,
    SdoAbortCode::InvalidSequenceNumber,
    SdoAbortCode::CrcError,
    SdoAbortCode::OutOfMemory,
    SdoAbortCode::UnsupportedAccess,
    SdoAbortCode::ReadOfWriteOnly,
    SdoAbortCode::WriteOfReadOnly,
    SdoAbortCode::ObjectDoesNotExist,
    SdoAbortCode::ObjectNotMappable,
    SdoAbortCode::PdoLengthExceeded,
    SdoAbortCode::ParameterIncompatible,
    SdoAbortCode::InternalIncompatible,
    SdoAbortCode::HardwareError,
    SdoAbortCode::LengthMismatch,
    SdoAbortCode::LengthTooHigh,
    SdoAbortCode::LengthTooLow,
    SdoAbortCode::SubIndexDoesNotExist,
    SdoAbortCode::InvalidValue,
    SdoAbortCode::ValueTooHigh,
    SdoAbortCode::ValueTooLow,
    SdoAbortCode::MaxBelowMin,
    SdoAbortCode::ResourceNotAvailable,
    SdoAbortCode::GeneralError,
    SdoAbortCode::CannotTransfer,
    SdoAbortCode::CannotTransferLocalControl,
    SdoAbortCode::CannotTransferDeviceState,
    SdoAbortCode::NoObjectDictionary,
    SdoAbortCode::NoDataAvailable,
};

/// Short name of an abort code (e.g. 0x06020000 -> "object does not exist"); "unknown abort code"
/// for a value CiA 301 does not define. Never null.
const char* sdoAbortName(std::uint32_t code) noexcept;

/// What an SDO frame is.
enum class SdoKind : std::uint8_t {
  DownloadRequest,   ///< client writes `value` (`size` bytes) to index/sub-index
  UploadRequest,     ///< client reads index/sub-index
  DownloadResponse,  ///< server confirms a write
  UploadResponse,    ///< server answers a read with `value` (`size` bytes)
  Abort,             ///< either side aborts the transfer of index/sub-index with `abortCode`
};

/// One expedited SDO message, decoded.
struct SdoMessage {
  SdoKind kind = SdoKind::UploadRequest;
  std::uint16_t index = 0;
  std::uint8_t subIndex = 0;
  /// Value of a download request or an upload response, zero-extended (little-endian on the bus).
  std::uint32_t value = 0;
  /// Value size [bytes] 1..4 of a download request or an upload response; 0 = not indicated by
  /// the sender (all 4 bytes taken). Unused for the other kinds.
  std::uint8_t size = 0;
  /// Abort code of an `Abort` (see `SdoAbortCode`).
  std::uint32_t abortCode = 0;
};

/// Builds the frame a client sends to `nodeId` (COB-ID 0x600 + node): a download request, an
/// upload request or an abort. `InvalidArgument` for a node id outside 1..127, a size above 4, a
/// value that does not fit `size` bytes, or a kind a client does not send (responses).
Status encodeSdoRequest(std::uint8_t nodeId, const SdoMessage& message, CanFrame& out) noexcept;

/// Builds the frame the server `nodeId` answers with (COB-ID 0x580 + node): a download response,
/// an expedited upload response or an abort. `InvalidArgument` as for the request, or for a
/// request kind.
Status encodeSdoResponse(std::uint8_t nodeId, const SdoMessage& message, CanFrame& out) noexcept;

/// Decodes a frame received by the SDO server of `nodeId`. `NotFound`: not its request COB-ID (or an
/// extended, remote or error frame); `Truncated`: fewer than 8 data bytes; `Unsupported`: a
/// segmented or block transfer; `Malformed`: an unknown command specifier. `out` is written only
/// on `Ok`.
Status decodeSdoRequest(const CanFrame& frame, std::uint8_t nodeId, SdoMessage& out) noexcept;

/// Decodes a frame the client receives from the server `nodeId`; same results as
/// `decodeSdoRequest` (a normal, non-expedited upload response is `Unsupported`).
Status decodeSdoResponse(const CanFrame& frame, std::uint8_t nodeId, SdoMessage& out) noexcept;

}  // namespace agv::drivers::canopen
