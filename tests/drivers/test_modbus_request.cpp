// The portable Modbus TCP request path (agv/drivers/protocol/plc/modbus_request.hpp) on requests
// written out byte by byte: the framer never reads past the request it assembles (pipelined
// requests stay in the stream), keeps a partial request across calls, reads an oversized request
// to its end and keeps its header, refuses an MBAP length that frames nothing; the checker serves
// the map's functions, refuses malformed shapes with 03, reads past the table with 02, unserved
// functions with 01, and discards non-Modbus frames and exception-flagged codes (0x83).
// Heap-free: also in the Cortex-M7 image (MCU).
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "agv/drivers/protocol/plc/modbus_request.hpp"
#include "agv_test.hpp"

using agv::Span;
using agv::Status;
using namespace agv::drivers::plc;

namespace {

constexpr std::uint16_t kTable = 110;

/// Feeds `bytes` through `f` in pieces of at most `chunk` bytes (as recv() would give them), stopping
/// at a complete request. Returns the bytes consumed; `status` the last commit's.
std::size_t feed(MbapRequestFramer& f, const std::uint8_t* bytes, std::size_t n, std::size_t chunk, Status& status) {
  std::size_t used = 0;
  status = Status::Ok;
  while (used < n && !f.complete()) {
    const Span<std::uint8_t> s = f.space();
    std::size_t k = s.size() < chunk ? s.size() : chunk;
    k = k < n - used ? k : n - used;
    std::memcpy(s.data(), bytes + used, k);
    status = f.commit(k);
    used += k;
    if (status != Status::Ok) {
      break;
    }
  }
  return used;
}

template <std::size_t N>
RequestCheck check(const std::uint8_t (&adu)[N]) {
  return checkModbusRequest(Span<const std::uint8_t>(adu, N), false, kTable);
}

}  // namespace

TEST_CASE("MBAP framer: pipelined requests one at a time, partial requests kept across calls", "[drivers][modbus]") {
  // Two FC 03 requests back to back (12 bytes each).
  const std::uint8_t two[24] = {0x00, 0x01, 0x00, 0x00, 0x00, 0x06, 0xFF, 0x03, 0x00, 0x00, 0x00, 0x04,
                                0x00, 0x02, 0x00, 0x00, 0x00, 0x06, 0xFF, 0x03, 0x00, 0x04, 0x00, 0x02};
  for (std::size_t chunk = 1; chunk <= 24; ++chunk) {
    MbapRequestFramer f;
    CHECK_FALSE(f.started());
    Status st = Status::Ok;
    const std::size_t first = feed(f, two, sizeof two, chunk, st);
    REQUIRE(st == Status::Ok);
    REQUIRE(f.complete());
    CHECK(first == 12U);  // never past the first request, whatever the piece size
    CHECK(f.adu().size() == 12U);
    CHECK(f.adu().data()[1] == 0x01);
    CHECK(f.space().size() == 0U);
    f.next();
    const std::size_t second = feed(f, two + first, sizeof two - first, chunk, st);
    REQUIRE(f.complete());
    CHECK(second == 12U);
    CHECK(f.adu().data()[1] == 0x02);
  }
  // A partial request: the header and two bytes, then the rest later.
  MbapRequestFramer f;
  Status st = Status::Ok;
  CHECK(feed(f, two, 9, 64, st) == 9U);
  CHECK(f.started());
  CHECK_FALSE(f.complete());
  CHECK(f.receivedBytes() == 9U);
  CHECK(f.adu().size() == 0U);
  CHECK(f.space().size() == 3U);
  CHECK(feed(f, two + 9, 3, 64, st) == 3U);
  CHECK(f.complete());
  // More than offered is refused.
  MbapRequestFramer g;
  CHECK(g.commit(8) == Status::InvalidArgument);
}

