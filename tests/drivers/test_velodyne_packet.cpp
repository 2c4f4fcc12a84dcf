// Velodyne packet decoding on packets built here byte by byte from the documented layout
// (drivers/protocol velodyne_packet.hpp): HDL-64E upper/lower blocks, HDL-32E, the VLP-16's
// interpolated azimuths and timing, dual return, the revolution assembler at the wrap, refused
// input counted (truncated, oversized, garbage, wrong block ids, azimuths >= 36000, other product),
// records to range-image returns, and no allocation per packet. Portable (every tree).
#include <array>
#include <cstdint>
#include <cstring>

#include "agv/drivers/protocol/velodyne/velodyne_packet.hpp"
#include "agv_test.hpp"

using agv::Span;
using agv::Status;
using namespace agv::drivers::velodyne;

namespace {
using Packet = std::array<std::uint8_t, kPacketBytes>;

void put16(std::uint8_t* p, unsigned v) {
  p[0] = static_cast<std::uint8_t>(v & 0xFFU);
  p[1] = static_cast<std::uint8_t>(v >> 8U);
}

/// A packet whose blocks start at `az0` and step by `step` (0.01 deg, wrapped), every channel's
/// distance = 1000 + 10 * block + channel, intensity = channel; dual: pairs share an azimuth.
Packet makePacket(unsigned az0, unsigned step, std::uint8_t mode, std::uint8_t product, bool hdl64 = false,
                  bool dual = false) {
  Packet p{};
  for (unsigned b = 0; b < 12; ++b) {
    std::uint8_t* blk = p.data() + b * 100;
    put16(blk, hdl64 && (b % 2U) == 1U ? 0xDDFFU : 0xEEFFU);
    const unsigned firing = hdl64 || dual ? b / 2U : b;
    put16(blk + 2, (az0 + firing * step) % 36000U);
    for (unsigned c = 0; c < 32; ++c) {
      put16(blk + 4 + c * 3, 1000U + 10U * b + c);
      blk[4 + c * 3 + 2] = static_cast<std::uint8_t>(c);
    }
  }
  put16(p.data() + 1200, 0x5678);
  put16(p.data() + 1202, 0x1234);
  p[1204] = mode;
  p[1205] = product;
  return p;
}

Span<const std::uint8_t> bytes(const Packet& p) {
  return Span<const std::uint8_t>(p.data(), p.size());
}
}  // namespace

TEST_CASE("HDL-64E: upper blocks lasers 0-31, lower blocks 32-63, block azimuth", "[drivers][velodyne]") {
  VelodyneConfig cfg;
  cfg.model = Model::Hdl64e;
  VelodyneDecoder dec(cfg);
  const Packet p = makePacket(1000, 17, 0, 0, true);
  FiringRecord out[kMaxRecordsPerPacket];
  std::size_t n = 0;
  PacketInfo info;
  REQUIRE(dec.decode(bytes(p), Span<FiringRecord>(out), n, &info) == Status::Ok);
  CHECK(n == 384U);
  CHECK(info.timestampUs == 0x12345678U);
  CHECK(info.returnMode == ReturnMode::Strongest);
  CHECK(out[0].laser == 0U);
  CHECK(out[31].laser == 31U);
  CHECK(out[32].laser == 32U);  // block 1 = lower block
  CHECK(out[63].laser == 63U);
  CHECK(out[32].azimuth == 1000U);
  CHECK(out[64].azimuth == 1017U);
  CHECK(out[64].laser == 0U);
  CHECK(out[40].distance == 1000U + 10U + 8U);
  CHECK(out[40].intensity == 8U);
  CHECK(laserCount(Model::Hdl64e) == 64U);
}

