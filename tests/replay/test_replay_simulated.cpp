// agvnav-replay on simulated gmapping-corrected logs with known truth: the cold start
// (ReplayOptions::coldStart: a mapping run's field, then the rest of the log localized with no pose
// given) and the laser odometry as the prediction input (ReplayOptions::scanOdometry).
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "agv/datasets/carmen_log.hpp"
#include "agv/sim/ray_caster.hpp"
#include "agv/sim/world.hpp"
#include "agv_test.hpp"
#include "replay.hpp"

namespace r = agv::replay;
using agv::Pose2d;

namespace {
constexpr double kPi = 3.14159265358979323846;

std::string pose3(const Pose2d& p) {
  char b[96];
  std::snprintf(b, sizeof b, "%.6f %.6f %.6f", p.x, p.y, p.theta);
  return b;
}

// A gmapping-corrected CARMEN log as the shared logs are written (shared/data/laser2d/README.md):
// the robot drives `loops` counter-clockwise circles of radius 3 m about (cx, cy), one FLASER line
// every 0.2 m and 0.4 s (181 beams over 180 deg, 1 cm Gaussian range noise, "no return" written as
// 81.9 m) with the corrected pose, and before each an ODOM line: the previous corrected pose composed
// with the raw odometry since, here 2 % long and turning 1 % more than the robot did.
agv::datasets::CarmenLog simulatedLog(const char* worldText, double cx, double cy, int loops) {
  agv::sim::World world;
  agv::sim::WorldParseError err;
  REQUIRE(agv::sim::parseWorld(worldText, world, err) == agv::Status::Ok);
  const agv::sim::RayCaster caster(world, 1.0);
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.01);
  const double radius = 3.0;
  const double step = 0.2;
  const int scans = static_cast<int>(std::lround(loops * 2.0 * kPi * radius / step));
  std::string text;
  Pose2d previous{};
  for (int k = 0; k < scans; ++k) {
    const double phi = k * step / radius;
    const Pose2d pose{cx + radius * std::cos(phi), cy + radius * std::sin(phi), agv::normalizeAngle(phi + kPi / 2)};
    const double ts = 100.0 + 0.4 * k;
    if (k > 0) {
      const Pose2d truthStep = agv::between(previous, pose);
      const Pose2d odo{1.02 * truthStep.x, 1.02 * truthStep.y, 1.01 * truthStep.theta};
      text += "ODOM " + pose3(previous.compose(odo)) + " 0 0 0 " + std::to_string(ts - 0.01) + " h " +
              std::to_string(ts - 0.01) + "\n";
    }
    text += "FLASER 181";
    for (int b = 0; b < 181; ++b) {
      const double angle = pose.theta - kPi / 2 + b * kPi / 180.0;
      const agv::sim::RayHit hit = caster.cast(agv::sim::Point2{pose.x, pose.y}, angle, 40.0);
      char v[32];
      std::snprintf(v, sizeof v, " %.3f", hit.hit ? hit.range + noise(rng) : 81.9);
      text += v;
    }
    text += " " + pose3(pose) + " " + pose3(pose) + " " + std::to_string(ts) + " h " + std::to_string(ts) + "\n";
    previous = pose;
  }
  return agv::datasets::parseCarmenLog(text);
}

// An asymmetric room: a hall with a wall stub, two pallet blocks and a pillar off its axes.
constexpr const char* kRoom =
    "hall 0 0 20 12\n"
    "wall 10 0 10 3\n"
    "pallet 3 2 5 3.5\n"
    "pallet 14 2 17 3\n"
    "pillar 15 9 0.3\n";
}  // namespace

