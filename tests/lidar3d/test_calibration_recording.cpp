// Calibration scans from recorded Velodyne data packets (agv::lidar_calibration recording_scans.hpp;
// docs/lidar-calibration.md, "Real recordings"): simulated placements written as HDL-64E packets
// read back as the very same returns (bare payloads and pcap) and calibrated to the same values as
// the simulation itself; refused recordings and tables by reason; the real einride VLP-16 recording
// cut into the revolutions its README describes.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <unistd.h>

#include "agv/core/angle.hpp"
#include "agv/datasets/velodyne_calibration.hpp"
#include "agv/drivers/protocol/velodyne/velodyne_packet.hpp"
#include "agv/lidar_calibration/hall_scans.hpp"
#include "agv/lidar_calibration/intrinsic_calibration.hpp"
#include "agv/lidar_calibration/recording_scans.hpp"
#include "agv/sim/calibration_hall.hpp"
#include "agv_test.hpp"

namespace {

namespace lc = agv::lidar_calibration;
namespace fs = std::filesystem;

const std::string kData = std::string(AGV_SHARED_DATA_DIR) + "/lidar3d";

agv::LaserIntrinsics& table(const std::string& name) {
  static agv::LaserIntrinsics hdl64;
  static agv::LaserIntrinsics vlp16;
  agv::LaserIntrinsics& t = name == "vlp16" ? vlp16 : hdl64;
  if (t.size() == 0) {
    std::string error;
    const std::string path =
        kData + (name == "vlp16" ? "/calibration/vlp16_db.yaml" : "/calibration/hdl64e_s2.1_sztaki.yaml");
    const bool ok = agv::datasets::readVelodyneCalibration(path, t, error);
    INFO(error);
    REQUIRE(ok);
  }
  return t;
}

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("agvnav-calibration-recording-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir / name;
}

std::vector<std::uint8_t> fileBytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::vector<std::uint8_t>(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void put(std::vector<std::uint8_t>& out, std::uint32_t v, int bytes, bool bigEndian = false) {
  for (int i = 0; i < bytes; ++i) {
    const int shift = bigEndian ? 8 * (bytes - 1 - i) : 8 * i;
    out.push_back(static_cast<std::uint8_t>((v >> shift) & 0xFFU));
  }
}

/// One pcap record (Ethernet / IPv4 / UDP to `port`) holding `payload`.
void pcapRecord(std::vector<std::uint8_t>& out, const std::uint8_t* payload, std::size_t n, std::uint16_t port) {
  const std::uint32_t frame = static_cast<std::uint32_t>(14 + 20 + 8 + n);
  put(out, 0, 4);  // ts sec
  put(out, 0, 4);  // ts usec
  put(out, frame, 4);
  put(out, frame, 4);
  for (int i = 0; i < 12; ++i)
    out.push_back(0);         // MAC addresses
  put(out, 0x0800, 2, true);  // IPv4
  out.push_back(0x45);        // version 4, 20-byte header
  out.push_back(0);
  put(out, static_cast<std::uint32_t>(20 + 8 + n), 2, true);
  put(out, 0, 2, true);  // id
  put(out, 0, 2, true);  // flags / fragment offset: not fragmented
  out.push_back(64);
  out.push_back(17);  // UDP
  put(out, 0, 2, true);
  put(out, 0xC0A8010A, 4, true);  // 192.168.1.10
  put(out, 0xFFFFFFFF, 4, true);
  put(out, 2368, 2, true);  // source port
  put(out, port, 2, true);
  put(out, static_cast<std::uint32_t>(8 + n), 2, true);
  put(out, 0, 2, true);
  out.insert(out.end(), payload, payload + n);
}

/// A reduced protocol whose firings lie on the packets' 0.01 deg grid (2000 per turn: 0.18 deg
/// steps from 0.09 deg) and whose ranges are quantised to the table's 2 mm.
lc::HallScansConfig gridProtocol(double noise) {
  lc::HallScansConfig c;
  c.placements = agv::sim::hallProtocol(3, 3.0, 22.0, 3, 0.0, agv::deg2rad(24.0));
  c.sensor.rangeNoise = noise;
  c.sensor.quantize = true;
  c.sensor.firings = 2000;
  c.sensor.azimuthWindow = agv::deg2rad(50.0);
  return c;
}

}  // namespace

TEST_CASE("simulated placements written as HDL-64E packets read back as the same returns and calibrate alike",
          "[lidar3d][lidar-calibration]") {
  std::mt19937_64 rng(5);
  const agv::LaserIntrinsics truth =
      agv::sim::perturbIntrinsics(table("hdl64"), 0.05, agv::deg2rad(0.3), agv::deg2rad(0.5), 0.0, rng);
  const std::vector<lc::CalibrationScan> scans = lc::simulateHallScans(gridProtocol(0.02), truth);
  std::vector<lc::CalibrationScan> read;
  std::string error;
  for (std::size_t s = 0; s < scans.size(); ++s) {
    const fs::path file = scratch("placement-" + std::to_string(s) + ".bin");
    double rounding = 1.0;
    REQUIRE(lc::writeRecording(file.string(), scans[s], truth, rounding, error));
    CHECK(rounding < 1e-12);  // on the grid: nothing rounded
    lc::RecordingStats stats;
    const bool ok =
        lc::readRecordingScans(file.string(), table("hdl64"), lc::RecordingScanOptions{}, read, stats, error);
    INFO(error);
    REQUIRE(ok);
    CHECK(stats.container == "payloads");
    CHECK(stats.used == 1U);
    CHECK(stats.refusedPackets == 0U);
    CHECK(stats.skippedBlocks == 0U);
    CHECK(stats.partial == 1U);  // the repeated first packet after the wrap
    CHECK(stats.returns == scans[s].returns.size());
  }
  REQUIRE(read.size() == scans.size());
  double worstPhi = 0.0;
  for (std::size_t s = 0; s < scans.size(); ++s) {
    REQUIRE(read[s].returns.size() == scans[s].returns.size());
    std::size_t differ = 0;
    for (std::size_t i = 0; i < scans[s].returns.size(); ++i) {
      const agv::RawReturn& a = scans[s].returns[i];
      const agv::RawReturn& b = read[s].returns[i];
      differ += a.laser != b.laser || a.range != b.range ? 1U : 0U;
      worstPhi = std::max(worstPhi, std::fabs(a.phi - b.phi));
    }
    CHECK(differ == 0U);
  }
  CHECK(worstPhi < 1e-12);

  lc::IntrinsicCalibrationConfig config;
  config.threads = 1;
  lc::IntrinsicCalibrationResult direct;
  lc::IntrinsicCalibrationResult recorded;
  REQUIRE(lc::calibrateIntrinsics(scans, table("hdl64"), config, direct, error));
  REQUIRE(lc::calibrateIntrinsics(read, table("hdl64"), config, recorded, error));
  REQUIRE(direct.lasers.size() == recorded.lasers.size());
  double worst = 0.0;
  for (std::size_t l = 0; l < direct.lasers.size(); ++l) {
    CHECK(direct.lasers[l].estimated == recorded.lasers[l].estimated);
    worst = std::max(
        worst,
        (agv::toVector(direct.lasers[l].estimate) - agv::toVector(recorded.lasers[l].estimate)).cwiseAbs().maxCoeff());
  }
  INFO("largest difference of an estimate " << worst);
  CHECK(worst < 1e-9);
  CHECK(direct.lasersEstimated == 64U);

  SECTION("the same packets in a pcap, among other traffic") {
    const std::vector<std::uint8_t> payloads = fileBytes(scratch("placement-0.bin"));
    const std::size_t n = payloads.size() / agv::drivers::velodyne::kPacketBytes;
    std::vector<std::uint8_t> pcap;
    put(pcap, 0xa1b2c3d4, 4);
    put(pcap, 2, 2);
    put(pcap, 4, 2);
    put(pcap, 0, 4);
    put(pcap, 0, 4);
    put(pcap, 65535, 4);
    put(pcap, 1, 4);  // Ethernet
    const std::uint8_t position[512] = {};
    for (std::size_t k = 0; k < n; ++k) {
      pcapRecord(pcap, payloads.data() + k * 1206, 1206, 2368);
      if (k == 3) {
        pcapRecord(pcap, position, sizeof position, 2368);  // a position packet: not a data packet
        pcapRecord(pcap, payloads.data(), 1206, 2369);      // another sensor's port
      }
    }
    const fs::path file = scratch("placement-0.pcap");
    std::ofstream(file, std::ios::binary)
        .write(reinterpret_cast<const char*>(pcap.data()), static_cast<std::streamsize>(pcap.size()));
    std::vector<lc::CalibrationScan> fromPcap;
    lc::RecordingStats stats;
    const bool ok =
        lc::readRecordingScans(file.string(), table("hdl64"), lc::RecordingScanOptions{}, fromPcap, stats, error);
    INFO(error);
    REQUIRE(ok);
    CHECK(stats.container == "pcap");
    CHECK(stats.packets == n);
    REQUIRE(fromPcap.size() == 1U);
    REQUIRE(fromPcap[0].returns.size() == read[0].returns.size());
    std::size_t differ = 0;
    for (std::size_t i = 0; i < read[0].returns.size(); ++i) {
      differ += fromPcap[0].returns[i].range != read[0].returns[i].range ||
                        fromPcap[0].returns[i].phi != read[0].returns[i].phi
                    ? 1U
                    : 0U;
    }
    CHECK(differ == 0U);
    lc::RecordingScanOptions otherPort;
    otherPort.port = 2370;
    fromPcap.clear();
    CHECK_FALSE(lc::readRecordingScans(file.string(), table("hdl64"), otherPort, fromPcap, stats, error));
    CHECK(error.find("port 2370") != std::string::npos);
  }
  fs::remove_all(scratch("x").parent_path());
}

TEST_CASE("recordings and tables that cannot be used are refused with the reason", "[lidar3d][lidar-calibration]") {
  std::mt19937_64 rng(6);
  const agv::LaserIntrinsics& hdl64 = table("hdl64");
  lc::HallScansConfig c = gridProtocol(0.0);
  c.placements.resize(1);
  const std::vector<lc::CalibrationScan> scans = lc::simulateHallScans(c, hdl64);
  REQUIRE(scans.size() == 1U);
  std::string error;
  double rounding = 0.0;
  std::vector<lc::CalibrationScan> out;
  lc::RecordingStats stats;
  const fs::path good = scratch("good.bin");
  REQUIRE(lc::writeRecording(good.string(), scans[0], hdl64, rounding, error));

  SECTION("a VLP-16 table is not written (its azimuths are interpolated per laser)") {
    CHECK_FALSE(lc::writeRecording(scratch("v.bin").string(), scans[0], table("vlp16"), rounding, error));
    CHECK(error.find("HDL-32E and HDL-64E") != std::string::npos);
  }
  SECTION("a range off the 2 mm grid has no packet form") {
    lc::CalibrationScan s = scans[0];
    s.returns[10].range += 0.0005;
    CHECK_FALSE(lc::writeRecording(scratch("g.bin").string(), s, hdl64, rounding, error));
    CHECK(error.find("grid") != std::string::npos);
  }
  SECTION("a firing going backwards is refused") {
    lc::CalibrationScan s = scans[0];
    std::swap(s.returns.front(), s.returns.back());
    CHECK_FALSE(lc::writeRecording(scratch("b.bin").string(), s, hdl64, rounding, error));
    CHECK(error.find("phi") != std::string::npos);
  }
  SECTION("a table of no Velodyne model") {
    agv::LaserIntrinsics twenty;
    REQUIRE(twenty.reset(20) == agv::Status::Ok);
    CHECK_FALSE(lc::readRecordingScans(good.string(), twenty, lc::RecordingScanOptions{}, out, stats, error));
    CHECK(error.find("no Velodyne model") != std::string::npos);
  }
  SECTION("HDL-64E packets read as a VLP-16's") {
    CHECK_FALSE(lc::readRecordingScans(good.string(), table("vlp16"), lc::RecordingScanOptions{}, out, stats, error));
    CHECK(error.find("none of its") != std::string::npos);
  }
  SECTION("a file that is not whole packets (a KITTI .bin)") {
    CHECK_FALSE(lc::readRecordingScans(kData + "/kitti00_hdl64/000094.bin", hdl64, lc::RecordingScanOptions{}, out,
                                       stats, error));
    CHECK(error.find("1206") != std::string::npos);
  }
  SECTION("a recording that never completes a turn") {
    std::vector<std::uint8_t> bytes = fileBytes(good);
    bytes.resize(bytes.size() / 2 / 1206 * 1206);  // the first half of the turn
    const fs::path half = scratch("half.bin");
    std::ofstream(half, std::ios::binary)
        .write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    CHECK_FALSE(lc::readRecordingScans(half.string(), hdl64, lc::RecordingScanOptions{}, out, stats, error));
    CHECK(error.find("no whole revolution") != std::string::npos);
    CHECK(stats.partial == 1U);
  }
  SECTION("a missing file") {
    CHECK_FALSE(
        lc::readRecordingScans(scratch("none.bin").string(), hdl64, lc::RecordingScanOptions{}, out, stats, error));
    CHECK(error.find("cannot be opened") != std::string::npos);
  }
  CHECK(out.empty());
  fs::remove_all(scratch("x").parent_path());
}

TEST_CASE("the real einride VLP-16 recording: the whole revolutions its README describes", "[lidar3d][realdata]") {
  // README: 1000 packets, 13 azimuth wrap-arounds at 10 Hz over 1.326 s, 203 034 returns.
  lc::RecordingScanOptions all;
  all.maxRevolutions = 0;
  std::vector<lc::CalibrationScan> scans;
  lc::RecordingStats stats;
  std::string error;
  const bool ok =
      lc::readRecordingScans(kData + "/vlp16_einride/recording.bin", table("vlp16"), all, scans, stats, error);
  INFO(error);
  REQUIRE(ok);
  CHECK(stats.packets == 1000U);
  CHECK(stats.refusedPackets == 0U);
  CHECK(stats.used == 12U);         // between 13 wraps
  CHECK(stats.revolutions == 14U);  // and the two cut by the recording's ends
  CHECK(stats.partial == 2U);
  REQUIRE(scans.size() == 12U);
  const double perTurn = 203034.0 / 13.26;  // returns per revolution from the README
  for (const lc::CalibrationScan& s : scans) {
    INFO(s.name << ": " << s.returns.size() << " returns");
    CHECK(std::fabs(static_cast<double>(s.returns.size()) - perTurn) < 0.05 * perTurn);
    for (const agv::RawReturn& r : s.returns) {
      if (!(r.laser < 16U && r.range >= 0.4 && r.range <= 12.5 && r.phi >= 0.0 && r.phi < agv::kTwoPi<double>)) {
        FAIL("return outside the README's ranges: laser " << r.laser << " range " << r.range << " phi " << r.phi);
      }
    }
  }
  // One revolution by default.
  std::vector<lc::CalibrationScan> one;
  REQUIRE(lc::readRecordingScans(kData + "/vlp16_einride/recording.bin", table("vlp16"), lc::RecordingScanOptions{},
                                 one, stats, error));
  CHECK(one.size() == 1U);
  CHECK(one[0].returns.size() == scans[0].returns.size());
}
