// Range image, beam-arrangement normals, normal and orientation signatures and the place database
// on ray-cast scenes (lidar3d_sim.hpp) and hand-made histograms. Portable: also in the MCU image
// (static images, no std::vector).
#include <cmath>
#include <cstdint>

#include "agv/lidar3d/normal_signature.hpp"
#include "agv/lidar3d/orientation_signature.hpp"
#include "agv/lidar3d/place_database.hpp"
#include "agv/lidar3d/profile_alignment.hpp"
#include "agv/lidar3d/range_image.hpp"
#include "agv_test.hpp"
#include "lidar3d_sim.hpp"

using agv::deg2rad;
using agv::rad2deg;

namespace {

constexpr std::size_t kLasers = 16;
constexpr std::size_t kFirings = 900;  // 0.4 deg: half the VLP-16's 10 Hz resolution (MCU RAM)
using TestImage = agv::RangeImage<kLasers, kFirings>;

TestImage g_image;  // one image (230 KiB): the MCU image has ~650 KiB of RAM left
// Scratch signatures for the test cases that need no second one: every static object is RAM of
// the MCU image (which has room for a few hundred bytes more).
agv::NormalSignature g_sig;
agv::OrientationSignature g_ori;
std::int8_t g_plane[kLasers * kFirings];

/// VLP-16 normals: lasers one step (2 deg) above and below. Two steps (4 deg, the thesis' choice for
/// the HDL-64E's 0.4-deg steps) put floor neighbours at grazing incidence farther apart than the
/// depth-jump rule allows (at 11 deg elevation the range changes by ~cot(11 deg) * 4 deg = 36 %).
agv::BeamNormalParams vlpNormals() {
  agv::BeamNormalParams p;
  p.laserStep = 1;
  return p;
}

agv::NormalSignatureParams vlpSignature() {
  agv::NormalSignatureParams p;
  p.normals = vlpNormals();
  return p;
}

agv::test::SimLidar vlp16(double noise) {
  agv::test::SimLidar l;
  l.lasers = kLasers;
  l.firings = kFirings;
  l.rangeNoise = noise;
  return l;
}

/// Angle [deg] between a normal and the true one oriented towards the sensor at the origin.
double angleToTruth(const Eigen::Vector3f& n, const Eigen::Vector3d& truth, const Eigen::Vector3f& point) {
  Eigen::Vector3d t = truth;
  if (t.dot(point.cast<double>()) > 0.0) {
    t = -t;
  }
  const double c = std::fmin(1.0, std::fabs(n.cast<double>().dot(t)) * 1.0);
  const double sign = n.cast<double>().dot(t) >= 0.0 ? 1.0 : -1.0;
  return sign > 0.0 ? rad2deg(std::acos(c)) : 180.0 - rad2deg(std::acos(c));
}

/// True when the cell and its four beam neighbours hit the same plane (the normal's truth is known).
bool onePlane(std::size_t r, std::size_t c, const agv::BeamNormalParams& p) {
  if (r < p.laserStep || r + p.laserStep >= kLasers) {
    return false;
  }
  const int id = g_plane[r * kFirings + c];
  const std::size_t before = (c + kFirings - p.firingStep) % kFirings;
  const std::size_t after = (c + p.firingStep) % kFirings;
  return id >= 0 && g_plane[r * kFirings + before] == id && g_plane[r * kFirings + after] == id &&
         g_plane[(r - p.laserStep) * kFirings + c] == id && g_plane[(r + p.laserStep) * kFirings + c] == id;
}

/// A scene with a floor, four walls and a plane tilted by 35 deg (a ramp): every plane seen.
agv::test::SimScene rampRoom() {
  agv::test::SimScene s = agv::test::boxRoom(-9.0, 13.0, -7.0, 10.0, -1.8, 6.0, false);
  // Ramp rising towards +x: normal (-sin 35, 0, cos 35), through (6, 0, -1.8).
  const Eigen::Vector3d n(-std::sin(deg2rad(35.0)), 0.0, std::cos(deg2rad(35.0)));
  s.add(n, n.dot(Eigen::Vector3d(6.0, 0.0, -1.8)));
  return s;
}

/// Checks the normals of every cell whose neighbourhood lies on one plane; returns how many.
/// noiseFree: every one within 0.05 deg (float rounding of points at <= 50 m over baselines of
/// >= 0.1 m: ~1e-6 * 50 / 0.1 rad, 0.03 deg). Otherwise the range noise sigma gives each normal a
/// predicted angular standard deviation s = sqrt(2) sigma sqrt(1/|u|^2 + 1/|v|^2) (u, v the two
/// differences); among the normals with s <= 0.5 deg, at most 1 % may exceed 2 deg (= 4 s:
/// 2-D Gaussian tail exp(-8) = 3e-4).
void checkPlaneNormals(const agv::test::SimScene& scene, const agv::BeamNormalParams& p, double sigma,
                       std::size_t& checked, std::size_t& tilted, std::size_t& outliers) {
  checked = 0;
  tilted = 0;
  outliers = 0;
  for (std::size_t r = 0; r < kLasers; ++r) {
    for (std::size_t c = 0; c < kFirings; ++c) {
      if (!onePlane(r, c, p)) {
        continue;
      }
      Eigen::Vector3f n;
      if (agv::beamNormal(g_image, r, c, p, n) != agv::NormalSkip::None) {
        continue;
      }
      const int id = g_plane[r * kFirings + c];
      const Eigen::Vector3f pt = g_image.at(r, c).point;
      const double err = angleToTruth(n, scene.planes[id].n, pt);
      if (sigma == 0.0) {
        ++checked;
        if (err > 0.05) {
          ++outliers;
        }
      } else {
        const std::size_t b = (c + kFirings - p.firingStep) % kFirings;
        const std::size_t a = (c + p.firingStep) % kFirings;
        const double u = (g_image.at(r, a).point - g_image.at(r, b).point).norm();
        const double v = (g_image.at(r + p.laserStep, c).point - g_image.at(r - p.laserStep, c).point).norm();
        const double s = rad2deg(std::sqrt(2.0) * sigma * std::sqrt(1.0 / (u * u) + 1.0 / (v * v)));
        if (s > 0.5) {
          continue;
        }
        ++checked;
        if (err > 2.0) {
          ++outliers;
        }
      }
      if (id == 5) {
        ++tilted;
      }
    }
  }
}

}  // namespace

