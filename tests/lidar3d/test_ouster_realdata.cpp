// Ouster OS-series decoding on the shared real captures (../shared/data/lidar3d/ouster_pcaps/):
// every capture through the pcap reader, the unit's JSON, the packet decoder and the Velodyne
// revolution assembler; frame / column / packet counts and valid pixels against the folder's
// README; the beam model against a hand computation from raw bytes; and, as a real check of the
// factory intrinsics, per-beam residuals to the biggest wall (RANSAC + PCA refit). Expected values
// come from the README and the JSON, never from the code under test; last, the conditioning of one
// placement (per-beam sigma of range offset / elevation / azimuth offset, the plane fixed and jointly
// with the plane). Figures: docs/ouster.md.
#include <algorithm>
#include <array>
#include <chrono>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "agv/datasets/ouster_capture.hpp"
#include "agv/drivers/protocol/ouster/ouster_packet.hpp"
#include "agv_test.hpp"

using namespace agv;
using namespace agv::drivers::ouster;
using agv::datasets::OusterMetadata;

namespace {
const std::string kDir = std::string(AGV_SHARED_DATA_DIR) + "/lidar3d/ouster_pcaps/";

struct Capture {
  const char* json;
  const char* pcap;
  const char* profile;  // README table
  std::size_t beams;    // README table
  std::size_t frames;   // README table
};
const Capture kCaptures[] = {
    {"OS-0-128-U1_v2.3.0_1024x10", "OS-0-128-U1_v2.3.0_1024x10", "RNG15_RFL8_NIR8", 128, 1},
    {"OS-2-128-U1_v2.3.0_1024x10", "OS-2-128-U1_v2.3.0_1024x10", "RNG19_RFL8_SIG16_NIR16", 128, 1},
    {"OS-1-128_v2.3.0_1024x10", "OS-1-128_v2.3.0_1024x10_lb_n3", "RNG15_RFL8_NIR8", 128, 3},
    {"OS-1-32-G_v2.1.1_1024x10", "OS-1-32-G_v2.1.1_1024x10", "LEGACY", 32, 1},
    {"OS-2-32-U0_v2.0.0_1024x10", "OS-2-32-U0_v2.0.0_1024x10", "LEGACY", 32, 1},
    {"OS-0-32-U1_v2.2.0_1024x10", "OS-0-32-U1_v2.2.0_1024x10", "RNG19_RFL8_SIG16_NIR16_DUAL", 32, 1},
};

struct Loaded {
  OusterMetadata meta;
  std::vector<std::vector<std::uint8_t>> packets;
};

Loaded load(const Capture& c) {
  Loaded l;
  std::string error;
  INFO(error);
  REQUIRE(datasets::readOusterMetadata(kDir + c.json + ".json", l.meta, error));
  datasets::PcapStats stats;
  REQUIRE(datasets::readPcapUdp(kDir + c.pcap + ".pcap", 7502, l.packets, stats, error));
  return l;
}

// The packet size from the README's layout description (not from the decoder).
std::size_t readmePacketBytes(const std::string& profile, std::size_t h, std::size_t cols) {
  if (profile == "LEGACY") {
    return cols * (16 + 12 * h + 4);
  }
  const std::size_t px = profile == "RNG15_RFL8_NIR8" ? 4 : profile == "RNG19_RFL8_SIG16_NIR16" ? 12 : 16;
  return 32 + cols * (12 + h * px) + 32;
}

struct Frame {
  std::vector<FiringRecord> records;
  std::vector<Eigen::Vector3d> points;  // sensor frame [m]
  std::vector<int> beam;
  std::vector<std::size_t> record;  // index into records
};

// Decodes every packet; one Frame per revolution of the assembler (fed column by column).
std::vector<Frame> decodeFrames(const Loaded& l, OusterCounters& counters, std::set<std::uint16_t>& frameIds,
                                std::map<std::uint16_t, std::set<std::uint16_t>>& columnsOfFrame) {
  OusterConfig cfg;
  cfg.format = l.meta.format;
  OusterDecoder dec(cfg);
  static std::vector<FiringRecord> storage(1024 * 128 * 2);
  drivers::velodyne::RevolutionAssembler rev(Span<FiringRecord>(storage.data(), storage.size()));
  std::vector<FiringRecord> out(kMaxRecordsPerPacket);
  std::vector<Frame> frames;
  auto take = [&]() {
    Frame f;
    const auto r = rev.revolution();
    f.records.assign(r.begin(), r.end());
    for (const FiringRecord& rec : f.records) {
      float xyz[3];
      if (ousterPoint(l.meta.intrinsics, rec, true, xyz) == Status::Ok) {
        f.points.emplace_back(xyz[0], xyz[1], xyz[2]);
        f.beam.push_back(rec.laser);
        f.record.push_back(static_cast<std::size_t>(&rec - f.records.data()));
      }
    }
    frames.push_back(std::move(f));
  };
  for (const auto& p : l.packets) {
    std::size_t n = 0;
    PacketInfo info;
    const Status st =
        dec.decode(Span<const std::uint8_t>(p.data(), p.size()), Span<FiringRecord>(out.data(), out.size()), n, &info);
    REQUIRE((st == Status::Ok || st == Status::Malformed));
    for (std::size_t c = 0; c < info.columnCount; ++c) {
      if (info.columns[c].valid) {
        frameIds.insert(info.columns[c].frameId);
        columnsOfFrame[info.columns[c].frameId].insert(info.columns[c].measurementId);
      }
    }
    // One column at a time: the assembler carries at most a Velodyne packet's records over a wrap.
    std::size_t i = 0;
    while (i < n) {
      std::size_t j = i;
      while (j < n && out[j].block == out[i].block) {
        ++j;
      }
      if (rev.add(Span<const FiringRecord>(out.data() + i, j - i))) {
        take();
      }
      i = j;
    }
  }
  if (rev.finish()) {
    take();
  }
  counters = dec.counters();
  return frames;
}

std::vector<Frame> decodeFrames(const Loaded& l) {
  OusterCounters k;
  std::set<std::uint16_t> ids;
  std::map<std::uint16_t, std::set<std::uint16_t>> cols;
  return decodeFrames(l, k, ids, cols);
}

struct PlaneFit {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double d = 0.0;  // n.p + d = 0
  std::vector<std::size_t> inliers;
};

PlaneFit refit(const std::vector<Eigen::Vector3d>& pts, const std::vector<std::size_t>& idx) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (std::size_t i : idx) {
    c += pts[i];
  }
  c /= static_cast<double>(idx.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (std::size_t i : idx) {
    cov += (pts[i] - c) * (pts[i] - c).transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  PlaneFit f;
  f.normal = es.eigenvectors().col(0).normalized();
  f.d = -f.normal.dot(c);
  return f;
}

// Biggest plane whose normal is horizontal (wall) or vertical (ground), RANSAC with a 5 cm
// threshold, then two PCA refits on the inliers. Deterministic (fixed seed).
PlaneFit biggestPlane(const std::vector<Eigen::Vector3d>& pts, bool wall, double minRange) {
  std::vector<std::size_t> cand;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (pts[i].norm() > minRange) {
      cand.push_back(i);
    }
  }
  std::mt19937 rng(19);
  std::uniform_int_distribution<std::size_t> pick(0, cand.size() - 1);
  PlaneFit best;
  for (int it = 0; it < 3000; ++it) {
    const Eigen::Vector3d a = pts[cand[pick(rng)]];
    const Eigen::Vector3d b = pts[cand[pick(rng)]];
    const Eigen::Vector3d c = pts[cand[pick(rng)]];
    Eigen::Vector3d n = (b - a).cross(c - a);
    if (n.norm() < 1e-6) {
      continue;
    }
    n.normalize();
    if (wall ? std::fabs(n.z()) > 0.1 : std::fabs(n.z()) < 0.95) {
      continue;
    }
    const double d = -n.dot(a);
    std::size_t count = 0;
    for (std::size_t i : cand) {
      count += std::fabs(n.dot(pts[i]) + d) < 0.05 ? 1U : 0U;
    }
    if (count > best.inliers.size()) {
      best.normal = n;
      best.d = d;
      best.inliers.clear();
      for (std::size_t i : cand) {
        if (std::fabs(n.dot(pts[i]) + d) < 0.05) {
          best.inliers.push_back(i);
        }
      }
    }
  }
  for (int k = 0; k < 2 && best.inliers.size() >= 3; ++k) {
    PlaneFit f = refit(pts, best.inliers);
    for (std::size_t i : cand) {
      if (std::fabs(f.normal.dot(pts[i]) + f.d) < 0.05) {
        f.inliers.push_back(i);
      }
    }
    best = f;
  }
  return best;
}

struct BeamResidual {
  int beam;
  std::size_t n;
  double rms;
  double median;
};

std::vector<BeamResidual> perBeam(const Frame& f, const PlaneFit& p) {
  std::map<int, std::vector<double>> res;
  for (std::size_t i : p.inliers) {
    res[f.beam[i]].push_back(p.normal.dot(f.points[i]) + p.d);
  }
  std::vector<BeamResidual> out;
  for (auto& [beam, r] : res) {
    if (r.size() < 20) {
      continue;
    }
    double s = 0.0;
    for (double v : r) {
      s += v * v;
    }
    std::sort(r.begin(), r.end());
    out.push_back({beam, r.size(), std::sqrt(s / static_cast<double>(r.size())), r[r.size() / 2]});
  }
  return out;
}
}  // namespace

