#pragma once
/// @file modbus_request.hpp
/// Modbus TCP requests on the server side, portable and heap-free: `MbapRequestFramer` cuts one
/// connection's byte stream into requests (MBAP header + PDU) without ever reading past the request
/// it is assembling, and `checkModbusRequest` decides, before anything is answered or written,
/// whether a complete request is served, refused with an exception or discarded unanswered.
///
/// The transport (drivers/linux, `ModbusPlcLink`) reads into `space()`, bounds the time a request
/// may take, and answers with libmodbus (`modbus_reply` / `modbus_reply_exception`) only requests
/// that `checkModbusRequest` marks `Serve`, so libmodbus never refuses one itself.

#include <array>
#include <cstddef>
#include <cstdint>

#include "agv/core/span.hpp"
#include "agv/core/status.hpp"

namespace agv::drivers::plc {

constexpr std::size_t kMbapHeaderSize = 7;  ///< transaction id, protocol id, length, unit id
constexpr std::size_t kMaxModbusAdu = 260;  ///< MBAP header + the longest PDU (253 bytes)

/// Cuts Modbus TCP requests out of one connection's byte stream (one object per connection; a
/// partial request survives between calls).
///
/// Requests whose MBAP length announces more than kMaxModbusAdu are read to their end and
/// discarded (only the header and function code are kept: `oversized()`), so the stream stays in
/// step and the request can still be answered with an exception. A length below 2 (no unit id and
/// function code) cannot frame anything: `commit()` returns `Malformed` and the connection must be
/// dropped.
class MbapRequestFramer {
 public:
  /// Where the next received bytes go: exactly the bytes the current request still needs (never
  /// more, so a following pipelined request stays in the socket). Empty when `complete()`.
  Span<std::uint8_t> space() noexcept;
  /// `n` bytes were written to `space()` (n <= its size). Ok; Malformed (MBAP length < 2: drop
  /// the connection); InvalidArgument when `n` is larger than the space offered.
  Status commit(std::size_t n) noexcept;
  /// A whole request is there: `adu()` until `next()`.
  bool complete() const noexcept { return complete_; }
  /// Some bytes of a request are there (complete or not).
  bool started() const noexcept { return received_ > 0U; }
  /// The request announced more than kMaxModbusAdu bytes; `adu()` holds its header and function
  /// code only.
  bool oversized() const noexcept { return oversized_; }
  /// Bytes of the current request received so far (discarded ones included).
  std::uint32_t receivedBytes() const noexcept { return received_; }
  /// The complete request (header + PDU), empty while incomplete.
  Span<const std::uint8_t> adu() const noexcept;
  /// Forgets the current request (complete or not); the next bytes start a new one.
  void next() noexcept;

 private:
  std::array<std::uint8_t, kMaxModbusAdu> buffer_{};
  std::size_t stored_ = 0;                ///< bytes in buffer_
  std::size_t wanted_ = kMbapHeaderSize;  ///< bytes buffer_ must hold before the next step
  std::uint32_t discard_ = 0;             ///< bytes still to be read and dropped (oversized request)
  std::uint32_t received_ = 0;
  bool headerDone_ = false;
  bool oversized_ = false;
  bool complete_ = false;
};

/// What to do with one complete request.
enum class RequestVerdict : std::uint8_t {
  Serve,         ///< well formed, a function of the map, registers in range: answer it (writes still
                 ///< go through PlcRegisterMap::checkWrite)
  Exception,     ///< answer with `exception` (the function code is < 0x80)
  RefusedWrite,  ///< a write the map never accepts (coils, mask write): exception 01, counts as a
                 ///< refused write
  Discard,       ///< not a request to answer: MBAP protocol id not 0 (not Modbus), or a function
                 ///< code with bit 7 set (an exception response, which no reply could echo)
};

/// Modbus exception codes used here.
enum class ModbusException : std::uint8_t {
  None = 0,
  IllegalFunction = 1,
  IllegalDataAddress = 2,
  IllegalDataValue = 3,
};

struct RequestCheck {
  RequestVerdict verdict = RequestVerdict::Discard;
  ModbusException exception = ModbusException::None;
  std::uint8_t function = 0;
  bool isWrite = false;               ///< FC 06, 16, 23 (the write part)
  std::uint16_t writeAddress = 0;     ///< first register written (Serve, isWrite)
  std::uint16_t writeCount = 0;       ///< registers written
  std::size_t writeValuesOffset = 0;  ///< offset in the ADU of the first big-endian value
};

/// Checks one complete request (`adu` from MbapRequestFramer; `oversized` its flag) against the
/// shape of Modbus and a holding-register table of `registerCount` registers starting at 0:
/// protocol id, function code, PDU length against what the function implies, quantities within
/// the Modbus limits (read 1..125, write 1..123, read/write 1..121 written), byte count equal to
/// twice the quantity, and read ranges inside the table (exception 02). Served functions: 03, 06,
/// 16, 23. Unit id: any (the vehicle is the only unit behind its address).
RequestCheck checkModbusRequest(Span<const std::uint8_t> adu, bool oversized, std::uint16_t registerCount) noexcept;

/// Builds an exception response to `request` (its transaction id, unit id, function | 0x80,
/// `code`) into `out` (at least 9 bytes). Returns its length (9), or 0 when `request` is shorter
/// than a header and a function code or the function already has bit 7 set.
std::size_t buildExceptionResponse(Span<const std::uint8_t> request, ModbusException code,
                                   Span<std::uint8_t> out) noexcept;

// --- Client side (the vehicle writing to and reading from a PLC that serves Modbus TCP) ---------
// MbapRequestFramer cuts responses as well: the MBAP framing is the same in both directions.

/// FC 03 request (read `count` holding registers at `address`) into `out` (at least 12 bytes).
/// Returns its length (12), or 0 when `out` is too small or `count` is not in 1..125.
std::size_t buildReadHoldingRequest(std::uint16_t transaction, std::uint8_t unit, std::uint16_t address,
                                    std::uint16_t count, Span<std::uint8_t> out) noexcept;

/// FC 16 request (write `values` from `address`) into `out` (at least 13 + 2 n bytes). Returns its
/// length, or 0 when `out` is too small or there are not 1..123 values.
std::size_t buildWriteMultipleRequest(std::uint16_t transaction, std::uint8_t unit, std::uint16_t address,
                                      Span<const std::uint16_t> values, Span<std::uint8_t> out) noexcept;

/// Checks a complete response `adu` to the request `request` (built above) and, for FC 03, copies
/// the registers into `values` (its size = the count requested). Ok; Rejected (an exception
/// response: `exception` set); Malformed (protocol id not 0, another transaction or function, a
/// length, byte count, address or quantity that does not match the request).
Status checkModbusResponse(Span<const std::uint8_t> adu, Span<const std::uint8_t> request, Span<std::uint16_t> values,
                           ModbusException& exception) noexcept;

}  // namespace agv::drivers::plc