TEST_CASE("MBAP framer: an MBAP length below 2 frames nothing; an oversized request is read to its end",
          "[drivers][modbus]") {
  const std::uint8_t zero[7] = {0x00, 0x01, 0x00, 0x00, 0x00, 0x01, 0xFF};
  MbapRequestFramer f;
  Status st = Status::Ok;
  feed(f, zero, sizeof zero, 7, st);
  CHECK(st == Status::Malformed);

  // FC 16 announcing 124 registers (248 bytes): 6 + 1 + 6 + 248 = 261 bytes > 260, then an FC 03.
  static std::uint8_t big[261 + 12];
  std::memset(big, 0xAB, sizeof big);
  const std::uint8_t head[13] = {0x00, 0x07, 0x00, 0x00, 0x00, 255, 0x01, 0x10, 0x00, 100, 0x00, 124, 248};
  std::memcpy(big, head, sizeof head);
  const std::uint8_t read[12] = {0x00, 0x08, 0x00, 0x00, 0x00, 0x06, 0x01, 0x03, 0x00, 0x00, 0x00, 0x01};
  std::memcpy(big + 261, read, sizeof read);
  for (std::size_t chunk : {std::size_t{1}, std::size_t{7}, std::size_t{100}, std::size_t{300}}) {
    MbapRequestFramer g;
    const std::size_t used = feed(g, big, sizeof big, chunk, st);
    REQUIRE(st == Status::Ok);
    REQUIRE(g.complete());
    CHECK(used == 261U);
    CHECK(g.oversized());
    CHECK(g.receivedBytes() == 261U);
    REQUIRE(g.adu().size() == 8U);
    CHECK(g.adu().data()[7] == 0x10);
    const RequestCheck c = checkModbusRequest(g.adu(), g.oversized(), kTable);
    CHECK(c.verdict == RequestVerdict::Exception);
    CHECK(c.exception == ModbusException::IllegalDataValue);
    g.next();
    feed(g, big + used, sizeof big - used, chunk, st);  // in step: the next request is whole
    REQUIRE(g.complete());
    CHECK_FALSE(g.oversized());
    CHECK(checkModbusRequest(g.adu(), false, kTable).verdict == RequestVerdict::Serve);
  }
}