TEST_CASE("lidar3d: beam normals of a floor, walls and a tilted plane are exact without noise", "[lidar3d]") {
  agv::test::LoopRng rng{7};
  const agv::test::SimScene scene = rampRoom();
  REQUIRE(agv::test::castScene(scene, vlp16(0.0), Eigen::Vector3d::Zero(), 0.0, 0.0, rng, g_image, g_plane) > 10000U);
  std::size_t checked = 0;
  std::size_t tilted = 0;
  std::size_t outliers = 0;
  // The thesis' neighbourhood (lasers two steps away) and the VLP-16 one (one step).
  checkPlaneNormals(scene, agv::BeamNormalParams{}, 0.0, checked, tilted, outliers);
  INFO("checked " << checked << " tilted " << tilted);
  CHECK(checked > 2000U);
  CHECK(tilted > 100U);
  CHECK(outliers == 0U);
  checkPlaneNormals(scene, vlpNormals(), 0.0, checked, tilted, outliers);
  CHECK(checked > 3000U);
  CHECK(tilted > 100U);
  CHECK(outliers == 0U);
}

TEST_CASE("lidar3d: beam normals with 3 mm range noise stay within 2 deg where the geometry predicts it", "[lidar3d]") {
  agv::test::LoopRng rng{11};
  const agv::test::SimScene scene = rampRoom();
  const double sigma = 0.003;
  REQUIRE(agv::test::castScene(scene, vlp16(sigma), Eigen::Vector3d::Zero(), 0.0, 0.0, rng, g_image, g_plane) > 10000U);
  std::size_t checked = 0;
  std::size_t tilted = 0;
  std::size_t outliers = 0;
  checkPlaneNormals(scene, vlpNormals(), sigma, checked, tilted, outliers);
  INFO("checked " << checked << " tilted " << tilted << " outliers " << outliers);
  CHECK(checked > 1000U);
  CHECK(tilted > 50U);
  CHECK(outliers * 100U <= checked);
}

TEST_CASE("lidar3d: a box room gives histogram peaks at n.z = 0 and 1 in the proportions of walls and floor",
          "[lidar3d]") {
  agv::test::LoopRng rng{3};
  const agv::test::SimScene room = agv::test::boxRoom(-16.0, 24.0, -12.0, 18.0, -1.8, 5.0, false);
  REQUIRE(agv::test::castScene(room, vlp16(0.0), Eigen::Vector3d::Zero(), 0.0, 0.0, rng, g_image, g_plane) > 0U);
  agv::NormalSignature sig;
  REQUIRE(agv::computeNormalSignature(g_image, vlpSignature(), sig) == agv::Status::Ok);
  // Truth: of the computed normals, those whose neighbourhood lies on the floor / on one wall; the
  // rest (neighbours across an edge) have no single truth and bound the disagreement.
  const agv::BeamNormalParams p = vlpNormals();
  std::size_t floor = 0;
  std::size_t wall = 0;
  std::size_t mixed = 0;
  for (std::size_t r = 0; r < kLasers; ++r) {
    for (std::size_t c = 0; c < kFirings; ++c) {
      Eigen::Vector3f n;
      if (agv::beamNormal(g_image, r, c, p, n) != agv::NormalSkip::None) {
        continue;
      }
      if (!onePlane(r, c, p)) {
        ++mixed;
      } else if (g_plane[r * kFirings + c] == 0) {
        ++floor;
      } else {
        ++wall;
      }
    }
  }
  const double total = static_cast<double>(floor + wall + mixed);
  REQUIRE(total == static_cast<double>(sig.counts.normals));
  const double floorShare = static_cast<double>(floor) / total;
  const double wallShare = static_cast<double>(wall) / total;
  const double mixedShare = static_cast<double>(mixed) / total;
  INFO("floor " << floorShare << " wall " << wallShare << " mixed " << mixedShare);
  CHECK(floorShare > 0.1);
  CHECK(wallShare > 0.2);
  CHECK(agv::normalBin(0.0F) == 50U);
  CHECK(agv::normalBin(1.0F) == 100U);
  const double peakWall = sig.bins[50];
  const double peakFloor = sig.bins[100];
  // Every normal of a single plane is within 0.05 deg of its truth (noise-free), so it lands in
  // its bin: each peak holds at least its plane's share, and at most that plus the mixed normals.
  CHECK(peakWall >= wallShare - 1e-5);
  CHECK(peakWall <= wallShare + mixedShare + 1e-5);
  CHECK(peakFloor >= floorShare - 1e-5);
  CHECK(peakFloor <= floorShare + mixedShare + 1e-5);
  for (std::size_t b = 0; b < agv::kNormalSignatureBins; ++b) {
    if (b != 50 && b != 100) {
      CHECK(sig.bins[b] <= mixedShare + 1e-4);
    }
  }
}

