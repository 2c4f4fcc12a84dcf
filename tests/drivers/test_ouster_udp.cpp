// The UDP receiver with Ouster OS-series packets (6 464 to 24 832 bytes, up to 20x a Velodyne packet) on
// loopback: every real capture of ../shared/data/lidar3d/ouster_pcaps/ replayed from a plain socket
// at the unit's own packet size, received, stamped and decoded exactly as the file decodes; a
// Velodyne-sized buffer refuses them and counts each; a frame's burst beyond the socket buffer is
// counted as kernel drops, and the receiver's default 4 MB buffer (2.6 such frames) loses none.
#include <algorithm>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "agv/datasets/ouster_capture.hpp"
#include "agv/drivers/linux/monotonic_clock.hpp"
#include "agv/drivers/linux/udp_receiver.hpp"
#include "agv/drivers/protocol/ouster/ouster_packet.hpp"
#include "agv/drivers/protocol/velodyne/velodyne_packet.hpp"
#include "agv_test.hpp"
#include "udp_loopback.hpp"

using agv::Duration;
using agv::Span;
using agv::Status;
using agv::Timestamp;
using namespace agv::drivers;

namespace {
const std::string kDir = std::string(AGV_SHARED_DATA_DIR) + "/lidar3d/ouster_pcaps/";

struct Capture {
  const char* json;
  const char* pcap;
};
// The six captures of the data README (every profile: LEGACY, RNG19 single and dual, RNG15).
const Capture kCaptures[] = {
    {"OS-0-128-U1_v2.3.0_1024x10", "OS-0-128-U1_v2.3.0_1024x10"},
    {"OS-2-128-U1_v2.3.0_1024x10", "OS-2-128-U1_v2.3.0_1024x10"},
    {"OS-1-128_v2.3.0_1024x10", "OS-1-128_v2.3.0_1024x10_lb_n3"},
    {"OS-1-32-G_v2.1.1_1024x10", "OS-1-32-G_v2.1.1_1024x10"},
    {"OS-2-32-U0_v2.0.0_1024x10", "OS-2-32-U0_v2.0.0_1024x10"},
    {"OS-0-32-U1_v2.2.0_1024x10", "OS-0-32-U1_v2.2.0_1024x10"},
};

struct Loaded {
  agv::datasets::OusterMetadata meta;
  std::vector<std::vector<std::uint8_t>> packets;
};

Loaded load(const Capture& c) {
  Loaded l;
  std::string error;
  INFO(error);
  REQUIRE(agv::datasets::readOusterMetadata(kDir + c.json + ".json", l.meta, error));
  agv::datasets::PcapStats stats;
  REQUIRE(agv::datasets::readPcapUdp(kDir + c.pcap + ".pcap", l.meta.udpPortLidar, l.packets, stats, error));
  REQUIRE_FALSE(l.packets.empty());
  return l;
}

/// What the decoder makes of a sequence of packets: the records, a checksum of every record's
/// laser, azimuth and distance in order, and the decoder's counters.
struct Decoded {
  std::size_t records = 0;
  std::uint64_t checksum = 0;
  ouster::OusterCounters counters{};
};

void decodeInto(ouster::OusterDecoder& dec, const std::uint8_t* p, std::size_t n, Decoded& d) {
  static ouster::FiringRecord out[ouster::kMaxRecordsPerPacket];
  std::size_t m = 0;
  const Status st = dec.decode(Span<const std::uint8_t>(p, n), Span<ouster::FiringRecord>(out), m);
  REQUIRE((st == Status::Ok || st == Status::Malformed));  // Malformed: a column skipped (invalid status)
  for (std::size_t i = 0; i < m; ++i) {
    d.checksum = d.checksum * 1000003U + out[i].laser * 65537U + out[i].azimuth * 257U + out[i].distance;
  }
  d.records += m;
  d.counters = dec.counters();
}
}  // namespace

