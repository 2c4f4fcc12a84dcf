// Error metrics and odometry rebuild of agvnav-replay on synthetic trajectories with known error.
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "agv/datasets/carmen_log.hpp"
#include "agv/datasets/trajectory_error.hpp"
#include "agv/report/json.hpp"
#include "agv_test.hpp"
#include "replay.hpp"

namespace r = agv::replay;
namespace d = agv::datasets;  // the metrics and the odometry rebuild live in agv_datasets
using agv::Pose2d;
using agv::report::Json;

namespace {
constexpr double kPi = 3.14159265358979323846;

// Straight line along x, one pose every `step` metres.
std::vector<Pose2d> line(std::size_t n, double step) {
  std::vector<Pose2d> t;
  for (std::size_t i = 0; i < n; ++i) {
    t.push_back(Pose2d{step * static_cast<double>(i), 0.0, 0.0});
  }
  return t;
}
}  // namespace

TEST_CASE("replay metrics: a scale error gives its per-metre figure, a perfect estimate zero", "[replay]") {
  const auto truth = line(81, 0.125);  // 10 m, steps exact in binary
  SECTION("identical") {
    const auto e = d::relativeError(truth, truth, 1.0);
    CHECK(e.position.count == 73U);  // segments from scans 0..72 reach 1 m
    CHECK(e.position.max < 1e-12);
    CHECK(e.heading.max < 1e-12);
    const auto a = d::absoluteError(truth, truth);
    CHECK(a.position.max < 1e-12);
  }
  SECTION("5 % scale error") {
    auto est = truth;
    for (auto& p : est) {
      p.x *= 1.05;
    }
    const auto e = d::relativeError(truth, est, 1.0);
    CHECK(e.position.mean == Approx(0.05).epsilon(1e-9));
    CHECK(e.position.median == Approx(0.05).epsilon(1e-9));
    CHECK(e.heading.max < 1e-12);
    const auto a = d::absoluteError(truth, est);
    CHECK(a.position.max == Approx(0.5).epsilon(1e-9));  // 5 % of 10 m at the end
  }
  SECTION("constant heading drift: 1 deg per step of 0.125 m") {
    std::vector<Pose2d> est{truth[0]};
    const double d = kPi / 180.0;
    for (std::size_t i = 1; i < truth.size(); ++i) {
      est.push_back(est.back().compose(Pose2d{0.125, 0.0, d}));
    }
    const auto e = d::relativeError(truth, est, 1.0);
    CHECK(e.heading.mean == Approx(8.0 * d).epsilon(1e-9));  // 8 steps per metre
    CHECK(e.heading.median == Approx(8.0 * d).epsilon(1e-9));
  }
}

TEST_CASE("replay metrics: the start is aligned before the absolute error", "[replay]") {
  const auto truth = line(20, 0.1);
  std::vector<Pose2d> est;
  const Pose2d offset{3.0, -2.0, 0.7};
  for (const auto& p : truth) {
    est.push_back(offset.compose(p));
  }
  const auto a = d::absoluteError(truth, est);
  CHECK(a.position.max < 1e-9);
  CHECK(a.heading.max < 1e-9);
  const auto e = d::relativeError(truth, est, 1.0);
  CHECK(e.position.max < 1e-9);
}

