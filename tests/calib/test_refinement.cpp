// Joint refinement of the six calibration parameters: exactness, Monte-Carlo against the closed
// form (with and without extra steering jitter), calibrated covariance, refusals, heap use.
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

#include "agv/calib/refinement.hpp"
#include "agv_test.hpp"
#include "calib_sim.hpp"

using agv::CalibrationResult;
using agv::CalibSegment;
using agv::deg2rad;
using agv::Pose2d;
using agv::RefinementOptions;
using agv::RefinementResult;
using agv::Status;
using agv::test::CalibSimConfig;
using agv::test::Stats;

namespace {

agv::Span<const CalibSegment> span(const std::vector<CalibSegment>& v) {
  return {v.data(), v.size()};
}

constexpr double kQuantStd = agv::kTwoPi<double> / 16384.0 / 3.4641016151377544;  // 14 bit / sqrt(12)

CalibSimConfig noisyConfig(double jitter) {
  CalibSimConfig cfg;
  cfg.sigmaXY = 5e-3;
  cfg.sigmaTheta = deg2rad(0.1);
  cfg.quantiseTicks = true;
  cfg.steerBits = 14;
  cfg.steerPlacement = deg2rad(0.5);
  cfg.steerJitter = jitter;
  return cfg;
}

struct Errors {
  Stats v[agv::kCalibParamCount];
  void add(const agv::TricycleParams& p, const Pose2d& l, const CalibSimConfig& cfg) {
    v[0].add(p.driveScale / cfg.truth.driveScale - 1.0);
    v[1].add(p.steerOffsetForward - cfg.truth.steerOffsetForward);
    v[2].add(p.steerOffsetBackward - cfg.truth.steerOffsetBackward);
    v[3].add(l.x - cfg.laser.x);
    v[4].add(l.y - cfg.laser.y);
    v[5].add(agv::angleDiff(l.theta, cfg.laser.theta));
  }
};

void printRow(const char* name, const Errors& e) {
  std::printf("  %-22s s_w %6.1f ppm | aF %6.3f mdeg | aB %6.3f mdeg | lx %6.4f mm | ly %6.4f mm | lt %6.3f mdeg\n",
              name, e.v[0].rms() * 1e6, agv::rad2deg(e.v[1].rms()) * 1e3, agv::rad2deg(e.v[2].rms()) * 1e3,
              e.v[3].rms() * 1e3, e.v[4].rms() * 1e3, agv::rad2deg(e.v[5].rms()) * 1e3);
}

struct MonteCarlo {
  Errors closed;
  Errors refined;
  Stats normalised[agv::kCalibParamCount];  // refined error / sqrt(covariance diagonal)
  int failures = 0;
  int costIncreased = 0;
};

MonteCarlo run(int trials, double jitter, bool shared, std::uint64_t seed) {
  CalibSimConfig cfg = noisyConfig(jitter);
  if (shared) {
    cfg.truth.steerOffsetBackward = cfg.truth.steerOffsetForward;
  }
  const agv::CalibrationOptions opt = agv::test::nominalOptions(cfg);
  RefinementOptions ropt;
  ropt.sigmaSteering = std::sqrt(kQuantStd * kQuantStd + jitter * jitter);
  ropt.sharedOffset = shared;
  std::mt19937_64 rng(seed);
  MonteCarlo mc;
  for (int t = 0; t < trials; ++t) {
    const auto segs = simulateCalibration(cfg, rng);
    CalibrationResult cf;
    const Status s = shared ? agv::calibrateStc(span(segs), opt, cf) : agv::calibrateAtc(span(segs), opt, cf);
    RefinementResult rf;
    if (s != Status::Ok || agv::refineCalibration(span(segs), cf.params, cf.laserPose, ropt, rf) != Status::Ok) {
      ++mc.failures;
      continue;
    }
    mc.costIncreased += rf.finalCost > rf.initialCost ? 1 : 0;
    mc.closed.add(cf.params, cf.laserPose, cfg);
    mc.refined.add(rf.params, rf.laserPose, cfg);
    const double err[agv::kCalibParamCount] = {rf.params.driveScale - cfg.truth.driveScale,
                                               rf.params.steerOffsetForward - cfg.truth.steerOffsetForward,
                                               rf.params.steerOffsetBackward - cfg.truth.steerOffsetBackward,
                                               rf.laserPose.x - cfg.laser.x,
                                               rf.laserPose.y - cfg.laser.y,
                                               agv::angleDiff(rf.laserPose.theta, cfg.laser.theta)};
    for (int i = 0; i < agv::kCalibParamCount; ++i) {
      mc.normalised[i].add(err[i] / std::sqrt(rf.covariance(i, i)));
    }
  }
  return mc;
}

void checkNotWorse(const MonteCarlo& mc) {
  for (int i = 0; i < agv::kCalibParamCount; ++i) {
    INFO("parameter " << i);
    CHECK(mc.refined.v[i].rms() <= mc.closed.v[i].rms());
    CHECK(mc.refined.v[i].unbiased());
  }
  CHECK(mc.failures == 0);
  CHECK(mc.costIncreased == 0);
}

}  // namespace