TEST_CASE("HDL-32E: 32 lasers per block, timing 46.08 us per block, 1.152 us per laser", "[drivers][velodyne]") {
  VelodyneConfig cfg;
  cfg.model = Model::Hdl32e;
  VelodyneDecoder dec(cfg);
  const Packet p = makePacket(35990, 16, 0x37, 0x21);
  FiringRecord out[kMaxRecordsPerPacket];
  std::size_t n = 0;
  REQUIRE(dec.decode(bytes(p), Span<FiringRecord>(out), n) == Status::Ok);
  REQUIRE(n == 384U);
  CHECK(out[0].azimuth == 35990U);
  CHECK(out[32].azimuth == 6U);  // wrapped
  CHECK(out[32 * 3 + 5].timeNs == 3U * 46080U + 5U * 1152U);
  CHECK(out[32 * 3 + 5].laser == 5U);
  // A VLP-16 packet on an HDL-32E decoder is another product: refused whole and counted.
  const Packet v = makePacket(0, 40, 0x37, 0x22);
  CHECK(dec.decode(bytes(v), Span<FiringRecord>(out), n) == Status::Unsupported);
  CHECK(n == 0U);
  CHECK(dec.counters().wrongProduct == 1U);
}

TEST_CASE("VLP-16: interpolated azimuth per laser and per firing sequence, timing", "[drivers][velodyne]") {
  VelodyneDecoder dec(VelodyneConfig{});
  const Packet p = makePacket(35900, 40, 0x37, 0x22);
  FiringRecord out[kMaxRecordsPerPacket];
  std::size_t n = 0;
  REQUIRE(dec.decode(bytes(p), Span<FiringRecord>(out), n) == Status::Ok);
  REQUIRE(n == 384U);
  // Block 0, sequence 0, laser 0: the block azimuth. Sequence 1 (channel 16), laser 0: half a step
  // later (55.296 / 110.592). Laser 15 of sequence 1: 40 * (15 * 2.304 + 55.296) / 110.592 = 32.5
  // -> rounds to 33 (lround, as velodyne_pointcloud's round()).
  CHECK(out[0].azimuth == 35900U);
  CHECK(out[0].laser == 0U);
  CHECK(out[16].azimuth == 35920U);
  CHECK(out[16].laser == 0U);
  CHECK(out[31].azimuth == 35933U);
  CHECK(out[31].timeNs == 15U * 2304U + 55296U);
  // Block 2 (azimuth 35980), sequence 1 laser 0: 36000 -> wraps to 0.
  CHECK(out[64 + 16].azimuth == 0U);
  // Last block (11): no next block in the packet, the previous step (40) is carried on.
  CHECK(out[11 * 32].azimuth == (35900U + 11U * 40U) % 36000U);
  CHECK(out[11 * 32 + 16].azimuth == (35900U + 11U * 40U + 20U) % 36000U);
  CHECK(out[11 * 32 + 16].timeNs == 11U * 110592U + 55296U);
}

TEST_CASE("Dual return: pairs share azimuth and timing, the odd block is the second return", "[drivers][velodyne]") {
  VelodyneDecoder dec(VelodyneConfig{});
  const Packet p = makePacket(100, 40, 0x39, 0x22, false, true);
  FiringRecord out[kMaxRecordsPerPacket];
  std::size_t n = 0;
  PacketInfo info;
  REQUIRE(dec.decode(bytes(p), Span<FiringRecord>(out), n, &info) == Status::Ok);
  CHECK(info.returnMode == ReturnMode::Dual);
  REQUIRE(n == 384U);
  CHECK(out[0].secondReturn == 0U);
  CHECK(out[32].secondReturn == 1U);
  CHECK(out[32 + 16].azimuth == out[16].azimuth);
  CHECK(out[16].azimuth == 120U);  // step between pairs (40), half of it for sequence 1
  CHECK(out[32 + 16].timeNs == out[16].timeNs);
  CHECK(out[64].timeNs == 110592U);  // block 2 = the head's second firing
  // Last mode and strongest mode are single-return packets.
  const Packet last = makePacket(100, 40, 0x38, 0x22);
  REQUIRE(dec.decode(bytes(last), Span<FiringRecord>(out), n, &info) == Status::Ok);
  CHECK(info.returnMode == ReturnMode::Last);
  CHECK(out[32].secondReturn == 0U);
}

