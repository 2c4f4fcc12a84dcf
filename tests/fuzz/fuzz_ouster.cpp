// libFuzzer target: the Ouster packet decoder (all four profiles) and the revolution assembler fed
// arbitrary bytes. The first byte chooses the profile, 16 or 4 columns per packet, 32 or 128 or 16
// pixels per column, the second return and keepNoReturn; the rest is cut into "datagrams" whose
// sizes come from the input (exact packets, truncated and oversized ones). Invariants: no crash or
// sanitizer report; records within the output span; beams below the pixels per column; blocks
// below the columns per packet; azimuths < 36000 and mapping back to a measurement id < W; every
// refused packet counted; every point finite or refused.
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "agv/drivers/protocol/ouster/ouster_packet.hpp"
#include "fuzz_support.hpp"

using namespace agv::drivers::ouster;
using agv::Span;
using agv::Status;
using agv::fuzz::check;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 3) {
    return 0;
  }
  OusterConfig cfg;
  cfg.format.profile = static_cast<Profile>(data[0] % 4U);
  cfg.format.columnsPerPacket = (data[0] & 4U) != 0U ? 4 : 16;
  const unsigned px = (data[0] >> 3U) % 3U;
  cfg.format.pixelsPerColumn = px == 0 ? 32 : px == 1 ? 128 : 16;
  cfg.format.columnsPerFrame = (data[0] & 0x20U) != 0U ? 512 : 1024;
  cfg.emitSecondReturn = (data[0] & 0x40U) != 0U;
  cfg.keepNoReturn = (data[0] & 0x80U) != 0U;
  const std::size_t bytes = packetBytes(cfg.format);
  check(bytes > 0U);
  OusterDecoder dec(cfg);
  static FiringRecord storage[5000];
  agv::drivers::velodyne::RevolutionAssembler rev(Span<FiringRecord>(storage, 5000));
  static FiringRecord out[kMaxRecordsPerPacket];
  static PixelExtra extra[kMaxRecordsPerPacket];
  OusterIntrinsics in;
  in.beams = cfg.format.pixelsPerColumn;
  in.columnsPerFrame = cfg.format.columnsPerFrame;
  in.beamOriginM = 0.015F;
  for (std::size_t i = 0; i < in.beams; ++i) {
    in.altitudeRad[i] = 0.01F * static_cast<float>(i);
    in.azimuthRad[i] = -0.05F;
  }
  std::size_t pos = 1;
  std::uint32_t calls = 0;
  while (pos + 2 <= size) {
    const std::size_t want = (data[pos] & 0x80U) != 0U ? bytes : ((data[pos] << 8U) | data[pos + 1]) % (bytes + 64U);
    pos += 2;
    const std::size_t n = size - pos < want ? size - pos : want;
    const std::size_t outSize = (data[pos - 1] & 0x40U) != 0U ? 7U : kMaxRecordsPerPacket;
    std::size_t written = 0;
    PacketInfo info;
    const Status st = dec.decode(Span<const std::uint8_t>(data + pos, n), Span<FiringRecord>(out, outSize), written,
                                 &info, Span<PixelExtra>(extra, outSize));
    ++calls;
    check(written <= outSize);
    if (n != bytes) {
      check(written == 0U);
    }
    for (std::size_t i = 0; i < written; ++i) {
      check(out[i].azimuth < agv::drivers::velodyne::kAzimuthTurn);
      check(measurementId(out[i].azimuth, cfg.format.columnsPerFrame) < cfg.format.columnsPerFrame);
      check(out[i].laser < cfg.format.pixelsPerColumn);
      check(out[i].block < cfg.format.columnsPerPacket);
      check(cfg.keepNoReturn || out[i].distance != 0U);
      check(extra[i].rangeMm <= kMaxRecordRangeMm);
      float xyz[3];
      if (ousterPoint(in, out[i], true, xyz) == Status::Ok) {
        check(std::isfinite(xyz[0]) && std::isfinite(xyz[1]) && std::isfinite(xyz[2]));
      }
    }
    (void)st;
    if (rev.add(Span<const FiringRecord>(out, written))) {
      check(rev.revolution().size() <= 5000U);
      check(rev.info().records == rev.revolution().size());
    }
    pos += n;
  }
  if (rev.finish()) {
    check(rev.revolution().size() <= 5000U);
  }
  const OusterCounters& c = dec.counters();
  check(c.packets + c.refusedPackets() == calls);
  return 0;
}
