// Laser egomotion from FALKO keypoints: ray-cast scans of a simulated room (drivers/sim) from two
// poses with known relative motion, range noise, a 180 deg turn between the scans, outlier
// keypoints, too few corners.
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include "agv/calib/keypoint_alignment.hpp"
#include "agv/falko/falko_descriptors.hpp"
#include "agv/falko/falko_detector.hpp"
#include "agv/sim/ray_caster.hpp"
#include "agv/sim/sim_laser.hpp"
#include "agv/sim/world.hpp"
#include "agv_test.hpp"
#include "keypoint_scan_sim.hpp"

using agv::deg2rad;
using agv::KeypointAlignment;
using agv::KeypointAlignmentOptions;
using agv::Pose2d;
using agv::Status;

namespace {

/// A 14 m x 10 m room with wall stubs (two concave corners each, seen alike from anywhere on
/// their side), pallet blocks and a wall piece: corners at many places and no symmetry that two
/// motions could explain equally well.
agv::sim::World room() {
  const char* text =
      "hall 0 0 14 10\n"
      "wall 2 0 2 0.6\nwall 9 0 9 0.8\nwall 12.5 0 12.5 0.5\n"
      "wall 3 10 3 9.3\nwall 7 10 7 9.5\nwall 10.5 10 10.5 9.2\n"
      "wall 0 2 0.7 2\nwall 0 6.5 0.5 6.5\nwall 0 8.5 0.9 8.5\n"
      "wall 14 3 13.4 3\nwall 14 7.5 13.2 7.5\n"
      "pallet 2 7 3.2 8.2\n"
      "pallet 10.5 1 12 1.8\n"
      "pallet 6 0 6.8 1.2\n"
      "pallet 11 6.5 11.8 8.5\n"
      "pallet 7.5 5.3 8.1 5.9\n";
  agv::sim::World w;
  agv::sim::WorldParseError err;
  REQUIRE(agv::sim::parseWorld(text, w, err) == Status::Ok);
  return w;
}

/// A room with two corners only (an L of walls and a box far away).
agv::sim::World sparseRoom() {
  agv::sim::World w;
  agv::sim::WorldParseError err;
  REQUIRE(agv::sim::parseWorld("wall 0 0 10 0\nwall 0 0 0 8\n", w, err) == Status::Ok);
  return w;
}

using agv::test::KeypointScan;

agv::sim::SimLaserParams laserParams(double sigma) {
  agv::sim::SimLaserParams p;
  p.angularResolution = deg2rad(0.25);
  p.rangeNoiseStdDev = sigma;
  p.rangeMax = 30.0;
  p.noReturnValue = 30.0F;
  return p;
}

void scanAt(const agv::sim::RayCaster& caster, const Pose2d& laserPose, double sigma, std::uint64_t seed,
            KeypointScan& out) {
  REQUIRE(agv::test::simulateKeypointScan(caster, laserPose, laserParams(sigma), seed, out) == Status::Ok);
}

/// Scans of room() from two laser poses (range noise 5 mm).
void roomScans(const Pose2d& p1, const Pose2d& p2, std::uint64_t seed, KeypointScan& a, KeypointScan& b) {
  static const agv::sim::World w = room();
  static const agv::sim::RayCaster caster(w, 1.0);
  scanAt(caster, p1, 0.005, seed, a);
  scanAt(caster, p2, 0.005, seed + 1U, b);
}

/// Ground-truth correspondences: second keypoints that, mapped by the true motion, lie within
/// `gate` of a first keypoint. Returns their count and the spread sum |q - q_mean|^2 and centroid.
struct TruthPairs {
  int count = 0;
  double spread = 0.0;
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
};
TruthPairs truthPairs(const KeypointScan& a, const KeypointScan& b, const Pose2d& motion, double gate) {
  TruthPairs t;
  std::vector<Eigen::Vector2d> qs;
  for (const auto& kb : b.keypoints) {
    const Eigen::Vector2d q(static_cast<double>(kb.x), static_cast<double>(kb.y));
    const Eigen::Vector2d m = motion.transformPoint(q);
    for (const auto& ka : a.keypoints) {
      if ((Eigen::Vector2d(static_cast<double>(ka.x), static_cast<double>(ka.y)) - m).norm() < gate) {
        qs.push_back(q);
        break;
      }
    }
  }
  t.count = static_cast<int>(qs.size());
  for (const auto& q : qs) {
    t.centroid += q;
  }
  if (!qs.empty()) {
    t.centroid /= static_cast<double>(qs.size());
  }
  for (const auto& q : qs) {
    t.spread += (q - t.centroid).squaredNorm();
  }
  return t;
}

struct Case {
  const char* name;
  Pose2d firstPose;
  Pose2d secondPose;
};

}  // namespace