TEST_CASE("Bad packets are counted and skipped, never decoded as data", "[drivers][velodyne]") {
  VelodyneDecoder dec(VelodyneConfig{});
  FiringRecord out[kMaxRecordsPerPacket];
  std::size_t n = 99;
  Packet p = makePacket(0, 40, 0x37, 0x22);
  // Truncated and oversized.
  CHECK(dec.decode(Span<const std::uint8_t>(p.data(), 1205), Span<FiringRecord>(out), n) == Status::Truncated);
  CHECK(n == 0U);
  CHECK(dec.decode(Span<const std::uint8_t>(), Span<FiringRecord>(out), n) == Status::Truncated);
  std::array<std::uint8_t, 1300> big{};
  std::memcpy(big.data(), p.data(), p.size());
  CHECK(dec.decode(Span<const std::uint8_t>(big.data(), big.size()), Span<FiringRecord>(out), n) == Status::Malformed);
  CHECK(n == 0U);
  // Garbage: every byte 0xA5 -> no valid block id, return mode byte invalid -> refused whole.
  Packet g;
  g.fill(0xA5);
  CHECK(dec.decode(bytes(g), Span<FiringRecord>(out), n) == Status::Unsupported);
  CHECK(n == 0U);
  // Garbage with valid factory bytes: every block refused by its id.
  g[1204] = 0x37;
  g[1205] = 0x22;
  CHECK(dec.decode(bytes(g), Span<FiringRecord>(out), n) == Status::Malformed);
  CHECK(n == 0U);
  // One wrong block id (an HDL-64E lower block on a VLP-16) and one impossible azimuth.
  put16(p.data() + 3 * 100, 0xDDFFU);
  put16(p.data() + 5 * 100 + 2, 36000U);
  CHECK(dec.decode(bytes(p), Span<FiringRecord>(out), n) == Status::Malformed);
  CHECK(n == 10U * 32U);
  for (std::size_t i = 0; i < n; ++i)
    CHECK((out[i].block != 3U && out[i].block != 5U));
  const VelodyneCounters& c = dec.counters();
  CHECK(c.truncated == 2U);
  CHECK(c.oversized == 1U);
  CHECK(c.wrongProduct == 1U);
  CHECK(c.badBlockId == 12U + 1U);
  CHECK(c.badAzimuth == 1U);
  CHECK(c.packets == 2U);
  // No-return records are skipped and counted; an output span too small is named and counted.
  Packet z = makePacket(0, 40, 0x37, 0x22);
  put16(z.data() + 4, 0U);
  FiringRecord small[10];
  CHECK(dec.decode(bytes(z), Span<FiringRecord>(small), n) == Status::CapacityExceeded);
  CHECK(n == 10U);
  CHECK(dec.counters().noReturn == 1U);
  CHECK(dec.counters().outputFull == 383U - 10U);
}