TEST_CASE(
    "lidar3d: the normal signature does not change when the sensor turns; the orientation signature gives the turn",
    "[lidar3d]") {
  const agv::test::SimScene room = agv::test::boxRoom(-16.0, 24.0, -12.0, 18.0, -1.8, 5.0, false);
  const double sigma = 0.005;
  agv::test::LoopRng rng{5};
  REQUIRE(agv::test::castScene(room, vlp16(sigma), Eigen::Vector3d::Zero(), 0.0, 0.0, rng, g_image) > 0U);
  static agv::NormalSignature ref;
  static agv::OrientationSignature refOrientation;
  REQUIRE(agv::computeNormalSignature(g_image, vlpSignature(), ref) == agv::Status::Ok);
  REQUIRE(agv::computeOrientationSignature(g_image, agv::OrientationParams{}, refOrientation) == agv::Status::Ok);
  // Two draws of the same histogram with N normals differ by chi-square ~ 2 (1 - sum p^2) / N on
  // average (multinomial variance p (1 - p) / N per bin, twice, over P + Q + 1 >= 1): allow 10x.
  double sumP2 = 0.0;
  for (const float p : ref.bins) {
    sumP2 += static_cast<double>(p) * p;
  }
  const double bound = 10.0 * 2.0 * (1.0 - sumP2) / static_cast<double>(ref.counts.normals);
  const double yaws[] = {10.0, 47.3, 135.0, -98.6};
  for (const double yawDeg : yaws) {
    static agv::NormalSignature turned;
    static agv::OrientationSignature turnedOrientation;
    REQUIRE(agv::test::castScene(room, vlp16(sigma), Eigen::Vector3d::Zero(), deg2rad(yawDeg), 0.37, rng, g_image) >
            0U);
    REQUIRE(agv::computeNormalSignature(g_image, vlpSignature(), turned) == agv::Status::Ok);
    INFO("yaw " << yawDeg << " chi2 " << agv::chiSquareDistance(ref, turned) << " bound " << bound);
    CHECK(agv::chiSquareDistance(ref, turned) <= bound);
    REQUIRE(agv::computeOrientationSignature(g_image, agv::OrientationParams{}, turnedOrientation) == agv::Status::Ok);
    const agv::Result<agv::YawEstimate> yaw = agv::relativeYaw(refOrientation, turnedOrientation);
    REQUIRE(yaw.ok());
    INFO("estimated " << rad2deg(yaw.value().yaw));
    // Sub-degree: 0.1 deg (measured at most 0.04); the best 1-deg shift alone is 0.3 deg off at
    // 47.3 and 0.4 deg at -98.6.
    AGV_CHECK_NEAR(rad2deg(agv::angleDiff(static_cast<double>(yaw.value().yaw), deg2rad(yawDeg))), 0.0, 0.1);
  }
  // The bound tells places apart: a room with a ramp is farther.
  REQUIRE(agv::test::castScene(rampRoom(), vlp16(sigma), Eigen::Vector3d::Zero(), 0.0, 0.0, rng, g_image) > 0U);
  static agv::NormalSignature elsewhere;
  REQUIRE(agv::computeNormalSignature(g_image, vlpSignature(), elsewhere) == agv::Status::Ok);
  CHECK(agv::chiSquareDistance(ref, elsewhere) > 3.0 * bound);
}

TEST_CASE("lidar3d: chi-square and Sorensen distances are symmetric, zero on identity and within [0, 1]", "[lidar3d]") {
  agv::test::LoopRng rng{21};
  static agv::NormalSignature a;
  static agv::NormalSignature b;
  for (int trial = 0; trial < 50; ++trial) {
    float sa = 0.0F;
    float sb = 0.0F;
    for (std::size_t i = 0; i < agv::kNormalSignatureBins; ++i) {
      // Sparse random histograms (some bins empty) so that disjoint supports occur too.
      a.bins[i] = rng.uniform() < 0.3 ? static_cast<float>(rng.uniform()) : 0.0F;
      b.bins[i] = rng.uniform() < 0.3 ? static_cast<float>(rng.uniform()) : 0.0F;
      sa += a.bins[i];
      sb += b.bins[i];
    }
    float l1 = 0.0F;
    for (std::size_t i = 0; i < agv::kNormalSignatureBins; ++i) {
      a.bins[i] /= sa;
      b.bins[i] /= sb;
      l1 += std::fabs(a.bins[i] - b.bins[i]);
    }
    a.counts.normals = 1;
    b.counts.normals = 1;
    const float chi = agv::chiSquareDistance(a, b);
    const float sor = agv::sorensenDistance(a, b);
    CHECK(chi == agv::chiSquareDistance(b, a));
    CHECK(sor == agv::sorensenDistance(b, a));
    CHECK(agv::chiSquareDistance(a, a) == 0.0F);
    CHECK(agv::sorensenDistance(a, a) == 0.0F);
    CHECK(chi > 0.0F);
    CHECK(chi <= 0.5F * l1 + 1e-6F);  // each term d^2 / (P + Q + 1) <= d / 2
    CHECK(sor > 0.0F);
    CHECK(sor <= 1.0F + 1e-6F);
    AGV_CHECK_NEAR(sor, 0.5F * l1, 1e-5);  // sum (P + Q) = 2
  }
  // Disjoint one-bin histograms reach the upper bound 1 of both.
  a = agv::NormalSignature{};
  b = agv::NormalSignature{};
  a.bins[0] = 1.0F;
  b.bins[100] = 1.0F;
  AGV_CHECK_NEAR(agv::chiSquareDistance(a, b), 1.0, 1e-6);
  AGV_CHECK_NEAR(agv::sorensenDistance(a, b), 1.0, 1e-6);
  // Empty signatures: 0 between themselves.
  CHECK(agv::sorensenDistance(agv::NormalSignature{}, agv::NormalSignature{}) == 0.0F);
}

