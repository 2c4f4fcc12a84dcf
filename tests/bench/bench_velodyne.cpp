// Velodyne decoding benchmark:
//   BM_VelodyneDecode/hdl64  one iteration = one HDL-64E S2 revolution at 10 Hz: 348 packets
//                            (0.1728 deg firing steps, 2084 firings x 64 lasers = 133 632 records),
//                            each decoded to firing records, fed to the revolution assembler and
//                            turned into range-image returns by the thesis' point model with the
//                            SZTAKI unit's factory calibration (../shared/data calibration/). The
//                            packets are built once from the documented layout with pseudo-random
//                            ranges 1..60 m (no zero: every record becomes a point).
//   BM_OusterDecode/os2_128  one iteration = one frame of the real OS-2-128 capture
//                            (../shared/data/lidar3d/ouster_pcaps/, RNG19_RFL8_SIG16_NIR16, 1024 x
//                            128): its first 64 packets of 24 832 bytes decoded to firing records,
//                            fed to the revolution assembler column by column and turned into
//                            range-image returns by Ouster's beam model with the unit's JSON.
//   BM_OusterDecode/os0_128  the same for the OS-0-128 capture (RNG15_RFL8_NIR8, 4-byte pixels).
// Counters: records = records per revolution; points = points per revolution.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "agv/datasets/ouster_capture.hpp"
#include "agv/datasets/velodyne_calibration.hpp"
#include "agv/drivers/protocol/ouster/ouster_packet.hpp"
#include "agv/drivers/protocol/velodyne/velodyne_packet.hpp"