TEST_CASE("Output room ending mid-packet: the records that fit, in order, the rest counted", "[drivers][velodyne]") {
  // The decoder stores a block branch-free while the output has room for all 32 of its records
  // and record by record after that; toFiringReturns stops at a full output. Both against the
  // same packet decoded into a full output (HDL-64E, no-return records in blocks 0, 2 and 3).
  VelodyneConfig cfg;
  cfg.model = Model::Hdl64e;
  Packet p = makePacket(12000, 17, 0x37, 0, true);
  put16(p.data() + 0 * 100 + 4 + 5 * 3, 0U);
  put16(p.data() + 2 * 100 + 4 + 31 * 3, 0U);
  put16(p.data() + 3 * 100 + 4 + 0 * 3, 0U);
  put16(p.data() + 3 * 100 + 4 + 9 * 3, 0U);
  VelodyneDecoder whole(cfg);
  static FiringRecord all[kMaxRecordsPerPacket];
  std::size_t n = 0;
  REQUIRE(whole.decode(bytes(p), Span<FiringRecord>(all), n) == Status::Ok);
  REQUIRE(n == kMaxRecordsPerPacket - 4U);
  CHECK(whole.counters().noReturn == 4U);
  VelodyneDecoder part(cfg);
  static FiringRecord some[100];  // three blocks (94 records kept) fit whole, then 6 of block 3
  std::size_t m = 0;
  CHECK(part.decode(bytes(p), Span<FiringRecord>(some), m) == Status::CapacityExceeded);
  REQUIRE(m == 100U);
  for (std::size_t i = 0; i < m; ++i) {
    CHECK(std::memcmp(&some[i], &all[i], sizeof(FiringRecord)) == 0);
  }
  CHECK(part.counters().noReturn == 4U);
  CHECK(part.counters().outputFull == static_cast<std::uint32_t>(n - 100U));
  // Keeping the no-return records: every one stored where it lies.
  cfg.keepNoReturn = true;
  VelodyneDecoder keep(cfg);
  CHECK(keep.decode(bytes(p), Span<FiringRecord>(all), n) == Status::Ok);
  CHECK(n == kMaxRecordsPerPacket);
  CHECK(all[5].distance == 0U);
  CHECK(all[6].distance == 1006U);
  CHECK(keep.counters().noReturn == 4U);
  // Points: a full output ends the conversion with the returns that fit written.
  static agv::LaserIntrinsics cal;
  REQUIRE(cal.reset(64) == Status::Ok);
  for (std::size_t i = 0; i < 64; ++i)
    REQUIRE(cal.set(i, agv::LaserParams{0.01, 0.02, -0.03, (static_cast<double>(i) - 31.5) * 0.01,
                                        0.001 * static_cast<double>(i)}) == Status::Ok);
  static agv::FiringReturn full[kMaxRecordsPerPacket];
  static agv::FiringReturn few[50];
  REQUIRE(whole.decode(bytes(p), Span<FiringRecord>(all), n) == Status::Ok);
  std::size_t k = 0;
  REQUIRE(toFiringReturns(Span<const FiringRecord>(all, n), cal, 2000, Span<agv::FiringReturn>(full), k) == Status::Ok);
  REQUIRE(k == n);
  CHECK(toFiringReturns(Span<const FiringRecord>(all, n), cal, 2000, Span<agv::FiringReturn>(few), k) ==
        Status::CapacityExceeded);
  REQUIRE(k == 50U);
  for (std::size_t i = 0; i < k; ++i) {
    CHECK(few[i].point == full[i].point);
    CHECK(few[i].laser == full[i].laser);
    CHECK(few[i].firing == full[i].firing);
  }
}

TEST_CASE("Revolution assembler cuts at the azimuth wrap", "[drivers][velodyne]") {
  VelodyneDecoder dec(VelodyneConfig{});
  static FiringRecord storage[3000];
  RevolutionAssembler rev(Span<FiringRecord>(storage, 3000));
  FiringRecord out[kMaxRecordsPerPacket];
  std::size_t n = 0;
  // 12 blocks x 2000 = 24 000 per packet: a turn is 1.5 packets. Start at 30 000.
  unsigned az = 30000;
  int completed = 0;
  std::size_t sizes[4] = {};
  bool complete[4] = {};
  for (int k = 0; k < 6; ++k) {
    const Packet p = makePacket(az, 2000, 0x37, 0x22);
    REQUIRE(dec.decode(bytes(p), Span<FiringRecord>(out), n) == Status::Ok);
    if (rev.add(Span<const FiringRecord>(out, n))) {
      sizes[completed] = rev.revolution().size();
      complete[completed] = rev.info().complete;
      // Every record of a revolution lies before the wrap: azimuths never fall by half a turn.
      const auto r = rev.revolution();
      for (std::size_t i = 1; i < r.size(); ++i)
        CHECK(r[i].azimuth + 18000 >= r[i - 1].azimuth);
      ++completed;
    }
    az = (az + 12U * 2000U) % 36000U;
  }
  // 6 packets = 144 000 / 36 000 = 4 turns from 30 000: wraps at packets 0, 2, 3 (36 000 x k).
  CHECK(completed == 4);
  CHECK(rev.revolutions() == 4U);
  CHECK_FALSE(complete[0]);  // began mid-turn
  CHECK(complete[1]);
  // A full turn = 18 blocks x 32 records (interpolated records near the cut move by one step).
  CHECK(sizes[1] == 18U * 32U);
  CHECK(sizes[2] == 18U * 32U);
  // End of the recording: finish() publishes the turn in progress (144 000 .. 174 000 = 15 blocks),
  // not closed by a wrap; a second finish() has nothing left.
  REQUIRE(rev.finish());
  CHECK(rev.revolution().size() == 15U * 32U);
  CHECK_FALSE(rev.info().complete);
  CHECK(rev.revolutions() == 5U);
  CHECK_FALSE(rev.finish());
  // Storage too small: refused records counted in the revolution, never silently dropped.
  static FiringRecord tiny[100];
  RevolutionAssembler small(Span<FiringRecord>(tiny, 100));
  az = 30000;
  std::uint32_t refused = 0;
  for (int k = 0; k < 3; ++k) {
    const Packet p = makePacket(az, 2000, 0x37, 0x22);
    REQUIRE(dec.decode(bytes(p), Span<FiringRecord>(out), n) == Status::Ok);
    if (small.add(Span<const FiringRecord>(out, n)) && small.info().complete) {
      refused = small.info().refused;
      CHECK(small.info().records == 100U);
    }
    az = (az + 12U * 2000U) % 36000U;
  }
  CHECK(refused == 18U * 32U - 100U);
}