TEST_CASE("lidar3d: bad input is refused and counted", "[lidar3d]") {
  agv::NormalSignature& sig = g_sig;
  agv::OrientationSignature& ori = g_ori;
  // Shape beyond the capacity: refused, counted, image left empty.
  CHECK(g_image.reset(kLasers + 1, kFirings) == agv::Status::CapacityExceeded);
  CHECK(g_image.reset(kLasers, kFirings + 1) == agv::Status::CapacityExceeded);
  CHECK(g_image.shapeRefusedCount() == 2U);
  CHECK(g_image.reset(0, 10) == agv::Status::InvalidArgument);
  REQUIRE(g_image.reset(kLasers, kFirings) == agv::Status::Ok);
  // Empty revolution.
  CHECK(g_image.buildFromRings(agv::Span<const agv::RingPoint>()) == agv::Status::EmptyInput);
  CHECK(agv::computeNormalSignature(g_image, vlpSignature(), sig) == agv::Status::EmptyInput);
  CHECK(sig.empty());
  CHECK(agv::computeOrientationSignature(g_image, agv::OrientationParams{}, ori) == agv::Status::EmptyInput);
  // All-invalid rings (every return zero = no return).
  static agv::RingPoint pts[64];
  for (std::size_t i = 0; i < 64; ++i) {
    pts[i].ring = static_cast<std::uint16_t>(i % kLasers);
  }
  CHECK(g_image.buildFromRings(agv::Span<const agv::RingPoint>(pts, 64)) == agv::Status::NotEnoughData);
  CHECK(g_image.stats().noReturn == 64U);
  CHECK(g_image.validCount() == 0U);
  CHECK(agv::computeNormalSignature(g_image, vlpSignature(), sig) == agv::Status::EmptyInput);
  CHECK(sig.empty());
  CHECK(agv::computeOrientationSignature(g_image, agv::OrientationParams{}, ori) == agv::Status::EmptyInput);
  CHECK(ori.empty());
  // NaN points: refused and counted, the others kept.
  for (std::size_t i = 0; i < 64; ++i) {
    pts[i].point = Eigen::Vector3f(5.0F + static_cast<float>(i) * 0.01F, 1.0F, 0.0F);
  }
  pts[3].point.x() = std::nanf("");
  pts[9].point.z() = INFINITY;
  CHECK(g_image.buildFromRings(agv::Span<const agv::RingPoint>(pts, 64)) == agv::Status::NonFiniteInput);
  CHECK(g_image.stats().nonFinite == 2U);
  CHECK(g_image.stats().placed + g_image.stats().collisions >= 62U);
  // More lasers than rows: refused and counted, not truncated silently.
  pts[5].ring = kLasers;
  pts[6].ring = 200;
  pts[3].point.x() = 1.0F;
  pts[9].point.z() = 1.0F;
  CHECK(g_image.buildFromRings(agv::Span<const agv::RingPoint>(pts, 64)) == agv::Status::CapacityExceeded);
  CHECK(g_image.stats().rowOverCapacity == 2U);
  // Firing records beyond the columns or with unknown laser ids.
  static agv::FiringReturn returns[4];
  const std::uint16_t rowOf[2] = {1, 0};
  returns[0] = agv::FiringReturn{Eigen::Vector3f(4.0F, 0.0F, 0.0F), 0, 0};
  returns[1] = agv::FiringReturn{Eigen::Vector3f(4.0F, 0.0F, 0.0F), 1, kFirings};
  returns[2] = agv::FiringReturn{Eigen::Vector3f(4.0F, 0.0F, 0.0F), 2, 3};
  returns[3] = agv::FiringReturn{Eigen::Vector3f(4.0F, 0.0F, 0.0F), 1, 7};
  CHECK(g_image.buildFromFirings(agv::Span<const agv::FiringReturn>(returns, 4),
                                 agv::Span<const std::uint16_t>(rowOf, 2)) == agv::Status::CapacityExceeded);
  CHECK(g_image.stats().columnOverCapacity == 1U);
  CHECK(g_image.stats().rowOverCapacity == 1U);
  CHECK(g_image.at(1, 0).valid());
  CHECK(g_image.at(0, 7).valid());
  // Too few normals for a signature.
  CHECK(agv::computeNormalSignature(g_image, vlpSignature(), sig) == agv::Status::NotEnoughData);
  CHECK(sig.empty());
  CHECK(sig.counts.belowMinimum < vlpSignature().minNormals);
  agv::NormalSignatureParams bad;
  bad.normals.maxRange = std::nanf("");
  CHECK(agv::computeNormalSignature(g_image, bad, sig) == agv::Status::InvalidArgument);
  // Orientation: nothing to compare.
  CHECK(agv::relativeYaw(agv::OrientationSignature{}, agv::OrientationSignature{}).status() ==
        agv::Status::NotEnoughData);
  // Elevation ranks: NaN and size mismatch.
  const float elev[3] = {0.1F, -0.2F, std::nanf("")};
  std::uint16_t ranks[3] = {};
  CHECK(agv::elevationRanks(agv::Span<const float>(elev, 3), agv::Span<std::uint16_t>(ranks, 3)) ==
        agv::Status::NonFiniteInput);
  CHECK(agv::elevationRanks(agv::Span<const float>(elev, 2), agv::Span<std::uint16_t>(ranks, 3)) ==
        agv::Status::InvalidArgument);
  REQUIRE(agv::elevationRanks(agv::Span<const float>(elev, 2), agv::Span<std::uint16_t>(ranks, 2)) == agv::Status::Ok);
  CHECK(ranks[0] == 1U);
  CHECK(ranks[1] == 0U);
}