namespace {
namespace vd = agv::drivers::velodyne;

std::vector<std::uint8_t> hdl64Revolution(std::size_t packets) {
  std::vector<std::uint8_t> bytes(packets * vd::kPacketBytes, 0);
  std::uint32_t rng = 12345;
  std::size_t firing = 0;
  for (std::size_t k = 0; k < packets; ++k) {
    std::uint8_t* p = bytes.data() + k * vd::kPacketBytes;
    for (std::size_t b = 0; b < 12; ++b, firing += b % 2U == 0U ? 1U : 0U) {
      std::uint8_t* blk = p + b * 100;
      const unsigned id = b % 2U == 0U ? 0xEEFFU : 0xDDFFU;
      const auto az = static_cast<unsigned>((firing * 1728U / 100U) % 36000U);  // 0.1728 deg steps
      blk[0] = static_cast<std::uint8_t>(id & 0xFFU);
      blk[1] = static_cast<std::uint8_t>(id >> 8U);
      blk[2] = static_cast<std::uint8_t>(az & 0xFFU);
      blk[3] = static_cast<std::uint8_t>(az >> 8U);
      for (std::size_t c = 0; c < 32; ++c) {
        rng = rng * 1664525U + 1013904223U;
        const unsigned raw = 500U + (rng >> 8U) % 29500U;  // 1..60 m at 2 mm
        blk[4 + c * 3] = static_cast<std::uint8_t>(raw & 0xFFU);
        blk[5 + c * 3] = static_cast<std::uint8_t>(raw >> 8U);
        blk[6 + c * 3] = static_cast<std::uint8_t>(rng >> 24U);
      }
    }
  }
  return bytes;
}

void BM_VelodyneDecodeHdl64(benchmark::State& state) {
  static agv::LaserIntrinsics cal;
  std::string err;
  if (!agv::datasets::readVelodyneCalibration(
          std::string(AGV_SHARED_DATA_DIR) + "/lidar3d/calibration/hdl64e_s2.1_sztaki_db.xml", cal, err)) {
    std::fprintf(stderr, "bench_velodyne: %s\n", err.c_str());
    std::abort();
  }
  constexpr std::size_t kPackets = 348;
  const std::vector<std::uint8_t> bytes = hdl64Revolution(kPackets);
  vd::VelodyneConfig cfg;
  cfg.model = vd::Model::Hdl64e;
  vd::VelodyneDecoder dec(cfg);
  std::vector<vd::FiringRecord> storage(140000);
  std::vector<agv::FiringReturn> returns(kPackets * vd::kMaxRecordsPerPacket);
  vd::RevolutionAssembler rev(agv::Span<vd::FiringRecord>(storage.data(), storage.size()));
  vd::FiringRecord out[vd::kMaxRecordsPerPacket];
  std::size_t records = 0;
  std::size_t points = 0;
  for (auto _ : state) {
    records = 0;
    points = 0;
    for (std::size_t k = 0; k < kPackets; ++k) {
      std::size_t n = 0;
      benchmark::DoNotOptimize(
          dec.decode(agv::Span<const std::uint8_t>(bytes.data() + k * vd::kPacketBytes, vd::kPacketBytes),
                     agv::Span<vd::FiringRecord>(out), n));
      benchmark::DoNotOptimize(rev.add(agv::Span<const vd::FiringRecord>(out, n)));
      std::size_t m = 0;
      benchmark::DoNotOptimize(
          vd::toFiringReturns(agv::Span<const vd::FiringRecord>(out, n), cal, 2000,
                              agv::Span<agv::FiringReturn>(returns.data() + points, returns.size() - points), m));
      records += n;
      points += m;
    }
    benchmark::ClobberMemory();
  }
  state.counters["records"] = static_cast<double>(records);
  state.counters["points"] = static_cast<double>(points);
}
BENCHMARK(BM_VelodyneDecodeHdl64)->Name("BM_VelodyneDecode/hdl64")->Unit(benchmark::kMillisecond);

namespace os = agv::drivers::ouster;

void BM_OusterDecode(benchmark::State& state, const char* capture, const char* metadata) {
  const std::string dir = std::string(AGV_SHARED_DATA_DIR) + "/lidar3d/ouster_pcaps/";
  agv::datasets::OusterMetadata meta;
  std::vector<std::vector<std::uint8_t>> packets;
  agv::datasets::PcapStats stats;
  std::string err;
  if (!agv::datasets::readOusterMetadata(dir + metadata + ".json", meta, err) ||
      !agv::datasets::readPcapUdp(dir + capture + ".pcap", meta.udpPortLidar, packets, stats, err)) {
    std::fprintf(stderr, "bench_velodyne: %s\n", err.c_str());
    std::abort();
  }
  const std::size_t frame = meta.format.columnsPerFrame / meta.format.columnsPerPacket;
  if (packets.size() < frame) {
    std::fprintf(stderr, "bench_velodyne: %s has %zu packets, fewer than a frame's %zu\n", capture, packets.size(),
                 frame);
    std::abort();
  }
  os::OusterConfig cfg;
  cfg.format = meta.format;
  os::OusterDecoder dec(cfg);
  std::vector<vd::FiringRecord> storage(os::kMaxColumnsPerFrame * os::kMaxPixelsPerColumn);
  vd::RevolutionAssembler rev(agv::Span<vd::FiringRecord>(storage.data(), storage.size()));
  std::vector<vd::FiringRecord> out(os::kMaxRecordsPerPacket);
  std::vector<agv::FiringReturn> returns(frame * os::kMaxRecordsPerPacket);
  std::size_t records = 0;
  std::size_t points = 0;
  for (auto _ : state) {
    records = 0;
    points = 0;
    rev.reset();
    for (std::size_t k = 0; k < frame; ++k) {
      std::size_t n = 0;
      benchmark::DoNotOptimize(dec.decode(agv::Span<const std::uint8_t>(packets[k].data(), packets[k].size()),
                                          agv::Span<vd::FiringRecord>(out.data(), out.size()), n));
      // Column by column: the assembler carries at most a Velodyne packet's records over a wrap.
      for (std::size_t i = 0; i < n;) {
        std::size_t j = i;
        while (j < n && out[j].block == out[i].block) {
          ++j;
        }
        benchmark::DoNotOptimize(rev.add(agv::Span<const vd::FiringRecord>(out.data() + i, j - i)));
        i = j;
      }
      std::size_t m = 0;
      benchmark::DoNotOptimize(
          os::toFiringReturns(agv::Span<const vd::FiringRecord>(out.data(), n), meta.intrinsics,
                              agv::Span<agv::FiringReturn>(returns.data() + points, returns.size() - points), m));
      records += n;
      points += m;
    }
    benchmark::DoNotOptimize(rev.finish());
    benchmark::ClobberMemory();
  }
  state.counters["records"] = static_cast<double>(records);
  state.counters["points"] = static_cast<double>(points);
}
BENCHMARK_CAPTURE(BM_OusterDecode, os2_128, "OS-2-128-U1_v2.3.0_1024x10", "OS-2-128-U1_v2.3.0_1024x10")
    ->Name("BM_OusterDecode/os2_128")
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_OusterDecode, os0_128, "OS-0-128-U1_v2.3.0_1024x10", "OS-0-128-U1_v2.3.0_1024x10")
    ->Name("BM_OusterDecode/os0_128")
    ->Unit(benchmark::kMillisecond);

}  // namespace