TEST_CASE("every Ouster capture decodes: frames, columns, packets, valid pixels", "[ouster][realdata]") {
  for (const Capture& c : kCaptures) {
    INFO(c.pcap);
    const Loaded l = load(c);
    CHECK(l.meta.profileName == c.profile);
    REQUIRE(l.meta.format.pixelsPerColumn == c.beams);
    REQUIRE(l.meta.format.columnsPerFrame == 1024);  // every file name says 1024xN
    const std::size_t bytes = readmePacketBytes(c.profile, c.beams, l.meta.format.columnsPerPacket);
    CHECK(packetBytes(l.meta.format) == bytes);
    CHECK(l.packets.size() == 64 * c.frames);  // README: 64 lidar packets per frame
    for (const auto& p : l.packets) {
      REQUIRE(p.size() == bytes);
    }
    OusterCounters k;
    std::set<std::uint16_t> ids;
    std::map<std::uint16_t, std::set<std::uint16_t>> cols;
    const std::vector<Frame> frames = decodeFrames(l, k, ids, cols);
    CHECK(k.refusedPackets() == 0);
    CHECK(k.packets == l.packets.size());
    CHECK(ids.size() == c.frames);
    REQUIRE(frames.size() == c.frames);
    for (const auto& [id, set] : cols) {
      CHECK(set.size() == 1024);  // all columns of each frame
    }
    for (const Frame& f : frames) {
      std::set<std::uint16_t> az;
      for (const FiringRecord& r : f.records) {
        az.insert(r.azimuth);
      }
      const double valid = static_cast<double>(f.records.size());
      const double fraction = valid / (1024.0 * static_cast<double>(c.beams));
      std::printf(
          "%-36s %-28s frame: %zu records (%.1f %% of %zu x 1024), %zu columns, %u invalid columns, "
          "%u beyond 131 m\n",
          c.pcap, c.profile, f.records.size(), 100.0 * fraction, c.beams, az.size(), k.invalidColumns,
          k.beyondRecordRange);
      CHECK(az.size() >= 1000);  // nearly every column has a return
      // README: valid pixels per frame 21.6k (OS-0-32 dual) to 119.7k (OS-2-128).
      CHECK(valid >= 21000.0);
      CHECK(valid <= 120500.0);
    }
    // Column timestamps against the JSON's lidar_mode "WxR" (R frames per second).
    {
      std::uint64_t tFirst = 0;
      std::uint64_t tLast = 0;
      unsigned mFirst = 0;
      unsigned mLast = 0;
      bool any = false;
      OusterConfig tc;
      tc.format = l.meta.format;
      OusterDecoder td(tc);
      std::vector<FiringRecord> tout(kMaxRecordsPerPacket);
      for (std::size_t pk = 0; pk < 64; ++pk) {  // the first frame
        PacketInfo info;
        std::size_t n = 0;
        REQUIRE(td.decode(Span<const std::uint8_t>(l.packets[pk].data(), l.packets[pk].size()),
                          Span<FiringRecord>(tout.data(), tout.size()), n, &info) == Status::Ok);
        for (std::size_t k2 = 0; k2 < info.columnCount; ++k2) {
          const ColumnHeader& h = info.columns[k2];
          if (!any || h.measurementId < mFirst) {
            mFirst = h.measurementId;
            tFirst = h.timestampNs;
          }
          if (!any || h.measurementId > mLast) {
            mLast = h.measurementId;
            tLast = h.timestampNs;
          }
          any = true;
        }
      }
      const std::size_t x = l.meta.lidarMode.find('x');
      REQUIRE(x != std::string::npos);
      const double rate = std::stod(l.meta.lidarMode.substr(x + 1));
      const double frameS = static_cast<double>(tLast - tFirst) / static_cast<double>(mLast - mFirst) * 1024.0 * 1e-9;
      std::printf("%-36s lidar_mode %s: frame period from the column timestamps %.2f ms\n", c.pcap,
                  l.meta.lidarMode.c_str(), 1000.0 * frameS);
      CHECK(std::fabs(frameS * rate - 1.0) < 0.01);
    }
    if (std::string(c.pcap).find("lb_n3") != std::string::npos) {
      CHECK(*ids.begin() == 1795);  // README: frame_id 1795-1797
      CHECK(*ids.rbegin() == 1797);
    }
    if (std::string(c.pcap).rfind("OS-2-128", 0) == 0) {
      CHECK(std::fabs(static_cast<double>(frames[0].records.size()) - 119700.0) < 300.0);
    }
    if (std::string(c.pcap).rfind("OS-0-32", 0) == 0) {
      CHECK(std::fabs(static_cast<double>(frames[0].records.size()) - 21600.0) < 300.0);
    }
  }
}