TEST_CASE("Records to range-image returns by the point model; no allocation per packet", "[drivers][velodyne]") {
  static agv::LaserIntrinsics cal;
  REQUIRE(cal.reset(16) == Status::Ok);
  for (std::size_t i = 0; i < 16; ++i)
    REQUIRE(cal.set(i, agv::LaserParams{0.0, 0.0, 0.0, (static_cast<double>(i) - 7.5) * 0.03, 0.0}) == Status::Ok);
  VelodyneDecoder dec(VelodyneConfig{});
  const Packet p = makePacket(9000, 40, 0x37, 0x22);
  static FiringRecord out[kMaxRecordsPerPacket];
  static agv::FiringReturn ret[kMaxRecordsPerPacket];
  static FiringRecord storage[4000];
  RevolutionAssembler rev(Span<FiringRecord>(storage, 4000));
  std::size_t n = 0;
  std::size_t m = 0;
  Status s1 = Status::NotInitialized;
  Status s2 = Status::NotInitialized;
  AGV_CHECK_NO_ALLOCATIONS(for (int k = 0; k < 50; ++k) {
    s1 = dec.decode(bytes(p), Span<FiringRecord>(out), n);
    (void)rev.add(Span<const FiringRecord>(out, n));
    s2 = toFiringReturns(Span<const FiringRecord>(out, n), cal, 1800, Span<agv::FiringReturn>(ret), m);
  });
  CHECK(s1 == Status::Ok);
  CHECK(s2 == Status::Ok);
  REQUIRE(m == 384U);
  // Laser 0 of block 0 at phi = 90 deg (to the right), raw 1000 = 2 m, elevation -0.225 rad:
  // REP-103 (0, -2 cos(-0.225), 2 sin(-0.225)); column 90 / 360 * 1800 = 450.
  AGV_CHECK_NEAR(ret[0].point.x(), 0.0, 1e-6);
  AGV_CHECK_NEAR(ret[0].point.y(), -2.0 * std::cos(-0.225), 1e-5);
  AGV_CHECK_NEAR(ret[0].point.z(), 2.0 * std::sin(-0.225), 1e-5);
  CHECK(ret[0].firing == 450U);
  CHECK(ret[0].laser == 0U);
  // A laser beyond the table is named, not placed.
  static agv::LaserIntrinsics eight;
  REQUIRE(eight.reset(8) == Status::Ok);
  CHECK(toFiringReturns(Span<const FiringRecord>(out, n), eight, 1800, Span<agv::FiringReturn>(ret), m) ==
        Status::OutOfRange);
  CHECK(m == 192U);
  CHECK(toFiringReturns(Span<const FiringRecord>(out, n), cal, 0, Span<agv::FiringReturn>(ret), m) ==
        Status::InvalidArgument);
}
