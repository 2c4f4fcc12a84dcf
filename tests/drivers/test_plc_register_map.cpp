// PLC register map: word orders checked against the IEEE-754 byte layout, status encoding, the
// command whitelist and bounds. Portable (every tree); the agreement with libmodbus's own float
// readers is checked in test_plc_register_map_libmodbus.cpp on the host.
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "agv/core/angle.hpp"
#include "agv/drivers/protocol/plc/plc_register_map.hpp"
#include "agv_test.hpp"

using agv::Span;
using agv::Status;
using namespace agv::drivers::plc;

namespace {
/// Reference reader written from the definition: the float's bits are A B C D (A = sign and high
/// exponent byte); ABCD sends A B in the first register (A in its high byte), CDAB swaps the
/// registers, BADC swaps the bytes in each register, DCBA does both.
float referenceGet(const std::uint16_t* r, WordOrder o) {
  const auto hi = [](std::uint16_t w) { return static_cast<std::uint32_t>(w >> 8U); };
  const auto lo = [](std::uint16_t w) { return static_cast<std::uint32_t>(w & 0xFFU); };
  std::uint32_t a = 0, b = 0, c = 0, d = 0;
  switch (o) {
    case WordOrder::ABCD:
      a = hi(r[0]), b = lo(r[0]), c = hi(r[1]), d = lo(r[1]);
      break;
    case WordOrder::CDAB:
      a = hi(r[1]), b = lo(r[1]), c = hi(r[0]), d = lo(r[0]);
      break;
    case WordOrder::BADC:
      a = lo(r[0]), b = hi(r[0]), c = lo(r[1]), d = hi(r[1]);
      break;
    case WordOrder::DCBA:
      a = lo(r[1]), b = hi(r[1]), c = lo(r[0]), d = hi(r[0]);
      break;
  }
  const std::uint32_t bits = (a << 24U) | (b << 16U) | (c << 8U) | d;
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}
const WordOrder kOrders[] = {WordOrder::ABCD, WordOrder::CDAB, WordOrder::BADC, WordOrder::DCBA};

bool sameBits(float a, float b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}
}  // namespace

TEST_CASE("Float word orders: the IEEE-754 layout of 1.0f and agreement with the byte-layout reader",
          "[drivers][modbus]") {
  std::uint16_t r[2];
  // 1.0f = 0x3F800000: A=3F B=80 C=00 D=00 (from the IEEE-754 definition).
  packFloat(1.0F, WordOrder::ABCD, r);
  CHECK((r[0] == 0x3F80 && r[1] == 0x0000));
  packFloat(1.0F, WordOrder::CDAB, r);
  CHECK((r[0] == 0x0000 && r[1] == 0x3F80));
  packFloat(1.0F, WordOrder::BADC, r);
  CHECK((r[0] == 0x803F && r[1] == 0x0000));
  packFloat(1.0F, WordOrder::DCBA, r);
  CHECK((r[0] == 0x0000 && r[1] == 0x803F));

  std::mt19937 rng(7);
  std::uniform_int_distribution<std::uint32_t> bits;
  std::vector<float> values = {
      0.0F, -0.0F, 1.0F, -2.5F, 3.14159265F, 1e-40F, 3.4e38F, -1e-3F, std::numeric_limits<float>::infinity()};
  for (int i = 0; i < 2000; ++i) {
    const std::uint32_t b = bits(rng);
    float f;
    std::memcpy(&f, &b, sizeof f);
    if (!std::isnan(f))
      values.push_back(f);
  }
  for (WordOrder o : kOrders) {
    for (float v : values) {
      packFloat(v, o, r);
      REQUIRE(sameBits(referenceGet(r, o), v));
      REQUIRE(sameBits(unpackFloat(r, o), v));
    }
  }
}