namespace {
/// A point of the flat wall x = distance seen at elevation (row - 3) deg and azimuth
/// (column - 30) * 0.25 deg, times `scale` along its ray.
Eigen::Vector3f wallPoint(std::size_t row, std::size_t column, float distance, float scale) {
  const double el = deg2rad(static_cast<double>(row) - 3.0);
  const double az = deg2rad((static_cast<double>(column) - 30.0) * 0.25);
  const double d = static_cast<double>(distance);
  return Eigen::Vector3f(distance, static_cast<float>(d * std::tan(az)),
                         static_cast<float>(d * std::tan(el) / std::cos(az))) *
         scale;
}

/// A fresh 7 x 60 shape holding the wall in rows 0..6, columns 10..49 (280 returns); `deadRow` (if
/// < 7) gets no return; the return at (3, 30) lies `farScale` times farther along its ray.
void wallImage(float distance, std::size_t deadRow, float farScale) {
  CHECK(g_image.reset(7, 60) == agv::Status::Ok);
  for (std::size_t r = 0; r < 7; ++r) {
    for (std::size_t c = 10; c < 50 && r != deadRow; ++c) {
      const float scale = r == 3 && c == 30 ? farScale : 1.0F;
      CHECK(g_image.set(r, c, wallPoint(r, c, distance, scale)) == agv::Status::Ok);
    }
  }
}

/// Lasers one row apart, firings two columns apart, any number of normals: small hand-made images.
agv::NormalSignatureParams smallNeighbourhood() {
  agv::NormalSignatureParams p;
  p.normals.firingStep = 2;
  p.normals.laserStep = 1;
  p.minNormals = 1;
  return p;
}

/// A 3 x 12 shape with a return at (1, 0) (10 m ahead), the firings two columns after it
/// (column 2) and before it (column 10 across the seam, when `withSeam`), 0.1 m to either side, and
/// the lasers below / above it lifted by -+0.1 * lift m in z and, for lift < 1, also -+0.05 m in y
/// (nearly parallel to the firing difference for small lift). The normal at (1, 0).
agv::NormalSkip seamCell(bool withSeam, float lift, Eigen::Vector3f& n) {
  const agv::BeamNormalParams p = smallNeighbourhood().normals;
  const float side = lift < 1.0F ? 0.05F : 0.0F;
  CHECK(g_image.reset(3, 12) == agv::Status::Ok);
  CHECK(g_image.set(1, 0, Eigen::Vector3f(10.0F, 0.0F, 0.0F)) == agv::Status::Ok);
  if (withSeam) {
    CHECK(g_image.set(1, 10, Eigen::Vector3f(10.0F, -0.1F, 0.0F)) == agv::Status::Ok);
  }
  CHECK(g_image.set(1, 2, Eigen::Vector3f(10.0F, 0.1F, 0.0F)) == agv::Status::Ok);
  CHECK(g_image.set(0, 0, Eigen::Vector3f(10.0F, -side, -0.1F * lift)) == agv::Status::Ok);
  CHECK(g_image.set(2, 0, Eigen::Vector3f(10.0F, side, 0.1F * lift)) == agv::Status::Ok);
  return agv::beamNormal(g_image, 1, 0, p, n);
}
}  // namespace

TEST_CASE("lidar3d: the skip rule of the normals: range 3..50 m, missing and far neighbours, parallel differences",
          "[lidar3d]") {
  const agv::NormalSignatureParams params = smallNeighbourhood();
  agv::NormalSignature& sig = g_sig;
  Eigen::Vector3f n;
  // A wall at 10 m seen by 7 lasers over 40 firings: 280 returns. Normals where all four neighbours
  // exist (rows 1..5, columns 12..47: 180); rows 0 and 6 lack a laser below / above (80) and
  // columns 10, 11, 48, 49 of rows 1..5 a firing before / after (20).
  wallImage(10.0F, 7, 1.0F);
  REQUIRE(g_image.validCount() == 280U);
  REQUIRE(agv::computeNormalSignature(g_image, params, sig) == agv::Status::Ok);
  CHECK(sig.counts.normals == 180U);
  CHECK(sig.counts.missingNeighbour == 100U);
  CHECK(sig.counts.outOfRange == 0U);
  CHECK(sig.counts.neighbourTooFar == 0U);
  CHECK(sig.counts.degenerate == 0U);
  AGV_CHECK_NEAR(sig.bins[50], 1.0, 1e-6);  // a wall: n.z = 0
  REQUIRE(agv::beamNormal(g_image, 3, 30, params.normals, n) == agv::NormalSkip::None);
  AGV_CHECK_NEAR(n.x(), -1.0, 1e-5);  // towards the sensor
  CHECK(agv::beamNormal(g_image, 0, 30, params.normals, n) == agv::NormalSkip::MissingNeighbour);
  CHECK(agv::beamNormal(g_image, 6, 30, params.normals, n) == agv::NormalSkip::MissingNeighbour);
  CHECK(agv::beamNormal(g_image, 3, 11, params.normals, n) == agv::NormalSkip::MissingNeighbour);
  CHECK(agv::beamNormal(g_image, 3, 5, params.normals, n) == agv::NormalSkip::OutOfRange);  // no return

  // Points 3..50 m only: the wall's ranges lie within 0.52 % above its distance.
  const float distances[] = {2.9F, 3.05F, 49.5F, 50.5F};
  const std::uint32_t expected[] = {0U, 180U, 180U, 0U};
  for (std::size_t i = 0; i < 4; ++i) {
    wallImage(distances[i], 7, 1.0F);
    const agv::Status st = agv::computeNormalSignature(g_image, params, sig);
    INFO("wall at " << distances[i] << " m: normals " << sig.counts.normals << ", out of range "
                    << sig.counts.outOfRange);
    CHECK(st == (expected[i] > 0U ? agv::Status::Ok : agv::Status::NotEnoughData));
    CHECK(sig.counts.normals == expected[i]);
    CHECK(sig.counts.outOfRange == (expected[i] > 0U ? 0U : 280U));
  }

  // A depth jump: the return at (3, 30) 40 % farther along its ray (4 m behind the wall: beyond
  // 0.25 x its range from its neighbours, and beyond 0.25 x theirs from them): it and the four
  // returns that use it as a neighbour are skipped.
  wallImage(10.0F, 7, 1.4F);
  REQUIRE(agv::computeNormalSignature(g_image, params, sig) == agv::Status::Ok);
  CHECK(sig.counts.neighbourTooFar == 5U);
  CHECK(sig.counts.normals == 175U);
  CHECK(sig.counts.missingNeighbour == 100U);
  CHECK(agv::beamNormal(g_image, 3, 30, params.normals, n) == agv::NormalSkip::NeighbourTooFar);
  CHECK(agv::beamNormal(g_image, 3, 28, params.normals, n) == agv::NormalSkip::NeighbourTooFar);
  CHECK(agv::beamNormal(g_image, 3, 32, params.normals, n) == agv::NormalSkip::NeighbourTooFar);
  CHECK(agv::beamNormal(g_image, 2, 30, params.normals, n) == agv::NormalSkip::NeighbourTooFar);
  CHECK(agv::beamNormal(g_image, 4, 30, params.normals, n) == agv::NormalSkip::NeighbourTooFar);
  CHECK(agv::beamNormal(g_image, 3, 34, params.normals, n) == agv::NormalSkip::None);

  // An all-invalid ring inside a revolution: the rings next to it lose a neighbour (rows 2 and 4),
  // rows 1 and 5 keep their normals (72); the orientation signature takes the row nearest the
  // horizon that has returns (2 or 4, both 1 deg off), not the dead one.
  wallImage(10.0F, 3, 1.0F);
  REQUIRE(g_image.validCount() == 240U);
  REQUIRE(agv::computeNormalSignature(g_image, params, sig) == agv::Status::Ok);
  CHECK(sig.counts.normals == 72U);
  CHECK(sig.counts.missingNeighbour == 168U);
  const agv::Result<std::size_t> row = agv::orientationRow(g_image, 0.0F);
  REQUIRE(row.ok());
  CHECK((row.value() == 2U || row.value() == 4U));
  agv::OrientationParams op;
  op.minFilledBins = 5;  // the wall spans 10 deg
  agv::OrientationSignature& ori = g_ori;
  REQUIRE(agv::computeOrientationSignature(g_image, op, ori) == agv::Status::Ok);
  CHECK(ori.row == row.value());
  CHECK(ori.filled >= 9U);

  // Columns wrap around (a revolution has no seam): at column 0 of 12 the firing before is column
  // 10; without a return there the neighbour is missing.
  CHECK(seamCell(true, 1.0F, n) == agv::NormalSkip::None);
  AGV_CHECK_NEAR(n.x(), -1.0, 1e-5);
  CHECK(seamCell(false, 1.0F, n) == agv::NormalSkip::MissingNeighbour);
  // Parallel differences (both along y) have no normal; nearly parallel ones within minSine (0.1):
  // sin 0.08 refused, sin 0.37 accepted.
  CHECK(seamCell(true, 0.0F, n) == agv::NormalSkip::Degenerate);
  CHECK(seamCell(true, 0.04F, n) == agv::NormalSkip::Degenerate);
  CHECK(seamCell(true, 0.2F, n) == agv::NormalSkip::None);
}

