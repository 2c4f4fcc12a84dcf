// Normal and orientation signatures on the real KITTI 00 HDL-64E scans (../shared/data/lidar3d):
// the consecutive pairs 94/95 and 198/199 (about 1 m apart) are closer than every pair across the
// two places (58 m apart) under both distances; the yaw of each pair agrees with poses_00.txt; a
// scan turned by a known angle gives that angle back. Host only (reads files).
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "agv/core/angle.hpp"
#include "agv/datasets/lidar3d_scans.hpp"
#include "agv/lidar3d/normal_signature.hpp"
#include "agv/lidar3d/orientation_signature.hpp"
#include "agv/lidar3d/place_database.hpp"
#include "agv_test.hpp"

namespace {
const std::string kKitti = std::string(AGV_SHARED_DATA_DIR) + "/lidar3d/kitti00_hdl64/";

struct Scan {
  agv::datasets::Revolution revolution;
  agv::NormalSignature normal;
  agv::OrientationSignature orientation;
};

agv::Hdl64RangeImage& image() {
  static auto img = std::make_unique<agv::Hdl64RangeImage>();
  return *img;
}

Scan load(int frame) {
  Scan s;
  std::string err;
  char name[32];
  std::snprintf(name, sizeof(name), "%06d.bin", frame);
  INFO(kKitti + name);
  REQUIRE(agv::datasets::readKittiVelodyne(kKitti + name, s.revolution, err));  // missing data fails loudly
  REQUIRE(s.revolution.rings == 64U);
  const agv::Span<const agv::RingPoint> pts(s.revolution.points.data(), s.revolution.points.size());
  REQUIRE(image().reset(64, 2000) == agv::Status::Ok);
  REQUIRE(image().buildFromRings(pts) == agv::Status::Ok);
  CHECK(image().stats().refused() == 0U);
  REQUIRE(agv::computeNormalSignature(image(), agv::NormalSignatureParams{}, s.normal) == agv::Status::Ok);
  REQUIRE(agv::computeOrientationSignature(image(), agv::OrientationParams{}, s.orientation) == agv::Status::Ok);
  return s;
}

const std::vector<Scan>& scans() {
  static const std::vector<Scan> all = {load(94), load(95), load(198), load(199)};
  return all;
}
}  // namespace

TEST_CASE("lidar3d kitti: rings recovered in elevation order, signatures from real revolutions", "[lidar3d][kitti]") {
  const std::vector<Scan>& s = scans();
  for (const Scan& scan : s) {
    CHECK(scan.revolution.points.size() > 120000U);
    CHECK(scan.normal.counts.normals > 20000U);
    CHECK(scan.orientation.filled > 300U);
  }
  // Ring 0 is the top laser (+2 deg), ring 63 the bottom one (-24.8 deg).
  const auto& pts = s[0].revolution.points;
  double top = 0.0;
  double bottom = 0.0;
  int nTop = 0;
  int nBottom = 0;
  for (const agv::RingPoint& p : pts) {
    const double el = std::atan2(p.point.z(), std::hypot(p.point.x(), p.point.y()));
    if (p.ring == 0) {
      top += el;
      ++nTop;
    } else if (p.ring == 63) {
      bottom += el;
      ++nBottom;
    }
  }
  REQUIRE(nTop > 0);
  REQUIRE(nBottom > 0);
  CHECK(agv::rad2deg(top / nTop) > 1.0);
  CHECK(agv::rad2deg(bottom / nBottom) < -20.0);
}

TEST_CASE("lidar3d kitti: consecutive scans are closer than scans of the other place under both distances",
          "[lidar3d][kitti]") {
  const std::vector<Scan>& s = scans();  // 0: 94, 1: 95, 2: 198, 3: 199
  const float pos1chi = agv::chiSquareDistance(s[0].normal, s[1].normal);
  const float pos2chi = agv::chiSquareDistance(s[2].normal, s[3].normal);
  const float pos1sor = agv::sorensenDistance(s[0].normal, s[1].normal);
  const float pos2sor = agv::sorensenDistance(s[2].normal, s[3].normal);
  for (int a = 0; a < 2; ++a) {
    for (int b = 2; b < 4; ++b) {
      const float negChi = agv::chiSquareDistance(s[a].normal, s[b].normal);
      const float negSor = agv::sorensenDistance(s[a].normal, s[b].normal);
      INFO("pair " << a << "/" << b << " chi2 " << negChi << " sor " << negSor << "; positives chi2 " << pos1chi << ", "
                   << pos2chi << " sor " << pos1sor << ", " << pos2sor);
      CHECK(pos1chi < negChi);
      CHECK(pos2chi < negChi);
      CHECK(pos1sor < negSor);
      CHECK(pos2sor < negSor);
    }
  }
  // The default place thresholds accept both positive pairs and refuse the negative pair 94/198.
  const agv::PlaceParams p;
  CHECK(pos1chi < p.chiSquareThreshold);
  CHECK(pos2chi < p.chiSquareThreshold);
  CHECK(pos1sor < p.sorensenThreshold);
  CHECK(pos2sor < p.sorensenThreshold);
  CHECK_FALSE((agv::chiSquareDistance(s[0].normal, s[2].normal) < p.chiSquareThreshold &&
               agv::sorensenDistance(s[0].normal, s[2].normal) < p.sorensenThreshold));
}