// Tolerance from the range noise: a refined FALKO corner is the intersection of two lines fitted
// to several beams each, so its position noise is at most about the range noise sigma_r of one
// beam (per axis). The alignment of n corner pairs seen in two scans then has a rotation std of
// sqrt(2) sigma_r / sqrt(sum |q - q_mean|^2) and a centroid std of sqrt(2 / n) sigma_r per axis;
// the laser origin lies |q_mean| from the centroid, so its translation std is bounded by
// sqrt(2 / n) sigma_r + |q_mean| std(rotation) per axis. Every trial must be within 4 of those
// stds (per axis for the translation), and the RMS over the trials within 1.5 of them.
TEST_CASE("calib.keypoint_alignment: ray-cast room, known motion, 180 deg turn", "[calib]") {
  const agv::sim::World w = room();
  const agv::sim::RayCaster caster(w, 1.0);
  const double sigma = 0.005;
  const Case cases[] = {
      {"small move", Pose2d{4.0, 4.0, deg2rad(10.0)}, Pose2d{5.2, 4.6, deg2rad(35.0)}},
      {"half circle (beta 180 deg)", Pose2d{4.0, 3.0, deg2rad(0.0)}, Pose2d{6.5, 3.5, deg2rad(180.0)}},
      {"half circle backward", Pose2d{6.0, 3.0, deg2rad(-90.0)}, Pose2d{9.5, 3.5, deg2rad(90.0)}},
  };
  static KeypointScan a;
  static KeypointScan b;
  for (const Case& c : cases) {
    const Pose2d truth = agv::between(c.firstPose, c.secondPose);
    const int trials = 20;
    double sumRot = 0.0;
    double sumRotPred = 0.0;
    double sumTr = 0.0;
    double sumTrPred = 0.0;
    int ok = 0;
    double inliers = 0.0;
    double keypointCount = 0.0;
    for (int trial = 0; trial < trials; ++trial) {
      scanAt(caster, c.firstPose, sigma, 100U + static_cast<std::uint64_t>(trial), a);
      scanAt(caster, c.secondPose, sigma, 900U + static_cast<std::uint64_t>(trial), b);
      const TruthPairs tp = truthPairs(a, b, truth, 0.05);
      REQUIRE(tp.count >= 5);
      KeypointAlignment out;
      // No guess: the consensus must find the motion on its own, 180 deg turn included.
      const Status s = agv::alignKeypoints(a.view(), b.view(), Pose2d{}, KeypointAlignmentOptions{}, out);
      REQUIRE(s == Status::Ok);
      ++ok;
      const double rotStd = std::sqrt(2.0) * sigma / std::sqrt(tp.spread);
      const double trStd = std::sqrt(2.0 / tp.count) * sigma + tp.centroid.norm() * rotStd;
      const double eRot = agv::angleDiff(out.motion.theta, truth.theta);
      const double ex = out.motion.x - truth.x;
      const double ey = out.motion.y - truth.y;
      CHECK(std::fabs(eRot) <= 4.0 * rotStd);
      CHECK(std::fabs(ex) <= 4.0 * trStd);
      CHECK(std::fabs(ey) <= 4.0 * trStd);
      CHECK(out.inliers >= 4U);
      CHECK(static_cast<int>(out.inliers) <= tp.count);
      CHECK(out.rms <= 3.0 * sigma);
      sumRot += eRot * eRot;
      sumRotPred += rotStd * rotStd;
      sumTr += 0.5 * (ex * ex + ey * ey);
      sumTrPred += trStd * trStd;
      inliers += static_cast<double>(out.inliers);
      keypointCount += 0.5 * static_cast<double>(a.keypoints.size() + b.keypoints.size());
    }
    const double rmsRot = std::sqrt(sumRot / trials);
    const double rmsTr = std::sqrt(sumTr / trials);
    std::printf(
        "keypoint alignment, %s: %d/%d ok, %.1f keypoints/scan, %.1f inliers, rotation rms %.4f deg "
        "(bound %.4f), translation rms %.2f mm (bound %.2f)\n",
        c.name, ok, trials, keypointCount / trials, inliers / trials, agv::rad2deg(rmsRot),
        agv::rad2deg(std::sqrt(sumRotPred / trials)), 1e3 * rmsTr, 1e3 * std::sqrt(sumTrPred / trials));
    CHECK(rmsRot <= 1.5 * std::sqrt(sumRotPred / trials));
    CHECK(rmsTr <= 1.5 * std::sqrt(sumTrPred / trials));
  }
}