TEST_CASE("cold start: the whole-field search finds the vehicle, the figures start at its restart", "[replay]") {
  const agv::datasets::CarmenLog log = simulatedLog(kRoom, 9.0, 7.0, 2);
  REQUIRE(log.issues.empty());
  r::ReplayOptions options = r::fr079Defaults();
  options.mapFraction = 0.5;  // the first loop maps, the second is localized
  options.coldStart = true;
  r::ReplayResult res;
  std::string error;
  REQUIRE(r::replayLog(log, options, res, error));
  REQUIRE(res.coldStart);
  REQUIRE(res.coldStartFound);
  CHECK_FALSE(res.coldStartWrong);
  CHECK(res.relocWrong == 0);
  // A search on the first scan, its candidate confirmed on the next two (relocConfirmations).
  CHECK(res.coldStartScans >= options.relocConfirmations);
  CHECK(res.coldStartScans <= 10);
  CHECK(res.coldStartPath == Approx(0.2 * static_cast<double>(res.coldStartScans)).epsilon(0.01));
  CHECK(res.coldStartSeconds == Approx(0.4 * static_cast<double>(res.coldStartScans)).epsilon(0.01));
  // Every trajectory starts at the restart; the odometry is chained from that scan's corrected pose.
  const std::size_t localized = res.scans - res.coldStartScans;
  CHECK(res.truth.size() == localized);
  CHECK(res.localizer.size() == localized);
  CHECK(res.odometry.size() == localized);
  CHECK(res.onMap.size() == localized);
  CHECK(res.odometry.front().x == res.truth.front().x);
  CHECK(res.odometry.front().theta == res.truth.front().theta);
  // The second loop drives the first one's circle: every scan is on the map. The matcher's
  // accuracy with 1 cm range noise is a few millimetres; the bound leaves the filter room.
  CHECK(res.onMapScans == localized);
  CHECK(res.localizerOnMap.position.rms < 0.03);
  CHECK(res.localizerOnMap.heading.rms < agv::deg2rad(0.5));
  // The odometry (2 % long, 1 % over-turning) drifts well beyond that over the loop.
  CHECK(res.odometryOnMap.position.rms > 5.0 * res.localizerOnMap.position.rms);

  // The same log started at the corrected pose: the same localization once found.
  r::ReplayOptions warm = options;
  warm.coldStart = false;
  r::ReplayResult given;
  REQUIRE(r::replayLog(log, warm, given, error));
  CHECK_FALSE(given.coldStart);
  CHECK(given.truth.size() == given.scans);
  CHECK(std::fabs(given.localizerOnMap.position.rms - res.localizerOnMap.position.rms) < 0.01);

  const agv::report::Json j = agv::report::Json::parse(agv::report::dumpJson(r::resultJson(res)));
  CHECK(j.at("cold_start").at("enabled") == true);
  CHECK(j.at("cold_start").at("found") == true);
  CHECK(j.at("cold_start").at("wrong") == false);
  CHECK(j.at("cold_start").at("scans_before_fix") == res.coldStartScans);
  CHECK(r::resultText(res).find("cold start (no pose given): first restart after") != std::string::npos);
}

TEST_CASE("cold start in a symmetric hall: no pose rather than a wrong one", "[replay]") {
  // The bare hall and a circle about its centre: every view has its 180-degree twin. The mapping
  // run is a whole loop (the laser looks ahead: half a loop never sees one of the end walls, and
  // then only the twin pose explains a scan of it), the next half loop is localized.
  const agv::datasets::CarmenLog log = simulatedLog("hall 0 0 16 10\n", 8.0, 5.0, 2);
  r::ReplayOptions options = r::fr079Defaults();
  options.maxScans = 141;      // of the 188: a loop and a half
  options.mapFraction = 0.67;  // the first 94 scans, the whole first loop
  options.coldStart = true;
  r::ReplayResult res;
  std::string error;
  REQUIRE(r::replayLog(log, options, res, error));
  REQUIRE(res.mappingScans == 94);
  CHECK_FALSE(res.coldStartFound);
  CHECK(res.relocConfirmed == 0);
  CHECK(res.relocWrong == 0);
  CHECK(res.relocSearches == res.scans);
  CHECK(res.relocAmbiguous > 0);
  CHECK(res.coldStartScans == res.scans);
  CHECK(res.truth.empty());
  CHECK(res.localizer.empty());
  CHECK(res.onMapScans == 0);
  CHECK(r::resultText(res).find("no pose found in " + std::to_string(res.scans) + " scans") != std::string::npos);
}