TEST_CASE("Ouster beam model matches a hand computation from the raw LEGACY bytes", "[ouster][realdata]") {
  const Loaded l = load(kCaptures[3]);  // OS-1-32-G, LEGACY
  const auto& p = l.packets[10];
  OusterConfig cfg;
  cfg.format = l.meta.format;
  OusterDecoder dec(cfg);
  std::vector<FiringRecord> out(kMaxRecordsPerPacket);
  std::size_t n = 0;
  REQUIRE(dec.decode(Span<const std::uint8_t>(p.data(), p.size()), Span<FiringRecord>(out.data(), out.size()), n) ==
          Status::Ok);
  // JSON values read here again in degrees and mm, the README's equations in double.
  const double alt[32] = {12.75, 10.03, 7.27,  4.47,  3.41,  2.35,  2.02,   1.65,   1.29,   0.93,  0.6,
                          0.23,  -0.13, -0.49, -0.83, -1.17, -1.54, -1.88,  -2.24,  -2.6,   -2.96, -3.65,
                          -4.36, -5.06, -5.76, -7.17, -8.57, -9.95, -11.31, -12.66, -14.01, -15.32};
  const double az[32] = {-4.22, -4.23, -4.24, -4.24, -1.43, 1.44, -1.42, -4.24, 4.27,  1.4,  -1.41,
                         -4.23, 4.24,  1.37,  -1.42, -4.23, 4.25, 1.41,  -1.42, -4.24, 4.25, -1.43,
                         4.25,  -1.42, 4.26,  4.25,  4.25,  4.23, 4.24,  4.24,  4.24,  4.24};
  const double nmm = 15.806;
  const double pi = 3.14159265358979323846;
  std::size_t k = 0;
  std::size_t checked = 0;
  for (std::size_t col = 0; col < 16; ++col) {
    const std::uint8_t* c = p.data() + col * (16 + 12 * 32 + 4);
    const unsigned m = c[8] | (c[9] << 8U);
    for (std::size_t row = 0; row < 32; ++row) {
      const std::uint8_t* px = c + 16 + 12 * row;
      const std::uint32_t r =
          (px[0] | (px[1] << 8U) | (px[2] << 16U) | (static_cast<std::uint32_t>(px[3]) << 24U)) & 0xFFFFFU;
      if (r == 0) {
        continue;
      }
      REQUIRE(k < n);
      const FiringRecord& rec = out[k++];
      REQUIRE(rec.laser == row);
      const double te = 2.0 * pi * (1.0 - m / 1024.0);
      const double th = te - az[row] * pi / 180.0;
      const double ph = alt[row] * pi / 180.0;
      const double x = (r - nmm) * std::cos(th) * std::cos(ph) + nmm * std::cos(te);
      const double y = (r - nmm) * std::sin(th) * std::cos(ph) + nmm * std::sin(te);
      const double z = (r - nmm) * std::sin(ph);
      float xyz[3];
      REQUIRE(ousterPoint(l.meta.intrinsics, rec, false, xyz) == Status::Ok);
      // 1 mm: the record's 2 mm counts round the range by at most 1 mm; float adds < 0.1 mm.
      CHECK(std::fabs(xyz[0] * 1000.0 - x) < 1.1);
      CHECK(std::fabs(xyz[1] * 1000.0 - y) < 1.1);
      CHECK(std::fabs(xyz[2] * 1000.0 - z) < 1.1);
      // Sensor frame: lidar_to_sensor_transform is a half turn about z and +36.18 mm in z.
      float s[3];
      REQUIRE(ousterPoint(l.meta.intrinsics, rec, true, s) == Status::Ok);
      CHECK(std::fabs(s[0] + xyz[0]) < 1e-6);
      CHECK(std::fabs(s[1] + xyz[1]) < 1e-6);
      CHECK(std::fabs(s[2] - xyz[2] - 0.03618F) < 1e-5);
      ++checked;
    }
  }
  CHECK(k == n);
  CHECK(checked > 100);
}