TEST_CASE("calib.keypoint_alignment: outlier keypoints", "[calib]") {
  const agv::sim::World w = room();
  const agv::sim::RayCaster caster(w, 1.0);
  // The second scene has objects the first has not (pallets put down meanwhile): their corners are
  // real keypoints with real descriptors and no partner.
  agv::sim::World changed = w;
  agv::sim::WorldParseError err;
  agv::sim::World extra;
  REQUIRE(agv::sim::parseWorld("pallet 2.5 5 3.3 5.6\npallet 8.5 7.5 9.3 8.3\npallet 12 3 12.6 3.5\n", extra, err) ==
          Status::Ok);
  changed.segments.insert(changed.segments.end(), extra.segments.begin(), extra.segments.end());
  const agv::sim::RayCaster changedCaster(changed, 1.0);
  const double sigma = 0.005;
  const Pose2d p1{4.0, 3.0, 0.0};
  const Pose2d p2{6.5, 3.5, deg2rad(180.0)};
  const Pose2d truth = agv::between(p1, p2);
  static KeypointScan a;
  static KeypointScan b;
  scanAt(caster, p1, sigma, 7U, a);
  scanAt(changedCaster, p2, sigma, 8U, b);
  const std::size_t realB = b.keypoints.size();
  // Plus copies of real keypoints (same descriptors) at wrong places: the worst kind of outlier,
  // a perfect descriptor match that no rigid motion explains. As many as the real ones.
  for (std::size_t i = 0; i < realB; ++i) {
    agv::FalkoKeypoint k = b.keypoints[i];
    k.x += 1.3F + 0.37F * static_cast<float>(i % 5U);
    k.y -= 0.9F + 0.21F * static_cast<float>(i % 7U);
    REQUIRE(b.keypoints.push_back(k) == Status::Ok);
    REQUIRE(b.bsc.push_back(b.bsc[i]) == Status::Ok);
    REQUIRE(b.cgh.push_back(b.cgh[i]) == Status::Ok);
  }
  const TruthPairs tp = truthPairs(a, b, truth, 0.05);
  KeypointAlignment out;
  REQUIRE(agv::alignKeypoints(a.view(), b.view(), Pose2d{}, KeypointAlignmentOptions{}, out) == Status::Ok);
  const double rotStd = std::sqrt(2.0) * sigma / std::sqrt(tp.spread);
  const double trStd = std::sqrt(2.0 / tp.count) * sigma + tp.centroid.norm() * rotStd;
  std::printf(
      "keypoint alignment with outliers: %zu keypoints (%zu real, %d with a partner), %zu inliers, "
      "rotation error %.4f deg, translation error %.2f mm\n",
      b.keypoints.size(), realB, tp.count, out.inliers, agv::rad2deg(agv::angleDiff(out.motion.theta, truth.theta)),
      1e3 * std::hypot(out.motion.x - truth.x, out.motion.y - truth.y));
  CHECK(std::fabs(agv::angleDiff(out.motion.theta, truth.theta)) <= 4.0 * rotStd);
  CHECK(std::fabs(out.motion.x - truth.x) <= 4.0 * trStd);
  CHECK(std::fabs(out.motion.y - truth.y) <= 4.0 * trStd);
  CHECK(static_cast<int>(out.inliers) <= tp.count);
  // The CGH descriptor works as well.
  KeypointAlignmentOptions cgh;
  cgh.descriptor = agv::KeypointDescriptor::Cgh;
  KeypointAlignment outCgh;
  REQUIRE(agv::alignKeypoints(a.view(), b.view(), Pose2d{}, cgh, outCgh) == Status::Ok);
  CHECK(std::fabs(agv::angleDiff(outCgh.motion.theta, truth.theta)) <= 4.0 * rotStd);
  CHECK(std::hypot(outCgh.motion.x - truth.x, outCgh.motion.y - truth.y) <= 4.0 * std::sqrt(2.0) * trStd);
}