namespace {
/// A normalised histogram: a bump of width 3 bins at `centre` plus a floor peak.
agv::NormalSignature bump(double centre, double floorShare) {
  agv::NormalSignature s;
  double sum = 0.0;
  for (std::size_t i = 0; i < agv::kNormalSignatureBins; ++i) {
    const double d = (static_cast<double>(i) - centre) / 3.0;
    s.bins[i] = static_cast<float>((1.0 - floorShare) * std::exp(-0.5 * d * d));
    sum += s.bins[i];
  }
  for (std::size_t i = 0; i < agv::kNormalSignatureBins; ++i) {
    s.bins[i] = static_cast<float>(s.bins[i] / sum * (1.0 - floorShare));
  }
  s.bins[100] += static_cast<float>(floorShare);
  s.counts.normals = 1000;
  return s;
}
}  // namespace

TEST_CASE("lidar3d: key-signatures, loops beyond the last 15 keys, capacity refused and counted", "[lidar3d]") {
  static agv::PlaceDatabase<40> db;
  agv::PlaceParams params;
  params.keyThreshold = 0.005F;
  params.chiSquareThreshold = 0.002F;
  params.sorensenThreshold = 0.1F;
  REQUIRE(db.setParams(params) == agv::Status::Ok);
  agv::PlaceParams bad = params;
  bad.chiSquareThreshold = -1.0F;
  CHECK(db.setParams(bad) == agv::Status::InvalidArgument);
  const agv::OrientationSignature noOrientation;
  agv::PlaceUpdate u;
  // A route of 30 places (bump centre moving 1 bin per revolution, 2 revolutions per place), then
  // back to places 0..4.
  std::uint32_t scan = 0;
  std::size_t loopsOnRoute = 0;
  for (int place = 0; place < 30; ++place) {
    for (int rev = 0; rev < 2; ++rev) {
      const agv::NormalSignature s = bump(10.0 + 2.5 * place, 0.3);
      AGV_CHECK_NO_ALLOCATIONS(CHECK(db.add(s, noOrientation, scan++, u) == agv::Status::Ok));
      CHECK(u.isKey == (rev == 0));
      loopsOnRoute += u.loop ? 1U : 0U;
    }
  }
  CHECK(db.size() == 30U);
  CHECK(loopsOnRoute == 0U);  // every earlier place differs
  for (int place = 0; place < 5; ++place) {
    const agv::NormalSignature s = bump(10.0 + 2.5 * place, 0.3);
    REQUIRE(db.add(s, noOrientation, scan++, u) == agv::Status::Ok);
    CHECK(u.loop);
    CHECK(u.loopKey == static_cast<std::uint32_t>(place));
    CHECK(u.loopScan == static_cast<std::uint32_t>(2 * place));
    CHECK(u.chiSquare < 1e-6F);
    CHECK_FALSE(u.hasYaw);  // no orientation signatures stored
  }
  // The last 15 keys take no part: revisiting the newest place finds nothing.
  REQUIRE(db.add(bump(10.0 + 2.5 * 29, 0.3), noOrientation, scan++, u) == agv::Status::Ok);
  CHECK_FALSE(u.loop);
  // Empty signature refused and counted.
  CHECK(db.add(agv::NormalSignature{}, noOrientation, scan++, u) == agv::Status::EmptyInput);
  CHECK(db.refusedEmpty() == 1U);
  // Capacity: a database of 2 keys refuses the third key and counts it.
  static agv::PlaceDatabase<2> small;
  REQUIRE(small.setParams(params) == agv::Status::Ok);
  CHECK(small.add(bump(10.0, 0.3), noOrientation, 0, u) == agv::Status::Ok);
  CHECK(small.add(bump(30.0, 0.3), noOrientation, 1, u) == agv::Status::Ok);
  CHECK(small.add(bump(50.0, 0.3), noOrientation, 2, u) == agv::Status::CapacityExceeded);
  CHECK(u.isKey);
  CHECK(small.refusedFull() == 1U);
  CHECK(small.size() == 2U);
}

