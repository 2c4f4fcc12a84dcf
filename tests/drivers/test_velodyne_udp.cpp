// The UDP receiver on loopback: the real einride VLP-16 recording (1000 packets) replayed from a
// plain socket, received, stamped and decoded; a too-small socket buffer makes the kernel drop
// datagrams and the receiver counts every one; an oversized datagram is refused and counted.
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "agv/datasets/velodyne_recording.hpp"
#include "agv/drivers/linux/monotonic_clock.hpp"
#include "agv/drivers/linux/udp_receiver.hpp"
#include "agv/drivers/protocol/velodyne/velodyne_packet.hpp"
#include "agv_test.hpp"
#include "udp_loopback.hpp"

using agv::Duration;
using agv::Span;
using agv::Status;
using agv::Timestamp;
using namespace agv::drivers;

namespace {
/// The recording's bytes through the shared reader (agv_datasets); empty when it cannot be read.
std::vector<std::uint8_t> recording() {
  agv::datasets::PacketRecording r;
  std::string error;
  if (!agv::datasets::readPacketRecording(std::string(AGV_SHARED_DATA_DIR) + "/lidar3d/vlp16_einride/recording.bin",
                                          velodyne::kPacketBytes, r, error)) {
    FAIL(error);
  }
  return r.bytes;
}

}  // namespace

TEST_CASE("einride recording replayed over loopback: every packet received, stamped and decoded",
          "[drivers][velodyne][udp]") {
  const std::vector<std::uint8_t> rec = recording();
  REQUIRE(rec.size() == 1000U * velodyne::kPacketBytes);
  UdpReceiver rx(agv::test::loopbackReceiver(1 << 20));
  REQUIRE(rx.open() == Status::Ok);
  REQUIRE(rx.localPort() != 0U);
  agv::test::UdpSender tx(rx.localPort());
  velodyne::VelodyneDecoder dec(velodyne::VelodyneConfig{});
  velodyne::FiringRecord out[velodyne::kMaxRecordsPerPacket];
  std::uint8_t buf[2048];
  std::size_t returns = 0;
  std::size_t identical = 0;
  Timestamp prev{};
  bool monotonic = true;
  bool withinCall = true;
  // Bursts of 20 packets (26 ms of a VLP-16's output), then read them back.
  for (std::size_t k0 = 0; k0 < 1000; k0 += 20) {
    const Timestamp sentFrom = monotonicNow();
    for (std::size_t k = k0; k < k0 + 20; ++k)
      REQUIRE(tx.send(rec.data() + k * velodyne::kPacketBytes, velodyne::kPacketBytes));
    for (std::size_t k = k0; k < k0 + 20; ++k) {
      std::size_t n = 0;
      Timestamp stamp{};
      REQUIRE(rx.receive(Span<std::uint8_t>(buf), Duration::fromMilliseconds(1000), n, stamp) == Status::Ok);
      const Timestamp after = monotonicNow();
      REQUIRE(n == velodyne::kPacketBytes);
      identical += std::memcmp(buf, rec.data() + k * velodyne::kPacketBytes, n) == 0 ? 1U : 0U;
      monotonic = monotonic && !(stamp < prev);
      // The kernel stamp lies between the first send of the burst and the return of receive()
      // (1 ms slack for the two clock reads that map it onto the monotonic clock).
      withinCall = withinCall && !(stamp < sentFrom - Duration::fromMilliseconds(1)) &&
                   !(after + Duration::fromMilliseconds(1) < stamp);
      prev = stamp;
      std::size_t m = 0;
      REQUIRE(dec.decode(Span<const std::uint8_t>(buf, n), Span<velodyne::FiringRecord>(out), m) == Status::Ok);
      returns += m;
    }
  }
  CHECK(identical == 1000U);
  CHECK(monotonic);
  CHECK(withinCall);
  CHECK(returns == 203034U);  // as decoded from the file (lidar3d.velodyne_realdata)
  CHECK(rx.counters().datagrams == 1000U);
  CHECK(rx.counters().kernelDrops == 0U);
  // Nothing more: a bounded wait ends in Timeout.
  std::size_t n = 0;
  Timestamp s{};
  CHECK(rx.receive(Span<std::uint8_t>(buf), Duration::fromMilliseconds(20), n, s) == Status::Timeout);
  // An oversized datagram (1300 bytes into a 1206-byte buffer) is refused and counted.
  std::vector<std::uint8_t> big(1300, 0xEE);
  REQUIRE(tx.send(big.data(), big.size()));
  CHECK(rx.receive(Span<std::uint8_t>(buf, velodyne::kPacketBytes), Duration::fromMilliseconds(1000), n, s) ==
        Status::Malformed);
  CHECK(rx.counters().oversized == 1U);
}

TEST_CASE("A full socket buffer: every datagram the kernel dropped is counted", "[drivers][velodyne][udp]") {
  const std::vector<std::uint8_t> rec = recording();
  REQUIRE(rec.size() == 1000U * velodyne::kPacketBytes);
  UdpReceiver rx(agv::test::loopbackReceiver(4096));  // the kernel doubles it and keeps a floor: a few datagrams fit
  REQUIRE(rx.open() == Status::Ok);
  agv::test::UdpSender tx(rx.localPort());
  for (std::size_t k = 0; k < 200; ++k)
    REQUIRE(tx.send(rec.data() + k * velodyne::kPacketBytes, velodyne::kPacketBytes));
  std::uint8_t buf[2048];
  std::size_t n = 0;
  Timestamp s{};
  std::uint32_t got = 0;
  while (rx.receive(Span<std::uint8_t>(buf), Duration::fromMilliseconds(50), n, s) == Status::Ok)
    ++got;
  // Send one more after the drain: its control message carries the final drop count.
  REQUIRE(tx.send(rec.data(), velodyne::kPacketBytes));
  REQUIRE(rx.receive(Span<std::uint8_t>(buf), Duration::fromMilliseconds(1000), n, s) == Status::Ok);
  ++got;
  WARN("small buffer: " << got << " received, " << rx.counters().kernelDrops << " dropped by the kernel");
  CHECK(got < 201U);
  CHECK(got + rx.counters().kernelDrops == 201U);
  CHECK(rx.counters().datagrams == got);
  UdpReceiver closed(agv::test::loopbackReceiver(0));
  CHECK(closed.receive(Span<std::uint8_t>(buf), Duration::fromMilliseconds(1), n, s) == Status::NotInitialized);
  UdpReceiverConfig bad = agv::test::loopbackReceiver(0);
  std::strcpy(bad.bindAddress, "not-an-address");
  UdpReceiver b(bad);
  CHECK(b.open() == Status::InvalidArgument);
}