TEST_CASE("replay odometry rebuild follows the data README's rule", "[replay]") {
  // scan 0 at A; ODOM (timestamped) = A (+) raw motion; scan 1 at its corrected pose B; no
  // timestamped ODOM between scans 1 and 2: zero increment.
  const std::string text =
      "ODOM 0 0 0 0 0 0 0.1 h 0.1\n"
      "FLASER 3 1 1 1 1.0 2.0 0.5 1.0 2.0 0.5 0.2 h 0.2\n"
      "ODOM 1.0 2.0 0.5 0 0 0 0 h 0\n"
      "ODOM 1.5 2.0 0.5 0 0 0 0.25 h 0.25\n"
      "ODOM 1.6 2.1 0.6 0 0 0 0.3 h 0.3\n"
      "FLASER 3 1 1 1 1.7 2.05 0.55 1.7 2.05 0.55 0.3 h 0.3\n"
      "ODOM 1.7 2.05 0.55 0 0 0 0 h 0\n"
      "FLASER 3 1 1 1 1.8 2.05 0.55 1.8 2.05 0.55 0.4 h 0.4\n";
  const auto log = agv::datasets::parseCarmenLog(text);
  REQUIRE(log.scans.size() == 3U);
  std::vector<Pose2d> inc;
  CHECK(d::odometryIncrements(log, 3, inc) == 1U);
  REQUIRE(inc.size() == 3U);
  const Pose2d expected = agv::between(Pose2d{1.0, 2.0, 0.5}, Pose2d{1.6, 2.1, 0.6});
  CHECK(inc[1].x == Approx(expected.x));
  CHECK(inc[1].y == Approx(expected.y));
  CHECK(inc[1].theta == Approx(0.1));
  CHECK(inc[2].x == 0.0);
  CHECK(inc[2].theta == 0.0);
}

TEST_CASE("replay refuses a log without scans", "[replay]") {
  const auto log = agv::datasets::parseCarmenLog("ODOM 0 0 0 0 0 0 0.1 h 0.1\n");
  r::ReplayResult res;
  std::string err;
  CHECK_FALSE(r::replayLog(log, r::fr079Defaults(), res, err));
  CHECK_FALSE(err.empty());
}

TEST_CASE("replay JSON: parses back with every documented field; SVG text escaped", "[replay]") {
  r::ReplayResult res;
  res.log = "odd \"name\" <1>.log";
  res.scans = 3;
  res.pathLength = 2.5;
  res.duration = 1.25;
  res.truth = line(3, 1.0);
  res.odometry = line(3, 1.1);
  res.localizer = line(3, 1.0);
  res.odometryRelative = d::relativeError(res.truth, res.odometry, 1.0);
  res.localizerRelative = d::relativeError(res.truth, res.localizer, 1.0);
  res.odometryAbsolute = d::absoluteError(res.truth, res.odometry);
  res.localizerAbsolute = d::absoluteError(res.truth, res.localizer);
  res.keypoints = 7;
  res.badCycles = 5;
  res.fieldContradicted = 4;
  res.rejectedField = 3;
  res.mapDeleted = 2;
  res.staticMap = true;
  res.meanTestRatio = 0.5;
  const Json j = Json::parse(agv::report::dumpJson(r::resultJson(res)));
  std::vector<std::string> keys;
  for (const auto& item : j.items()) {
    keys.push_back(item.key());
  }
  CHECK(keys == std::vector<std::string>{"log",
                                         "scans",
                                         "path_length_m",
                                         "duration_s",
                                         "zero_increments",
                                         "odometry_per_metre",
                                         "localizer_per_metre",
                                         "odometry_absolute",
                                         "localizer_absolute",
                                         "static_map",
                                         "mapping_run",
                                         "on_map",
                                         "on_route",
                                         "scan_matching",
                                         "field_relocalization",
                                         "cold_start",
                                         "surface_map",
                                         "scan_odometry",
                                         "laser_x_m",
                                         "odometry_noise",
                                         "localizer",
                                         "replay_seconds"});
  CHECK(j.at("log") == res.log);
  CHECK(j.at("scans") == 3);
  CHECK(j.at("path_length_m") == 2.5);
  CHECK(j.at("static_map") == true);
  for (const char* part : {"odometry_per_metre", "localizer_per_metre", "odometry_absolute", "localizer_absolute"}) {
    INFO(part);
    for (const char* quantity : {"position_m", "heading_deg"}) {
      for (const char* stat : {"count", "mean", "median", "rms", "max"}) {
        CHECK(j.at(part).at(quantity).at(stat).is_number());
      }
    }
  }
  CHECK(j.at("odometry_per_metre").at("position_m").at("mean").get<double>() == res.odometryRelative.position.mean);
  CHECK(j.at("odometry_per_metre").at("position_m").at("count").get<std::size_t>() ==
        res.odometryRelative.position.count);
  const Json& loc = j.at("localizer");
  CHECK(loc.size() == 20U);
  CHECK(loc.at("map_restarts") == 0);
  CHECK(loc.at("keypoints") == 7);
  CHECK(loc.at("bad_cycles") == 5);
  CHECK(loc.at("field_contradicted") == 4);
  CHECK(loc.at("rejected_field") == 3);
  CHECK(loc.at("map_deleted") == 2);
  CHECK(loc.at("mean_test_ratio") == 0.5);
  CHECK(loc.at("occluded_or_no_return") == 0);

  const std::string svg = r::trajectorySvg(res);
  CHECK(svg.find("odd &quot;name&quot; &lt;1&gt;.log (3 scans)") != std::string::npos);
  CHECK(svg.find("<1>") == std::string::npos);
}