TEST_CASE("lidar3d: the orientation check refuses a look-alike place whose surroundings differ", "[lidar3d]") {
  static agv::PlaceDatabase<4> db;
  agv::PlaceParams params;
  params.skipRecentKeys = 0;
  params.keyThreshold = 1e-7F;
  params.maxOrientationCost = 0.2F;
  REQUIRE(db.setParams(params) == agv::Status::Ok);
  // Two keys: the same normal histogram, surroundings at 10 m (a) and at 10 m / 30 m alternating (b).
  static agv::OrientationSignature a;
  static agv::OrientationSignature b;
  static agv::OrientationSignature aTurned;
  for (std::size_t k = 0; k < agv::kOrientationBins; ++k) {
    a.meanRange[k] = 10.0F + 4.0F * std::sin(static_cast<float>(k) * 0.05F);
    b.meanRange[k] = (k / 45U) % 2U == 0U ? 10.0F : 30.0F;
  }
  a.filled = b.filled = static_cast<std::uint16_t>(agv::kOrientationBins);
  for (std::size_t k = 0; k < agv::kOrientationBins; ++k) {
    aTurned.meanRange[k] = a.meanRange[(k + 20U) % agv::kOrientationBins];  // a turned by 20 deg
  }
  aTurned.filled = a.filled;
  const agv::NormalSignature s = bump(40.0, 0.3);
  agv::NormalSignature s2 = s;
  s2.bins[0] += 2e-3F;  // a new key, still within the loop thresholds
  agv::PlaceUpdate u;
  REQUIRE(db.add(s, b, 0, u) == agv::Status::Ok);
  REQUIRE(db.add(s2, a, 1, u) == agv::Status::Ok);
  REQUIRE(u.isKey);
  // The query looks like key 0 by its histogram (nearest), but its surroundings are key 1's, turned.
  REQUIRE(db.add(s, aTurned, 2, u) == agv::Status::Ok);
  CHECK(u.candidates == 2U);
  CHECK(u.rejectedByOrientation == 1U);
  REQUIRE(u.loop);
  CHECK(u.loopScan == 1U);
  REQUIRE(u.hasYaw);
  AGV_CHECK_NEAR(rad2deg(static_cast<double>(u.yaw.yaw)), 20.0, 0.01);
  CHECK(u.yaw.relativeCost() < 1e-4F);
  // With the check off the nearest histogram wins.
  params.maxOrientationCost = 0.0F;
  REQUIRE(db.setParams(params) == agv::Status::Ok);
  REQUIRE(db.add(s, aTurned, 3, u) == agv::Status::Ok);
  REQUIRE(u.loop);
  CHECK(u.loopScan == 0U);
  CHECK(u.rejectedByOrientation == 0U);
}

TEST_CASE("lidar3d: the profile alignment recovers the translation and the yaw between two revolutions", "[lidar3d]") {
  // The ramp yard (a 40 x 30 m room and a 35-deg ramp, which the horizontal beam sees at ~8.6 m),
  // seen from the origin and from places up to 3.6 m away, turned (also by ~180 deg).
  agv::test::LoopRng rng{31};
  const agv::test::SimScene yard = agv::test::rampYard();
  static agv::OrientationSignature a;
  static agv::OrientationSignature b;
  REQUIRE(agv::test::castScene(yard, vlp16(0.02), Eigen::Vector3d::Zero(), 0.0, 0.0, rng, g_image) > 0U);
  REQUIRE(agv::computeOrientationSignature(g_image, agv::OrientationParams{}, a) == agv::Status::Ok);
  struct Case {
    double x, y, yawDeg;
  };
  const Case cases[] = {{3.0, -2.0, 25.0}, {-2.5, 1.5, 170.0}, {1.0, 3.4, -95.0}, {0.2, 0.1, 3.0}};
  for (const Case& c : cases) {
    REQUIRE(agv::test::castScene(yard, vlp16(0.02), Eigen::Vector3d(c.x, c.y, 0.0), deg2rad(c.yawDeg), 0.21, rng,
                                 g_image) > 0U);
    REQUIRE(agv::computeOrientationSignature(g_image, agv::OrientationParams{}, b) == agv::Status::Ok);
    const agv::Result<agv::YawEstimate> coarse = agv::relativeYaw(a, b);
    REQUIRE(coarse.ok());
    const agv::Result<agv::ProfileAlignment> al = agv::alignProfiles(a, b, coarse.value().yaw);
    REQUIRE(al.ok());
    const agv::ProfileAlignment& r = al.value();
    INFO("case " << c.x << " " << c.y << " " << c.yawDeg << ": coarse " << rad2deg(coarse.value().yaw) << ", aligned "
                 << rad2deg(r.yaw) << " deg, " << r.x << " " << r.y << " m, paired " << r.matchedFraction() << ", rms "
                 << r.rms << ", iterations " << r.iterations);
    CHECK(r.converged);
    AGV_CHECK_NEAR(rad2deg(agv::angleDiff(static_cast<double>(r.yaw), deg2rad(c.yawDeg))), 0.0, 0.2);
    AGV_CHECK_NEAR(static_cast<double>(r.x), c.x, 0.05);
    AGV_CHECK_NEAR(static_cast<double>(r.y), c.y, 0.05);
    CHECK(r.matchedFraction() > 0.9F);
    AGV_CHECK_NEAR(static_cast<double>(r.translation()), std::hypot(c.x, c.y), 0.05);
  }
  // Bad input: an empty signature, a NaN start, parameters out of their domain.
  CHECK(agv::alignProfiles(a, agv::OrientationSignature{}, 0.0F).status() == agv::Status::NotEnoughData);
  CHECK(agv::alignProfiles(a, b, std::nanf("")).status() == agv::Status::InvalidArgument);
  agv::ProfileAlignParams bad;
  bad.endGate = 0.0F;
  CHECK(agv::alignProfiles(a, b, 0.0F, bad).status() == agv::Status::InvalidArgument);
  CHECK_FALSE(agv::isValid(bad));
}

