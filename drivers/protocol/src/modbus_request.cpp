#include "agv/drivers/protocol/plc/modbus_request.hpp"

namespace agv::drivers::plc {
namespace {

constexpr std::size_t kLengthOffset = 4;              // MBAP length: unit id + PDU
constexpr std::size_t kFunctionOffset = 7;            // first PDU byte
constexpr std::size_t kKeptOfOversized = 8;           // header + function code
constexpr std::uint16_t kMaxReadQuantity = 125;       // FC 03, FC 23 read part
constexpr std::uint16_t kMaxWriteQuantity = 123;      // FC 16
constexpr std::uint16_t kMaxReadWriteQuantity = 121;  // FC 23 write part

constexpr std::uint8_t kReadHolding = 0x03;
constexpr std::uint8_t kWriteSingle = 0x06;
constexpr std::uint8_t kWriteMultiple = 0x10;
constexpr std::uint8_t kReadWrite = 0x17;
constexpr std::uint8_t kWriteCoil = 0x05;
constexpr std::uint8_t kWriteCoils = 0x0F;
constexpr std::uint8_t kMaskWrite = 0x16;

std::uint16_t be16(const std::uint8_t* p) noexcept {
  return static_cast<std::uint16_t>((static_cast<unsigned>(p[0]) << 8U) | p[1]);
}

RequestCheck exception(RequestCheck c, ModbusException e) noexcept {
  c.verdict = RequestVerdict::Exception;
  c.exception = e;
  return c;
}

bool readRangeOk(std::uint16_t address, std::uint16_t quantity, std::uint16_t registerCount) noexcept {
  return static_cast<std::uint32_t>(address) + quantity <= registerCount;
}

}  // namespace

Span<std::uint8_t> MbapRequestFramer::space() noexcept {
  if (complete_) {
    return {};
  }
  if (discard_ > 0U && stored_ >= wanted_) {
    // Dropped bytes go after the kept header and function code; at most the rest of the buffer.
    const std::size_t room = buffer_.size() - kKeptOfOversized;
    return {buffer_.data() + kKeptOfOversized, discard_ < room ? discard_ : room};
  }
  return {buffer_.data() + stored_, wanted_ - stored_};
}

Status MbapRequestFramer::commit(std::size_t n) noexcept {
  if (n > space().size()) {
    return Status::InvalidArgument;
  }
  received_ += static_cast<std::uint32_t>(n);
  if (discard_ > 0U && stored_ >= wanted_) {
    discard_ -= static_cast<std::uint32_t>(n);
    complete_ = discard_ == 0U;
    return Status::Ok;
  }
  stored_ += n;
  if (stored_ < wanted_) {
    return Status::Ok;
  }
  if (!headerDone_) {
    headerDone_ = true;
    const std::size_t length = be16(buffer_.data() + kLengthOffset);
    if (length < 2U) {
      return Status::Malformed;  // no unit id and function code: nothing can be framed after this
    }
    const std::size_t total = kMbapHeaderSize - 1U + length;
    if (total <= buffer_.size()) {
      wanted_ = total;
      return Status::Ok;
    }
    oversized_ = true;
    wanted_ = kKeptOfOversized;
    discard_ = static_cast<std::uint32_t>(total - kKeptOfOversized);
    return Status::Ok;
  }
  complete_ = true;
  if (oversized_ && discard_ > 0U) {
    complete_ = false;  // the function code is in; now drop the rest
  }
  return Status::Ok;
}

Span<const std::uint8_t> MbapRequestFramer::adu() const noexcept {
  return complete_ ? Span<const std::uint8_t>(buffer_.data(), stored_) : Span<const std::uint8_t>{};
}

void MbapRequestFramer::next() noexcept {
  stored_ = 0;
  wanted_ = kMbapHeaderSize;
  discard_ = 0;
  received_ = 0;
  headerDone_ = false;
  oversized_ = false;
  complete_ = false;
}

RequestCheck checkModbusRequest(Span<const std::uint8_t> adu, bool oversized, std::uint16_t registerCount) noexcept {
  RequestCheck c;
  if (adu.size() < kFunctionOffset + 1U) {
    return c;  // Discard: not even a function code
  }
  const std::uint8_t* a = adu.data();
  c.function = a[kFunctionOffset];
  if (a[2] != 0U || a[3] != 0U || (c.function & 0x80U) != 0U) {
    return c;  // Discard: not Modbus, or an exception response
  }
  const bool served = c.function == kReadHolding || c.function == kWriteSingle || c.function == kWriteMultiple ||
                      c.function == kReadWrite;
  if (c.function == kWriteCoil || c.function == kWriteCoils || c.function == kMaskWrite) {
    c.verdict = RequestVerdict::RefusedWrite;
    c.exception = ModbusException::IllegalFunction;
    c.isWrite = true;
    return c;
  }
  if (!served) {
    return exception(c, ModbusException::IllegalFunction);
  }
  c.isWrite = c.function != kReadHolding;
  if (oversized) {
    return exception(c, ModbusException::IllegalDataValue);  // a quantity beyond what a frame holds
  }
  const std::uint8_t* pdu = a + kFunctionOffset;
  const std::size_t pduLength = adu.size() - kFunctionOffset;
  switch (c.function) {
    case kReadHolding: {
      if (pduLength != 5U) {
        return exception(c, ModbusException::IllegalDataValue);
      }
      const std::uint16_t address = be16(pdu + 1);
      const std::uint16_t quantity = be16(pdu + 3);
      if (quantity < 1U || quantity > kMaxReadQuantity) {
        return exception(c, ModbusException::IllegalDataValue);
      }
      if (!readRangeOk(address, quantity, registerCount)) {
        return exception(c, ModbusException::IllegalDataAddress);
      }
      break;
    }
    case kWriteSingle:
      if (pduLength != 5U) {
        return exception(c, ModbusException::IllegalDataValue);
      }
      c.writeAddress = be16(pdu + 1);
      c.writeCount = 1;
      c.writeValuesOffset = kFunctionOffset + 3U;
      break;
    case kWriteMultiple: {
      if (pduLength < 6U) {
        return exception(c, ModbusException::IllegalDataValue);
      }
      const std::uint16_t quantity = be16(pdu + 3);
      const std::size_t bytes = pdu[5];
      if (quantity < 1U || quantity > kMaxWriteQuantity || bytes != 2U * quantity || pduLength != 6U + bytes) {
        return exception(c, ModbusException::IllegalDataValue);
      }
      c.writeAddress = be16(pdu + 1);
      c.writeCount = quantity;
      c.writeValuesOffset = kFunctionOffset + 6U;
      break;
    }
    default: {  // kReadWrite
      if (pduLength < 10U) {
        return exception(c, ModbusException::IllegalDataValue);
      }
      const std::uint16_t readAddress = be16(pdu + 1);
      const std::uint16_t readQuantity = be16(pdu + 3);
      const std::uint16_t writeQuantity = be16(pdu + 7);
      const std::size_t bytes = pdu[9];
      if (readQuantity < 1U || readQuantity > kMaxReadQuantity || writeQuantity < 1U ||
          writeQuantity > kMaxReadWriteQuantity || bytes != 2U * writeQuantity || pduLength != 10U + bytes) {
        return exception(c, ModbusException::IllegalDataValue);
      }
      if (!readRangeOk(readAddress, readQuantity, registerCount)) {
        return exception(c, ModbusException::IllegalDataAddress);
      }
      c.writeAddress = be16(pdu + 5);
      c.writeCount = writeQuantity;
      c.writeValuesOffset = kFunctionOffset + 10U;
      break;
    }
  }
  c.verdict = RequestVerdict::Serve;
  return c;
}

namespace {
void putBe16(std::uint8_t* p, std::uint16_t v) noexcept {
  p[0] = static_cast<std::uint8_t>(v >> 8U);
  p[1] = static_cast<std::uint8_t>(v & 0xFFU);
}

void putHeader(std::uint8_t* o, std::uint16_t transaction, std::uint16_t length, std::uint8_t unit) noexcept {
  putBe16(o, transaction);
  putBe16(o + 2, 0);
  putBe16(o + 4, length);
  o[6] = unit;
}
}  // namespace

std::size_t buildReadHoldingRequest(std::uint16_t transaction, std::uint8_t unit, std::uint16_t address,
                                    std::uint16_t count, Span<std::uint8_t> out) noexcept {
  if (out.size() < 12U || count < 1U || count > kMaxReadQuantity) {
    return 0;
  }
  std::uint8_t* o = out.data();
  putHeader(o, transaction, 6, unit);
  o[7] = kReadHolding;
  putBe16(o + 8, address);
  putBe16(o + 10, count);
  return 12;
}

std::size_t buildWriteMultipleRequest(std::uint16_t transaction, std::uint8_t unit, std::uint16_t address,
                                      Span<const std::uint16_t> values, Span<std::uint8_t> out) noexcept {
  const std::size_t n = values.size();
  if (n < 1U || n > kMaxWriteQuantity || out.size() < 13U + 2U * n) {
    return 0;
  }
  std::uint8_t* o = out.data();
  putHeader(o, transaction, static_cast<std::uint16_t>(7U + 2U * n), unit);
  o[7] = kWriteMultiple;
  putBe16(o + 8, address);
  putBe16(o + 10, static_cast<std::uint16_t>(n));
  o[12] = static_cast<std::uint8_t>(2U * n);
  for (std::size_t i = 0; i < n; ++i) {
    putBe16(o + 13 + 2 * i, values.data()[i]);
  }
  return 13U + 2U * n;
}

Status checkModbusResponse(Span<const std::uint8_t> adu, Span<const std::uint8_t> request, Span<std::uint16_t> values,
                           ModbusException& exception) noexcept {
  exception = ModbusException::None;
  if (adu.size() < kFunctionOffset + 2U || request.size() < 12U) {
    return Status::Malformed;
  }
  const std::uint8_t* a = adu.data();
  const std::uint8_t* q = request.data();
  const std::uint8_t function = q[kFunctionOffset];
  if (a[0] != q[0] || a[1] != q[1] || a[2] != 0U || a[3] != 0U ||
      be16(a + kLengthOffset) + kMbapHeaderSize - 1U != adu.size()) {
    return Status::Malformed;
  }
  if (a[kFunctionOffset] == static_cast<std::uint8_t>(function | 0x80U)) {
    if (adu.size() != 9U) {
      return Status::Malformed;
    }
    exception = static_cast<ModbusException>(a[8]);
    return Status::Rejected;
  }
  if (a[kFunctionOffset] != function) {
    return Status::Malformed;
  }
  if (function == kReadHolding) {
    const std::size_t count = be16(q + 10);
    if (values.size() != count || a[8] != 2U * count || adu.size() != 9U + 2U * count) {
      return Status::Malformed;
    }
    for (std::size_t i = 0; i < count; ++i) {
      values.data()[i] = be16(a + 9 + 2 * i);
    }
    return Status::Ok;
  }
  // FC 16: the reply echoes the address and the quantity.
  if (adu.size() != 12U || be16(a + 8) != be16(q + 8) || be16(a + 10) != be16(q + 10)) {
    return Status::Malformed;
  }
  return Status::Ok;
}

std::size_t buildExceptionResponse(Span<const std::uint8_t> request, ModbusException code,
                                   Span<std::uint8_t> out) noexcept {
  if (request.size() < kFunctionOffset + 1U || out.size() < 9U || (request.data()[kFunctionOffset] & 0x80U) != 0U) {
    return 0;
  }
  std::uint8_t* o = out.data();
  o[0] = request.data()[0];  // transaction id
  o[1] = request.data()[1];
  o[2] = 0;  // protocol id
  o[3] = 0;
  o[4] = 0;  // length: unit id, function, code
  o[5] = 3;
  o[6] = request.data()[6];  // unit id
  o[7] = static_cast<std::uint8_t>(request.data()[kFunctionOffset] | 0x80U);
  o[8] = static_cast<std::uint8_t>(code);
  return 9;
}

}  // namespace agv::drivers::plc