TEST_CASE("calib.keypoint_alignment: the guess gates keep only motions near the guess", "[calib]") {
  // With a gate around a guess far from the truth, no hypothesis survives: refused, not wrong.
  const agv::sim::World w = room();
  const agv::sim::RayCaster caster(w, 1.0);
  const Pose2d p1{4.0, 3.0, 0.0};
  const Pose2d p2{6.5, 3.5, deg2rad(180.0)};
  static KeypointScan a;
  static KeypointScan b;
  scanAt(caster, p1, 0.005, 1U, a);
  scanAt(caster, p2, 0.005, 2U, b);
  const Pose2d truth = agv::between(p1, p2);
  KeypointAlignmentOptions opt;
  opt.guessTranslationGate = 0.5;
  opt.guessRotationGate = deg2rad(10.0);
  KeypointAlignment out;
  const Pose2d near{truth.x + 0.3, truth.y - 0.2, truth.theta + deg2rad(5.0)};
  REQUIRE(agv::alignKeypoints(a.view(), b.view(), near, opt, out) == Status::Ok);
  CHECK(std::hypot(out.motion.x - truth.x, out.motion.y - truth.y) < 0.02);
  const Pose2d far{truth.x, truth.y, truth.theta + deg2rad(90.0)};
  CHECK(agv::alignKeypoints(a.view(), b.view(), far, opt, out) == Status::NotEnoughData);
}

TEST_CASE("calib.keypoint_alignment: too few corners refused", "[calib]") {
  const agv::sim::World w = sparseRoom();
  const agv::sim::RayCaster caster(w, 1.0);
  static KeypointScan a;
  static KeypointScan b;
  const Pose2d p1{3.0, 2.0, 0.3};
  const Pose2d p2{4.0, 3.0, 1.0};
  scanAt(caster, p1, 0.005, 3U, a);
  scanAt(caster, p2, 0.005, 4U, b);
  CHECK(a.keypoints.size() < 4U);
  KeypointAlignment out;
  const Status s = agv::alignKeypoints(a.view(), b.view(), Pose2d{}, KeypointAlignmentOptions{}, out);
  CHECK((s == Status::NotEnoughData || s == Status::EmptyInput));
  CHECK(out.inliers < 4U);
  // Scans of two different rooms: corners exist but do not agree.
  const agv::sim::World other = room();
  const agv::sim::RayCaster otherCaster(other, 1.0);
  static KeypointScan c;
  scanAt(otherCaster, Pose2d{7.0, 5.0, 0.0}, 0.005, 5U, c);
  KeypointAlignmentOptions strict;
  strict.minInliers = 8;
  CHECK(agv::alignKeypoints(c.view(), a.view(), Pose2d{}, strict, out) == Status::NotEnoughData);
}