TEST_CASE("lidar3d kitti: the yaw of the consecutive pairs agrees with poses_00.txt within 1 deg", "[lidar3d][kitti]") {
  std::vector<Eigen::Matrix<double, 3, 4>> poses;
  std::string err;
  REQUIRE(agv::datasets::readKittiPoses(kKitti + "poses_00.txt", poses, err));
  REQUIRE(poses.size() == 4541U);
  const std::vector<Scan>& s = scans();
  const int frames[2][2] = {{94, 95}, {198, 199}};
  for (int k = 0; k < 2; ++k) {
    const double truth = agv::datasets::kittiRelativeYaw(poses[frames[k][0]], poses[frames[k][1]]);
    const agv::Result<agv::YawEstimate> est = agv::relativeYaw(s[2 * k].orientation, s[2 * k + 1].orientation);
    REQUIRE(est.ok());
    INFO("frames " << frames[k][0] << "/" << frames[k][1] << " truth " << agv::rad2deg(truth) << " deg, estimate "
                   << agv::rad2deg(static_cast<double>(est.value().yaw)) << " deg");
    AGV_CHECK_NEAR(agv::rad2deg(agv::angleDiff(static_cast<double>(est.value().yaw), truth)), 0.0, 1.0);
  }
}

TEST_CASE("lidar3d kitti: a real scan turned by a known angle gives the angle back within 0.5 deg",
          "[lidar3d][kitti]") {
  const std::vector<Scan>& s = scans();
  const double angles[] = {17.3, -95.6, 170.2, 0.4, 63.75};
  for (int k = 0; k < 4; k += 2) {
    for (const double deg : angles) {
      // Turning the points by +angle is the sensor turned by -angle.
      const double c = std::cos(agv::deg2rad(deg));
      const double sn = std::sin(agv::deg2rad(deg));
      std::vector<agv::RingPoint> turned = s[k].revolution.points;
      for (agv::RingPoint& p : turned) {
        const double x = p.point.x();
        const double y = p.point.y();
        p.point.x() = static_cast<float>(c * x - sn * y);
        p.point.y() = static_cast<float>(sn * x + c * y);
      }
      REQUIRE(image().buildFromRings(agv::Span<const agv::RingPoint>(turned.data(), turned.size())) == agv::Status::Ok);
      agv::OrientationSignature o;
      agv::NormalSignature n;
      REQUIRE(agv::computeOrientationSignature(image(), agv::OrientationParams{}, o) == agv::Status::Ok);
      REQUIRE(agv::computeNormalSignature(image(), agv::NormalSignatureParams{}, n) == agv::Status::Ok);
      const agv::Result<agv::YawEstimate> est = agv::relativeYaw(s[k].orientation, o);
      REQUIRE(est.ok());
      INFO("scan " << k << " turned " << deg << " deg: estimate " << agv::rad2deg(-est.value().yaw));
      AGV_CHECK_NEAR(agv::rad2deg(agv::angleDiff(static_cast<double>(-est.value().yaw), agv::deg2rad(deg))), 0.0, 0.5);
      // Yaw invariance of the normal signature on real data: far below the positive pairs' distance.
      CHECK(agv::chiSquareDistance(s[k].normal, n) < 0.5F * agv::chiSquareDistance(s[0].normal, s[1].normal));
    }
  }
}

TEST_CASE("lidar3d nclt: an HDL-32E revolution with interleaved laser ids gives a signature", "[lidar3d][nclt]") {
  agv::datasets::Revolution rev;
  std::string err;
  REQUIRE(agv::datasets::readNcltVelodyne(std::string(AGV_SHARED_DATA_DIR) + "/lidar3d/nclt_hdl32/1326652795280148.bin",
                                          rev, err));
  CHECK(rev.points.size() == 23546U);
  CHECK(rev.rings == 32U);
  static agv::RangeImage<32, 1024> img;
  REQUIRE(img.reset(32, 1024) == agv::Status::Ok);
  REQUIRE(img.buildFromRings(agv::Span<const agv::RingPoint>(rev.points.data(), rev.points.size())) == agv::Status::Ok);
  agv::NormalSignature n;
  REQUIRE(agv::computeNormalSignature(img, agv::NormalSignatureParams{}, n) == agv::Status::Ok);
  INFO("normals " << n.counts.normals << " out of range " << n.counts.outOfRange << " missing neighbour "
                  << n.counts.missingNeighbour << " too far " << n.counts.neighbourTooFar << " degenerate "
                  << n.counts.degenerate);
  CHECK(n.counts.normals > 500U);
  // More lasers than the image holds: refused and counted.
  static agv::RangeImage<16, 1024> small;
  CHECK(small.buildFromRings(agv::Span<const agv::RingPoint>(rev.points.data(), rev.points.size())) ==
        agv::Status::CapacityExceeded);
  CHECK(small.stats().rowOverCapacity > 0U);
}
