#include "places.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <utility>

#include "agv/core/angle.hpp"
#include "agv/datasets/lidar3d_scans.hpp"
#include "agv/datasets/velodyne_calibration.hpp"
#include "agv/datasets/velodyne_recording.hpp"
#include "agv/drivers/protocol/velodyne/velodyne_packet.hpp"
#include "agv/lidar3d/laser_intrinsics.hpp"
#include "agv/report/svg.hpp"
#include "agv/sim/multibeam_world.hpp"

namespace agv::places {

namespace {

constexpr std::size_t kMaxKeys = 8192;
using Database = PlaceDatabase<kMaxKeys>;
using Image = RangeImage<64, 2048>;

/// The number in a file name ("000094.bin" -> 94), -1 when there is none.
long frameOf(const std::string& path) {
  const std::size_t slash = path.find_last_of('/');
  const std::string name = slash == std::string::npos ? path : path.substr(slash + 1);
  const std::string stem = name.substr(0, name.find('.'));
  if (stem.empty() || stem.size() > 18 || stem.find_first_not_of("0123456789") != std::string::npos) {
    return -1;
  }
  return std::strtol(stem.c_str(), nullptr, 10);
}

double distance(const Pose2d& a, const Pose2d& b) {
  return std::hypot(a.x - b.x, a.y - b.y);
}

/// Signatures and the per-scan record of one revolution whose image was built with status `st`.
void finishRevolution(const PlacesOptions& options, const Image& image, Status st, ScanResult scan, PlacesResult& r) {
  NormalSignature sig;
  OrientationSignature ori;
  if (st == Status::Ok) {
    st = computeNormalSignature(image, options.signature, sig);
  }
  if (st == Status::Ok && computeOrientationSignature(image, options.orientation, ori) != Status::Ok) {
    ori = OrientationSignature{};  // no yaw for this scan; the place signature still counts
  }
  scan.status = st;
  scan.normals = sig.counts.normals;
  for (const float b : sig.bins) {
    scan.signatureSum += static_cast<double>(b);
  }
  r.scans.push_back(scan);
  r.signatures.push_back(sig);
  r.orientations.push_back(ori);
}

/// Image, signatures and the per-scan record of one revolution of ring-ordered points.
void addRevolution(const PlacesOptions& options, std::size_t columns, Image& image, const datasets::Revolution& rev,
                   ScanResult scan, PlacesResult& r) {
  scan.points = rev.points.size();
  Status st = image.reset(std::max<std::size_t>(rev.rings, 1), columns);
  if (st == Status::Ok) {
    st = image.buildFromRings(Span<const RingPoint>(rev.points.data(), rev.points.size()));
    scan.collisions = image.stats().collisions;
  }
  finishRevolution(options, image, st, scan, r);
}

/// One assembled revolution of records: firing returns (points by `cal`), range image, signatures.
/// Returns the number of firing returns.
std::size_t addFiringRevolution(const PlacesOptions& options, std::size_t columns, Image& image,
                                Span<const drivers::velodyne::FiringRecord> records, const LaserIntrinsics& cal,
                                const std::vector<std::uint16_t>& rowOfLaser, std::vector<FiringReturn>& returns,
                                ScanResult scan, PlacesResult& r) {
  std::size_t m = 0;
  // toFiringReturns' columns grow with phi (clockwise), buildFromRings' counter-clockwise: neither
  // matters here (the normals are turned towards the sensor, the orientation signature bins each
  // cell by its point's atan2(y, x)); lidar3d.places_vlp16_turned checks the yaw's sign.
  Status st =
      drivers::velodyne::toFiringReturns(records, cal, columns, Span<FiringReturn>(returns.data(), returns.size()), m);
  scan.points = m;
  if (st == Status::Ok) {
    st = image.reset(rowOfLaser.size(), columns);
  }
  if (st == Status::Ok) {
    st = image.buildFromFirings(Span<const FiringReturn>(returns.data(), m),
                                Span<const std::uint16_t>(rowOfLaser.data(), rowOfLaser.size()));
    scan.collisions = image.stats().collisions;
  }
  finishRevolution(options, image, st, scan, r);
  return m;
}

/// VLP-16 raw packet recordings: decoder -> revolution assembler -> firing returns (calibration
/// file) -> range image -> signatures. Revolutions begun mid-turn (a file's first) are counted and
/// not run; the records after a file's last wrap never complete a revolution.
bool runPackets(const PlacesOptions& options, std::size_t columns, Image& image, PlacesResult& r, std::string& error) {
  namespace vd = drivers::velodyne;
  if (options.calibrationPath.empty()) {
    error = "VLP-16 packets need a calibration file (--calibration: db.xml or velodyne_pointcloud YAML)";
    return false;
  }
  auto cal = std::make_unique<LaserIntrinsics>();
  if (!datasets::readVelodyneCalibration(options.calibrationPath, *cal, error)) {
    return false;
  }
  const std::size_t lasers = vd::laserCount(vd::Model::Vlp16);
  if (cal->size() != lasers) {
    error = options.calibrationPath + ": " + std::to_string(cal->size()) + " lasers, a VLP-16 has " +
            std::to_string(lasers) + " (calibration of another sensor?)";
    return false;
  }
  std::vector<float> elevations(lasers);
  for (std::size_t i = 0; i < lasers; ++i) {
    elevations[i] = static_cast<float>(cal->params(i).theta);
  }
  std::vector<std::uint16_t> rowOfLaser(lasers);
  if (elevationRanks(Span<const float>(elevations.data(), lasers), Span<std::uint16_t>(rowOfLaser.data(), lasers)) !=
      Status::Ok) {
    error = options.calibrationPath + ": elevations cannot be ranked";
    return false;
  }
  std::vector<vd::FiringRecord> storage(80000);  // dual return at 5 Hz stays within
  std::vector<FiringReturn> returns(storage.size());
  vd::FiringRecord out[vd::kMaxRecordsPerPacket];
  PacketStats& ps = r.packets;
  for (const std::string& file : options.files) {
    datasets::PacketRecording rec;
    if (options.format == Format::Vlp16Bag) {
      datasets::VelodyneScanBag bag;
      if (!datasets::readVelodyneScanBag(file, bag, error)) {
        return false;
      }
      ps.messages += bag.messages.size();
      rec = std::move(bag.packets);
    } else if (!datasets::readPacketRecording(file, vd::kPacketBytes, rec, error)) {
      return false;
    }
    vd::VelodyneDecoder dec(vd::VelodyneConfig{});
    vd::RevolutionAssembler assembler(Span<vd::FiringRecord>(storage.data(), storage.size()));
    std::size_t decoded = 0;
    for (std::size_t k = 0; k < rec.packets; ++k) {
      std::size_t n = 0;
      const Status st =
          dec.decode(Span<const std::uint8_t>(rec.packet(k), rec.packetBytes), Span<vd::FiringRecord>(out), n);
      if (st != Status::Ok && st != Status::Malformed) {
        continue;  // refused, counted by the decoder
      }
      ++decoded;
      ps.records += n;
      if (!assembler.add(Span<const vd::FiringRecord>(out, n))) {
        continue;
      }
      ++ps.revolutions;
      ps.refusedRecords += assembler.info().refused;
      if (!assembler.info().complete) {
        ++ps.incomplete;
        continue;
      }
      ScanResult scan;
      scan.file = file + "#rev" + std::to_string(assembler.revolutions() - 1);
      scan.frame = static_cast<long>(assembler.revolutions() - 1);
      ps.firingReturns +=
          addFiringRevolution(options, columns, image, assembler.revolution(), *cal, rowOfLaser, returns, scan, r);
    }
    const vd::VelodyneCounters& c = dec.counters();
    ps.packets += rec.packets;
    ps.refusedPackets += c.refusedPackets();
    ps.skippedBlocks += c.badBlockId + c.badAzimuth;
    ++ps.files;
    if (decoded == 0) {
      error = file + ": none of its " + std::to_string(rec.packets) + " packets is a VLP-16 data packet (truncated " +
              std::to_string(c.truncated) + ", another product " + std::to_string(c.wrongProduct) + ")";
      return false;
    }
  }
  return true;
}

/// The simulated VLP-16 as its packets (no encoder exists in drivers/protocol; this one writes what
/// VelodyneDecoder reads, strongest return, product 0x22). The simulator casts every laser of firing
/// column f at the counter-clockwise azimuth (f + 0.5) * 0.2 deg; the head angle phi grows
/// clockwise, so column f becomes firing k = 1799 - f, sent in phi order at phi = k * 0.2 deg (0.1 deg
/// before the ray: then the decoder's per-laser interpolation, +0..0.125 deg, keeps each laser of a
/// firing in its column). Two firings per block (the second interpolated by the decoder), 12 blocks,
/// 75 packets per revolution. Appends the packets to `out`.
void encodeVlp16Revolution(const std::vector<RingPoint>& points, const std::vector<std::uint16_t>& laserOfRing,
                           std::size_t firings, std::vector<std::uint8_t>& out) {
  namespace vd = drivers::velodyne;
  constexpr std::size_t kLasers = 16;
  std::vector<std::uint16_t> raw(firings * kLasers, 0);
  for (const RingPoint& p : points) {
    double a = std::atan2(static_cast<double>(p.point.y()), static_cast<double>(p.point.x()));
    if (a < 0.0) {
      a += 2.0 * kPi<double>;
    }
    const auto f =
        std::min(static_cast<std::size_t>(a / (2.0 * kPi<double>)*static_cast<double>(firings)), firings - 1);
    const std::size_t k = firings - 1 - f;
    const double counts = std::round(static_cast<double>(p.point.norm()) / 0.002);
    raw[k * kLasers + laserOfRing[p.ring]] = static_cast<std::uint16_t>(std::min(counts, 65535.0));
  }
  const std::size_t perPacket = 2 * vd::kBlocksPerPacket;
  for (std::size_t k0 = 0; k0 + perPacket <= firings; k0 += perPacket) {
    const std::size_t base = out.size();
    out.resize(base + vd::kPacketBytes, 0);
    std::uint8_t* pkt = out.data() + base;
    for (std::size_t b = 0; b < vd::kBlocksPerPacket; ++b) {
      std::uint8_t* blk = pkt + b * 100;
      const std::size_t k = k0 + 2 * b;
      const auto az = static_cast<std::uint16_t>(k * vd::kAzimuthTurn / firings);
      blk[0] = 0xFF;
      blk[1] = 0xEE;
      blk[2] = static_cast<std::uint8_t>(az & 0xFFU);
      blk[3] = static_cast<std::uint8_t>(az >> 8U);
      for (std::size_t seq = 0; seq < 2; ++seq) {
        for (std::size_t l = 0; l < kLasers; ++l) {
          const std::uint16_t d = raw[(k + seq) * kLasers + l];
          std::uint8_t* rec = blk + 4 + (seq * kLasers + l) * 3;
          rec[0] = static_cast<std::uint8_t>(d & 0xFFU);
          rec[1] = static_cast<std::uint8_t>(d >> 8U);
          rec[2] = 100;
        }
      }
    }
    pkt[1204] = static_cast<std::uint8_t>(vd::ReturnMode::Strongest);
    pkt[1205] = 0x22;
  }
}

/// The simulated VLP-16 route through its packets: each revolution encoded (encodeVlp16Revolution),
/// decoded, assembled and turned into firing returns with the sensor's own table (elevations, no
/// offsets) like a recording; the first packet of the last revolution is sent once more to cut it.
/// The first revolution begins exactly at phi = 0, so it is run although the assembler marks it
/// incomplete.
bool simulatePackets(const PlacesOptions& options, const sim::MultibeamSensor& sensor, const sim::MultibeamWorld& world,
                     const std::vector<sim::RoutePose>& route, std::mt19937_64& rng, Image& image, PlacesResult& r,
                     std::string& error) {
  namespace vd = drivers::velodyne;
  const std::size_t lasers = sensor.elevation.size();
  if (options.sim.sensor != "vlp16" || lasers != 16 || sensor.firings % 24 != 0) {
    error = "--sim-packets: VLP-16 only";
    return false;
  }
  auto cal = std::make_unique<LaserIntrinsics>();
  std::vector<float> elevations(lasers);
  bool ok = cal->reset(lasers) == Status::Ok;
  for (std::size_t i = 0; i < lasers && ok; ++i) {
    LaserParams lp;
    lp.theta = sensor.elevation[i];
    lp.alpha = sensor.azimuthOffset[i];  // beta = phi - alpha, phi = -(ray azimuth): ray = -beta
    ok = cal->set(i, lp) == Status::Ok;
    elevations[i] = static_cast<float>(sensor.elevation[i]);
  }
  std::vector<std::uint16_t> rowOfLaser(lasers);
  if (!ok || elevationRanks(Span<const float>(elevations.data(), lasers),
                            Span<std::uint16_t>(rowOfLaser.data(), lasers)) != Status::Ok) {
    error = "the simulated sensor's table is not valid";
    return false;
  }
  std::vector<std::uint16_t> laserOfRing(lasers);
  for (std::size_t i = 0; i < lasers; ++i) {
    laserOfRing[rowOfLaser[i]] = static_cast<std::uint16_t>(i);
  }
  std::vector<vd::FiringRecord> storage(80000);
  std::vector<FiringReturn> returns(storage.size());
  vd::FiringRecord out[vd::kMaxRecordsPerPacket];
  vd::VelodyneDecoder dec(vd::VelodyneConfig{});
  vd::RevolutionAssembler assembler(Span<vd::FiringRecord>(storage.data(), storage.size()));
  PacketStats& ps = r.packets;
  std::vector<RingPoint> points;
  std::vector<std::uint8_t> bytes;
  std::size_t emitted = 0;
  const auto feed = [&](const std::uint8_t* pkt) {
    std::size_t n = 0;
    ++ps.packets;
    if (dec.decode(Span<const std::uint8_t>(pkt, vd::kPacketBytes), Span<vd::FiringRecord>(out), n) != Status::Ok) {
      return;  // counted by the decoder
    }
    ps.records += n;
    if (!assembler.add(Span<const vd::FiringRecord>(out, n))) {
      return;
    }
    ++ps.revolutions;
    ps.refusedRecords += assembler.info().refused;
    ScanResult scan;
    scan.file = "sim:" + options.sim.sensor + ":packets:lap" + std::to_string(route[emitted].lap);
    scan.frame = static_cast<long>(emitted);
    ps.firingReturns +=
        addFiringRevolution(options, sensor.firings, image, assembler.revolution(), *cal, rowOfLaser, returns, scan, r);
    ++emitted;
  };
  std::vector<std::uint8_t> firstPacket;
  for (std::size_t i = 0; i < route.size(); ++i) {
    sim::scanRevolution(world, sensor, route[i].pose, rng, points);
    r.truth.push_back(route[i].pose);
    bytes.clear();
    encodeVlp16Revolution(points, laserOfRing, sensor.firings, bytes);
    firstPacket.assign(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(vd::kPacketBytes));
    for (std::size_t k = 0; k + vd::kPacketBytes <= bytes.size(); k += vd::kPacketBytes) {
      feed(bytes.data() + k);
    }
  }
  if (!firstPacket.empty()) {
    feed(firstPacket.data());  // the wrap that ends the last revolution (its records are not run)
  }
  ps.refusedPackets += dec.counters().refusedPackets();
  ps.files = 0;
  if (emitted != route.size()) {
    error = "the packet path assembled " + std::to_string(emitted) + " revolutions of " + std::to_string(route.size());
    return false;
  }
  return true;
}

/// The simulated route: the yard world, the sensor, one revolution per route pose.
bool simulate(const PlacesOptions& options, Image& image, PlacesResult& r, std::string& error) {
  const SimRouteOptions& o = options.sim;
  sim::MultibeamSensor sensor;
  if (o.sensor == "vlp16") {
    sensor = sim::vlp16Sensor();
  } else if (o.sensor == "hdl64") {
    if (!datasets::readVelodyneCalibration(o.calibration, sensor.elevation, sensor.azimuthOffset, error)) {
      return false;
    }
    sensor.firings = 2000;
  } else {
    error = "unknown simulated sensor '" + o.sensor + "' (hdl64, vlp16)";
    return false;
  }
  if (sensor.elevation.size() > Image::kLasers || sensor.firings > Image::kFirings) {
    error = "the simulated sensor exceeds the range image's capacity";
    return false;
  }
  const sim::MultibeamWorld world = sim::yardWorld(o.width, o.height, o.seed);
  const std::vector<sim::RoutePose> route = sim::yardRoute(o.width, o.height, o.step, o.back, o.again, o.lateral);
  std::mt19937_64 rng(o.seed * 7919U + 1U);
  datasets::Revolution rev;
  rev.rings = sensor.elevation.size();
  if (o.packets) {
    return simulatePackets(options, sensor, world, route, rng, image, r, error);
  }
  for (std::size_t i = 0; i < route.size(); ++i) {
    sim::scanRevolution(world, sensor, route[i].pose, rng, rev.points);
    ScanResult scan;
    scan.file = "sim:" + o.sensor + ":lap" + std::to_string(route[i].lap);
    scan.frame = static_cast<long>(i);
    r.truth.push_back(route[i].pose);
    addRevolution(options, sensor.firings, image, rev, scan, r);
  }
  return true;
}

/// Runs the place database over the stored signatures with T_chi2 and T_Sor times `scale`; fills the
/// per-scan outcome when `record`. Returns the precision / recall figures.
PrPoint runDatabase(const PlacesOptions& options, PlacesResult& r, float scale, bool record) {
  auto db = std::make_unique<Database>();
  PlaceParams p = options.place;
  p.chiSquareThreshold *= scale;
  p.sorensenThreshold *= scale;
  PrPoint pr;
  pr.chiSquareThreshold = p.chiSquareThreshold;
  pr.sorensenThreshold = p.sorensenThreshold;
  (void)db->setParams(p);  // validated by runPlaces
  const bool truth = !r.truth.empty();
  for (std::size_t i = 0; i < r.scans.size(); ++i) {
    ScanResult& scan = r.scans[i];
    if (scan.status != Status::Ok) {
      continue;
    }
    bool positive = false;
    if (truth) {
      const std::size_t eligible = db->size() > p.skipRecentKeys ? db->size() - p.skipRecentKeys : 0;
      for (std::size_t k = 0; k < eligible && !positive; ++k) {
        positive = distance(r.truth[db->at(k)->scan], r.truth[i]) <= options.radius;
      }
    }
    PlaceUpdate u;
    (void)db->add(r.signatures[i], r.orientations[i], static_cast<std::uint32_t>(i), u);  // refusals counted
    bool loopTrue = false;
    if (u.loop) {
      ++pr.detected;
      if (truth) {
        loopTrue = distance(r.truth[u.loopScan], r.truth[i]) <= options.radius;
        pr.truePositives += loopTrue ? 1U : 0U;
      }
    }
    pr.positives += positive ? 1U : 0U;
    if (record) {
      scan.update = u;
      scan.hasTruth = truth;
      scan.truePositiveCandidate = positive;
      scan.loopTrue = loopTrue;
      if (truth && u.loop) {
        scan.loopDistance = distance(r.truth[u.loopScan], r.truth[i]);
      }
      if (truth && u.loop && u.hasYaw) {
        scan.hasYawError = true;
        scan.yawTruth = angleDiff(r.truth[i].theta, r.truth[u.loopScan].theta);
        scan.signatureYawError = angleDiff(static_cast<double>(u.yaw.yaw), scan.yawTruth);
        scan.yawError =
            u.hasAlignment ? angleDiff(static_cast<double>(u.alignment.yaw), scan.yawTruth) : scan.signatureYawError;
      }
      if (truth && u.loop && u.hasAlignment) {
        const Pose2d& k = r.truth[u.loopScan];
        const double dx = r.truth[i].x - k.x;
        const double dy = r.truth[i].y - k.y;
        const double c = std::cos(k.theta);
        const double sn = std::sin(k.theta);
        scan.hasTranslationError = true;
        scan.translationTruth = Eigen::Vector2d(c * dx + sn * dy, -sn * dx + c * dy);
        scan.translationError = (Eigen::Vector2d(u.alignment.x, u.alignment.y) - scan.translationTruth).norm();
      }
    }
  }
  if (record) {
    r.keys = db->size();
  }
  pr.precision = pr.detected > 0 ? static_cast<double>(pr.truePositives) / static_cast<double>(pr.detected) : 1.0;
  pr.recall = pr.positives > 0 ? static_cast<double>(pr.truePositives) / static_cast<double>(pr.positives) : 1.0;
  return pr;
}

}  // namespace

bool simulatedSensorSet(const std::string& sensor, SensorSet& set) {
  set = SensorSet{};
  if (sensor == "hdl64") {
    const PlaceParams place{};
    set.chiSquareThreshold = place.chiSquareThreshold;
    set.sorensenThreshold = place.sorensenThreshold;
    set.laserStep = BeamNormalParams{}.laserStep;
    return true;
  }
  if (sensor == "vlp16") {
    set.chiSquareThreshold = 9.0e-4F;
    set.sorensenThreshold = 0.105F;
    set.laserStep = 1;
    return true;
  }
  return false;
}

bool runPlaces(const PlacesOptions& options, PlacesResult& r, std::string& error) {
  r = PlacesResult{};
  const auto t0 = std::chrono::steady_clock::now();
  if (!isValid(options.place) || !isValid(options.signature.normals) || !(options.radius > 0.0)) {
    error = "parameters out of their domain";
    return false;
  }
  auto image = std::make_unique<Image>();
  if (!options.sim.sensor.empty()) {
    if (!simulate(options, *image, r, error)) {
      return false;
    }
  } else {
    if (options.files.empty()) {
      error = "no revolution given";
      return false;
    }
    if (isPacketFormat(options.format)) {
      if (!options.posesPath.empty()) {
        error = "--poses (KITTI frames) does not apply to packet recordings";
        return false;
      }
      if (!runPackets(options, options.columns > 0 ? options.columns : 1800, *image, r, error)) {
        return false;
      }
      if (r.scans.empty()) {
        error = "no complete revolution in the packet recording(s)";
        return false;
      }
    }
    std::vector<Eigen::Matrix<double, 3, 4>> poses;
    if (!options.posesPath.empty() && !datasets::readKittiPoses(options.posesPath, poses, error)) {
      return false;
    }
    const std::size_t columns = options.columns > 0 ? options.columns : (options.format == Format::Kitti ? 2000 : 1024);
    for (std::size_t f = 0; f < options.files.size() && !isPacketFormat(options.format); ++f) {
      const std::string& file = options.files[f];
      ScanResult scan;
      scan.file = file;
      scan.frame = frameOf(file);
      datasets::Revolution rev;
      const bool read = options.format == Format::Kitti ? datasets::readKittiVelodyne(file, rev, error)
                                                        : datasets::readNcltVelodyne(file, rev, error);
      if (!read) {
        return false;
      }
      if (!poses.empty()) {
        if (scan.frame < 0 || static_cast<std::size_t>(scan.frame) >= poses.size()) {
          error = file + ": no pose for this file (frame " + std::to_string(scan.frame) + ")";
          return false;
        }
        // On the ground, in the sensor's convention (x forward, y left, z up): x = the camera's z, y =
        // minus the camera's x; yaw about the up axis (kittiRelativeYaw from identity). (The camera
        // is ~0.27 m ahead of the Velodyne: at the pairs' 1-3 deg turns that moves a translation by
        // ~1 cm.)
        const Eigen::Matrix<double, 3, 4>& p = poses[static_cast<std::size_t>(scan.frame)];
        r.truth.push_back(
            Pose2d{p(2, 3), -p(0, 3), datasets::kittiRelativeYaw(Eigen::Matrix<double, 3, 4>::Identity(), p)});
      }
      addRevolution(options, columns, *image, rev, scan, r);
    }
  }
  r.summary = runDatabase(options, r, 1.0F, true);
  for (const float t : options.curveScale) {
    r.curve.push_back(runDatabase(options, r, t, false));
  }
  double sumAbs = 0.0;
  for (const ScanResult& s : r.scans) {
    if (s.hasYawError) {
      const double e = std::fabs(rad2deg(s.yawError));
      r.yawErrorMaxDeg = std::max(r.yawErrorMaxDeg, e);
      sumAbs += e;
      ++r.yawCount;
    }
  }
  r.yawErrorMeanAbsDeg = r.yawCount > 0 ? sumAbs / static_cast<double>(r.yawCount) : 0.0;
  {
    std::vector<double> all;
    std::vector<double> same;
    std::vector<double> opposite;
    std::vector<double> coarse;
    std::vector<double> trans;
    for (const ScanResult& s : r.scans) {
      if (s.hasYawError) {
        const double e = std::fabs(rad2deg(s.yawError));
        all.push_back(e);
        (std::fabs(s.yawTruth) > kPi<double> / 2.0 ? opposite : same).push_back(e);
        coarse.push_back(std::fabs(rad2deg(s.signatureYawError)));
      }
      if (s.hasTranslationError) {
        trans.push_back(s.translationError);
      }
    }
    auto stats = [](std::vector<double> v) {
      PlacesResult::YawStats st;
      st.count = v.size();
      if (v.empty()) {
        return st;
      }
      std::sort(v.begin(), v.end());
      const auto at = [&v](double q) {
        return v[std::min(v.size() - 1, static_cast<std::size_t>(std::ceil(q * static_cast<double>(v.size())) - 1.0))];
      };
      st.median = at(0.5);
      st.p90 = at(0.9);
      st.max = v.back();
      st.within1 = static_cast<double>(std::count_if(v.begin(), v.end(), [](double e) { return e <= 1.0; })) /
                   static_cast<double>(v.size());
      return st;
    };
    r.yawAll = stats(all);
    r.yawSame = stats(same);
    r.yawOpposite = stats(opposite);
    r.signatureYawAll = stats(coarse);
    const PlacesResult::YawStats t = stats(trans);
    r.translationCount = t.count;
    r.translationErrorMedian = t.median;
    r.translationErrorMax = t.max;
  }
  // Relative yaw between consecutive revolutions (what a recording without poses can report).
  double stepAbs = 0.0;
  for (std::size_t i = 1; i < r.scans.size(); ++i) {
    if (r.orientations[i - 1].empty() || r.orientations[i].empty()) {
      continue;
    }
    const Result<YawEstimate> y = relativeYaw(r.orientations[i - 1], r.orientations[i], options.orientation.minOverlap);
    if (!y.ok()) {
      continue;
    }
    ScanResult& s = r.scans[i];
    s.hasStepYaw = true;
    s.stepYaw = static_cast<double>(y.value().yaw);
    s.stepYawRelativeCost = y.value().relativeCost();
    const double e = std::fabs(rad2deg(s.stepYaw));
    r.stepYawMaxAbsDeg = std::max(r.stepYawMaxAbsDeg, e);
    stepAbs += e;
    ++r.stepYawCount;
  }
  r.stepYawMeanAbsDeg = r.stepYawCount > 0 ? stepAbs / static_cast<double>(r.stepYawCount) : 0.0;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return true;
}

namespace {
/// Precision and recall only with ground truth (without, every loop would count as false).
report::Json prJson(const PrPoint& p, bool truth) {
  report::Json j;
  j["chi_square_threshold"] = report::shortestDouble(p.chiSquareThreshold);
  j["sorensen_threshold"] = report::shortestDouble(p.sorensenThreshold);
  j["detected"] = p.detected;
  if (!truth) {
    return j;
  }
  j["true_positives"] = p.truePositives;
  j["positives"] = p.positives;
  j["precision"] = p.precision;
  j["recall"] = p.recall;
  return j;
}
}  // namespace

report::Json placesJson(const PlacesOptions& options, const PlacesResult& r) {
  report::Json doc;
  doc["program"] = "agvnav-lidar-places";
  doc["format"] = options.format == Format::Kitti      ? "kitti"
                  : options.format == Format::Nclt     ? "nclt"
                  : options.format == Format::Vlp16Bag ? "vlp16-bag"
                                                       : "vlp16-packets";
  report::Json params;
  params["key_threshold"] = report::shortestDouble(options.place.keyThreshold);
  params["skip_recent_keys"] = options.place.skipRecentKeys;
  params["chi_square_threshold"] = report::shortestDouble(options.place.chiSquareThreshold);
  params["sorensen_threshold"] = report::shortestDouble(options.place.sorensenThreshold);
  params["orientation_check"] = report::shortestDouble(options.place.maxOrientationCost);
  params["loop_translation_m"] = report::shortestDouble(options.place.maxLoopTranslation);
  params["min_aligned_fraction"] = report::shortestDouble(options.place.minAlignedFraction);
  params["radius_m"] = options.radius;
  params["firing_step"] = options.signature.normals.firingStep;
  params["laser_step"] = options.signature.normals.laserStep;
  params["normal_min_range_m"] = static_cast<double>(options.signature.normals.minRange);
  doc["parameters"] = params;
  doc["scans"] = r.scans.size();
  doc["keys"] = r.keys;
  doc["ground_truth"] = !r.truth.empty();
  doc["source"] =
      options.sim.sensor.empty() ? "files" : "sim:" + options.sim.sensor + (options.sim.packets ? ":packets" : "");
  doc["summary"] = prJson(r.summary, !r.truth.empty());
  report::Json curve = report::Json::array();
  for (const PrPoint& p : r.curve) {
    curve.push_back(prJson(p, !r.truth.empty()));
  }
  doc["pr_curve"] = curve;
  report::Json yaw;
  yaw["count"] = r.yawCount;
  yaw["max_abs_error_deg"] = r.yawErrorMaxDeg;
  yaw["mean_abs_error_deg"] = r.yawErrorMeanAbsDeg;
  const auto statsJson = [](const PlacesResult::YawStats& st) {
    report::Json j;
    j["count"] = st.count;
    j["median_abs_error_deg"] = st.median;
    j["p90_abs_error_deg"] = st.p90;
    j["max_abs_error_deg"] = st.max;
    j["within_1deg"] = st.within1;
    return j;
  };
  yaw["median_abs_error_deg"] = r.yawAll.median;
  yaw["p90_abs_error_deg"] = r.yawAll.p90;
  yaw["within_1deg"] = r.yawAll.within1;
  yaw["same_direction"] = statsJson(r.yawSame);
  yaw["opposite_direction"] = statsJson(r.yawOpposite);
  yaw["signature_only"] = statsJson(r.signatureYawAll);
  doc["yaw"] = yaw;
  report::Json tr;
  tr["count"] = r.translationCount;
  tr["median_error_m"] = r.translationErrorMedian;
  tr["max_error_m"] = r.translationErrorMax;
  doc["loop_translation"] = tr;
  report::Json step;
  step["count"] = r.stepYawCount;
  step["max_abs_deg"] = r.stepYawMaxAbsDeg;
  step["mean_abs_deg"] = r.stepYawMeanAbsDeg;
  doc["yaw_between_consecutive"] = step;
  if ((isPacketFormat(options.format) && options.sim.sensor.empty()) || options.sim.packets) {
    const PacketStats& ps = r.packets;
    report::Json pj;
    pj["calibration"] = options.calibrationPath;
    pj["files"] = ps.files;
    if (options.format == Format::Vlp16Bag) {
      pj["messages"] = ps.messages;
    }
    pj["packets"] = ps.packets;
    pj["refused_packets"] = ps.refusedPackets;
    pj["skipped_blocks"] = ps.skippedBlocks;
    pj["records"] = ps.records;
    pj["revolutions_assembled"] = ps.revolutions;
    pj["revolutions_incomplete_skipped"] = ps.incomplete;
    pj["refused_records"] = ps.refusedRecords;
    pj["firing_returns"] = ps.firingReturns;
    doc["packets"] = pj;
  }
  report::Json loops = report::Json::array();
  report::Json scans = report::Json::array();
  for (std::size_t i = 0; i < r.scans.size(); ++i) {
    const ScanResult& s = r.scans[i];
    report::Json js;
    js["file"] = s.file;
    js["frame"] = s.frame;
    js["points"] = s.points;
    js["normals"] = s.normals;
    js["collisions"] = s.collisions;
    js["status"] = toString(s.status);
    js["key"] = s.update.isKey;
    js["chi_square_to_last_key"] = report::shortestDouble(s.update.chiSquareToLastKey);
    js["signature_sum"] = s.signatureSum;
    if (s.hasStepYaw) {
      js["yaw_from_previous_deg"] = rad2deg(s.stepYaw);
      js["yaw_from_previous_relative_cost"] = report::shortestDouble(s.stepYawRelativeCost);
    }
    scans.push_back(js);
    if (s.update.loop) {
      report::Json l;
      l["scan"] = i;
      l["frame"] = s.frame;
      l["key_scan"] = s.update.loopScan;
      l["key_frame"] = r.scans[s.update.loopScan].frame;
      l["chi_square"] = report::shortestDouble(s.update.chiSquare);
      l["sorensen"] = report::shortestDouble(s.update.sorensen);
      l["candidates"] = s.update.candidates;
      if (s.hasTruth) {
        l["true"] = s.loopTrue;
        l["distance_m"] = s.loopDistance;
      }
      if (s.update.hasYaw) {
        l["yaw_deg"] = rad2deg(static_cast<double>(s.update.yaw.yaw));
        l["orientation_relative_cost"] = report::shortestDouble(s.update.yaw.relativeCost());
      }
      if (s.update.hasAlignment) {
        l["aligned_yaw_deg"] = rad2deg(static_cast<double>(s.update.alignment.yaw));
        l["translation_m"] = static_cast<double>(s.update.alignment.translation());
        l["aligned_x_m"] = static_cast<double>(s.update.alignment.x);
        l["aligned_y_m"] = static_cast<double>(s.update.alignment.y);
        l["aligned_fraction"] = static_cast<double>(s.update.alignment.matchedFraction());
        l["aligned_rms_m"] = static_cast<double>(s.update.alignment.rms);
        l["inlier_fraction"] = static_cast<double>(s.update.alignment.inlierFraction());
        l["alternative_inlier_fraction"] = static_cast<double>(s.update.alternativeInlierFraction);
        l["translation_observability"] = static_cast<double>(s.update.alignment.translationObservability);
      }
      l["rejected_by_orientation"] = s.update.rejectedByOrientation;
      l["rejected_by_alignment"] = s.update.rejectedByAlignment;
      if (s.hasYawError) {
        l["yaw_truth_deg"] = rad2deg(s.yawTruth);
        l["yaw_error_deg"] = rad2deg(s.yawError);
        l["signature_yaw_error_deg"] = rad2deg(s.signatureYawError);
      }
      if (s.hasTranslationError) {
        l["translation_error_m"] = s.translationError;
      }
      loops.push_back(l);
    }
  }
  doc["loops"] = loops;
  doc["per_scan"] = scans;
  return doc;
}

std::string placesSvg(const PlacesResult& r) {
  const double w = 900.0;
  const double h = 420.0;
  report::SvgDocument svg(w, h, {{"font-family", "sans-serif"}, {"font-size", "12"}});
  // Left: the key signatures (n.z on x, share on a square-root y scale).
  const double x0 = 40.0;
  const double y0 = 380.0;
  const double pw = 380.0;
  const double ph = 340.0;
  svg.addText("text", {{"x", x0}, {"y", 20.0}}, "normal signatures of the keys (x: n.z -1..1, y: sqrt share)");
  svg.add("rect", {{"x", x0}, {"y", y0 - ph}, {"width", pw}, {"height", ph}, {"fill", "none"}, {"stroke", "#888"}});
  std::size_t drawn = 0;
  for (std::size_t i = 0; i < r.scans.size() && drawn < 12; ++i) {
    if (!r.scans[i].update.isKey) {
      continue;
    }
    report::SvgPoints pts;
    for (std::size_t b = 0; b < kNormalSignatureBins; ++b) {
      pts.add(x0 + pw * static_cast<double>(b) / 100.0,
              y0 - ph * std::sqrt(static_cast<double>(r.signatures[i].bins[b])));
    }
    const char* colours[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b"};
    svg.add("polyline",
            {{"fill", "none"}, {"stroke", colours[drawn % 6]}, {"stroke-width", "1"}, {"points", pts.str()}});
    ++drawn;
  }
  // Right: the trajectory and its loops (green true, red false).
  if (!r.truth.empty()) {
    const double ox = 470.0;
    std::vector<Eigen::Vector2d> positions;
    for (const Pose2d& p : r.truth) {
      positions.emplace_back(p.x, p.y);
    }
    Eigen::Vector2d lo = positions.front();
    Eigen::Vector2d hi = lo;
    for (const Eigen::Vector2d& p : positions) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    const double span = std::max({hi.x() - lo.x(), hi.y() - lo.y(), 1.0});
    const auto px = [&](const Eigen::Vector2d& p) { return ox + 10.0 + 380.0 * (p.x() - lo.x()) / span; };
    const auto py = [&](const Eigen::Vector2d& p) { return y0 - 340.0 * (p.y() - lo.y()) / span; };
    svg.addText("text", {{"x", ox}, {"y", 20.0}}, "positions (ground truth) and detected loops");
    for (std::size_t i = 0; i < r.scans.size(); ++i) {
      svg.add("circle", {{"cx", px(positions[i])}, {"cy", py(positions[i])}, {"r", 2.0}, {"fill", "#444"}});
      const ScanResult& s = r.scans[i];
      if (s.update.loop) {
        const Eigen::Vector2d& k = positions[s.update.loopScan];
        svg.add("line", {{"x1", px(positions[i])},
                         {"y1", py(positions[i])},
                         {"x2", px(k)},
                         {"y2", py(k)},
                         {"stroke", s.loopTrue ? "#2ca02c" : "#d62728"},
                         {"stroke-width", "1.5"}});
      }
    }
  }
  return svg.str();
}

}  // namespace agv::places