TEST_CASE("calib.keypoint_alignment: unrefined keypoints take no part unless asked", "[calib]") {
  static KeypointScan a;
  static KeypointScan b;
  roomScans(Pose2d{4.0, 3.0, 0.0}, Pose2d{6.5, 3.5, deg2rad(180.0)}, 21U, a, b);
  for (agv::FalkoKeypoint& k : b.keypoints) {
    k.refined = false;
  }
  KeypointAlignment out;
  KeypointAlignmentOptions opt;
  CHECK(agv::alignKeypoints(a.view(), b.view(), Pose2d{}, opt, out) == Status::NotEnoughData);
  CHECK(out.candidates == 0U);
  opt.refinedOnly = false;
  CHECK(agv::alignKeypoints(a.view(), b.view(), Pose2d{}, opt, out) == Status::Ok);
  CHECK(out.inliers >= 4U);
}

TEST_CASE("calib.keypoint_alignment: bad inputs", "[calib]") {
  static KeypointScan a;
  static KeypointScan b;
  roomScans(Pose2d{4.0, 4.0, 0.0}, Pose2d{5.0, 4.5, 0.5}, 1U, a, b);
  KeypointAlignment out;
  const KeypointAlignmentOptions opt;
  CHECK(agv::alignKeypoints(a.view(), agv::KeypointScanView{}, Pose2d{}, opt, out) == Status::EmptyInput);
  agv::KeypointScanView mismatch = b.view();
  mismatch.bsc = mismatch.bsc.subspan(0, mismatch.bsc.size() - 1);
  CHECK(agv::alignKeypoints(a.view(), mismatch, Pose2d{}, opt, out) == Status::InvalidArgument);
  KeypointAlignmentOptions bad;
  bad.candidatesPerKeypoint = agv::kMaxKeypointCandidates + 1;
  CHECK(agv::alignKeypoints(a.view(), b.view(), Pose2d{}, bad, out) == Status::InvalidArgument);
  bad = opt;
  bad.minInliers = 2;
  CHECK(agv::alignKeypoints(a.view(), b.view(), Pose2d{}, bad, out) == Status::InvalidArgument);
  bad = opt;
  bad.inlierGate = std::nan("");
  CHECK(agv::alignKeypoints(a.view(), b.view(), Pose2d{}, bad, out) == Status::InvalidArgument);
  CHECK(agv::alignKeypoints(a.view(), b.view(), Pose2d{std::nan(""), 0.0, 0.0}, opt, out) == Status::NonFiniteInput);
  static KeypointScan nanScan;
  nanScan = b;
  nanScan.keypoints[0].x = std::numeric_limits<float>::infinity();
  CHECK(agv::alignKeypoints(a.view(), nanScan.view(), Pose2d{}, opt, out) == Status::NonFiniteInput);
  // Over capacity: a view longer than kMaxKeypoints.
  static std::vector<agv::FalkoKeypoint> many(agv::kMaxKeypoints + 1);
  static std::vector<agv::BscDescriptor> manyBsc(agv::kMaxKeypoints + 1);
  const agv::KeypointScanView big{{many.data(), many.size()}, {manyBsc.data(), manyBsc.size()}, {}};
  CHECK(agv::alignKeypoints(a.view(), big, Pose2d{}, opt, out) == Status::CapacityExceeded);
}

TEST_CASE("calib.keypoint_alignment: deterministic and allocation-free", "[calib]") {
  static KeypointScan a;
  static KeypointScan b;
  roomScans(Pose2d{4.0, 3.0, 0.0}, Pose2d{6.5, 3.5, deg2rad(180.0)}, 11U, a, b);
  KeypointAlignmentOptions opt;
  opt.maxDraws = 400;  // fewer than all pairs of candidates: the generator draws them
  opt.maxHypotheses = 50;
  KeypointAlignment o1;
  KeypointAlignment o2;
  Status s1 = Status::InvalidArgument;
  Status s2 = Status::InvalidArgument;
  AGV_CHECK_NO_ALLOCATIONS(s1 = agv::alignKeypoints(a.view(), b.view(), Pose2d{}, opt, o1));
  s2 = agv::alignKeypoints(a.view(), b.view(), Pose2d{}, opt, o2);
  CHECK(s1 == s2);
  CHECK(o1.motion.x == o2.motion.x);
  CHECK(o1.motion.theta == o2.motion.theta);
  CHECK(o1.inliers == o2.inliers);
  CHECK(o1.hypotheses <= 50);
}