TEST_CASE("Ouster walls: per-beam plane residuals with the factory intrinsics", "[ouster][realdata]") {
  // README: OS-2-128 wall at 10.9 m (117 of 128 beams, per-beam median -8..+12 mm), OS-0-128 wall
  // at 10.9 m, OS-0-32 wall at 4.2 m; lb_n3 ground ~1.9-2.0 m below the sensor.
  struct Wall {
    std::size_t capture;
    double distance;
    std::size_t minBeams;
    double medianBound;  // |per-beam median| [m]
    double rmsBound;     // per-beam RMS [m]
  };
  // OS-2-128 and OS-0-32: 2 cm (the README's independent fit: -8..+12 mm on the OS-2-128).
  // OS-0-128: its upper beams 6..24 (28..41 deg up, hitting the wall 5.8..9.5 m above the sensor)
  // sit 16..37 mm in front of the plane, beams 30, 34, 45 17 mm behind: an elevation-dependent
  // bias this test records but cannot attribute (facade not flat over 9 m, or the OS-0's beam
  // model: docs/ouster.md); bound 5 cm so that a wrong model (decimetres) still fails.
  const Wall walls[] = {{1, 10.9, 100, 0.02, 0.03}, {0, 10.9, 40, 0.05, 0.04}, {5, 4.2, 10, 0.02, 0.03}};
  for (const Wall& w : walls) {
    const Capture& c = kCaptures[w.capture];
    INFO(c.pcap);
    const Loaded l = load(c);
    const std::vector<Frame> frames = decodeFrames(l);
    REQUIRE(!frames.empty());
    const Frame& f = frames[0];
    const PlaneFit p = biggestPlane(f.points, true, 1.0);
    const double dist = std::fabs(p.d);
    const std::vector<BeamResidual> beams = perBeam(f, p);
    double worstRms = 0.0;
    double minMed = 1.0;
    double maxMed = -1.0;
    double sum2 = 0.0;
    std::size_t total = 0;
    for (const BeamResidual& b : beams) {
      worstRms = std::max(worstRms, b.rms);
      minMed = std::min(minMed, b.median);
      maxMed = std::max(maxMed, b.median);
      sum2 += b.rms * b.rms * static_cast<double>(b.n);
      total += b.n;
    }
    std::printf(
        "%-36s wall at %.3f m: %zu inliers, %zu beams with >= 20 points; per-beam RMS overall %.1f mm, "
        "worst %.1f mm; per-beam median %+.1f .. %+.1f mm\n",
        c.pcap, dist, p.inliers.size(), beams.size(), 1000.0 * std::sqrt(sum2 / static_cast<double>(total)),
        1000.0 * worstRms, 1000.0 * minMed, 1000.0 * maxMed);
    for (const BeamResidual& b : beams) {
      std::printf("  beam %3d: %5zu points, RMS %5.1f mm, median %+5.1f mm\n", b.beam, b.n, 1000.0 * b.rms,
                  1000.0 * b.median);
    }
    CHECK(std::fabs(dist - w.distance) < 0.3);
    CHECK(beams.size() >= w.minBeams);
    CHECK(minMed > -w.medianBound);
    CHECK(maxMed < w.medianBound);
    CHECK(worstRms < w.rmsBound);  // inliers are within 5 cm
  }
  // Ground under the moving OS-1-128: 1.9-2.0 m below the sensor in every frame.
  const Loaded l = load(kCaptures[2]);
  const std::vector<Frame> frames = decodeFrames(l);
  REQUIRE(frames.size() == 3);
  for (const Frame& f : frames) {
    const PlaneFit g = biggestPlane(f.points, false, 1.0);
    const double below = g.normal.z() > 0 ? g.d : -g.d;  // height of the origin above the plane
    std::printf("OS-1-128 lb_n3 ground: %.3f m below the sensor frame origin, %zu inliers\n", below, g.inliers.size());
    CHECK(below > 1.8);
    CHECK(below < 2.1);
    CHECK(g.inliers.size() > 15000);
  }
}

TEST_CASE("Ouster decoder refuses truncated, oversized and garbage packets and skips bad columns",
          "[ouster][realdata]") {
  const Loaded l = load(kCaptures[1]);  // OS-2-128, RNG19
  OusterConfig cfg;
  cfg.format = l.meta.format;
  OusterDecoder dec(cfg);
  std::vector<FiringRecord> out(kMaxRecordsPerPacket);
  std::size_t n = 0;
  std::vector<std::uint8_t> p = l.packets[20];
  const Span<FiringRecord> o(out.data(), out.size());
  REQUIRE(dec.decode(Span<const std::uint8_t>(p.data(), p.size()), o, n) == Status::Ok);
  const std::size_t full = n;
  REQUIRE(full > 0);
  CHECK(dec.decode(Span<const std::uint8_t>(p.data(), p.size() - 1), o, n) == Status::Truncated);
  CHECK(n == 0);
  std::vector<std::uint8_t> big = p;
  big.push_back(0);
  CHECK(dec.decode(Span<const std::uint8_t>(big.data(), big.size()), o, n) == Status::Malformed);
  CHECK(n == 0);
  std::vector<std::uint8_t> typ = p;
  typ[0] = 2;  // packet type (1 = lidar data)
  CHECK(dec.decode(Span<const std::uint8_t>(typ.data(), typ.size()), o, n) == Status::Unsupported);
  CHECK(n == 0);
  // Column 3 invalid (status bit 0 cleared), column 5 with measurement id 4000 >= 1024.
  const std::size_t col = 12 + 128 * 12;
  std::size_t inCol3 = 0;
  std::size_t inCol5 = 0;
  for (std::size_t i = 0; i < full; ++i) {
    inCol3 += out[i].block == 3 ? 1U : 0U;
    inCol5 += out[i].block == 5 ? 1U : 0U;
  }
  std::vector<std::uint8_t> bad = p;
  bad[32 + 3 * col + 10] &= 0xFEU;
  bad[32 + 5 * col + 8] = 0xA0;
  bad[32 + 5 * col + 9] = 0x0F;
  CHECK(dec.decode(Span<const std::uint8_t>(bad.data(), bad.size()), o, n) == Status::Malformed);
  CHECK(n == full - inCol3 - inCol5);
  CHECK(dec.counters().invalidColumns == 1);
  CHECK(dec.counters().badMeasurementId == 1);
  // Output too small: the first records, the rest counted.
  CHECK(dec.decode(Span<const std::uint8_t>(p.data(), p.size()), Span<FiringRecord>(out.data(), 10), n) ==
        Status::CapacityExceeded);
  CHECK(n == 10);
  CHECK(dec.counters().outputFull == full - 10);
  const OusterCounters k = dec.counters();
  CHECK(k.truncated == 1);
  CHECK(k.oversized == 1);
  CHECK(k.badPacketType == 1);
  // Garbage of the right size in the LEGACY profile: column status words are not all-ones, so
  // every column is skipped and nothing is emitted.
  OusterConfig lc;
  lc.format = Format{Profile::Legacy, 16, 32, 1024};
  OusterDecoder ld(lc);
  std::mt19937 rng(7);
  std::vector<std::uint8_t> g(packetBytes(lc.format));
  for (auto& b : g) {
    b = static_cast<std::uint8_t>(rng());
  }
  CHECK(ld.decode(Span<const std::uint8_t>(g.data(), g.size()), o, n) == Status::Malformed);
  CHECK(n == 0);
  CHECK(ld.counters().invalidColumns + ld.counters().badMeasurementId == 16);
  // Bad format: refused before reading.
  OusterConfig zc;
  zc.format.pixelsPerColumn = 0;
  OusterDecoder zd(zc);
  CHECK(zd.decode(Span<const std::uint8_t>(g.data(), g.size()), o, n) == Status::InvalidArgument);
  // The dual profile's second return on request.
  const Loaded d = load(kCaptures[5]);
  OusterConfig dc;
  dc.format = d.meta.format;
  dc.emitSecondReturn = true;
  OusterDecoder dd(dc);
  std::size_t seconds = 0;
  for (const auto& pk : d.packets) {
    REQUIRE(dd.decode(Span<const std::uint8_t>(pk.data(), pk.size()), o, n) == Status::Ok);
    for (std::size_t i = 0; i < n; ++i) {
      seconds += out[i].secondReturn;
    }
  }
  std::printf("OS-0-32 dual: %zu second returns\n", seconds);
  CHECK(seconds > 0);
}

