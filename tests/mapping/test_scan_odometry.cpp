// mapping::ScanOdometry: wheel steps corrected by scan matching, on scans ray-cast in a simulated
// room with known poses, against the wheel odometry they started from.
#include "agv/mapping/scan_odometry.hpp"

#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "agv/core/angle.hpp"
#include "agv/sim/ray_caster.hpp"
#include "agv/sim/world.hpp"
#include "agv_test.hpp"

using agv::Pose2d;

namespace {
constexpr double kPi = 3.14159265358979323846;

// 181 beams over 180 degrees from `pose`, 1 cm Gaussian range noise.
void castScan(const agv::sim::RayCaster& caster, const Pose2d& pose, std::mt19937& rng, agv::LaserScan& scan) {
  std::normal_distribution<double> noise(0.0, 0.01);
  scan.angleMin = static_cast<float>(-kPi / 2);
  scan.angleIncrement = static_cast<float>(kPi / 180.0);
  scan.rangeMin = 0.1F;
  scan.rangeMax = 40.0F;
  scan.ranges.clear();
  for (int b = 0; b < 181; ++b) {
    const agv::sim::RayHit hit = caster.cast(agv::sim::Point2{pose.x, pose.y}, pose.theta + scan.angle(b), 39.0);
    (void)scan.ranges.push_back(hit.hit ? static_cast<float>(hit.range + noise(rng)) : 40.0F);
  }
}

struct Drive {
  std::vector<Pose2d> truth;
  std::vector<Pose2d> wheelSteps;  // 3 % long, turning 2 % more, 0.2 deg per step of heading drift
  std::vector<std::unique_ptr<agv::LaserScan>> scans;
};

// 8 m straight along the room, then a quarter circle of 3 m radius to the left, 0.2 m per scan.
Drive drive(const agv::sim::RayCaster& caster) {
  Drive d;
  std::mt19937 rng(11);
  for (int k = 0; k <= 40; ++k) {
    d.truth.push_back(Pose2d{2.0 + 0.2 * k, 3.0, 0.0});
  }
  for (int k = 1; k <= 23; ++k) {
    const double phi = 0.2 * k / 3.0;
    d.truth.push_back(Pose2d{10.0 + 3.0 * std::sin(phi), 6.0 - 3.0 * std::cos(phi), phi});
  }
  for (std::size_t i = 0; i < d.truth.size(); ++i) {
    const Pose2d t = i == 0 ? Pose2d{} : agv::between(d.truth[i - 1], d.truth[i]);
    d.wheelSteps.push_back(Pose2d{1.03 * t.x, 1.03 * t.y, 1.02 * t.theta + agv::deg2rad(0.2)});
    d.scans.push_back(std::make_unique<agv::LaserScan>());
    castScan(caster, d.truth[i], rng, *d.scans.back());
  }
  return d;
}

constexpr const char* kRoom =
    "hall 0 0 20 12\n"
    "wall 10 0 10 1.5\n"
    "pallet 3 7 5 8.5\n"
    "pallet 14 9 17 10\n"
    "pillar 7 1.5 0.3\n"
    "pillar 15 4 0.3\n";

// The drive in kRoom.
Drive roomDrive() {
  agv::sim::World world;
  agv::sim::WorldParseError err;
  REQUIRE(agv::sim::parseWorld(kRoom, world, err) == agv::Status::Ok);
  const agv::sim::RayCaster caster(world, 1.0);
  return drive(caster);
}
}  // namespace

TEST_CASE("scan odometry: the walls hold the track where the wheels slip and over-turn", "[mapping][scan_odometry]") {
  const Drive d = roomDrive();
  const agv::mapping::StepSigmas window{};
  agv::mapping::ScanOdometry odometry(Pose2d{});
  odometry.start(*d.scans[0], d.truth[0]);
  CHECK(odometry.scans() == 1);
  Pose2d wheels = d.truth[0];
  double worst = 0.0;
  double worstHeading = 0.0;
  for (std::size_t i = 1; i < d.truth.size(); ++i) {
    const Pose2d& p = odometry.next(*d.scans[i], d.wheelSteps[i], window.covariance(d.wheelSteps[i]));
    wheels = wheels.compose(d.wheelSteps[i]);
    worst = std::max(worst, std::hypot(p.x - d.truth[i].x, p.y - d.truth[i].y));
    worstHeading = std::max(worstHeading, std::fabs(agv::normalizeAngle(p.theta - d.truth[i].theta)));
  }
  CHECK(odometry.scans() == d.truth.size());
  CHECK(odometry.matched() == d.truth.size() - 1);  // the room is in view from every pose
  const Pose2d& end = d.truth.back();
  const double wheelError = std::hypot(wheels.x - end.x, wheels.y - end.y);
  const double wheelHeading = std::fabs(agv::normalizeAngle(wheels.theta - end.theta));
  // The wheels end decimetres and degrees off over 12.6 m (3 % of the path, 2 % of the turn and
  // 0.2 deg per step: about 14 deg). The matched track has no absolute reference either, but each
  // match leaves only its own error (with 1 cm range noise on 181 beams a few hundredths of a
  // degree and millimetres), which adds up as a random walk over the 63 steps: within a few
  // centimetres and a few tenths of a degree.
  CHECK(wheelError > 0.3);
  CHECK(wheelHeading > agv::deg2rad(10.0));
  CHECK(worst < 0.03);
  CHECK(worstHeading < agv::deg2rad(0.6));

  // The track function is the class's poses.
  std::vector<agv::LaserScan> scans;
  for (const auto& s : d.scans) {
    scans.push_back(*s);
  }
  std::vector<Eigen::Matrix3d> covariances;
  for (const Pose2d& s : d.wheelSteps) {
    covariances.push_back(window.covariance(s));
  }
  std::vector<Pose2d> track;
  CHECK(agv::mapping::scanMatchedTrack(scans, Pose2d{}, d.truth[0], d.wheelSteps, covariances, track) ==
        d.truth.size() - 1);
  REQUIRE(track.size() == d.truth.size());
  CHECK(track.back().x == odometry.pose().x);
  CHECK(track.back().y == odometry.pose().y);
  CHECK(track.back().theta == odometry.pose().theta);
}