namespace {

/// Errors of keypoint egomotion against the truth, pooled over trials.
struct EgomotionErrors {
  int trials = 0;
  int aligned = 0;
  double sumLong = 0.0;  // translation error along the true translation / its length [1]
  double sumLong2 = 0.0;
  double sumRot = 0.0;  // rotation error / pi [1]
  double sumRot2 = 0.0;
  double sumX = 0.0;  // translation error per axis [m]
  double sumY = 0.0;
  double sumX2 = 0.0;
  double sumY2 = 0.0;
  double meanLong() const { return sumLong / aligned; }
  double seLong() const { return std::sqrt((sumLong2 / aligned - meanLong() * meanLong()) / aligned); }
  double meanRot() const { return sumRot / aligned; }
  double seRot() const { return std::sqrt((sumRot2 / aligned - meanRot() * meanRot()) / aligned); }
  double sdRot() const { return std::sqrt(sumRot2 / aligned - meanRot() * meanRot()) * agv::kPi<double>; }
  double sdX() const { return std::sqrt(sumX2 / aligned - (sumX / aligned) * (sumX / aligned)); }
  double sdY() const { return std::sqrt(sumY2 / aligned - (sumY / aligned) * (sumY / aligned)); }
};

/// Keypoint egomotion of the half circles (beta 180 deg) that `agvnav-calibrate` drives from its
/// default start (10, 12.5, 0) in the built-in warehouse: steering 18..50 deg left and right, the
/// simulator's laser mount (1.62, 0.025, 0.7 deg), its default laser (0.25 deg, 1 cm range
/// noise), the routine's guess gates around the true motion. `withPillars` false: the same hall
/// without its three round building pillars.
EgomotionErrors warehouseHalfCircles(bool withPillars, int seeds) {
  agv::sim::World w;
  agv::sim::WorldParseError err;
  REQUIRE(agv::sim::parseWorld(agv::sim::defaultWorldText(), w, err) == Status::Ok);
  if (!withPillars) {
    std::vector<agv::sim::Circle> kept;
    for (const agv::sim::Circle& c : w.circles) {
      if (c.kind != agv::sim::ObstacleKind::Pillar) {
        kept.push_back(c);
      }
    }
    REQUIRE(kept.size() + 3U == w.circles.size());
    w.circles = kept;
  }
  const agv::sim::RayCaster caster(w, 1.0);
  const agv::sim::SimLaserParams laser;  // what agvnav-calibrate simulates
  REQUIRE(laser.rangeNoiseStdDev == 0.01);
  const Pose2d start{10.0, 12.5, 0.0};
  const Pose2d mount{1.62, 0.025, deg2rad(0.7)};
  const double wheelbase = 1.5;
  KeypointAlignmentOptions opt;
  opt.guessTranslationGate = 1.0;
  opt.guessRotationGate = deg2rad(10.0);
  static KeypointScan a;
  static KeypointScan b;
  EgomotionErrors e;
  for (int s = 0; s < seeds; ++s) {
    const Pose2d first = start.compose(mount);
    REQUIRE(agv::test::simulateKeypointScan(caster, first, laser, 100U + 2U * static_cast<unsigned>(s), a) ==
            Status::Ok);
    for (const double steerDeg : {18.0, 26.0, 34.0, 42.0, 50.0}) {
      for (const double side : {1.0, -1.0}) {
        const double radius = wheelbase / std::tan(deg2rad(steerDeg));
        const Pose2d second = start.compose(Pose2d{0.0, side * 2.0 * radius, side * agv::kPi<double>}).compose(mount);
        REQUIRE(agv::test::simulateKeypointScan(caster, second, laser, 101U + 2U * static_cast<unsigned>(s), b) ==
                Status::Ok);
        const Pose2d truth = agv::between(first, second);
        KeypointAlignment out;
        ++e.trials;
        if (agv::alignKeypoints(a.view(), b.view(), truth, opt, out) != Status::Ok) {
          continue;
        }
        ++e.aligned;
        const Eigen::Vector2d t(truth.x, truth.y);
        const Eigen::Vector2d d(out.motion.x - truth.x, out.motion.y - truth.y);
        const double lng = d.dot(t) / t.squaredNorm();
        const double rot = agv::angleDiff(out.motion.theta, truth.theta) / agv::kPi<double>;
        e.sumLong += lng;
        e.sumLong2 += lng * lng;
        e.sumRot += rot;
        e.sumRot2 += rot * rot;
        e.sumX += d.x();
        e.sumY += d.y();
        e.sumX2 += d.x() * d.x();
        e.sumY2 += d.y() * d.y();
      }
    }
  }
  return e;
}

}  // namespace

