// Localizer acceptance on the simulated world (host only).
#include <cstdio>
#include <cstdlib>
#include <memory>

#include "agv_test.hpp"
#include "sim_run.hpp"

using namespace agv;
using namespace agv::sim;

namespace {
std::unique_ptr<LandmarkMap> makeMap() {
  return std::make_unique<LandmarkMap>();
}

struct EndStats {
  double rmsPos = 0.0;
  double rmsHeading = 0.0;
};
EndStats endStats(const RunConfig& base, int runs, LandmarkMap& map) {
  double sp = 0.0;
  double sh = 0.0;
  for (int r = 0; r < runs; ++r) {
    RunConfig cfg = base;
    cfg.seed = base.seed + static_cast<std::uint32_t>(r);
    const RunResult res = runOnce(cfg, map);
    sp += res.endError.head<2>().squaredNorm();
    sh += res.endError(2) * res.endError(2);
  }
  return {std::sqrt(sp / runs), std::sqrt(sh / runs)};
}
}  // namespace

TEST_CASE("localizer: end-of-path accuracy with a reflector map (12 m and 7 m paths, 50 ms lag)",
          "[localization][sim]") {
  auto map = makeMap();
  for (int p = 0; p < 2; ++p) {
    RunConfig cfg;
    cfg.path = p == 0 ? path12m() : path7m();
    cfg.seed = 100;
    const EndStats s = endStats(cfg, 20, *map);
    const RunResult one = runOnce(cfg, *map);
    double inView = 0.0;
    for (const auto& c : one.cycles)
      inView += c.health.used;
    std::printf("landmarks used per cycle (mean): %.1f\n", inView / one.cycles.size());
    std::printf("accuracy %s path: RMS position %.2f mm, heading %.2f cdeg (20 runs)\n", p == 0 ? "12 m" : "7 m",
                s.rmsPos * 1e3, rad2deg(s.rmsHeading) * 100.0);
    CHECK(s.rmsPos <= 0.005);
    CHECK(rad2deg(s.rmsHeading) * 100.0 <= 5.0);
  }
}

TEST_CASE("localizer: NEES over 50 Monte-Carlo runs lies within the 95 % chi-square bounds", "[localization][sim]") {
  auto map = makeMap();
  const int runs = 50;
  std::vector<double> sum;
  std::size_t cycles = 0;
  for (int r = 0; r < runs; ++r) {
    RunConfig cfg;
    cfg.seed = 1000 + static_cast<std::uint32_t>(r);
    const RunResult res = runOnce(cfg, *map);
    if (r == 0) {
      cycles = res.cycles.size();
      sum.assign(cycles, 0.0);
    }
    REQUIRE(res.cycles.size() == cycles);
    for (std::size_t k = 0; k < cycles; ++k)
      sum[k] += res.cycles[k].nees;
  }
  // Per cycle: N * ANEES ~ chi2(3N). Two-sided 95 % bounds (z = 1.96).
  const double lo = chiSquareQuantile(3.0 * runs, -1.959964) / runs;
  const double hi = chiSquareQuantile(3.0 * runs, 1.959964) / runs;
  std::size_t inside = 0;
  double total = 0.0;
  for (std::size_t k = 0; k < cycles; ++k) {
    const double anees = sum[k] / runs;
    total += anees;
    if (anees >= lo && anees <= hi)
      ++inside;
    else if (std::getenv("AGV_PRINT_NEES") != nullptr)
      std::printf("cycle %zu ANEES %.3f outside\n", k, anees);
  }
  const double meanAnees = total / static_cast<double>(cycles);
  std::printf(
      "NEES: %d runs, %zu cycles, per-cycle 95%% band [%.3f, %.3f], %zu cycles inside (%.1f %%), mean ANEES %.3f\n",
      runs, cycles, lo, hi, inside, 100.0 * inside / cycles, meanAnees);
  CHECK(static_cast<double>(inside) >= 0.90 * static_cast<double>(cycles));
  CHECK(meanAnees >= lo);
  CHECK(meanAnees <= hi);
}