TEST_CASE("cold start needs a mapping run with its field and the field relocalization", "[replay]") {
  const agv::datasets::CarmenLog log = simulatedLog(kRoom, 9.0, 7.0, 1);
  r::ReplayOptions options = r::fr079Defaults();
  options.coldStart = true;
  r::ReplayResult res;
  std::string error;
  CHECK_FALSE(r::replayLog(log, options, res, error));  // map-less: nothing to search
  CHECK(error.find("cold start") != std::string::npos);
  options.mapFraction = 0.5;
  options.fieldRelocalization = false;
  error.clear();
  CHECK_FALSE(r::replayLog(log, options, res, error));
  CHECK(error.find("cold start") != std::string::npos);
  options.fieldRelocalization = true;
  options.scanMatching = false;
  error.clear();
  CHECK_FALSE(r::replayLog(log, options, res, error));
  CHECK(error.find("cold start") != std::string::npos);
}

TEST_CASE("laser odometry as the prediction: its steps beat the wheels', the localization holds", "[replay]") {
  const agv::datasets::CarmenLog log = simulatedLog(kRoom, 9.0, 7.0, 2);
  r::ReplayOptions options = r::fr079Defaults();
  options.mapFraction = 0.5;
  REQUIRE(options.scanOdometry);  // the default with a mapping run
  r::ReplayResult res;
  std::string error;
  REQUIRE(r::replayLog(log, options, res, error));
  REQUIRE(res.scanOdometry);
  CHECK(res.scanOdometryScans == log.scans.size());
  CHECK(res.scanOdometryMatched + 1 == res.scanOdometryScans);  // the room is in view everywhere
  // The wheels run 2 % long and over-turn by 1 %: about 2 cm and 0.6 deg per metre on this
  // circle. The matched steps keep only the matcher's error.
  CHECK(res.odometryRelative.position.mean > 0.015);
  CHECK(res.scanOdometryRelative.position.mean < res.odometryRelative.position.mean / 3.0);
  CHECK(res.scanOdometryRelative.heading.mean < res.odometryRelative.heading.mean / 3.0);
  CHECK(res.localizerOnMap.position.rms < 0.03);
  CHECK(res.localizerOnMap.heading.rms < agv::deg2rad(0.5));
  const agv::report::Json j = agv::report::Json::parse(agv::report::dumpJson(r::resultJson(res)));
  CHECK(j.at("scan_odometry").at("enabled") == true);
  CHECK(j.at("scan_odometry").at("matched") == res.scanOdometryMatched);
  CHECK(r::resultText(res).find("laser odometry (the prediction's steps)") != std::string::npos);

  // Map-less there is no mapping run to fit on: the wheel steps, and the given noise model.
  options.mapFraction = 0.0;
  r::ReplayResult mapless;
  REQUIRE(r::replayLog(log, options, mapless, error));
  CHECK_FALSE(mapless.scanOdometry);
  CHECK(mapless.odometryNoiseSteps == 0);
  CHECK(mapless.odometryNoise.translationVariancePerMetre == options.odometryNoise.translationVariancePerMetre);
  // The wheel steps on request (--no-scan-odometry): no laser odometry in the result.
  options.mapFraction = 0.5;
  options.scanOdometry = false;
  r::ReplayResult wheels;
  REQUIRE(r::replayLog(log, options, wheels, error));
  CHECK_FALSE(wheels.scanOdometry);
  CHECK(wheels.scanOdometryScans == 0);
}