TEST_CASE("refinement keeps an exact solution and converges to it from a perturbed start", "[calib][refine]") {
  for (const Pose2d& laser : {Pose2d{1.6, 0.4, deg2rad(5.0)}, Pose2d{-0.8, 0.3, deg2rad(175.0)}}) {
    CalibSimConfig cfg;
    cfg.laser = laser;
    std::mt19937_64 rng(21);
    const auto segs = simulateCalibration(cfg, rng);
    agv::TricycleParams start = cfg.truth;
    start.driveScale *= 1.002;
    start.steerOffsetForward += deg2rad(0.2);
    start.steerOffsetBackward -= deg2rad(0.3);
    const Pose2d startLaser{laser.x + 0.02, laser.y - 0.03, laser.theta + deg2rad(0.5)};
    RefinementResult r;
    REQUIRE(agv::refineCalibration(span(segs), start, startLaser, {}, r) == Status::Ok);
    CHECK(std::fabs(r.params.driveScale / cfg.truth.driveScale - 1.0) < 1e-9);
    CHECK(std::fabs(r.params.steerOffsetForward / cfg.truth.steerOffsetForward - 1.0) < 1e-9);
    CHECK(std::fabs(r.params.steerOffsetBackward / cfg.truth.steerOffsetBackward - 1.0) < 1e-9);
    CHECK(std::fabs(r.laserPose.x / laser.x - 1.0) < 1e-9);
    CHECK(std::fabs(r.laserPose.y / laser.y - 1.0) < 1e-9);
    CHECK(std::fabs(r.laserPose.theta / laser.theta - 1.0) < 1e-9);
    CHECK(r.finalCost < 1e-12);
    CHECK(r.initialCost > 1e3);
    CHECK(r.iterations < 30);
  }
}

TEST_CASE("Monte-Carlo: refinement beats the ATC closed form by >= 15 % RMS on s_w and the offsets",
          "[calib][refine][montecarlo]") {
  const MonteCarlo mc = run(500, 0.0, false, 0xBEEF);
  std::printf("refinement vs ATC closed form (N = 500), RMS errors:\n");
  printRow("ATC closed form", mc.closed);
  printRow("joint refinement", mc.refined);
  checkNotWorse(mc);
  for (int i : {agv::kParamDriveScale, agv::kParamOffsetForward, agv::kParamOffsetBackward}) {
    INFO("parameter " << i);
    CHECK(mc.refined.v[i].rms() <= 0.85 * mc.closed.v[i].rms());
  }
  // The covariance describes the errors: normalised errors have unit spread (within sampling).
  for (int i = 0; i < agv::kCalibParamCount; ++i) {
    INFO("parameter " << i << " normalised std " << mc.normalised[i].stddev());
    CHECK(mc.normalised[i].stddev() > 0.85);
    CHECK(mc.normalised[i].stddev() < 1.15);
  }
}