TEST_CASE("localizer: 50 ms scan lag is absorbed by the odometry history", "[localization][sim][latency]") {
  auto map = makeMap();
  RunConfig cfg;
  cfg.seed = 300;
  cfg.lagSeconds = 0.0;
  const EndStats noLag = endStats(cfg, 20, *map);
  cfg.lagSeconds = 0.05;
  const EndStats lag = endStats(cfg, 20, *map);
  // Wrong on purpose: the same lagged scans fused at their delivery time.
  cfg.stampAtDelivery = true;
  double naiveRms = 0.0;
  int naiveLost = 0;
  for (int r = 0; r < 20; ++r) {
    cfg.seed = 300 + static_cast<std::uint32_t>(r);
    const RunResult res = runOnce(cfg, *map);
    double s = 0.0;
    for (const auto& c : res.cycles)
      s += c.error.head<2>().squaredNorm();
    naiveRms += s / res.cycles.size();
    if (res.lostAtCycle >= 0)
      ++naiveLost;
  }
  naiveRms = std::sqrt(naiveRms / 20);
  std::printf(
      "latency: end RMS no lag %.2f mm, 50 ms lag %.2f mm; lag ignored: RMS along path %.1f mm, %d/20 runs lost\n",
      noLag.rmsPos * 1e3, lag.rmsPos * 1e3, naiveRms * 1e3, naiveLost);
  CHECK(lag.rmsPos <= 1.5 * noLag.rmsPos);
  CHECK(lag.rmsHeading <= 1.5 * noLag.rmsHeading);
  CHECK(naiveRms > 5.0 * lag.rmsPos);
}

TEST_CASE("localizer: 20 % spurious and 10 % missed detections stay within 1.5x the clean errors",
          "[localization][sim]") {
  auto map = makeMap();
  for (int p = 0; p < 2; ++p) {
    RunConfig cfg;
    cfg.path = p == 0 ? path12m() : path7m();
    cfg.seed = 500;
    const EndStats clean = endStats(cfg, 20, *map);
    cfg.noise.spuriousFraction = 0.2;
    cfg.noise.missProbability = 0.1;
    const EndStats dirty = endStats(cfg, 20, *map);
    std::printf("robustness %s: clean %.2f mm / %.2f cdeg, 20%% spurious + 10%% missed %.2f mm / %.2f cdeg\n",
                p == 0 ? "12 m" : "7 m", clean.rmsPos * 1e3, rad2deg(clean.rmsHeading) * 100.0, dirty.rmsPos * 1e3,
                rad2deg(dirty.rmsHeading) * 100.0);
    CHECK(dirty.rmsPos <= 1.5 * clean.rmsPos);
    CHECK(dirty.rmsHeading <= 1.5 * clean.rmsHeading);
  }
}

TEST_CASE("localizer: a kidnapped vehicle is flagged lost within 5 cycles", "[localization][sim]") {
  auto map = makeMap();
  const Pose2d offsets[] = {{2.0, 1.0, 0.5}, {-1.5, 0.5, -0.3}, {0.5, 0.0, 0.0}, {0.0, 0.0, 0.2}};
  for (const Pose2d& off : offsets) {
    RunConfig cfg;
    cfg.seed = 700;
    cfg.kidnapAtCycle = 40;
    cfg.kidnapOffset = off;
    const RunResult res = runOnce(cfg, *map);
    INFO("offset " << off.x << " " << off.y << " " << off.theta << " lost at cycle " << res.lostAtCycle);
    std::printf("kidnap by (%.1f m, %.1f m, %.2f rad): lost %d cycles after\n", off.x, off.y, off.theta,
                res.lostAtCycle - cfg.kidnapAtCycle);
    REQUIRE(res.lostAtCycle > cfg.kidnapAtCycle);
    CHECK(res.lostAtCycle - cfg.kidnapAtCycle <= 5);
    // Not lost before the kidnap.
    for (int c = 0; c < cfg.kidnapAtCycle; ++c)
      CHECK_FALSE(res.cycles[static_cast<std::size_t>(c)].health.lost);
  }
}