TEST_CASE(
    "checkCorrectedLog: a FLIRTLib log, a missing odometry and pose jumps beyond physics are refused with the line",
    "[replay]") {
  namespace r = agv::replay;
  namespace d = agv::datasets;  // the metrics and the odometry rebuild live in agv_datasets
  // FLASER n r1..rn x y th odom_x odom_y odom_th ts host logger_ts
  const auto flaser = [](double x, double ts) {
    return "FLASER 3 1.0 2.0 3.0 " + std::to_string(x) + " 0 0 " + std::to_string(x) + " 0 0 " + std::to_string(ts) +
           " h " + std::to_string(ts) + "\n";
  };
  const auto odom = [](double x, double ts) {
    return "ODOM " + std::to_string(x) + " 0 0 0 0 0 " + std::to_string(ts) + " h " + std::to_string(ts) + "\n";
  };
  std::string error;
  const std::string good = odom(0.0, 1.0) + flaser(0.0, 1.0) + odom(0.5, 2.0) + flaser(0.5, 2.0);
  CHECK(d::checkCorrectedLog(agv::datasets::parseCarmenLog(good), error));

  const std::string flirt = "VERTEX2 7 1.0 2.0 0.5\n" + good;
  CHECK_FALSE(d::checkCorrectedLog(agv::datasets::parseCarmenLog(flirt), error));
  CHECK(error.find("line 1: a FLIRTLib log") != std::string::npos);

  CHECK_FALSE(d::checkCorrectedLog(agv::datasets::parseCarmenLog(flaser(0.0, 1.0) + flaser(0.5, 2.0)), error));
  CHECK(error.find("no ODOM line") != std::string::npos);

  // 2000 km in one second (line 4) is beyond physics; 12 m in one second is over the 10 m step but
  // below 20 m/s: a fast robot, accepted.
  const std::string jump = odom(0.0, 1.0) + flaser(0.0, 1.0) + odom(0.5, 2.0) + flaser(2.0e6, 2.0);
  CHECK_FALSE(d::checkCorrectedLog(agv::datasets::parseCarmenLog(jump), error));
  CHECK(error.find("line 4: the corrected pose jumps") != std::string::npos);
  const std::string fast = odom(0.0, 1.0) + flaser(0.0, 1.0) + odom(12.0, 2.0) + flaser(12.0, 2.0);
  CHECK(d::checkCorrectedLog(agv::datasets::parseCarmenLog(fast), error));  // 12 m/s: a fast robot, not a jump
  const std::string odoJump = odom(0.0, 1.0) + flaser(0.0, 1.0) + odom(500.0, 2.0) + flaser(0.5, 2.0);
  CHECK_FALSE(d::checkCorrectedLog(agv::datasets::parseCarmenLog(odoJump), error));
  CHECK(error.find("line 3: the odometry jumps") != std::string::npos);
}