TEST_CASE("Monte-Carlo: refinement is not worse than the closed form with 0.05 deg steering jitter",
          "[calib][refine][montecarlo]") {
  const MonteCarlo mc = run(500, deg2rad(0.05), false, 0xCAFE);
  std::printf("with 0.05 deg steering jitter (N = 500), RMS errors:\n");
  printRow("ATC closed form", mc.closed);
  printRow("joint refinement", mc.refined);
  checkNotWorse(mc);
}

TEST_CASE("Monte-Carlo: refinement with one shared offset improves the STC closed form",
          "[calib][refine][montecarlo]") {
  const MonteCarlo mc = run(500, 0.0, true, 0xF00D);
  std::printf("refinement (shared offset) vs STC closed form (N = 500), RMS errors:\n");
  printRow("STC closed form", mc.closed);
  printRow("joint refinement", mc.refined);
  checkNotWorse(mc);
  CHECK(mc.refined.v[0].rms() <= 0.85 * mc.closed.v[0].rms());
  CHECK(mc.refined.v[1].rms() <= 0.85 * mc.closed.v[1].rms());
}

TEST_CASE("refinement refuses bad input and does not allocate", "[calib][refine]") {
  CalibSimConfig cfg = noisyConfig(0.0);
  std::mt19937_64 rng(22);
  const auto segs = simulateCalibration(cfg, rng);
  CalibrationResult cf;
  REQUIRE(agv::calibrateAtc(span(segs), agv::test::nominalOptions(cfg), cf) == Status::Ok);
  RefinementResult r;
  Status s = Status::NotInitialized;
  AGV_CHECK_NO_ALLOCATIONS(s = agv::refineCalibration(span(segs), cf.params, cf.laserPose, {}, r));
  CHECK(s == Status::Ok);
  CHECK(r.finalCost <= r.initialCost);

  // forward data only: alpha_B is unobservable unless tied to alpha_F
  const std::vector<CalibSegment> forward(segs.begin(), segs.begin() + 10);
  CHECK(agv::refineCalibration(span(forward), cf.params, cf.laserPose, {}, r) == Status::Unobservable);
  RefinementOptions shared;
  shared.sharedOffset = true;
  CHECK(agv::refineCalibration(span(forward), cf.params, cf.laserPose, shared, r) == Status::Ok);
  CHECK(r.params.steerOffsetBackward == r.params.steerOffsetForward);

  std::vector<CalibSegment> bad = segs;
  bad[4].egomotion.theta = std::numeric_limits<double>::quiet_NaN();
  CHECK(agv::refineCalibration(span(bad), cf.params, cf.laserPose, {}, r) == Status::NonFiniteInput);
  agv::TricycleParams nanParams = cf.params;
  nanParams.driveScale = std::numeric_limits<double>::infinity();
  CHECK(agv::refineCalibration(span(segs), nanParams, cf.laserPose, {}, r) == Status::NonFiniteInput);
  CHECK(agv::refineCalibration(agv::Span<const CalibSegment>(segs.data(), 1), cf.params, cf.laserPose, {}, r) ==
        Status::NotEnoughData);
  RefinementOptions badOpt;
  badOpt.sigmaTranslation = 0.0;
  CHECK(agv::refineCalibration(span(segs), cf.params, cf.laserPose, badOpt, r) == Status::InvalidArgument);
  std::vector<CalibSegment> many;
  while (many.size() <= agv::kMaxCalibSegments) {
    many.push_back(segs[many.size() % segs.size()]);
  }
  CHECK(agv::refineCalibration(span(many), cf.params, cf.laserPose, {}, r) == Status::CapacityExceeded);
}