TEST_CASE("localizer: FALKO-corner maps: dynamic with no prior map, and static from a mapping run",
          "[localization][sim][falko]") {
  auto map = makeMap();
  // The start pose is known (a reference station): 2 mm, 2 cdeg. Without a prior map it defines
  // the map frame, so it bounds the error against the world.
  RunConfig base;
  base.cornerWorld = true;
  base.surveyedMap = false;
  base.initialSigmaXY = 0.002;
  base.initialSigmaTheta = deg2rad(0.02);
  const int runs = 20;
  // (a) dynamic map, no prior, 7 m path into the corridor
  {
    double sp = 0.0;
    double sh = 0.0;
    double maxLm = 0.0;
    for (int r = 0; r < runs; ++r) {
      RunConfig cfg = base;
      cfg.path = path7m();
      cfg.mapMode = MapMode::Dynamic;
      cfg.seed = 900 + static_cast<std::uint32_t>(r);
      const RunResult res = runOnce(cfg, *map);
      sp += res.endError.head<2>().squaredNorm();
      sh += res.endError(2) * res.endError(2);
      for (const auto& c : res.cycles)
        CHECK_FALSE(c.health.lost);
      maxLm = std::max(maxLm, static_cast<double>(map->size()));
    }
    const double rp = std::sqrt(sp / runs);
    const double rh = rad2deg(std::sqrt(sh / runs)) * 100.0;
    std::printf("FALKO dynamic map, no prior, 7 m: RMS %.2f mm / %.2f cdeg (%d runs, map up to %.0f landmarks)\n",
                rp * 1e3, rh, runs, maxLm);
    CHECK(rp <= 0.02);
    CHECK(rh <= 10.0);
  }
  // (b) a mapping run on the 12 m path, then the map frozen (static) and localised against
  {
    double sp = 0.0;
    double sh = 0.0;
    for (int r = 0; r < runs; ++r) {
      RunConfig mapping = base;
      mapping.path = path12m();
      mapping.mapMode = MapMode::Dynamic;
      mapping.seed = 1200 + static_cast<std::uint32_t>(r);
      (void)runOnce(mapping, *map);
      RunConfig cfg = base;
      cfg.path = path12m();
      cfg.mapMode = MapMode::Static;
      cfg.clearMap = false;
      cfg.initialSigmaXY = 0.01;  // later runs start from an ordinary initial guess
      cfg.initialSigmaTheta = deg2rad(0.5);
      cfg.seed = 5200 + static_cast<std::uint32_t>(r);
      const RunResult res = runOnce(cfg, *map);
      sp += res.endError.head<2>().squaredNorm();
      sh += res.endError(2) * res.endError(2);
    }
    const double rp = std::sqrt(sp / runs);
    const double rh = rad2deg(std::sqrt(sh / runs)) * 100.0;
    std::printf("FALKO static map from a mapping run, 12 m: RMS %.2f mm / %.2f cdeg (%d runs)\n", rp * 1e3, rh, runs);
    CHECK(rp <= 0.01);
    CHECK(rh <= 10.0);
  }
}

TEST_CASE("localizer: driven through the unicycle odometry input (log-style increments)", "[localization][sim]") {
  auto map = makeMap();
  RunConfig cfg;
  cfg.unicycleOdometry = true;
  cfg.lagSeconds = 0.0;  // log increments arrive at the scan instants
  cfg.seed = 1500;
  const EndStats s = endStats(cfg, 20, *map);
  std::printf("unicycle input, reflector map, 12 m: RMS %.2f mm / %.2f cdeg\n", s.rmsPos * 1e3,
              rad2deg(s.rmsHeading) * 100.0);
  CHECK(s.rmsPos <= 0.005);
  CHECK(rad2deg(s.rmsHeading) * 100.0 <= 5.0);
  const RunResult res = runOnce(cfg, *map);
  for (const auto& c : res.cycles) {
    CHECK_FALSE(c.health.lost);
    CHECK(c.health.used >= 10U);
  }
}

TEST_CASE("localizer: reflector map with a 2 mm survey error still meets 5 mm / 5 cdeg", "[localization][sim]") {
  auto map = makeMap();
  RunConfig cfg;
  cfg.surveySigma = 0.002;
  cfg.seed = 1700;
  const EndStats s = endStats(cfg, 20, *map);
  std::printf("survey error 2 mm, reflector map, 12 m: RMS %.2f mm / %.2f cdeg\n", s.rmsPos * 1e3,
              rad2deg(s.rmsHeading) * 100.0);
  CHECK(s.rmsPos <= 0.005);
  CHECK(rad2deg(s.rmsHeading) * 100.0 <= 5.0);
}
