// Scan-to-map matching on real data: the likelihood field of the first half of a corrected log
// (the mapping run, placed with the corrected poses), and the scans of the second half matched
// against it from a prior displaced from their corrected pose. Each log's corrected poses are
// themselves a SLAM estimate (a few centimetres of jitter: docs/localization.md), so the
// tolerances are the ground truth's, not the matcher's. This isolates the matcher from the
// tracking (odometry, gating, recovery), which agvnav-replay measures.
#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "agv/core/angle.hpp"
#include "agv/datasets/carmen_log.hpp"
#include "agv/localization/likelihood_field.hpp"
#include "agv/localization/scan_matcher.hpp"
#include "agv/mapping/surface_mapper.hpp"
#include "agv_test.hpp"

using namespace agv;

namespace {

const std::string kData = std::string(AGV_SHARED_DATA_DIR) + "/laser2d/";

struct RealMatch {
  std::size_t tried = 0;     // scans on the map
  std::size_t ok = 0;        // matched
  std::vector<double> pos;   // [m] error of the matched pose vs the corrected pose
  std::vector<double> head;  // [rad]
};

double median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

/// Every `step`-th scan of the second half of `rel`, matched from the corrected pose displaced by
/// up to `dxy` [m] and `dth` [rad] with a prior covariance covering that displacement.
RealMatch matchSecondHalf(const std::string& rel, double laserX, std::size_t step, double dxy, double dth) {
  datasets::CarmenLog log;
  std::string err;
  REQUIRE(datasets::readCarmenLog(kData + rel, log, err));
  const std::size_t n = log.scans.size();
  const std::size_t half = n / 2;
  const Pose2d mount{laserX, 0.0, 0.0};
  constexpr double kRangeMax = 20.0;
  mapping::SurfaceMapper mapper;
  auto scan = std::make_unique<LaserScan>();
  for (std::size_t i = 0; i < half; ++i) {
    (void)log.scans[i].toLaserScan(*scan);
    const Pose2d laser = log.scans[i].robotPose.compose(mount);
    mapper.beginScan();
    for (std::size_t b = 0; b < scan->size(); ++b) {
      if (scan->isValid(b) && scan->ranges[b] < kRangeMax) {
        const double a = static_cast<double>(scan->angle(b));
        const double r = static_cast<double>(scan->ranges[b]);
        mapper.add(laser.transformPoint(Eigen::Vector2d(r * std::cos(a), r * std::sin(a))), laser.translation());
      }
    }
  }
  auto field = std::make_unique<LikelihoodField<std::size_t{8} << 20U>>();
  REQUIRE(mapper.build(LikelihoodFieldParams{}, 2, *field, err) == Status::Ok);
  auto matcher = std::make_unique<ScanMatcher>();
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::Matrix3d P = Eigen::Matrix3d::Zero();
  P.diagonal() << dxy * dxy / 3.0, dxy * dxy / 3.0, dth * dth / 3.0;  // uniform +-d: variance d^2/3
  RealMatch m;
  for (std::size_t i = half; i < n; i += step) {
    (void)log.scans[i].toLaserScan(*scan);
    for (float& r : scan->ranges) {
      r = r < kRangeMax ? r : std::numeric_limits<float>::infinity();
    }
    const Pose2d truth = log.scans[i].robotPose;
    // On the map: half of the points within the inlier distance at the corrected pose.
    const ScanMatchResult atTruth = matcher->match(*scan, mount, truth, *field);
    if (atTruth.points == 0 || atTruth.inliers < atTruth.points / 2) {
      continue;
    }
    ++m.tried;
    const Pose2d prior{truth.x + dxy * u(rng), truth.y + dxy * u(rng), truth.theta + dth * u(rng)};
    const ScanMatchResult r = matcher->match(*scan, mount, prior, P, *field);
    if (r.status != Status::Ok) {
      continue;
    }
    ++m.ok;
    m.pos.push_back(std::hypot(r.pose.x - truth.x, r.pose.y - truth.y));
    m.head.push_back(std::fabs(normalizeAngle(r.pose.theta - truth.theta)));
  }
  return m;
}

}  // namespace

TEST_CASE("scan matching on real logs: second-half scans against the first half's field", "[replay][realdata]") {
  struct Case {
    const char* log;
    double laserX;
  };
  for (const Case c : {Case{"fr079/freiburg-079-corrected.log.gz", -0.04}, Case{"intel/intel-corrected.log.gz", 0.0},
                       Case{"aces/aces-corrected.log.gz", 0.0}, Case{"mit-csail/csail-corrected.log.gz", 0.0}}) {
    // Displaced by up to 0.3 m and 6 deg: beyond the refinement's basin, within the search.
    const RealMatch m = matchSecondHalf(c.log, c.laserX, 5, 0.3, deg2rad(6.0));
    INFO(c.log << ": " << m.ok << " of " << m.tried << " on-map scans matched");
    REQUIRE(m.tried >= 15U);
    REQUIRE(m.ok >= 10U);
    const double medPos = median(m.pos);
    const double medHead = median(m.head);
    INFO("median error " << medPos << " m, " << rad2deg(medHead) << " deg");
    std::printf("%s: %zu of %zu on-map scans matched; median error %.3f m, %.2f deg\n", c.log, m.ok, m.tried, medPos,
                rad2deg(medHead));
    CHECK(medPos < 0.10);
    CHECK(medHead < deg2rad(1.0));
  }
}