namespace {
// A path of `n` random steps (0.1..1 m, turns up to 0.5 rad) whose "corrected" poses jitter by
// 1 cm / 0.2 deg per scan (a SLAM estimate's own scatter, which a fit must not take for odometry
// noise); each step's odometry lands `error(d, turn, rng)` away from the true step.
struct JitteredPath {
  agv::datasets::CarmenLog log;
  std::vector<Pose2d> inc;
  double meanDistance = 0.0;
  double meanTurn = 0.0;
};

template <class Error>
JitteredPath jitteredPath(std::uint64_t seed, std::size_t n, Error error) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> dist(0.1, 1.0);
  std::uniform_real_distribution<double> turnDist(-0.5, 0.5);
  std::normal_distribution<double> unit(0.0, 1.0);
  JitteredPath p;
  p.log.scans.resize(n);
  p.inc.resize(n);
  Pose2d truth{};
  for (std::size_t i = 0; i < n; ++i) {
    Pose2d jittered = truth;
    if (i > 0) {
      const double d = dist(rng);
      const double turn = turnDist(rng);
      const Pose2d step{d * std::cos(turn / 2.0), d * std::sin(turn / 2.0), turn};
      const Pose2d noise = error(d, turn, rng);
      truth = truth.compose(step);
      jittered = truth.compose(Pose2d{0.01 * unit(rng), 0.01 * unit(rng), 0.0035 * unit(rng)});
      // The odometry step that lands `noise` away from the true step: inc (+) noise = step.
      p.inc[i] = step.compose(noise.inverse());
      p.meanDistance += d / static_cast<double>(n - 1);
      p.meanTurn += std::fabs(turn) / static_cast<double>(n - 1);
    }
    p.log.scans[i].robotPose = jittered;
  }
  return p;
}
}  // namespace

TEST_CASE("replay odometry noise fit: recovers the variances a simulated odometry was drawn with", "[replay]") {
  // The odometry error of each step is drawn from the unicycle model (heading variance
  // a |turn| + b d, position variance c d per axis).
  const double a = 0.008;   // [rad^2/rad]
  const double b = 0.002;   // [rad^2/m]
  const double c = 0.0015;  // [m^2/m]
  const std::size_t n = 20000;
  const JitteredPath path = jitteredPath(3, n, [&](double d, double turn, std::mt19937_64& rng) {
    std::normal_distribution<double> unit(0.0, 1.0);
    return Pose2d{std::sqrt(c * d) * unit(rng), std::sqrt(c * d) * unit(rng),
                  std::sqrt(a * std::fabs(turn) + b * d) * unit(rng)};
  });
  std::size_t steps = 0;
  const agv::UnicycleNoiseParams fallback{};
  const agv::UnicycleNoiseParams fit = r::fitOdometryNoise(path.log, path.inc, 1, n, fallback, steps);
  CHECK(steps == n - 1);
  // 20 000 squared Gaussian errors: each coefficient within 10 %.
  CHECK(fit.rotationVariancePerRadian == Approx(a).epsilon(0.10));
  CHECK(fit.rotationVariancePerMetre == Approx(b).epsilon(0.10));
  CHECK(fit.translationVariancePerMetre == Approx(c).epsilon(0.10));
  // Too few steps: the fallback, and no steps reported.
  const agv::UnicycleNoiseParams few = r::fitOdometryNoise(path.log, path.inc, 1, 10, fallback, steps);
  CHECK(steps == 0);
  CHECK(few.translationVariancePerMetre == fallback.translationVariancePerMetre);
}

TEST_CASE("replay odometry noise fit: an odometry error below the ground truth's jitter is not fitted as zero",
          "[replay]") {
  // Exact odometry: every step's error is the corrected poses' jitter, which does not grow with
  // the step. The fit cannot tell the odometry's error from it, and must not call it zero: the
  // model's variance at the mean step is the jitter's.
  const std::size_t n = 20000;
  const JitteredPath path = jitteredPath(5, n, [](double, double, std::mt19937_64&) { return Pose2d{}; });
  std::size_t steps = 0;
  const agv::UnicycleNoiseParams fit = r::fitOdometryNoise(path.log, path.inc, 1, n, agv::UnicycleNoiseParams{}, steps);
  REQUIRE(steps == n - 1);
  // Per axis the step's error is the difference of two 1 cm jitters (2e-4 m^2), plus the heading
  // jitter turning the step (d^2 x 1.2e-5, a few percent); the heading's, of two 0.0035 rad jitters.
  CHECK(fit.translationVariancePerMetre * path.meanDistance == Approx(2.0e-4).epsilon(0.10));
  CHECK(fit.rotationVariancePerRadian * path.meanTurn + fit.rotationVariancePerMetre * path.meanDistance ==
        Approx(2.0 * 0.0035 * 0.0035).epsilon(0.10));
}