// Why keypoint calibration runs underestimated s_w (docs/calibration.md, "Keypoint egomotion in
// the warehouse"): FALKO reports a corner on each round pillar, at the intersection of two lines
// fitted to the arc facing the sensor (about 0.29 m from the centre of a 0.25 m pillar). That
// point moves with the viewpoint, towards each laser position, so the translations of keypoint
// egomotion come out short while the rotations stay nearly unbiased. The bounds pinned here
// (this test measures: with pillars -1020 +- 61 ppm along the translation, rotation +20 +- 8 ppm
// of pi, scatter 8.6 / 9.2 mm per axis and 0.038 deg; without the pillars -221 +- 55 ppm and
// -8 +- 7 ppm) let a regression show; the routine weighs keypoint egomotion with the scatter
// measured here (RoutineOptions::keypointRefinement: 10 mm, 0.04 deg), so that the rotations,
// not the short translations, set s_w.
TEST_CASE("calib.keypoint_alignment: warehouse half circles, translation bias from round pillars", "[calib]") {
  const int seeds = 100;
  const EgomotionErrors pillars = warehouseHalfCircles(true, seeds);
  const EgomotionErrors plain = warehouseHalfCircles(false, seeds);
  std::printf(
      "warehouse half circles, %d seeds x 10: with pillars %d aligned, translation %+.0f +- %.0f ppm, rotation "
      "%+.0f +- %.0f ppm of pi (sd %.4f deg), sd x %.2f mm, y %.2f mm; without pillars %d aligned, translation "
      "%+.0f +- %.0f ppm, rotation %+.0f +- %.0f ppm of pi\n",
      seeds, pillars.aligned, 1e6 * pillars.meanLong(), 1e6 * pillars.seLong(), 1e6 * pillars.meanRot(),
      1e6 * pillars.seRot(), agv::rad2deg(pillars.sdRot()), 1e3 * pillars.sdX(), 1e3 * pillars.sdY(), plain.aligned,
      1e6 * plain.meanLong(), 1e6 * plain.seLong(), 1e6 * plain.meanRot(), 1e6 * plain.seRot());
  // Enough segments align for a calibration (the 18 deg right circle sees too few common corners).
  CHECK(pillars.aligned >= pillars.trials / 2);
  CHECK(plain.aligned >= plain.trials / 2);
  // The pillars shorten the translations: the bias is significant with them, at most 1300 ppm,
  // and four times smaller without them (the true corners' refinement is nearly unbiased).
  CHECK(pillars.meanLong() < -3.0 * pillars.seLong());
  CHECK(pillars.meanLong() > -1300e-6);
  CHECK(std::fabs(plain.meanLong()) < 0.25 * std::fabs(pillars.meanLong()) + 3.0 * plain.seLong());
  // The rotations are nearly unbiased (60 ppm of a half circle is a quarter of the s_w std of an
  // 8-segment calibration) in both halls.
  CHECK(std::fabs(pillars.meanRot()) < 60e-6);
  CHECK(std::fabs(plain.meanRot()) < 60e-6);
  // The scatter stays within the routine's keypoint noise model (10 mm per axis, 0.04 deg) with
  // the 10 % margin of a 100-seed estimate.
  CHECK(pillars.sdX() < 1.1 * 0.010);
  CHECK(pillars.sdY() < 1.1 * 0.010);
  CHECK(pillars.sdRot() < 1.1 * deg2rad(0.04));
}