TEST_CASE("Ouster decoding, assembling and points allocate nothing per packet", "[ouster][realdata]") {
  const Loaded l = load(kCaptures[1]);  // OS-2-128: 2048-pixel packets
  OusterConfig cfg;
  cfg.format = l.meta.format;
  OusterDecoder dec(cfg);
  static FiringRecord out[kMaxRecordsPerPacket];
  static PixelExtra extra[kMaxRecordsPerPacket];
  static FiringReturn ret[kMaxRecordsPerPacket];
  static FiringRecord storage[140000];
  static PacketInfo info;
  drivers::velodyne::RevolutionAssembler rev{Span<FiringRecord>(storage)};
  std::size_t n = 0;
  std::size_t m = 0;
  Status s1 = Status::NotInitialized;
  Status s2 = Status::NotInitialized;
  std::size_t points = 0;
  std::size_t records = 0;
  AGV_CHECK_NO_ALLOCATIONS(for (const auto& p
                                : l.packets) {
    s1 = dec.decode(Span<const std::uint8_t>(p.data(), p.size()), Span<FiringRecord>(out), n, &info,
                    Span<PixelExtra>(extra));
    for (std::size_t i = 0; i < n; i += 128) {  // at most one column of 128 records per add
      (void)rev.add(Span<const FiringRecord>(out + i, std::min<std::size_t>(128, n - i)));
    }
    s2 = toFiringReturns(Span<const FiringRecord>(out, n), l.meta.intrinsics, Span<FiringReturn>(ret), m);
    points += m;
    records += n;
  });
  CHECK(s1 == Status::Ok);
  CHECK(s2 == Status::Ok);
  CHECK(points == records);                                          // every first return has a point
  CHECK(std::fabs(static_cast<double>(points) - 119700.0) < 300.0);  // README: 119.7k valid pixels
  // Time per frame (printed, not checked: the machine is shared): decode + points, 20 frames.
  const auto t0 = std::chrono::steady_clock::now();
  for (int rep = 0; rep < 20; ++rep) {
    for (const auto& p : l.packets) {
      (void)dec.decode(Span<const std::uint8_t>(p.data(), p.size()), Span<FiringRecord>(out), n);
      (void)toFiringReturns(Span<const FiringRecord>(out, n), l.meta.intrinsics, Span<FiringReturn>(ret), m);
    }
  }
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() / 20.0;
  std::printf("OS-2-128 frame (64 packets, ~120k returns): decode + points %.2f ms\n", ms);
}

TEST_CASE("Ouster range-image returns are the beam model's points, column by column, on every capture",
          "[ouster][realdata]") {
  // toFiringReturns() factors the trigonometry per beam and column; ousterPoint() is the model
  // per point. They differ by float rounding: measured 3.2-3.8e-7 m per m of range (3 ulp); the
  // bound is 1e-6 (another compiler may contract to FMA). A wrong term would be 1e-3 or more.
  for (const Capture& c : kCaptures) {
    INFO(c.pcap);
    const Loaded l = load(c);
    OusterConfig cfg;
    cfg.format = l.meta.format;
    cfg.emitSecondReturn = true;  // second returns are skipped by toFiringReturns: checked below
    OusterDecoder dec(cfg);
    static FiringRecord out[kMaxRecordsPerPacket];
    static FiringReturn ret[kMaxRecordsPerPacket];
    std::size_t compared = 0;
    std::size_t seconds = 0;
    double worst = 0.0;
    bool columnsEqual = true;
    bool lasersEqual = true;
    for (const auto& p : l.packets) {
      std::size_t n = 0;
      (void)dec.decode(Span<const std::uint8_t>(p.data(), p.size()), Span<FiringRecord>(out), n);
      std::size_t m = 0;
      REQUIRE(toFiringReturns(Span<const FiringRecord>(out, n), l.meta.intrinsics, Span<FiringReturn>(ret), m) ==
              Status::Ok);
      std::size_t k = 0;
      for (std::size_t i = 0; i < n; ++i) {
        if (out[i].secondReturn != 0U) {
          ++seconds;
          continue;
        }
        float xyz[3];
        if (ousterPoint(l.meta.intrinsics, out[i], true, xyz) != Status::Ok) {
          continue;
        }
        REQUIRE(k < m);
        const FiringReturn& r = ret[k++];
        const double range = 0.002 * out[i].distance;
        const double e = (r.point.cast<double>() - Eigen::Vector3d(xyz[0], xyz[1], xyz[2])).norm();
        worst = std::max(worst, e / std::max(range, 1.0));
        const std::int32_t w = l.meta.intrinsics.columnsPerFrame;
        const std::int32_t col =
            (static_cast<std::int32_t>(measurementId(out[i].azimuth, l.meta.format.columnsPerFrame)) +
             l.meta.intrinsics.pixelShift[out[i].laser] % w + w) %
            w;
        columnsEqual = columnsEqual && r.firing == static_cast<std::uint32_t>(col);
        lasersEqual = lasersEqual && r.laser == out[i].laser;
        ++compared;
      }
      CHECK(k == m);  // nothing more than the model's points
    }
    std::printf("%s: %zu returns against the beam model, worst %.2e m per m of range\n", c.pcap, compared, worst);
    CHECK(compared > 10000U);
    CHECK(worst < 1e-6);
    CHECK(columnsEqual);
    CHECK(lasersEqual);
    if (std::string(c.profile).find("DUAL") != std::string::npos) {
      CHECK(seconds > 0U);
    }
  }
}