TEST_CASE("lidar3d: the geometric verification refuses a candidate farther than the loop radius", "[lidar3d]") {
  agv::test::LoopRng rng{33};
  const agv::test::SimScene yard = agv::test::rampYard();
  static agv::OrientationSignature here;
  static agv::OrientationSignature near;
  static agv::OrientationSignature far;
  REQUIRE(agv::test::castScene(yard, vlp16(0.02), Eigen::Vector3d::Zero(), 0.0, 0.0, rng, g_image) > 0U);
  REQUIRE(agv::computeOrientationSignature(g_image, agv::OrientationParams{}, here) == agv::Status::Ok);
  REQUIRE(agv::test::castScene(yard, vlp16(0.02), Eigen::Vector3d(1.5, 1.0, 0.0), deg2rad(30.0), 0.0, rng, g_image) >
          0U);
  REQUIRE(agv::computeOrientationSignature(g_image, agv::OrientationParams{}, near) == agv::Status::Ok);
  // 3.6 m away. (From 5 m in this small room, 12-24 m to the walls, the signature's yaw is 90 deg
  // off and the alignment from there pairs 56 % of the bins at a wrong pose: the verification
  // trusts an alignment from a start within its basin only.)
  REQUIRE(agv::test::castScene(yard, vlp16(0.02), Eigen::Vector3d(3.0, -2.0, 0.0), deg2rad(10.0), 0.0, rng, g_image) >
          0U);
  REQUIRE(agv::computeOrientationSignature(g_image, agv::OrientationParams{}, far) == agv::Status::Ok);
  static agv::PlaceDatabase<4> db;
  agv::PlaceParams params;
  params.skipRecentKeys = 0;
  params.keyThreshold = 1e-7F;
  params.maxLoopTranslation = 3.0F;
  REQUIRE(db.setParams(params) == agv::Status::Ok);
  agv::PlaceParams bad = params;
  bad.minAlignedFraction = 1.5F;
  CHECK(db.setParams(bad) == agv::Status::InvalidArgument);
  // Two keys with the same histogram: 3.6 m from the query (nearest by chi-square) and 1.8 m.
  const agv::NormalSignature s = bump(40.0, 0.3);
  agv::NormalSignature s2 = s;
  s2.bins[0] += 2e-3F;
  agv::PlaceUpdate u;
  REQUIRE(db.add(s, far, 0, u) == agv::Status::Ok);
  REQUIRE(db.add(s2, near, 1, u) == agv::Status::Ok);
  REQUIRE(u.isKey);
  AGV_CHECK_NO_ALLOCATIONS(REQUIRE(db.add(s, here, 2, u) == agv::Status::Ok));
  CHECK(u.candidates == 2U);
  CHECK(u.rejectedByAlignment == 1U);
  REQUIRE(u.loop);
  CHECK(u.loopScan == 1U);
  REQUIRE(u.hasAlignment);
  // The query (at the origin, yaw 0) in the frame of key 1 (at (1.5, 1), turned by 30 deg).
  const double c = std::cos(deg2rad(30.0));
  const double sn = std::sin(deg2rad(30.0));
  AGV_CHECK_NEAR(static_cast<double>(u.alignment.x), c * -1.5 + sn * -1.0, 0.05);
  AGV_CHECK_NEAR(static_cast<double>(u.alignment.y), -sn * -1.5 + c * -1.0, 0.05);
  AGV_CHECK_NEAR(rad2deg(static_cast<double>(u.alignment.yaw)), -30.0, 0.2);
  // Without the verification the nearest histogram (3.6 m away) is the loop.
  params.maxLoopTranslation = 0.0F;
  REQUIRE(db.setParams(params) == agv::Status::Ok);
  REQUIRE(db.add(s, here, 3, u) == agv::Status::Ok);
  REQUIRE(u.loop);
  CHECK(u.loopScan == 0U);
  CHECK_FALSE(u.hasAlignment);
}

TEST_CASE("lidar3d: steady-state calls allocate nothing", "[lidar3d][alloc]") {
  agv::test::LoopRng rng{9};
  const agv::test::SimScene room = agv::test::boxRoom(-16.0, 24.0, -12.0, 18.0, -1.8, 5.0, false);
  REQUIRE(agv::test::castScene(room, vlp16(0.005), Eigen::Vector3d::Zero(), 0.0, 0.0, rng, g_image) > 0U);
  agv::NormalSignature& sig = g_sig;
  agv::OrientationSignature& ori = g_ori;
  static agv::OrientationSignature ori2;
  static agv::RingPoint pts[256];
  for (std::size_t i = 0; i < 256; ++i) {
    pts[i].point = g_image.at(i % kLasers, (i * 7) % kFirings).point;
    pts[i].ring = static_cast<std::uint16_t>(i % kLasers);
  }
  AGV_CHECK_NO_ALLOCATIONS(CHECK(agv::computeNormalSignature(g_image, vlpSignature(), sig) == agv::Status::Ok));
  AGV_CHECK_NO_ALLOCATIONS(
      CHECK(agv::computeOrientationSignature(g_image, agv::OrientationParams{}, ori) == agv::Status::Ok));
  ori2 = ori;
  AGV_CHECK_NO_ALLOCATIONS(CHECK(agv::relativeYaw(ori, ori2).ok()));
  AGV_CHECK_NO_ALLOCATIONS(CHECK(agv::alignProfiles(ori, ori2, 0.0F).ok()));
  AGV_CHECK_NO_ALLOCATIONS((void)agv::chiSquareDistance(sig, sig); (void)agv::sorensenDistance(sig, sig));
  AGV_CHECK_NO_ALLOCATIONS(CHECK(g_image.buildFromRings(agv::Span<const agv::RingPoint>(pts, 256)) == agv::Status::Ok));
}