TEST_CASE("scan odometry: a scan with nothing to match keeps the wheel step", "[mapping][scan_odometry]") {
  const Drive d = roomDrive();
  agv::mapping::ScanOdometry odometry(Pose2d{});
  odometry.start(*d.scans[0], d.truth[0]);
  agv::LaserScan blind = *d.scans[1];
  for (float& r : blind.ranges) {
    r = blind.rangeMax;  // no return on any beam
  }
  const Pose2d step = d.wheelSteps[1];
  const Pose2d p = odometry.next(blind, step, agv::mapping::StepSigmas{}.covariance(step));
  const Pose2d prior = d.truth[0].compose(step);
  CHECK_FALSE(odometry.lastMatched());
  CHECK(odometry.matched() == 0);
  CHECK(p.x == prior.x);
  CHECK(p.y == prior.y);
  CHECK(p.theta == prior.theta);
  // A restart drops the counts and the map.
  odometry.start(*d.scans[2], d.truth[2]);
  CHECK(odometry.scans() == 1);
  CHECK(odometry.pose().x == d.truth[2].x);
}

TEST_CASE("scan odometry: the step sigmas grow with the distance driven and the turn", "[mapping][scan_odometry]") {
  const agv::mapping::StepSigmas s{};
  CHECK(s.sigmaXY(Pose2d{}) == Approx(s.xy));
  CHECK(s.sigmaXY(Pose2d{0.6, 0.8, 0.0}) == Approx(s.xy + s.xyPerMetre));
  CHECK(s.sigmaTheta(Pose2d{1.0, 0.0, -0.5}) == Approx(s.theta + s.thetaPerMetre + 0.5 * s.thetaPerRadian));
  const Eigen::Matrix3d c = s.covariance(Pose2d{1.0, 0.0, 0.5});
  CHECK(c(0, 0) == Approx(s.sigmaXY(Pose2d{1.0, 0.0, 0.5}) * s.sigmaXY(Pose2d{1.0, 0.0, 0.5})));
  CHECK(c(1, 1) == c(0, 0));
  CHECK(c(2, 2) == Approx(std::pow(s.sigmaTheta(Pose2d{1.0, 0.0, 0.5}), 2)));
  CHECK(c(0, 1) == 0.0);
}

TEST_CASE("scan odometry: a match refused over the step's window is found over the wider retry",
          "[mapping][scan_odometry]") {
  const Drive d = roomDrive();
  // A wheel step 14 deg off in heading (a slip in a turn) with a 3 deg sigma: the truth lies
  // beyond the window's 3 sigmas and the refinement's 0.2 rad from the prior.
  Pose2d step = agv::between(d.truth[0], d.truth[1]);
  step.theta += agv::deg2rad(14.0);
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  covariance.diagonal() << 0.02 * 0.02, 0.02 * 0.02, agv::deg2rad(3.0) * agv::deg2rad(3.0);
  const Pose2d prior = d.truth[0].compose(step);

  agv::mapping::ScanOdometry plain(Pose2d{});
  plain.start(*d.scans[0], d.truth[0]);
  const Pose2d p = plain.next(*d.scans[1], step, covariance);
  CHECK_FALSE(plain.lastMatched());
  CHECK(p.theta == prior.theta);  // the wheel step, 14 deg off
  CHECK(plain.retried() == 0);

  agv::mapping::ScanOdometry retrying(Pose2d{}, agv::ScanMatchParams{}, agv::SurfaceMapParams{}, 2.0);
  retrying.start(*d.scans[0], d.truth[0]);
  const Pose2d q = retrying.next(*d.scans[1], step, covariance);
  CHECK(retrying.lastMatched());
  CHECK(retrying.retried() == 1);
  CHECK(std::hypot(q.x - d.truth[1].x, q.y - d.truth[1].y) < 0.03);
  CHECK(std::fabs(agv::normalizeAngle(q.theta - d.truth[1].theta)) < agv::deg2rad(0.5));
  // A step within its window is matched at the first try.
  const Pose2d r = retrying.next(*d.scans[2], d.wheelSteps[2], agv::mapping::StepSigmas{}.covariance(d.wheelSteps[2]));
  CHECK(retrying.lastMatched());
  CHECK(retrying.retried() == 1);
  CHECK(std::hypot(r.x - d.truth[2].x, r.y - d.truth[2].y) < 0.03);
  // A restart clears the count.
  retrying.start(*d.scans[3], d.truth[3]);
  CHECK(retrying.retried() == 0);
}