TEST_CASE("Ouster metadata JSON: bad files are refused with the field named", "[ouster]") {
  OusterMetadata m;
  std::string error;
  CHECK_FALSE(datasets::parseOusterMetadata("not json", m, error));
  CHECK_FALSE(datasets::parseOusterMetadata("{}", m, error));
  CHECK(error.find("data_format") != std::string::npos);
  const std::string df =
      R"("data_format": {"columns_per_frame": 1024, "columns_per_packet": 16, "pixels_per_column": 2,
         "pixel_shift_by_row": [0, 8]})";
  const std::string ok = "{" + df +
                         R"(, "beam_altitude_angles": [1, -1], "beam_azimuth_angles": [0.5, -0.5],
      "lidar_origin_to_beam_origin_mm": 12.5, "lidar_to_sensor_transform": [-1,0,0,0, 0,-1,0,0, 0,0,1,36.18, 0,0,0,1]})";
  REQUIRE(datasets::parseOusterMetadata(ok, m, error));
  CHECK(m.profileName == "LEGACY");
  CHECK(m.intrinsics.beams == 2);
  CHECK(std::fabs(m.intrinsics.beamOriginM - 0.0125F) < 1e-7F);
  CHECK(std::fabs(m.intrinsics.lidarToSensor[11] - 0.03618F) < 1e-7F);
  CHECK(std::fabs(m.intrinsics.altitudeRad[0] - 0.0174533F) < 1e-6F);
  CHECK(m.intrinsics.pixelShift[1] == 8);
  // One altitude short, a string where a number goes, an unknown profile, too many pixels.
  std::string bad = ok;
  bad.replace(bad.find("[1, -1]"), 7, "[1]");
  CHECK_FALSE(datasets::parseOusterMetadata(bad, m, error));
  CHECK(error.find("beam_altitude_angles") != std::string::npos);
  bad = ok;
  bad.replace(bad.find("12.5"), 4, "\"x\"");
  CHECK_FALSE(datasets::parseOusterMetadata(bad, m, error));
  bad = ok;
  bad.replace(bad.find("\"columns_per_frame\""), 0, "\"udp_profile_lidar\": \"FIVE_WORD_PIXEL\", ");
  CHECK_FALSE(datasets::parseOusterMetadata(bad, m, error));
  CHECK(error.find("unsupported profile") != std::string::npos);
  bad = ok;
  bad.replace(bad.find("\"pixels_per_column\": 2"), 22, "\"pixels_per_column\": 256");
  CHECK_FALSE(datasets::parseOusterMetadata(bad, m, error));
}

TEST_CASE("One wall at one distance: per-beam range offset and elevation are not separable", "[ouster][realdata]") {
  // The conditioning of the OS-2-128 wall for per-beam intrinsics: for every inlier of a beam, the
  // derivative of its distance to the (fixed) wall plane with respect to the beam's range offset dr,
  // elevation dphi and azimuth da, from the README's beam model in double (lidar frame). Columns
  // nearly parallel = the data cannot tell the parameters apart (docs/ouster.md).
  const Capture& c = kCaptures[1];
  const Loaded l = load(c);
  const std::vector<Frame> frames = decodeFrames(l);
  REQUIRE(!frames.empty());
  const Frame& f = frames[0];
  const PlaneFit p = biggestPlane(f.points, true, 1.0);
  // Plane to the lidar frame: sensor = R lidar + t (R, t from the JSON via the intrinsics).
  const float* T = l.meta.intrinsics.lidarToSensor;
  Eigen::Matrix3d R;
  R << T[0], T[1], T[2], T[4], T[5], T[6], T[8], T[9], T[10];
  const Eigen::Vector3d t(T[3], T[7], T[11]);
  const Eigen::Vector3d nl = R.transpose() * p.normal;
  const double pi = 3.14159265358979323846;
  const double nOff = l.meta.intrinsics.beamOriginM;
  std::map<int, std::vector<Eigen::Vector3d>> jac;  // per beam: d(distance)/d(dr, dphi, da)
  for (std::size_t i : p.inliers) {
    const FiringRecord& r = f.records[f.record[i]];
    const int b = r.laser;
    const double m = measurementId(r.azimuth, 1024);
    const double te = 2.0 * pi * (1.0 - m / 1024.0);
    const double th = te - l.meta.intrinsics.azimuthRad[b];
    const double ph = l.meta.intrinsics.altitudeRad[b];
    const double rr = r.distance * 0.002 - nOff;
    const Eigen::Vector3d u(std::cos(th) * std::cos(ph), std::sin(th) * std::cos(ph), std::sin(ph));
    const Eigen::Vector3d dPhi =
        rr * Eigen::Vector3d(-std::cos(th) * std::sin(ph), -std::sin(th) * std::sin(ph), std::cos(ph));
    const Eigen::Vector3d dAz = -rr * Eigen::Vector3d(-std::sin(th) * std::cos(ph), std::cos(th) * std::cos(ph), 0.0);
    jac[b].emplace_back(nl.dot(u), nl.dot(dPhi), nl.dot(dAz));
  }
  // Per beam: 1-sigma of (dr, dphi, da) from this wall alone, sigma^2 (J^T J)^-1 with sigma the
  // beam's own RMS residual, and the dr-dphi correlation.
  std::vector<double> sdr;
  std::vector<double> sphi;
  std::vector<double> sda;
  std::vector<double> rho;
  std::map<int, double> rms;
  for (const BeamResidual& br : perBeam(f, p)) {
    rms[br.beam] = br.rms;
  }
  for (const auto& [b, rows] : jac) {
    if (rows.size() < 20 || rms.count(b) == 0) {
      continue;
    }
    Eigen::Matrix3d JtJ = Eigen::Matrix3d::Zero();
    for (const Eigen::Vector3d& row : rows) {
      JtJ += row * row.transpose();
    }
    const Eigen::Matrix3d cov = rms[b] * rms[b] * JtJ.inverse();
    sdr.push_back(1000.0 * std::sqrt(cov(0, 0)));
    sphi.push_back(1000.0 * std::sqrt(cov(1, 1)));
    sda.push_back(1000.0 * std::sqrt(cov(2, 2)));
    rho.push_back(std::fabs(cov(0, 1)) / std::sqrt(cov(0, 0) * cov(1, 1)));
  }
  REQUIRE(sdr.size() >= 100);
  auto summary = [](std::vector<double> v, const char* what) {
    std::sort(v.begin(), v.end());
    std::printf("  %-26s min %8.3f  median %8.3f  max %8.3f\n", what, v.front(), v[v.size() / 2], v.back());
    return v;
  };
  std::printf("OS-2-128 wall at %.2f m, one placement, %zu beams, 1-sigma from each beam's own points:\n",
              std::fabs(p.d), sdr.size());
  const auto r1 = summary(sdr, "sigma(dr) [mm]");
  const auto r2 = summary(sphi, "sigma(dphi) [mrad]");
  const auto r3 = summary(sda, "sigma(da) [mrad]");
  const auto r4 = summary(rho, "|corr(dr, dphi)|");
  // Geometry, not the decoder: every beam's dr and dphi are strongly correlated on one wall
  // (the thesis' D_corr / theta), yet the wall's width (beams meet it at up to ~30 deg incidence)
  // keeps them from being exactly collinear.
  CHECK(r4[r4.size() / 2] > 0.9);
  CHECK(r4.back() < 1.0);
}

