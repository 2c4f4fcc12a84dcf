// libFuzzer target: the Velodyne packet decoder and the revolution assembler fed arbitrary bytes.
// The first byte chooses the model, the HDL-64E return mode, the product check and keepNoReturn;
// the rest is cut into "datagrams" whose sizes come from the input (so truncated, exact and
// oversized packets all occur). Invariants: no crash or sanitizer report; records within the output
// span; azimuths < 36000; laser ids below the model's count; every refused packet counted; the
// assembler's revolutions within its storage.
#include <cstddef>
#include <cstdint>

#include "agv/drivers/protocol/velodyne/velodyne_packet.hpp"
#include "fuzz_support.hpp"

using namespace agv::drivers::velodyne;
using agv::Span;
using agv::Status;
using agv::fuzz::check;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 3) {
    return 0;
  }
  VelodyneConfig cfg;
  cfg.model = static_cast<Model>(data[0] % 3U);
  cfg.hdl64ReturnMode = (data[0] & 4U) != 0U ? ReturnMode::Dual : ReturnMode::Strongest;
  cfg.checkProductId = (data[0] & 8U) != 0U;
  cfg.keepNoReturn = (data[0] & 16U) != 0U;
  VelodyneDecoder dec(cfg);
  static FiringRecord storage[2000];
  RevolutionAssembler rev(Span<FiringRecord>(storage, 2000));
  static FiringRecord out[kMaxRecordsPerPacket];
  std::size_t pos = 1;
  std::uint32_t calls = 0;
  while (pos + 2 <= size) {
    // Datagram length: mostly exactly one packet, else what the two length bytes say.
    const std::size_t want = (data[pos] & 0x80U) != 0U ? kPacketBytes : ((data[pos] << 8U) | data[pos + 1]) % 1400U;
    pos += 2;
    const std::size_t n = size - pos < want ? size - pos : want;
    const std::size_t outSize = (data[pos - 1] & 0x40U) != 0U ? 7U : kMaxRecordsPerPacket;  // sometimes too small
    std::size_t written = 0;
    const Status st = dec.decode(Span<const std::uint8_t>(data + pos, n), Span<FiringRecord>(out, outSize), written);
    ++calls;
    check(written <= outSize);
    if (st == Status::Truncated || st == Status::Unsupported || (st == Status::Malformed && n != kPacketBytes)) {
      check(written == 0U);
    }
    for (std::size_t i = 0; i < written; ++i) {
      check(out[i].azimuth < kAzimuthTurn);
      check(out[i].laser < laserCount(cfg.model));
      check(cfg.keepNoReturn || out[i].distance != 0U);
    }
    if (rev.add(Span<const FiringRecord>(out, written))) {
      check(rev.revolution().size() <= 2000U);
      check(rev.info().records == rev.revolution().size());
    }
    pos += n;
  }
  const VelodyneCounters& c = dec.counters();
  check(c.packets + c.refusedPackets() == calls);
  return 0;
}