TEST_CASE("Modbus request check: served, refused with the right exception, or discarded", "[drivers][modbus]") {
  // Served.
  const std::uint8_t read40[12] = {0, 1, 0, 0, 0, 6, 0xFF, 0x03, 0, 0, 0, 40};
  RequestCheck c = check(read40);
  CHECK(c.verdict == RequestVerdict::Serve);
  CHECK_FALSE(c.isWrite);
  const std::uint8_t write108[12] = {0, 1, 0, 0, 0, 6, 0xFF, 0x06, 0, 108, 0x12, 0x34};
  c = check(write108);
  CHECK(c.verdict == RequestVerdict::Serve);
  CHECK(c.isWrite);
  CHECK(c.writeAddress == 108U);
  CHECK(c.writeCount == 1U);
  CHECK(c.writeValuesOffset == 10U);
  const std::uint8_t write2[17] = {0, 1, 0, 0, 0, 11, 0xFF, 0x10, 0, 100, 0, 2, 4, 0, 1, 0, 9};
  c = check(write2);
  CHECK(c.verdict == RequestVerdict::Serve);
  CHECK(c.writeAddress == 100U);
  CHECK(c.writeCount == 2U);
  CHECK(c.writeValuesOffset == 13U);
  const std::uint8_t rw[19] = {0, 1, 0, 0, 0, 13, 0xFF, 0x17, 0, 0, 0, 4, 0, 108, 0, 1, 2, 0, 5};
  c = check(rw);
  CHECK(c.verdict == RequestVerdict::Serve);
  CHECK(c.writeAddress == 108U);
  CHECK(c.writeCount == 1U);
  CHECK(c.writeValuesOffset == 17U);

  // Exception 02: reads past the table (FC 03 and the read part of FC 23, which libmodbus would
  // refuse after the write part passed our checks).
  const std::uint8_t readPast[12] = {0, 1, 0, 0, 0, 6, 0xFF, 0x03, 0, 108, 0, 4};
  CHECK(check(readPast).exception == ModbusException::IllegalDataAddress);
  const std::uint8_t rwPast[19] = {0, 1, 0, 0, 0, 13, 0xFF, 0x17, 0, 200, 0, 4, 0, 108, 0, 1, 2, 0, 5};
  c = check(rwPast);
  CHECK(c.verdict == RequestVerdict::Exception);
  CHECK(c.exception == ModbusException::IllegalDataAddress);
  CHECK(c.isWrite);

  // Exception 03: quantities out of the Modbus limits, byte counts and lengths that disagree.
  const std::uint8_t read0[12] = {0, 1, 0, 0, 0, 6, 0xFF, 0x03, 0, 0, 0, 0};
  CHECK(check(read0).exception == ModbusException::IllegalDataValue);
  const std::uint8_t read126[12] = {0, 1, 0, 0, 0, 6, 0xFF, 0x03, 0, 0, 0, 126};
  CHECK(check(read126).exception == ModbusException::IllegalDataValue);
  const std::uint8_t readLong[13] = {0, 1, 0, 0, 0, 7, 0xFF, 0x03, 0, 0, 0, 4, 0};
  CHECK(check(readLong).exception == ModbusException::IllegalDataValue);
  const std::uint8_t countMismatch[17] = {0, 1, 0, 0, 0, 11, 0xFF, 0x10, 0, 100, 0, 3, 4, 0, 1, 0, 9};
  CHECK(check(countMismatch).exception == ModbusException::IllegalDataValue);
  const std::uint8_t bytesMismatch[17] = {0, 1, 0, 0, 0, 11, 0xFF, 0x10, 0, 100, 0, 2, 6, 0, 1, 0, 9};
  CHECK(check(bytesMismatch).exception == ModbusException::IllegalDataValue);
  const std::uint8_t shortWrite[10] = {0, 1, 0, 0, 0, 4, 0xFF, 0x06, 0, 108};
  c = check(shortWrite);
  CHECK(c.exception == ModbusException::IllegalDataValue);
  CHECK(c.isWrite);

  // Exception 01: functions the map does not serve, 00 and 07 included; report server id (17).
  for (std::uint8_t fc : {std::uint8_t{0x00}, std::uint8_t{0x01}, std::uint8_t{0x04}, std::uint8_t{0x07},
                          std::uint8_t{0x08}, std::uint8_t{0x11}, std::uint8_t{0x2B}, std::uint8_t{0x7F}}) {
    const std::uint8_t req[8] = {0, 1, 0, 0, 0, 2, 0xFF, fc};
    c = check(req);
    CHECK(c.verdict == RequestVerdict::Exception);
    CHECK(c.exception == ModbusException::IllegalFunction);
  }
  // Coil and mask writes: refused writes (exception 01, health bit 8 in the link).
  const std::uint8_t coil[12] = {0, 1, 0, 0, 0, 6, 0xFF, 0x05, 0, 0, 0xFF, 0};
  c = check(coil);
  CHECK(c.verdict == RequestVerdict::RefusedWrite);
  CHECK(c.exception == ModbusException::IllegalFunction);

  // Discarded: protocol id not 0; an exception-flagged code (0x83 would be answered as 0x03).
  const std::uint8_t notModbus[12] = {0, 1, 0xFF, 0xFF, 0, 6, 0xFF, 0x06, 0, 108, 0x12, 0x34};
  CHECK(check(notModbus).verdict == RequestVerdict::Discard);
  const std::uint8_t x83[9] = {0, 1, 0, 0, 0, 3, 0xFF, 0x83, 0x02};
  CHECK(check(x83).verdict == RequestVerdict::Discard);
}

TEST_CASE("Modbus exception response: transaction and unit id echoed, function | 0x80", "[drivers][modbus]") {
  const std::uint8_t req[8] = {0x12, 0x34, 0, 0, 0, 2, 0x07, 0x11};
  std::uint8_t out[9] = {};
  REQUIRE(buildExceptionResponse(Span<const std::uint8_t>(req, 8), ModbusException::IllegalFunction, out) == 9U);
  const std::uint8_t want[9] = {0x12, 0x34, 0, 0, 0, 3, 0x07, 0x91, 0x01};
  CHECK(std::memcmp(out, want, 9) == 0);
  const std::uint8_t x83[8] = {0, 1, 0, 0, 0, 2, 0x01, 0x83};
  CHECK(buildExceptionResponse(Span<const std::uint8_t>(x83, 8), ModbusException::IllegalFunction, out) == 0U);
  CHECK(buildExceptionResponse(Span<const std::uint8_t>(req, 7), ModbusException::IllegalFunction, out) == 0U);
}

