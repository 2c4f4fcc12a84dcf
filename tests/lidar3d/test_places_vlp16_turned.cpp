// agvnav-lidar-places' packet path (runPlaces, --format vlp16) against a known turn: the einride
// VLP-16 recording followed by a copy whose block azimuths are all shifted by a known angle (the
// sensor turned counter-clockwise by that angle: every object is seen at phi + shift, phi growing
// clockwise). The relative yaw between the last revolution of the original and the first of the
// turned copy must be the shift (within 0.5 deg, the bound for a scan turned by a known
// angle); the revolutions within each file stay 0 deg apart (a static scene). Host only.
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "agv/core/angle.hpp"
#include "agv/datasets/velodyne_recording.hpp"
#include "agv/drivers/protocol/velodyne/velodyne_packet.hpp"
#include "agv_test.hpp"
#include "places.hpp"

namespace {
const std::string kRecording = std::string(AGV_SHARED_DATA_DIR) + "/lidar3d/vlp16_einride/recording.bin";
const std::string kCalibration = std::string(AGV_SHARED_DATA_DIR) + "/lidar3d/calibration/vlp16_db.yaml";

/// Writes the recording with every block azimuth shifted by `shift` counts (0.01 deg) to `path`.
void writeTurned(const agv::datasets::PacketRecording& rec, int shift, const std::string& path) {
  std::vector<std::uint8_t> b = rec.bytes;
  for (std::size_t k = 0; k < rec.packets; ++k) {
    for (std::size_t blk = 0; blk < agv::drivers::velodyne::kBlocksPerPacket; ++blk) {
      std::uint8_t* p = b.data() + k * rec.packetBytes + blk * 100 + 2;
      const int az = p[0] | (p[1] << 8);
      const int turned = ((az + shift) % 36000 + 36000) % 36000;
      p[0] = static_cast<std::uint8_t>(turned & 0xFF);
      p[1] = static_cast<std::uint8_t>(turned >> 8);
    }
  }
  std::ofstream f(path, std::ios::binary);
  f.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
  REQUIRE(f.good());
}
}  // namespace

TEST_CASE("VLP-16 packets through agvnav-lidar-places: a known turn is recovered with its sign",
          "[lidar3d][velodyne][realdata]") {
  agv::datasets::PacketRecording rec;
  std::string error;
  INFO(error);
  REQUIRE(agv::datasets::readPacketRecording(kRecording, agv::drivers::velodyne::kPacketBytes, rec, error));
  for (const int shift : {4500, -10025, 17000}) {
    const std::string turned = "/tmp/agvnav_places_turned_" + std::to_string(::getpid()) + ".bin";
    writeTurned(rec, shift, turned);
    agv::places::PlacesOptions o;
    o.format = agv::places::Format::Vlp16Packets;
    o.files = {kRecording, turned};
    o.calibrationPath = kCalibration;
    o.signature.normals.laserStep = 1;
    agv::places::PlacesResult r;
    const bool ok = agv::places::runPlaces(o, r, error);
    std::remove(turned.c_str());
    REQUIRE(ok);
    // Two files of 13 cuts each, the first of each begun mid-turn.
    REQUIRE(r.scans.size() == 24U);
    CHECK(r.packets.packets == 2000U);
    CHECK(r.packets.incomplete == 2U);
    INFO("shift " << shift / 100.0 << " deg");
    for (std::size_t i = 1; i < r.scans.size(); ++i) {
      REQUIRE(r.scans[i].hasStepYaw);
      const double expected = i == 12 ? agv::deg2rad(shift / 100.0) : 0.0;
      INFO("revolution " << i << ": yaw from the previous " << agv::rad2deg(r.scans[i].stepYaw) << " deg");
      CHECK(std::fabs(agv::rad2deg(agv::angleDiff(r.scans[i].stepYaw, expected))) < 0.5);
    }
    WARN("shift " << shift / 100.0 << " deg: recovered " << agv::rad2deg(r.scans[12].stepYaw) << " deg");
  }
}
