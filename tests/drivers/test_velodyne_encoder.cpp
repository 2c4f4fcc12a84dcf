// Velodyne packet encoding (drivers/protocol velodyne_encoder.hpp): HDL-64E and HDL-32E firings
// packed into data packets read back by the decoder as the same lasers, azimuths and distances;
// the byte layout checked at known offsets; partial packets padded with firings the decoder
// skips; bad input (VLP-16, wrong laser count, azimuth of a whole turn) refused with nothing
// added; no allocation per firing. Portable (every tree).
#include <array>
#include <cstdint>
#include <vector>

#include "agv/drivers/protocol/velodyne/velodyne_encoder.hpp"
#include "agv/drivers/protocol/velodyne/velodyne_packet.hpp"
#include "agv_test.hpp"

using agv::Span;
using agv::Status;
using namespace agv::drivers::velodyne;

namespace {

/// Firing k's distance of laser l: 0 (no return) for every 7th pair, else a count that names both.
std::uint16_t distanceOf(std::size_t k, std::size_t l) {
  return (k + l) % 7U == 3U ? std::uint16_t{0} : static_cast<std::uint16_t>(500U + 100U * k + l);
}

std::uint16_t azimuthOf(std::size_t k) {
  return static_cast<std::uint16_t>(35000U + 17U * k) % kAzimuthTurn;
}

/// Encodes `firings` firings of `model`, decodes every packet, and checks the records against the
/// input: each non-zero distance once, at its firing's azimuth, nothing else.
void roundTrip(Model model, std::size_t firings, std::size_t expectPackets) {
  const std::size_t lasers = laserCount(model);
  VelodyneEncoder enc(model);
  VelodyneConfig cfg;
  cfg.model = model;
  VelodyneDecoder dec(cfg);
  std::vector<FiringRecord> got;
  FiringRecord out[kMaxRecordsPerPacket];
  std::uint16_t d[64];
  std::size_t packets = 0;
  auto take = [&](bool ready) {
    if (!ready) {
      return;
    }
    ++packets;
    REQUIRE(enc.packet().size() == kPacketBytes);
    std::size_t n = 0;
    REQUIRE(dec.decode(enc.packet(), Span<FiringRecord>(out), n) == Status::Ok);
    got.insert(got.end(), out, out + n);
  };
  for (std::size_t k = 0; k < firings; ++k) {
    for (std::size_t l = 0; l < lasers; ++l) {
      d[l] = distanceOf(k, l);
    }
    bool ready = false;
    REQUIRE(enc.add(azimuthOf(k), Span<const std::uint16_t>(d, lasers), ready) == Status::Ok);
    take(ready);
  }
  bool ready = false;
  REQUIRE(enc.flush(ready) == Status::Ok);
  take(ready);
  CHECK(packets == expectPackets);
  CHECK(enc.packets() == expectPackets);
  std::size_t expected = 0;
  for (std::size_t k = 0; k < firings; ++k) {
    for (std::size_t l = 0; l < lasers; ++l) {
      expected += distanceOf(k, l) != 0 ? 1U : 0U;
    }
  }
  REQUIRE(got.size() == expected);
  std::size_t i = 0;
  for (std::size_t k = 0; k < firings; ++k) {
    for (std::size_t l = 0; l < lasers; ++l) {
      if (distanceOf(k, l) == 0) {
        continue;
      }
      INFO("firing " << k << " laser " << l);
      CHECK(got[i].laser == l);
      CHECK(got[i].azimuth == azimuthOf(k));
      CHECK(got[i].distance == distanceOf(k, l));
      CHECK(got[i].secondReturn == 0U);
      ++i;
    }
  }
  CHECK(dec.counters().refusedPackets() == 0U);
  CHECK(dec.counters().badBlockId == 0U);
}

}  // namespace

TEST_CASE("HDL-64E firings round-trip through packets: upper and lower blocks, the padding skipped",
          "[drivers][velodyne]") {
  roundTrip(Model::Hdl64e, 13, 3);  // 6 firings per packet: 6 + 6 + 1 padded
  roundTrip(Model::Hdl64e, 12, 2);  // exactly two packets, nothing to flush
}

TEST_CASE("HDL-32E firings round-trip through packets; the factory bytes name the product", "[drivers][velodyne]") {
  roundTrip(Model::Hdl32e, 25, 3);  // 12 firings per packet: 12 + 12 + 1 padded
  VelodyneEncoder enc(Model::Hdl32e);
  std::array<std::uint16_t, 32> d{};
  d[5] = 0x1234;
  bool ready = false;
  REQUIRE(enc.add(0x0102, Span<const std::uint16_t>(d.data(), d.size()), ready) == Status::Ok);
  CHECK_FALSE(ready);
  REQUIRE(enc.flush(ready) == Status::Ok);
  REQUIRE(ready);
  const std::uint8_t* p = enc.packet().data();
  CHECK(p[0] == 0xFF);  // block id 0xEEFF, little-endian
  CHECK(p[1] == 0xEE);
  CHECK(p[2] == 0x02);  // azimuth
  CHECK(p[3] == 0x01);
  CHECK(p[4 + 5 * 3] == 0x34);  // laser 5's distance
  CHECK(p[4 + 5 * 3 + 1] == 0x12);
  CHECK(p[1100 + 2] == 0x02);  // the padded last block repeats the azimuth
  CHECK(p[1204] == 0x37);      // strongest return
  CHECK(p[1205] == 0x21);      // HDL-32E
}

TEST_CASE("bad firings are refused and add nothing; no allocation per firing", "[drivers][velodyne]") {
  std::array<std::uint16_t, 64> d{};
  d.fill(1000);
  bool ready = true;
  VelodyneEncoder vlp(Model::Vlp16);
  CHECK(vlp.add(0, Span<const std::uint16_t>(d.data(), 16), ready) == Status::Unsupported);
  CHECK_FALSE(ready);
  CHECK(vlp.flush(ready) == Status::Unsupported);

  VelodyneEncoder enc(Model::Hdl64e);
  CHECK(enc.add(100, Span<const std::uint16_t>(d.data(), 32), ready) == Status::InvalidArgument);
  CHECK(enc.add(kAzimuthTurn, Span<const std::uint16_t>(d.data(), 64), ready) == Status::InvalidArgument);
  CHECK(enc.add(100, Span<const std::uint16_t>(), ready) == Status::InvalidArgument);
  REQUIRE(enc.flush(ready) == Status::Ok);
  CHECK_FALSE(ready);  // nothing was added: no packet
  CHECK(enc.packets() == 0U);

  std::size_t packets = 0;
  Status st = Status::NotInitialized;
  AGV_CHECK_NO_ALLOCATIONS(for (std::uint16_t k = 0; k < 600; ++k) {
    st = enc.add(static_cast<std::uint16_t>(k * 60U), Span<const std::uint16_t>(d.data(), 64), ready);
    packets += ready ? 1U : 0U;
  });
  CHECK(st == Status::Ok);
  CHECK(packets == 100U);
}