TEST_CASE("Modbus client frames: requests built byte by byte, responses checked against them", "[drivers][modbus]") {
  std::uint8_t req[40] = {};
  REQUIRE(buildReadHoldingRequest(0x1234, 0xFF, 100, 9, req) == 12U);
  const std::uint8_t wantRead[12] = {0x12, 0x34, 0, 0, 0, 6, 0xFF, 0x03, 0, 100, 0, 9};
  CHECK(std::memcmp(req, wantRead, 12) == 0);
  CHECK(buildReadHoldingRequest(1, 1, 0, 0, req) == 0U);
  CHECK(buildReadHoldingRequest(1, 1, 0, 126, req) == 0U);
  std::uint8_t small[11];
  CHECK(buildReadHoldingRequest(1, 1, 0, 1, small) == 0U);

  // FC 03 response with two registers.
  std::uint16_t two[2] = {};
  ModbusException e = ModbusException::None;
  std::uint8_t read2[12];
  REQUIRE(buildReadHoldingRequest(7, 1, 100, 2, read2) == 12U);
  const std::uint8_t rsp[13] = {0, 7, 0, 0, 0, 7, 1, 0x03, 4, 0x12, 0x34, 0xAB, 0xCD};
  CHECK(checkModbusResponse(Span<const std::uint8_t>(rsp, 13), Span<const std::uint8_t>(read2, 12), two, e) ==
        Status::Ok);
  CHECK(two[0] == 0x1234U);
  CHECK(two[1] == 0xABCDU);
  std::uint8_t bad[13];
  std::memcpy(bad, rsp, 13);
  bad[1] = 8;  // another transaction
  CHECK(checkModbusResponse(Span<const std::uint8_t>(bad, 13), Span<const std::uint8_t>(read2, 12), two, e) ==
        Status::Malformed);
  std::memcpy(bad, rsp, 13);
  bad[8] = 2;  // byte count
  CHECK(checkModbusResponse(Span<const std::uint8_t>(bad, 13), Span<const std::uint8_t>(read2, 12), two, e) ==
        Status::Malformed);
  const std::uint8_t exc[9] = {0, 7, 0, 0, 0, 3, 1, 0x83, 0x02};
  CHECK(checkModbusResponse(Span<const std::uint8_t>(exc, 9), Span<const std::uint8_t>(read2, 12), two, e) ==
        Status::Rejected);
  CHECK(e == ModbusException::IllegalDataAddress);

  // FC 16 of three values and its echo.
  const std::uint16_t values[3] = {1, 0x0203, 0xFFFF};
  const std::size_t n = buildWriteMultipleRequest(9, 0xFF, 0, Span<const std::uint16_t>(values, 3), req);
  REQUIRE(n == 19U);
  const std::uint8_t wantWrite[19] = {0, 9, 0, 0, 0, 13, 0xFF, 0x10, 0, 0, 0, 3, 6, 0, 1, 2, 3, 0xFF, 0xFF};
  CHECK(std::memcmp(req, wantWrite, 19) == 0);
  const std::uint8_t echo[12] = {0, 9, 0, 0, 0, 6, 0xFF, 0x10, 0, 0, 0, 3};
  CHECK(checkModbusResponse(Span<const std::uint8_t>(echo, 12), Span<const std::uint8_t>(req, n), {}, e) == Status::Ok);
  const std::uint8_t wrongEcho[12] = {0, 9, 0, 0, 0, 6, 0xFF, 0x10, 0, 0, 0, 2};
  CHECK(checkModbusResponse(Span<const std::uint8_t>(wrongEcho, 12), Span<const std::uint8_t>(req, n), {}, e) ==
        Status::Malformed);
  CHECK(buildWriteMultipleRequest(1, 1, 0, Span<const std::uint16_t>(values, 0), req) == 0U);
}