TEST_CASE("One wall, plane and all beams together: what one placement observes", "[ouster][realdata]") {
  // The joint conditioning of the OS-2-128 wall (docs/ouster.md): parameters are every beam's range
  // offset dr, elevation dphi and azimuth offset da (Ouster's beam model, the mapping onto the
  // thesis' D_corr / theta / alpha) and the wall plane itself (normal in its tangent plane, offset),
  // as agvnav-lidar-calibrate sets the Velodyne problem up. Rows: the distance of every inlier to the
  // plane, weighted by its beam's own RMS residual. The plane is eliminated (Schur complement); the
  // columns are normalised; the singular values and the smallest directions say what this one
  // placement cannot separate.
  const Capture& c = kCaptures[1];
  const Loaded l = load(c);
  const std::vector<Frame> frames = decodeFrames(l);
  REQUIRE(!frames.empty());
  const Frame& f = frames[0];
  const PlaneFit p = biggestPlane(f.points, true, 1.0);
  const float* T = l.meta.intrinsics.lidarToSensor;
  Eigen::Matrix3d R;
  R << T[0], T[1], T[2], T[4], T[5], T[6], T[8], T[9], T[10];
  const Eigen::Vector3d nl = R.transpose() * p.normal;
  // Tangent basis of the plane normal (lidar frame).
  const Eigen::Vector3d e1 = nl.unitOrthogonal();
  const Eigen::Vector3d e2 = nl.cross(e1);
  const double pi = 3.14159265358979323846;
  const double nOff = l.meta.intrinsics.beamOriginM;
  std::map<int, double> rms;
  for (const BeamResidual& br : perBeam(f, p)) {
    rms[br.beam] = br.rms;
  }
  std::map<int, int> column;  // beam -> first of its 3 columns
  for (const auto& [b, r] : rms) {
    const int k = static_cast<int>(column.size());
    column[b] = 3 * k;
  }
  const int nb = static_cast<int>(column.size());
  const int nc = 3 * nb + 3;
  REQUIRE(nb >= 100);
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(nc, nc);
  std::size_t rows = 0;
  for (std::size_t i : p.inliers) {
    const FiringRecord& r = f.records[f.record[i]];
    const int b = r.laser;
    if (column.count(b) == 0) {
      continue;
    }
    const double m = measurementId(r.azimuth, 1024);
    const double te = 2.0 * pi * (1.0 - m / 1024.0);
    const double th = te - l.meta.intrinsics.azimuthRad[b];
    const double ph = l.meta.intrinsics.altitudeRad[b];
    const double rr = r.distance * 0.002 - nOff;
    const Eigen::Vector3d u(std::cos(th) * std::cos(ph), std::sin(th) * std::cos(ph), std::sin(ph));
    const Eigen::Vector3d point = rr * u + nOff * Eigen::Vector3d(std::cos(te), std::sin(te), 0.0);
    const Eigen::Vector3d dPhi =
        rr * Eigen::Vector3d(-std::cos(th) * std::sin(ph), -std::sin(th) * std::sin(ph), std::cos(ph));
    const Eigen::Vector3d dAz = -rr * Eigen::Vector3d(-std::sin(th) * std::cos(ph), std::cos(th) * std::cos(ph), 0.0);
    Eigen::VectorXd a = Eigen::VectorXd::Zero(nc);
    const int c0 = column[b];
    a[c0] = nl.dot(u);
    a[c0 + 1] = nl.dot(dPhi);
    a[c0 + 2] = nl.dot(dAz);
    a[3 * nb] = e1.dot(point);
    a[3 * nb + 1] = e2.dot(point);
    a[3 * nb + 2] = -1.0;
    const double w = 1.0 / (rms[b] * rms[b]);
    // Only the beam's 3 columns and the plane's 3 are non-zero.
    const int idx[6] = {c0, c0 + 1, c0 + 2, 3 * nb, 3 * nb + 1, 3 * nb + 2};
    for (const int x : idx) {
      for (const int y : idx) {
        H(x, y) += w * a[x] * a[y];
      }
    }
    ++rows;
  }
  // Plane-fixed per-beam covariance (the test above) and the joint one with the plane eliminated.
  const int nl3 = 3 * nb;
  const Eigen::MatrixXd hpp = H.bottomRightCorner(3, 3);
  const Eigen::MatrixXd hlp = H.topRightCorner(nl3, 3);
  const Eigen::MatrixXd S = H.topLeftCorner(nl3, nl3) - hlp * hpp.inverse() * hlp.transpose();
  Eigen::VectorXd scale(nl3);
  for (int i = 0; i < nl3; ++i) {
    scale[i] = 1.0 / std::sqrt(S(i, i));
  }
  const Eigen::MatrixXd Sn = scale.asDiagonal() * S * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(Sn);
  // The common offsets (the same dr / dphi / da on every beam), in the normalised columns.
  std::array<Eigen::VectorXd, 3> common;
  const char* names[3] = {"common dr", "common dphi", "common da"};
  for (int k = 0; k < 3; ++k) {
    common[static_cast<std::size_t>(k)] = Eigen::VectorXd::Zero(nl3);
    for (int j = 0; j < nb; ++j) {
      common[static_cast<std::size_t>(k)][3 * j + k] = 1.0 / scale[3 * j + k];
    }
    common[static_cast<std::size_t>(k)].normalize();
  }
  const double smax = std::sqrt(es.eigenvalues()[nl3 - 1]);
  std::printf(
      "OS-2-128 wall at %.2f m, joint: %d beams x (dr, dphi, da) + plane, %zu rows; normalised singular values "
      "(largest %.3g):\n",
      std::fabs(p.d), nb, rows, smax);
  std::array<double, 3> commonOverlap{};  // largest |cos| of each common offset with the 3 smallest directions
  for (int i = 0; i < 8; ++i) {
    const Eigen::VectorXd v = es.eigenvectors().col(i);
    // Dominant parameter kind and its share of the direction.
    std::array<double, 3> share{};
    int top = 0;
    for (int j = 0; j < nl3; ++j) {
      share[static_cast<std::size_t>(j % 3)] += v[j] * v[j];
      if (std::fabs(v[j]) > std::fabs(v[top])) {
        top = j;
      }
    }
    std::printf(
        "  %.3e: dr %.2f dphi %.2f da %.2f of the direction; largest component beam %d %s %.2f; |cos| with "
        "common dr %.2f, dphi %.2f, da %.2f\n",
        std::sqrt(std::max(0.0, es.eigenvalues()[i])), share[0], share[1], share[2], top / 3,
        top % 3 == 0 ? "dr" : (top % 3 == 1 ? "dphi" : "da"), v[top], std::fabs(v.dot(common[0])),
        std::fabs(v.dot(common[1])), std::fabs(v.dot(common[2])));
    for (int k = 0; k < 3 && i < 3; ++k) {
      commonOverlap[static_cast<std::size_t>(k)] =
          std::max(commonOverlap[static_cast<std::size_t>(k)], std::fabs(v.dot(common[static_cast<std::size_t>(k)])));
    }
  }
  // Per beam: 1-sigma with the plane fixed (own block of H), joint with the plane free, and joint
  // with the three common offsets held (what one wall can say about beams relative to each other).
  const Eigen::MatrixXd covJoint = S.inverse();
  Eigen::MatrixXd Sh = S;
  for (int k = 0; k < 3; ++k) {
    Eigen::VectorXd g = Eigen::VectorXd::Zero(nl3);
    for (int j = 0; j < nb; ++j) {
      g[3 * j + k] = 1.0;
    }
    Sh += 1e3 * S.diagonal().mean() / g.squaredNorm() * g * g.transpose();
  }
  const Eigen::MatrixXd covHeld = Sh.inverse();
  std::array<std::vector<double>, 3> fixedSigma;
  std::array<std::vector<double>, 3> jointSigma;
  std::array<std::vector<double>, 3> heldSigma;
  std::vector<double> heldCorr;
  std::size_t smallerThanFixed = 0;
  for (int j = 0; j < nb; ++j) {
    const Eigen::Matrix3d own = H.block<3, 3>(3 * j, 3 * j).inverse();
    for (int k = 0; k < 3; ++k) {
      const double sf = std::sqrt(own(k, k));
      const double sj = std::sqrt(covJoint(3 * j + k, 3 * j + k));
      fixedSigma[static_cast<std::size_t>(k)].push_back(sf);
      jointSigma[static_cast<std::size_t>(k)].push_back(sj);
      heldSigma[static_cast<std::size_t>(k)].push_back(std::sqrt(covHeld(3 * j + k, 3 * j + k)));
      smallerThanFixed += sj < sf * (1.0 - 1e-9) ? 1U : 0U;
    }
    heldCorr.push_back(std::fabs(covHeld(3 * j, 3 * j + 1)) /
                       std::sqrt(covHeld(3 * j, 3 * j) * covHeld(3 * j + 1, 3 * j + 1)));
  }
  const auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  const double units[3] = {1e3, 1e3, 1e3};
  for (int k = 0; k < 3; ++k) {
    const std::size_t ks = static_cast<std::size_t>(k);
    std::printf("  sigma(%s) median: plane fixed %.3f, joint %.3f, joint with the common offsets held %.3f [%s]\n",
                names[k] + 7, units[k] * median(fixedSigma[ks]), units[k] * median(jointSigma[ks]),
                units[k] * median(heldSigma[ks]), k == 0 ? "mm" : "mrad");
  }
  std::printf("  |corr(dr, dphi)| median with the common offsets held %.3f\n", median(heldCorr));
  // The common offsets' own 1-sigma (the mean over the beams of each parameter).
  for (int k = 0; k < 3; ++k) {
    Eigen::VectorXd g = Eigen::VectorXd::Zero(nl3);
    for (int j = 0; j < nb; ++j) {
      g[3 * j + k] = 1.0 / nb;
    }
    std::printf("  sigma(%s) %.3f %s\n", names[k], 1e3 * std::sqrt(g.dot(covJoint * g)), k == 0 ? "mm" : "mrad");
  }
  // Freeing the plane can only add uncertainty (a marginal of a larger problem).
  CHECK(smallerThanFixed == 0);
  // A common azimuth offset is a turn of the head about its vertical axis, which the free plane
  // follows; only the beam-origin offset n (the n cos(theta_e) term does not turn with a_i) breaks
  // it: the weakest direction by far, and the common azimuth unobservable from one wall.
  const Eigen::VectorXd weakest = es.eigenvectors().col(0);
  INFO("overlap of the 3 smallest directions with common dr " << commonOverlap[0] << ", dphi " << commonOverlap[1]
                                                              << ", da " << commonOverlap[2]);
  CHECK(std::fabs(weakest.dot(common[2])) > 0.95);
  CHECK(es.eigenvalues()[0] < 0.01 * es.eigenvalues()[1]);
  // Relative to each other the beams' azimuth offsets are as well determined as with the plane
  // fixed, and range offset and elevation stay correlated per beam.
  CHECK(median(heldSigma[2]) < 1.5 * median(fixedSigma[2]));
  CHECK(median(heldCorr) > 0.9);
}