TEST_CASE("Ouster captures replayed over loopback: every packet received whole, stamped, decoded as the file",
          "[drivers][ouster][udp]") {
  for (const Capture& c : kCaptures) {
    INFO(c.pcap);
    const Loaded l = load(c);
    const std::size_t bytes = ouster::packetBytes(l.meta.format);
    REQUIRE(bytes > 0U);
    ouster::OusterConfig cfg;
    cfg.format = l.meta.format;
    ouster::OusterDecoder fromFile(cfg);
    ouster::OusterDecoder fromSocket(cfg);
    Decoded file;
    for (const auto& p : l.packets) {
      decodeInto(fromFile, p.data(), p.size(), file);
    }
    // 16 packets per burst (a 128-beam unit: 16 x 24.8 kB, 1/64 of a frame), read back after each.
    UdpReceiver rx(agv::test::loopbackReceiver(4 << 20));
    REQUIRE(rx.open() == Status::Ok);
    agv::test::UdpSender tx(rx.localPort());
    std::vector<std::uint8_t> buf(65536);
    Decoded socket;
    std::size_t identical = 0;
    bool monotonic = true;
    Timestamp prev{};
    for (std::size_t k0 = 0; k0 < l.packets.size(); k0 += 16) {
      const std::size_t k1 = std::min(l.packets.size(), k0 + 16);
      for (std::size_t k = k0; k < k1; ++k) {
        REQUIRE(tx.send(l.packets[k].data(), l.packets[k].size()));
      }
      for (std::size_t k = k0; k < k1; ++k) {
        std::size_t n = 0;
        Timestamp stamp{};
        REQUIRE(rx.receive(Span<std::uint8_t>(buf.data(), buf.size()), Duration::fromMilliseconds(1000), n, stamp) ==
                Status::Ok);
        REQUIRE(n == l.packets[k].size());
        identical += std::memcmp(buf.data(), l.packets[k].data(), n) == 0 ? 1U : 0U;
        monotonic = monotonic && !(stamp < prev);
        prev = stamp;
        decodeInto(fromSocket, buf.data(), n, socket);
      }
    }
    CHECK(identical == l.packets.size());
    CHECK(monotonic);
    CHECK(rx.counters().datagrams == l.packets.size());
    CHECK(rx.counters().kernelDrops == 0U);
    CHECK(rx.counters().oversized == 0U);
    CHECK(file.records > 0U);
    CHECK(socket.records == file.records);
    CHECK(socket.checksum == file.checksum);
    CHECK(socket.counters.packets == file.counters.packets);
    CHECK(socket.counters.validColumns == file.counters.validColumns);
    CHECK(socket.counters.invalidColumns == file.counters.invalidColumns);
    CHECK(socket.counters.refusedPackets() == 0U);
    // A receiver buffer sized for Velodyne packets refuses an Ouster packet (the kernel cuts it)
    // and counts it: a receive buffer is sized to the unit's packetBytes(), not to 1206.
    std::uint8_t small[velodyne::kPacketBytes];
    REQUIRE(tx.send(l.packets[0].data(), l.packets[0].size()));
    std::size_t n = 0;
    Timestamp s{};
    CHECK(rx.receive(Span<std::uint8_t>(small), Duration::fromMilliseconds(1000), n, s) == Status::Malformed);
    CHECK(rx.counters().oversized == 1U);
    CHECK(rx.receive(Span<std::uint8_t>(buf.data(), buf.size()), Duration::fromMilliseconds(20), n, s) ==
          Status::Timeout);
  }
}

TEST_CASE("Ouster frame sent in one burst: the socket buffer decides what the kernel drops, and every drop is counted",
          "[drivers][ouster][udp]") {
  const Loaded l = load(kCaptures[1]);  // OS-2-128, RNG19: 24 832-byte packets
  const std::size_t bytes = ouster::packetBytes(l.meta.format);
  REQUIRE(l.packets.size() >= 64U);
  const std::size_t frame = l.meta.format.columnsPerFrame / l.meta.format.columnsPerPacket;  // packets per frame
  REQUIRE(frame <= l.packets.size());
  std::vector<std::uint8_t> buf(65536);
  const auto burst = [&](int rcvbuf, std::uint32_t& got, std::uint32_t& dropped) {
    UdpReceiver rx(agv::test::loopbackReceiver(rcvbuf));
    REQUIRE(rx.open() == Status::Ok);
    agv::test::UdpSender tx(rx.localPort());
    for (std::size_t k = 0; k < frame; ++k) {
      REQUIRE(tx.send(l.packets[k].data(), l.packets[k].size()));
    }
    got = 0;
    std::size_t n = 0;
    Timestamp s{};
    while (rx.receive(Span<std::uint8_t>(buf.data(), buf.size()), Duration::fromMilliseconds(50), n, s) == Status::Ok) {
      ++got;
    }
    // One more after the drain: its control message carries the final drop count.
    REQUIRE(tx.send(l.packets[0].data(), l.packets[0].size()));
    REQUIRE(rx.receive(Span<std::uint8_t>(buf.data(), buf.size()), Duration::fromMilliseconds(1000), n, s) ==
            Status::Ok);
    ++got;
    dropped = rx.counters().kernelDrops;
    CHECK(rx.counters().datagrams == got);
  };
  std::uint32_t got = 0;
  std::uint32_t dropped = 0;
  burst(static_cast<int>(4 * bytes), got, dropped);  // a few packets' worth
  WARN("OS-2-128 frame (" << frame << " packets of " << bytes << " B) into a 4-packet buffer: " << got << " received, "
                          << dropped << " dropped by the kernel");
  CHECK(got < frame + 1U);
  CHECK(got + dropped == frame + 1U);
  burst(4 << 20, got, dropped);  // the receiver's default: 4 MB, 2.6 frames of this unit
  CHECK(dropped == 0U);
  CHECK(got == frame + 1U);
}
