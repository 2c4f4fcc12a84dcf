// libFuzzer target: the Modbus TCP server's request path without sockets, as ModbusPlcLink runs it
// (drivers/linux/src/modbus_plc_link.cpp): a connection's byte stream cut by MbapRequestFramer in
// reads of a fuzzed size, each complete request classified by checkModbusRequest, served writes
// checked by PlcRegisterMap::checkWrite and applied to a register table, the command block decoded.
// Invariants: the framer never offers room past its buffer nor reads past the request it
// assembles (each request consumes exactly 6 + its MBAP length bytes), a complete request is 8..260
// bytes; a served request's values lie inside it and its read range inside the table; a write the
// map accepted leaves a command block that decodes; only the command block 100..108 ever changes.
// The same bytes are then checked as PLC responses to the client's FC 03 and FC 16 requests
// (checkModbusResponse): accepted only with the exact length of the reply.
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "agv/drivers/protocol/plc/modbus_request.hpp"
#include "agv/drivers/protocol/plc/plc_register_map.hpp"
#include "fuzz_support.hpp"

using namespace agv::drivers::plc;
using agv::Span;
using agv::Status;
using agv::fuzz::check;

namespace {

std::uint16_t be16(const std::uint8_t* p) {
  return static_cast<std::uint16_t>((p[0] << 8U) | p[1]);
}

void handle(const MbapRequestFramer& framer, std::uint16_t* table, const PlcRegisterMap& map) {
  const Span<const std::uint8_t> adu = framer.adu();
  check(adu.size() >= 8U && adu.size() <= kMaxModbusAdu);
  check(!framer.oversized() || adu.size() == 8U);
  if (!framer.oversized()) {
    check(adu.size() == 6U + be16(adu.data() + 4));
  }
  const RequestCheck c = checkModbusRequest(adu, framer.oversized(), PlcRegisterMap::kRegisterCount);
  std::uint8_t reply[9];
  if (c.verdict == RequestVerdict::Exception || c.verdict == RequestVerdict::RefusedWrite) {
    check(c.exception != ModbusException::None);
    check(buildExceptionResponse(adu, c.exception, reply) == 9U);
    check(reply[7] == (adu.data()[7] | 0x80U));
    return;
  }
  if (c.verdict != RequestVerdict::Serve) {
    return;
  }
  check(!framer.oversized());
  if (!c.isWrite) {
    check(be16(adu.data() + 8) + be16(adu.data() + 10) <= PlcRegisterMap::kRegisterCount);
    return;
  }
  check(c.writeCount >= 1U && c.writeCount <= 123U);
  check(c.writeValuesOffset + 2U * c.writeCount <= adu.size());
  std::uint16_t values[123];
  for (std::size_t i = 0; i < c.writeCount; ++i) {
    values[i] = be16(adu.data() + c.writeValuesOffset + 2U * i);
  }
  const Span<const std::uint16_t> t(table, PlcRegisterMap::kRegisterCount);
  if (map.checkWrite(c.writeAddress, Span<const std::uint16_t>(values, c.writeCount), t) != Status::Ok) {
    return;
  }
  check(c.writeAddress >= PlcRegisterMap::kCommandBase &&
        c.writeAddress + c.writeCount <= PlcRegisterMap::kCommandBase + PlcRegisterMap::kCommandCount);
  std::memcpy(table + c.writeAddress, values, 2U * c.writeCount);
  check(map.decodeCommand(t).ok());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const PlcRegisterMap map;
  static std::uint16_t table[PlcRegisterMap::kRegisterCount];
  std::memset(table, 0, sizeof table);
  for (std::size_t i = 0; i < PlcRegisterMap::kCommandBase; ++i) {
    table[i] = static_cast<std::uint16_t>(0xA500U + i);  // the status block: must never change
  }
  const std::size_t chunk = size > 0 ? static_cast<std::size_t>(data[size - 1] % 61U) + 1U : 1U;
  MbapRequestFramer framer;
  std::size_t pos = 0;
  std::size_t requestStart = 0;
  while (pos < size) {
    const Span<std::uint8_t> space = framer.space();
    check(space.size() > 0U && space.size() <= kMaxModbusAdu);
    const std::size_t n = size - pos < chunk ? size - pos : chunk;
    const std::size_t k = n < space.size() ? n : space.size();
    std::memcpy(space.data(), data + pos, k);
    pos += k;
    if (framer.commit(k) != Status::Ok) {
      break;  // the link drops the connection
    }
    check(framer.receivedBytes() == pos - requestStart);
    if (framer.complete()) {
      handle(framer, table, map);
      framer.next();
      requestStart = pos;
    }
  }
  for (std::size_t i = 0; i < PlcRegisterMap::kCommandBase; ++i) {
    check(table[i] == static_cast<std::uint16_t>(0xA500U + i));
  }
  // The same bytes as the PLC's responses to the client's two requests (transaction 1 and 2).
  static std::uint8_t readRequest[12];
  static std::uint8_t writeRequest[13 + 2 * 44];
  static const std::uint16_t status[44] = {};
  check(buildReadHoldingRequest(1, 0xFF, 100, 9, readRequest) == 12U);
  check(buildWriteMultipleRequest(2, 0xFF, 0, Span<const std::uint16_t>(status, 44), writeRequest) ==
        sizeof writeRequest);
  MbapRequestFramer responses;
  pos = 0;
  while (pos < size) {
    const Span<std::uint8_t> space = responses.space();
    const std::size_t k = size - pos < space.size() ? size - pos : space.size();
    std::memcpy(space.data(), data + pos, k);
    pos += k;
    if (responses.commit(k) != Status::Ok) {
      break;
    }
    if (responses.complete()) {
      std::uint16_t block[9];
      ModbusException e = ModbusException::None;
      const Status r = checkModbusResponse(responses.adu(), readRequest, block, e);
      check(r != Status::Ok || responses.adu().size() == 9U + 18U);
      check(r == Status::Rejected || e == ModbusException::None);  // an exception code only with Rejected
      const Status w = checkModbusResponse(responses.adu(), writeRequest, {}, e);
      check(w != Status::Ok || responses.adu().size() == 12U);
      responses.next();
    }
  }
  return 0;
}