TEST_CASE("Status block: every field decodes back in the configured word order", "[drivers][modbus]") {
  for (WordOrder o : kOrders) {
    PlcMapConfig cfg;
    cfg.wordOrder = o;
    PlcRegisterMap map(cfg);
    PlcStatus s;
    s.heartbeat = 4242;
    s.mode = agv::hal::NavMode::Calibrating;
    s.health = static_cast<std::uint16_t>(PlcHealthBit::LaserOk) | static_cast<std::uint16_t>(PlcHealthBit::MapLoaded);
    s.lastStatus = Status::Rejected;
    s.pose = agv::Pose2d(123.456, -78.9, -2.5);
    s.covariance = {1e-4, -2e-5, 3e-6, 4e-4, 5e-6, 6e-5};
    s.stamp = agv::Timestamp::fromNanoseconds((std::int64_t{1} << 32) * 1000000 + 123456789);  // wraps
    s.matchedLandmarks = 7;
    s.visibleReflectors = 9;
    s.reflectorsFused = 6;
    s.reflectorsRejected = 3;
    s.cornersFused = 2;
    s.cornersRejected = 11;
    s.calibration.driveScale = 2.5e-4;
    s.calibration.steerOffsetForward = 0.0123;
    s.calibration.steerOffsetBackward = -0.0045;
    s.calibration.laserMount = agv::Pose2d(0.8, -0.05, 0.02);
    s.calibration.wheelbase = 1.55;
    s.routine.state = 8;  // aborted
    s.routine.phase = 3;  // backward right
    s.routine.segment = 17;
    s.routine.total = 24;
    s.routine.lastRefusal = Status::DeviceFault;
    s.routine.driveFault = 0x2310;  // CiA 402: continuous over-current
    std::vector<std::uint16_t> table(PlcRegisterMap::kRegisterCount, 0xAAAA);
    REQUIRE(map.encodeStatus(s, Span<std::uint16_t>(table.data(), table.size())) == Status::Ok);
    CHECK(table[0] == 4242);
    CHECK(table[1] == 2);
    CHECK(table[2] == 5);
    CHECK(table[3] == static_cast<std::uint16_t>(Status::Rejected));
    auto f = [&](int a) { return static_cast<double>(referenceGet(&table[static_cast<std::size_t>(a)], o)); };
    AGV_CHECK_NEAR(f(4), 123.456, 1e-5);
    AGV_CHECK_NEAR(f(6), -78.9, 1e-5);
    AGV_CHECK_NEAR(f(8), -2.5, 1e-7);
    const double cov[6] = {1e-4, -2e-5, 3e-6, 4e-4, 5e-6, 6e-5};
    for (int i = 0; i < 6; ++i)
      AGV_CHECK_NEAR(f(10 + 2 * i), cov[i], std::fabs(cov[i]) * 1e-6);
    CHECK(unpackU32(&table[22], o) == 123U);  // 2^32 ms + 123 ms, modulo 2^32
    CHECK(table[24] == 7);
    CHECK(table[25] == 9);
    AGV_CHECK_NEAR(f(26), 2.5e-4, 1e-10);
    AGV_CHECK_NEAR(f(28), 0.0123, 1e-8);
    AGV_CHECK_NEAR(f(30), -0.0045, 1e-8);
    AGV_CHECK_NEAR(f(32), 0.8, 1e-7);
    AGV_CHECK_NEAR(f(34), -0.05, 1e-8);
    AGV_CHECK_NEAR(f(36), 0.02, 1e-8);
    AGV_CHECK_NEAR(f(38), 1.55, 1e-7);
    CHECK(table[40] == 6);
    CHECK(table[41] == 3);
    CHECK(table[42] == 2);
    CHECK(table[43] == 11);
    CHECK(table[44] == 8);
    CHECK(table[45] == 3);
    CHECK(table[46] == 17);
    CHECK(table[47] == 24);
    CHECK(table[48] == static_cast<std::uint16_t>(Status::DeviceFault));
    CHECK(table[49] == 0x2310);
    CHECK(table[50] == 0xAAAA);  // nothing written past the block
  }
  PlcRegisterMap map;
  std::vector<std::uint16_t> shortTable(10);
  CHECK(map.encodeStatus(PlcStatus{}, Span<std::uint16_t>(shortTable.data(), shortTable.size())) ==
        Status::InvalidArgument);
}

