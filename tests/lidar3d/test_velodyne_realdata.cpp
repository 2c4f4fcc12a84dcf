// Velodyne decoding on the shared real data (host only): the factory calibration files through both
// parsers and the thesis' point model against points computed here by hand from the files' numbers;
// the einride VLP-16 recording against the counts its README states; the nebula VLP-16 bag's last
// message against nebula's own decoded cloud (.pcd). Paths from AGV_SHARED_DATA_DIR.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <string>
#include <vector>

#include "agv/datasets/velodyne_calibration.hpp"
#include "agv/datasets/velodyne_recording.hpp"
#include "agv/drivers/protocol/velodyne/velodyne_packet.hpp"
#include "agv_test.hpp"

using agv::LaserIntrinsics;
using agv::Span;
using agv::Status;
using namespace agv::drivers::velodyne;

namespace {
const std::string kDir = std::string(AGV_SHARED_DATA_DIR) + "/lidar3d/";
constexpr double kPi = 3.14159265358979323846;

std::vector<std::uint8_t> readBytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::vector<std::uint8_t>(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

LaserIntrinsics load(const std::string& file) {
  LaserIntrinsics t;
  std::string error;
  INFO(error);
  REQUIRE(agv::datasets::readVelodyneCalibration(kDir + "calibration/" + file, t, error));
  return t;
}

/// The thesis' model written out in double from raw file values (the xml's cm and degrees), then
/// the Velodyne frame mapped to REP-103 (x = Py, y = -Px).
struct Hand {
  double dCorrCm, vOffCm, hOffCm, thetaDeg, alphaDeg;
};
void handPoint(const Hand& h, std::uint16_t raw, double phiDeg, double out[3]) {
  const double d = raw * 0.002 + h.dCorrCm / 100.0;
  const double th = h.thetaDeg * kPi / 180.0;
  const double vo = h.vOffCm / 100.0;
  const double ho = h.hOffCm / 100.0;
  const double pz = d * std::sin(th) + vo * std::cos(th);
  const double dxy = d * std::cos(th) - vo * std::sin(th);
  const double beta = (phiDeg - h.alphaDeg) * kPi / 180.0;
  const double px = dxy * std::sin(beta) - ho * std::cos(beta);
  const double py = dxy * std::cos(beta) + ho * std::sin(beta);
  out[0] = py;
  out[1] = -px;
  out[2] = pz;
}
}  // namespace

TEST_CASE("Factory files: db.xml and YAML into one table, points by the thesis' model", "[lidar3d][velodyne]") {
  const LaserIntrinsics xml = load("hdl64e_s2.1_sztaki_db.xml");
  const LaserIntrinsics yaml = load("hdl64e_s2.1_sztaki.yaml");
  REQUIRE(xml.size() == 64U);
  REQUIRE(yaml.size() == 64U);
  CHECK(xml.distanceResolution() == Approx(0.002).epsilon(1e-12));
  // The two files of the SZTAKI unit are the same numbers (the YAML was converted from the xml;
  // the YAML prints them with float noise ~1e-9).
  for (std::size_t i = 0; i < 64; ++i) {
    AGV_CHECK_NEAR(xml.params(i).distCorrection, yaml.params(i).distCorrection, 1e-7);
    AGV_CHECK_NEAR(xml.params(i).vertOffset, yaml.params(i).vertOffset, 1e-7);
    AGV_CHECK_NEAR(xml.params(i).horizOffset, yaml.params(i).horizOffset, 1e-7);
    AGV_CHECK_NEAR(xml.params(i).theta, yaml.params(i).theta, 1e-7);
    AGV_CHECK_NEAR(xml.params(i).alpha, yaml.params(i).alpha, 1e-7);
  }
  // Lasers 0, 1 and 63 of the xml, copied from the file (cm, deg).
  const Hand h0{151.95264, 19.548199, 2.5999999, -8.7686234, -7.1559157};
  const Hand h1{151.45139, 19.601112, -2.5999999, -8.3563347, -3.967427};
  const Hand h63{143.29738, 12.086253, -2.5999999, -12.070212, 1.4242532};
  const std::pair<std::size_t, Hand> lasers[] = {{0, h0}, {1, h1}, {63, h63}};
  // Float arithmetic on ranges <= 130 m: 1e-6 relative is 0.13 mm; 20 um covers the ranges here.
  for (const auto& [id, h] : lasers) {
    for (const std::uint16_t raw : {std::uint16_t{1000}, std::uint16_t{5000}, std::uint16_t{30000}}) {
      for (const int az : {0, 4500, 12345, 27000, 35999}) {
        double e[3];
        handPoint(h, raw, az / 100.0, e);
        const Eigen::Vector3f p = xml.laserPoint(id, raw, static_cast<float>(az));
        const double tol = 2e-5 * std::max(1.0, std::hypot(e[0], e[1]) / 10.0);
        INFO("laser " << id << " raw " << raw << " az " << az);
        AGV_CHECK_NEAR(p.x(), e[0], tol);
        AGV_CHECK_NEAR(p.y(), e[1], tol);
        AGV_CHECK_NEAR(p.z(), e[2], tol);
      }
    }
  }
  // A point worked on paper: VLP-16 laser 1 (+1 deg, no offsets), raw 5000 = 10 m, phi = 90 deg
  // (to the right): Velodyne frame (10 cos 1 deg, 0, 10 sin 1 deg) = (9.99848, 0, 0.17452);
  // REP-103 (0, -9.99848, 0.17452).
  const LaserIntrinsics vlp = load("vlp16_db.yaml");
  REQUIRE(vlp.size() == 16U);
  const Eigen::Vector3f p = vlp.laserPoint(1, 5000, 9000.0F);
  AGV_CHECK_NEAR(p.x(), 0.0, 1e-5);
  AGV_CHECK_NEAR(p.y(), -9.998477, 1e-5);
  AGV_CHECK_NEAR(p.z(), 0.174524, 1e-5);
  // HDL-32E generic and the UT Austin HDL-64E: elevations from the files, first laser by hand.
  const LaserIntrinsics h32 = load("hdl32e_db.yaml");
  REQUIRE(h32.size() == 32U);
  AGV_CHECK_NEAR(h32.params(0).theta, -0.5352924815866609, 1e-15);
  const LaserIntrinsics ut = load("hdl64e_utexas.yaml");
  REQUIRE(ut.size() == 64U);
  double e[3];
  handPoint(Hand{10.0000001490116, 0.0, 0.0, -0.124932751059532 * 180.0 / kPi, -0.0698131695389748 * 180.0 / kPi}, 4000,
            300.0, e);
  const Eigen::Vector3f q = ut.laserPoint(0, 4000, 30000.0F);
  AGV_CHECK_NEAR(q.x(), e[0], 2e-5);
  AGV_CHECK_NEAR(q.y(), e[1], 2e-5);
  AGV_CHECK_NEAR(q.z(), e[2], 2e-5);
}

TEST_CASE("Calibration parsers refuse broken files by name", "[lidar3d][velodyne]") {
  LaserIntrinsics t;
  std::string error;
  CHECK_FALSE(agv::datasets::parseVelodyneYaml("lasers:\n- {laser_id: 0, rot_correction: 0.1}\n", t, error));
  CHECK(error.find("missing") != std::string::npos);
  CHECK_FALSE(agv::datasets::parseVelodyneYaml(
      "lasers:\n- {laser_id: 1, rot_correction: 0, vert_correction: 0, dist_correction: 0}\n", t, error));
  CHECK(error.find("outside") != std::string::npos);
  CHECK_FALSE(agv::datasets::parseVelodyneYaml(
      "lasers:\n- {laser_id: 0, rot_correction: x, vert_correction: 0, dist_correction: 0}\n", t, error));
  CHECK(error.find("rot_correction") != std::string::npos);
  CHECK_FALSE(agv::datasets::parseVelodyneYaml(
      "lasers:\n- {laser_id: 0, rot_correction: 0, vert_correction: 0, dist_correction: 0}\nnum_lasers: 2\n", t,
      error));
  CHECK(error.find("num_lasers") != std::string::npos);
  // Degrees where radians are expected (|theta| > pi) are refused by the table.
  CHECK_FALSE(agv::datasets::parseVelodyneYaml(
      "lasers:\n- {laser_id: 0, rot_correction: 0, vert_correction: -15, dist_correction: 0}\n", t, error));
  CHECK_FALSE(agv::datasets::parseVelodyneDbXml("<DB></DB>", t, error));
  CHECK(error.find("points_") != std::string::npos);
  CHECK_FALSE(agv::datasets::parseVelodyneDbXml(
      "<points_><px><id_>0</id_><rotCorrection_>1</rotCorrection_></px></points_>", t, error));
  CHECK(agv::datasets::parseVelodyneYaml(
      "lasers:\n- {laser_id: 0, rot_correction: 0, vert_correction: 0, dist_correction: 0}\n", t, error));
  CHECK(t.size() == 1U);
}

TEST_CASE("einride VLP-16 recording decodes to the counts its README states", "[lidar3d][velodyne][realdata]") {
  agv::datasets::PacketRecording recording;
  std::string error;
  INFO(error);
  REQUIRE(agv::datasets::readPacketRecording(kDir + "vlp16_einride/recording.bin", kPacketBytes, recording, error));
  REQUIRE(recording.packets == 1000U);  // README: 1000 packets, 1 206 000 bytes
  VelodyneDecoder dec(VelodyneConfig{});
  std::vector<FiringRecord> storage(40000);
  RevolutionAssembler rev(Span<FiringRecord>(storage.data(), storage.size()));
  FiringRecord out[kMaxRecordsPerPacket];
  std::size_t returns = 0;
  std::uint16_t minRaw = 0xFFFF;
  std::uint16_t maxRaw = 0;
  std::uint32_t wraps = 0;
  std::uint32_t completeRevs = 0;
  std::size_t revMin = 1U << 30U;
  std::size_t revMax = 0;
  int minStep = 36000;
  int maxStep = 0;
  int prevAz = -1;
  for (std::size_t k = 0; k < 1000; ++k) {
    const Span<const std::uint8_t> pkt(recording.packet(k), kPacketBytes);
    std::size_t n = 0;
    PacketInfo info;
    REQUIRE(dec.decode(pkt, Span<FiringRecord>(out), n, &info) == Status::Ok);
    CHECK(info.returnMode == ReturnMode::Strongest);
    returns += n;
    for (std::size_t i = 0; i < n; ++i) {
      minRaw = std::min(minRaw, out[i].distance);
      maxRaw = std::max(maxRaw, out[i].distance);
    }
    for (std::size_t b = 0; b < kBlocksPerPacket; ++b) {  // block azimuths straight from the bytes
      const int az = pkt[b * 100 + 2] | (pkt[b * 100 + 3] << 8);
      if (prevAz >= 0) {
        const int step = (az - prevAz + 36000) % 36000;
        minStep = std::min(minStep, step);
        maxStep = std::max(maxStep, step);
        wraps += az < prevAz ? 1U : 0U;
      }
      prevAz = az;
    }
    if (rev.add(Span<const FiringRecord>(out, n))) {
      CHECK(rev.info().refused == 0U);
      if (rev.info().complete) {
        ++completeRevs;
        revMin = std::min(revMin, rev.info().records);
        revMax = std::max(revMax, rev.info().records);
      }
    }
  }
  const VelodyneCounters& c = dec.counters();
  CHECK(c.packets == 1000U);
  CHECK(c.refusedPackets() == 0U);
  CHECK(c.badBlockId == 0U);  // README: 12 000 blocks, all 0xEEFF
  CHECK(c.badAzimuth == 0U);
  CHECK(returns == 203034U);  // README: 203 034 non-zero returns
  CHECK(returns + c.noReturn == 12000U * 32U);
  CHECK(wraps == 13U);  // README: 13 azimuth wrap-arounds
  CHECK(rev.revolutions() == 13U);
  CHECK(completeRevs == 12U);
  // README: block azimuth step 0.39-0.41 deg; the bytes hold 0.38 (837 of 11 999 steps) to 0.42
  // (269): the README's range is the bulk (89 %), the extremes are one count either side.
  CHECK(minStep == 38);
  CHECK(maxStep == 42);
  CHECK(minRaw * 0.002 >= 0.5);  // README: range 0.5-12.3 m (rounded to 0.1 m)
  CHECK(minRaw * 0.002 < 0.6);
  CHECK(maxRaw * 0.002 >= 12.25);
  CHECK(maxRaw * 0.002 < 12.35);
  WARN("einride: " << returns << " returns, " << rev.revolutions() << " revolutions, complete ones " << revMin << ".."
                   << revMax << " records");
}

namespace {
struct PcdPoint {
  float x, y, z;
  std::uint8_t intensity, returnType;
  std::uint16_t channel;
  float azimuth, elevation, distance;
  std::uint32_t time;
};
static_assert(sizeof(PcdPoint) == 32, "PCD record of the nebula file: 32 bytes");
}  // namespace

TEST_CASE("nebula VLP-16 message against nebula's decoded cloud", "[lidar3d][velodyne][realdata]") {
  agv::datasets::VelodyneScanBag bag;
  std::string error;
  INFO(error);
  REQUIRE(agv::datasets::readVelodyneScanBag(kDir + "vlp16_nebula/1673400471837873222_0.db3", bag, error));
  // README / metadata.yaml: 4 messages of 150-151 packets on /velodyne_packets, frame "velodyne".
  REQUIRE(bag.messages.size() == 4U);
  CHECK(bag.topic == "/velodyne_packets");
  CHECK(bag.packets.packetBytes == kPacketBytes);
  std::size_t inBag = 0;
  for (const agv::datasets::VelodyneScanMessage& msg : bag.messages) {
    CHECK(msg.frameId == "velodyne");
    CHECK(msg.packetCount >= 150U);
    CHECK(msg.packetCount <= 151U);
    CHECK(msg.firstPacket == inBag);
    inBag += msg.packetCount;
  }
  CHECK(bag.packets.packets == inBag);
  // metadata.yaml: the bag's messages span 300 143 486 ns from 1673400471837873222.
  CHECK(bag.messages.front().bagTimeNs == 1673400471837873222LL);
  CHECK(bag.messages.back().bagTimeNs - bag.messages.front().bagTimeNs == 300143486LL);
  const LaserIntrinsics cal = load("vlp16_db.yaml");
  float elev[16];
  std::uint16_t ring[16];
  for (std::size_t i = 0; i < 16; ++i)
    elev[i] = static_cast<float>(cal.params(i).theta);
  REQUIRE(agv::elevationRanks(Span<const float>(elev), Span<std::uint16_t>(ring)) == Status::Ok);

  VelodyneDecoder dec(VelodyneConfig{});
  struct Mine {
    FiringRecord r;
    Eigen::Vector3f p;
  };
  std::multimap<std::pair<int, int>, Mine> byRingAzimuth;  // (ring, azimuth) -> returns
  std::multimap<std::pair<int, int>, Mine> byNextAzimuth;  // second returns at the next pair's azimuth
  std::size_t packets = 0;
  FiringRecord out[kMaxRecordsPerPacket];
  for (std::size_t m = 1; m < 4; ++m) {  // the last message and two before (the cloud is cut elsewhere)
    const agv::datasets::VelodyneScanMessage& msg = bag.messages[m];
    for (std::size_t k = 0; k < msg.packetCount; ++k) {
      const std::uint8_t* pkt = bag.packets.packet(msg.firstPacket + k);
      std::size_t n = 0;
      PacketInfo info;
      REQUIRE(dec.decode(Span<const std::uint8_t>(pkt, kPacketBytes), Span<FiringRecord>(out), n, &info) == Status::Ok);
      CHECK(info.returnMode == ReturnMode::Dual);
      ++packets;
      for (std::size_t i = 0; i < n; ++i) {
        // Convention mapped: nebula does not interpolate the packet's last firing (blocks 10 and 11
        // of a dual-return packet: azimuth step 0); velodyne_pointcloud and we carry the previous
        // step on. For those records the comparison takes the block's azimuth from the bytes.
        FiringRecord r = out[i];
        if (r.block >= 10)
          r.azimuth = static_cast<std::uint16_t>(pkt[r.block * 100 + 2] | (pkt[r.block * 100 + 3] << 8));
        byRingAzimuth.insert({{ring[r.laser], r.azimuth}, Mine{r, cal.laserPoint(r.laser, r.distance, r.azimuth)}});
        // Second convention: for some second returns (odd block of a pair) nebula gives the next
        // pair's block azimuth. Those are matched separately and counted.
        if (r.secondReturn != 0U && r.block + 1U < kBlocksPerPacket) {
          const std::uint8_t* nb = pkt + (r.block + 1U) * 100U;
          const auto nextAz = static_cast<std::uint16_t>(nb[2] | (nb[3] << 8));
          FiringRecord rn = r;
          rn.azimuth = nextAz;
          byNextAzimuth.insert({{ring[r.laser], nextAz}, Mine{rn, cal.laserPoint(r.laser, r.distance, nextAz)}});
        }
      }
    }
  }
  CHECK(dec.counters().refusedPackets() == 0U);

  const std::vector<std::uint8_t> pcd = readBytes(kDir + "vlp16_nebula/1673400472138016708.pcd");
  const std::string head(pcd.begin(), pcd.begin() + 400);
  const std::size_t dataAt = head.find("DATA binary\n") + 12;
  REQUIRE((pcd.size() - dataAt) == 14831U * sizeof(PcdPoint));
  std::size_t matched = 0;
  std::size_t matchedNext = 0;
  std::size_t azOver = 0;
  std::size_t inexact = 0;
  std::size_t xyzOver = 0;
  double worstDist = 0.0;
  double worstAz = 0.0;
  double worstXyz = 0.0;
  for (std::size_t i = 0; i < 14831U; ++i) {
    PcdPoint q;
    std::memcpy(&q, pcd.data() + dataAt + i * sizeof q, sizeof q);
    // nebula's azimuth: radians, clockwise seen from above from +x (forward), = phi; channel =
    // ring in elevation order; its x y z are REP-103, like ours.
    const double azCd = q.azimuth * 18000.0 / kPi;
    const Mine* best = nullptr;
    double bestErr = 1e9;
    const auto nearest = [&](const std::multimap<std::pair<int, int>, Mine>& map) {
      best = nullptr;
      bestErr = 1e9;
      const int a0 = static_cast<int>(std::lround(azCd));
      for (int a = a0 - 1; a <= a0 + 1; ++a) {
        const auto range = map.equal_range({q.channel, (a + 36000) % 36000});
        for (auto it = range.first; it != range.second; ++it) {
          const double err = std::fabs(it->second.r.distance * 0.002 - q.distance);
          if (err < bestErr) {
            bestErr = err;
            best = &it->second;
          }
        }
      }
      return best != nullptr && bestErr <= 0.002;
    };
    if (!nearest(byRingAzimuth) && nearest(byNextAzimuth)) {
      ++matchedNext;
    }
    if (best == nullptr || bestErr > 0.002) {
      UNSCOPED_INFO("unmatched: channel " << q.channel << " azimuth " << azCd / 100.0 << " deg distance "
                                          << q.distance);
      continue;
    }
    ++matched;
    const double dAz = std::fabs(std::remainder(best->r.azimuth - azCd, 36000.0)) / 100.0;
    worstDist = std::max(worstDist, bestErr);
    worstAz = std::max(worstAz, dAz);
    azOver += dAz > 0.01 ? 1U : 0U;
    inexact += bestErr > 1e-5 ? 1U : 0U;
    // nebula's x y z come from its own azimuth: the points differ by at most the azimuth
    // difference times the horizontal range (+ float noise).
    const double xyz = static_cast<double>((best->p - Eigen::Vector3f(q.x, q.y, q.z)).norm());
    xyzOver += xyz > 1e-4 + q.distance * (dAz * kPi / 180.0) + bestErr ? 1U : 0U;
    worstXyz = std::max(worstXyz, static_cast<double>((best->p - Eigen::Vector3f(q.x, q.y, q.z)).norm()));
  }
  WARN("nebula: " << packets << " packets decoded, " << matched << " of 14831 points matched (" << matchedNext
                  << " of them at the next pair's azimuth), " << azOver << " beyond 0.01 deg, " << inexact
                  << " distances not equal, " << xyzOver << " points beyond their bound; worst |d distance| "
                  << worstDist << " m, |d azimuth| " << worstAz << " deg, |d xyz| " << worstXyz << " m");
  CHECK(matched == 14831U);
  CHECK(worstDist <= 0.002 + 1e-6);  // nebula's distance is a float32 of raw * 0.002
  // 0.01 deg = one count of the packet's azimuth (the two decoders round the interpolation
  // differently) + 2e-5 deg: nebula stores the azimuth as float32 radians (ulp at 2 pi: 2.7e-5 deg).
  CHECK(worstAz <= 0.01 + 2e-5);
  CHECK(xyzOver == 0U);
}
