#include "agv/lidar_calibration/recording_scans.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>

#include "agv/core/angle.hpp"
#include "agv/datasets/ouster_capture.hpp"
#include "agv/datasets/velodyne_recording.hpp"
#include "agv/drivers/protocol/velodyne/velodyne_encoder.hpp"

namespace agv::lidar_calibration {

namespace vd = drivers::velodyne;

namespace {

constexpr double kRadPerCount = kPi<double> / 18000.0;  // 0.01 deg
constexpr std::uint16_t kStartWindow = 100;             // 1 deg: a recording cut at a turn's start
constexpr std::size_t kStorage = 200000;                // records of one revolution (HDL-64E S2: ~134 000)

/// The container of `path` from its first bytes: "pcap", "rosbag2" or "payloads".
std::string containerOf(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  unsigned char head[16] = {};
  in.read(reinterpret_cast<char*>(head), sizeof head);
  const std::streamsize n = in.gcount();
  if (n >= 4) {
    const auto byte = [&](int k) { return static_cast<std::uint32_t>(head[k]); };
    const std::uint32_t le = byte(0) | (byte(1) << 8U) | (byte(2) << 16U) | (byte(3) << 24U);
    const std::uint32_t be = byte(3) | (byte(2) << 8U) | (byte(1) << 16U) | (byte(0) << 24U);
    for (const std::uint32_t magic : {0xa1b2c3d4U, 0xa1b23c4dU}) {
      if (le == magic || be == magic) {
        return "pcap";
      }
    }
  }
  if (n == 16 && std::string(reinterpret_cast<const char*>(head), 15) == "SQLite format 3") {
    return "rosbag2";
  }
  return "payloads";
}

/// The payloads of the recording, back to back.
bool readPayloads(const std::string& path, const RecordingScanOptions& options, const std::string& container,
                  datasets::PacketRecording& rec, std::string& error) {
  if (container == "rosbag2") {
    datasets::VelodyneScanBag bag;
    if (!datasets::readVelodyneScanBag(path, bag, error)) {
      return false;
    }
    rec = std::move(bag.packets);
    return true;
  }
  if (container == "pcap") {
    std::vector<std::vector<std::uint8_t>> payloads;
    datasets::PcapStats ps;
    if (!datasets::readPcapUdp(path, options.port, payloads, ps, error)) {
      return false;
    }
    rec.packetBytes = vd::kPacketBytes;
    for (const std::vector<std::uint8_t>& p : payloads) {
      if (p.size() != vd::kPacketBytes) {
        continue;  // not a data packet (a position packet on the same port is 512 bytes)
      }
      rec.bytes.insert(rec.bytes.end(), p.begin(), p.end());
      ++rec.packets;
    }
    if (rec.packets == 0) {
      error = path + ": no " + std::to_string(vd::kPacketBytes) + "-byte UDP payload to port " +
              std::to_string(options.port) + " among its " + std::to_string(ps.records) + " records";
      return false;
    }
    return true;
  }
  return datasets::readPacketRecording(path, vd::kPacketBytes, rec, error);
}

CalibrationScan toScan(const std::string& name, Span<const vd::FiringRecord> records, double resolution) {
  CalibrationScan scan;
  scan.name = name;
  scan.returns.reserve(records.size());
  for (const vd::FiringRecord& r : records) {
    if (r.secondReturn != 0 || r.distance == 0) {
      continue;
    }
    scan.returns.push_back(RawReturn{r.laser, r.azimuth * kRadPerCount, r.distance * resolution});
  }
  return scan;
}

}  // namespace

bool velodyneModelOf(std::size_t lasers, vd::Model& model) noexcept {
  for (const vd::Model m : {vd::Model::Vlp16, vd::Model::Hdl32e, vd::Model::Hdl64e}) {
    if (vd::laserCount(m) == lasers) {
      model = m;
      return true;
    }
  }
  return false;
}

bool readRecordingScans(const std::string& path, const LaserIntrinsics& intrinsics, const RecordingScanOptions& options,
                        std::vector<CalibrationScan>& out, RecordingStats& stats, std::string& error) {
  stats = RecordingStats{};
  vd::Model model = vd::Model::Vlp16;
  if (!velodyneModelOf(intrinsics.size(), model)) {
    error = "a table of " + std::to_string(intrinsics.size()) + " lasers is no Velodyne model (16, 32 or 64)";
    return false;
  }
  if (!std::ifstream(path, std::ios::binary)) {
    error = path + ": cannot be opened";
    return false;
  }
  stats.container = containerOf(path);
  datasets::PacketRecording rec;
  if (!readPayloads(path, options, stats.container, rec, error)) {
    return false;
  }
  stats.packets = rec.packets;
  vd::VelodyneConfig config;
  config.model = model;
  vd::VelodyneDecoder decoder(config);
  std::vector<vd::FiringRecord> storage(kStorage);
  vd::RevolutionAssembler assembler(Span<vd::FiringRecord>(storage.data(), storage.size()));
  vd::FiringRecord records[vd::kMaxRecordsPerPacket];
  std::size_t decoded = 0;
  for (std::size_t k = 0; k < rec.packets; ++k) {
    std::size_t n = 0;
    const Status st = decoder.decode(Span<const std::uint8_t>(rec.packet(k), rec.packetBytes),
                                     Span<vd::FiringRecord>(records, vd::kMaxRecordsPerPacket), n);
    if (st != Status::Ok && st != Status::Malformed) {
      continue;  // refused whole, counted by the decoder
    }
    ++decoded;
    if (!assembler.add(Span<const vd::FiringRecord>(records, n))) {
      continue;
    }
    ++stats.revolutions;
    const Span<const vd::FiringRecord> rev = assembler.revolution();
    const bool whole =
        assembler.info().complete || (assembler.revolutions() == 1 && rev.size() > 0 && rev[0].azimuth < kStartWindow);
    if (!whole) {
      ++stats.partial;
      continue;
    }
    if (options.maxRevolutions != 0 && stats.used >= options.maxRevolutions) {
      continue;
    }
    CalibrationScan scan =
        toScan(std::filesystem::path(path).filename().string() + "#rev" + std::to_string(assembler.revolutions() - 1),
               rev, intrinsics.distanceResolution());
    stats.returns += scan.returns.size();
    ++stats.used;
    out.push_back(std::move(scan));
  }
  if (assembler.finish()) {  // the records after the last wrap: cut by the end of the recording
    ++stats.revolutions;
    ++stats.partial;
  }
  const vd::VelodyneCounters& c = decoder.counters();
  stats.refusedPackets = c.refusedPackets();
  stats.skippedBlocks = c.badBlockId + c.badAzimuth;
  if (decoded == 0) {
    error = path + ": none of its " + std::to_string(rec.packets) + " packets is a data packet of a " +
            std::to_string(intrinsics.size()) + "-laser sensor (truncated " + std::to_string(c.truncated) +
            ", another product " + std::to_string(c.wrongProduct) + ")";
    return false;
  }
  if (stats.used == 0) {
    error = path + ": no whole revolution in " + std::to_string(rec.packets) + " packets (" +
            std::to_string(stats.revolutions) + " partial: a recording must span a turn from wrap to wrap)";
    return false;
  }
  return true;
}

bool writeRecording(const std::string& path, const CalibrationScan& scan, const LaserIntrinsics& intrinsics,
                    double& maxAzimuthRounding, std::string& error) {
  maxAzimuthRounding = 0.0;
  vd::Model model = vd::Model::Vlp16;
  if (!velodyneModelOf(intrinsics.size(), model) || model == vd::Model::Vlp16) {
    error = "recordings are written for HDL-32E and HDL-64E tables only (32 or 64 lasers), not " +
            std::to_string(intrinsics.size());
    return false;
  }
  const std::size_t lasers = intrinsics.size();
  const double res = intrinsics.distanceResolution();
  vd::VelodyneEncoder encoder(model);
  std::vector<std::uint8_t> bytes;
  std::vector<std::uint16_t> firing(lasers, 0);
  bool ready = false;
  auto emit = [&]() {
    if (ready) {
      const Span<const std::uint8_t> p = encoder.packet();
      bytes.insert(bytes.end(), p.data(), p.data() + p.size());
    }
  };
  std::size_t i = 0;
  double lastPhi = -1.0;
  while (i < scan.returns.size()) {
    const double phi = scan.returns[i].phi;
    if (!(phi >= 0.0 && phi < kTwoPi<double>) || phi <= lastPhi) {
      error = scan.name + ": return " + std::to_string(i) + ": phi " + std::to_string(phi) +
              " rad is outside [0, 2 pi) or not after the previous firing's";
      return false;
    }
    lastPhi = phi;
    std::fill(firing.begin(), firing.end(), std::uint16_t{0});
    for (; i < scan.returns.size() && scan.returns[i].phi == phi; ++i) {
      const RawReturn& r = scan.returns[i];
      const double counts = std::round(r.range / res);
      if (r.laser >= lasers || firing[r.laser] != 0 || !(counts >= 1.0 && counts <= 65535.0) ||
          std::fabs(counts * res - r.range) > 1e-9) {
        error = scan.name + ": return " + std::to_string(i) + " (laser " + std::to_string(r.laser) + ", range " +
                std::to_string(r.range) +
                " m) has no packet form: a laser outside the table or twice in one firing, or a range off the " +
                std::to_string(res * 1e3) + " mm grid or beyond 65535 counts";
        return false;
      }
      firing[r.laser] = static_cast<std::uint16_t>(counts);
    }
    const double centi = phi / kRadPerCount;
    const double az = std::round(centi);
    maxAzimuthRounding = std::max(maxAzimuthRounding, std::fabs(az - centi) * kRadPerCount);
    if (az >= vd::kAzimuthTurn) {
      error = scan.name + ": firing at phi " + std::to_string(phi) + " rad rounds to a whole turn (0.01 deg packets)";
      return false;
    }
    const auto azimuth = static_cast<std::uint16_t>(az);
    if (encoder.add(azimuth, Span<const std::uint16_t>(firing.data(), lasers), ready) != Status::Ok) {
      error = scan.name + ": firing at phi " + std::to_string(phi) + " rad not encoded";
      return false;
    }
    emit();
  }
  if (encoder.flush(ready) != Status::Ok) {
    error = scan.name + ": not encoded";
    return false;
  }
  emit();
  if (bytes.empty()) {
    error = scan.name + ": no return to write";
    return false;
  }
  bytes.insert(bytes.end(), bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(vd::kPacketBytes));
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  if (!f) {
    error = path + ": cannot be written";
    return false;
  }
  return true;
}

}  // namespace agv::lidar_calibration