TEST_CASE("Command writes: whitelist, whole 32-bit fields, bounds", "[drivers][modbus]") {
  PlcMapConfig cfg;
  cfg.wordOrder = WordOrder::CDAB;
  cfg.maxAbsPosition = 500.0;
  PlcRegisterMap map(cfg);
  std::vector<std::uint16_t> table(PlcRegisterMap::kRegisterCount, 0);
  const Span<const std::uint16_t> t(table.data(), table.size());
  auto write = [&](std::uint16_t addr, std::vector<std::uint16_t> v) {
    return map.checkWrite(addr, Span<const std::uint16_t>(v.data(), v.size()), t);
  };
  std::uint16_t x[2], y[2], th[2];
  packFloat(12.5F, WordOrder::CDAB, x);
  packFloat(-3.25F, WordOrder::CDAB, y);
  packFloat(1.5F, WordOrder::CDAB, th);

  CHECK(write(100, {1, 7, x[0], x[1], y[0], y[1], th[0], th[1], 99}) == Status::Ok);
  CHECK(write(100, {3}) == Status::Ok);
  CHECK(write(108, {65535}) == Status::Ok);
  // Read-only and non-existent registers.
  for (std::uint16_t a : {0, 1, 4, 39, 40, 43, 44, 99, 109, 200}) {
    CHECK(write(a, {1}) == Status::OutOfRange);
  }
  CHECK(write(99, {0, 1}) == Status::OutOfRange);      // straddles the block start
  CHECK(write(107, {0, 0, 0}) == Status::OutOfRange);  // runs past the block end
  // Half of a float.
  CHECK(write(102, {x[0]}) == Status::Malformed);
  CHECK(write(103, {x[1], y[0], y[1]}) == Status::Malformed);
  // Values out of bounds.
  CHECK(write(100, {4}) == Status::InvalidArgument);
  std::uint16_t bad[2];
  packFloat(501.0F, WordOrder::CDAB, bad);
  CHECK(write(102, {bad[0], bad[1]}) == Status::InvalidArgument);
  packFloat(std::numeric_limits<float>::quiet_NaN(), WordOrder::CDAB, bad);
  CHECK(write(104, {bad[0], bad[1]}) == Status::InvalidArgument);
  packFloat(3.3F, WordOrder::CDAB, bad);
  CHECK(write(106, {bad[0], bad[1]}) == Status::InvalidArgument);

  // Decoding the accepted block gives SI values.
  const std::uint16_t block[9] = {1, 7, x[0], x[1], y[0], y[1], th[0], th[1], 99};
  const auto c = map.decodeCommandBlock(block);
  REQUIRE(c.ok());
  CHECK(c.value().code == PlcCommandCode::Localize);
  CHECK(c.value().sequence == 7);
  AGV_CHECK_NEAR(c.value().pose.x, 12.5, 1e-9);
  AGV_CHECK_NEAR(c.value().pose.y, -3.25, 1e-9);
  AGV_CHECK_NEAR(c.value().pose.theta, 1.5, 1e-7);
  CHECK(c.value().plcHeartbeat == 99);
}

TEST_CASE("Register map encoding and checks do not allocate", "[drivers][modbus]") {
  PlcRegisterMap map;
  static std::uint16_t table[PlcRegisterMap::kRegisterCount] = {};
  PlcStatus s;
  s.pose = agv::Pose2d(1.0, 2.0, 0.5);
  const std::uint16_t write[2] = {1, 2};
  Status a = Status::NotInitialized;
  Status b = Status::NotInitialized;
  bool decoded = false;
  AGV_CHECK_NO_ALLOCATIONS({
    a = map.encodeStatus(s, Span<std::uint16_t>(table));
    b = map.checkWrite(100, Span<const std::uint16_t>(write, 2),
                       Span<const std::uint16_t>(table, PlcRegisterMap::kRegisterCount));
    decoded = map.decodeCommand(Span<const std::uint16_t>(table, PlcRegisterMap::kRegisterCount)).ok();
  });
  CHECK(a == Status::Ok);
  CHECK(b == Status::Ok);
  CHECK(decoded);
}
