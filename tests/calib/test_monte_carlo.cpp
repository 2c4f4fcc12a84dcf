// Monte-Carlo of the closed forms: egomotion noise N(0, 5 mm) per axis and N(0, 0.1 deg), drive
// tick quantisation, 14-bit steering quantisation, 10 segments per direction, beta = 180 deg,
// steering 18..50 deg left and right, forward and backward. Errors must be unbiased and their
// spread within the bounds of the calibration issue.
#include <cstdio>
#include <random>
#include <vector>

#include "agv_test.hpp"
#include "calib_sim.hpp"

using agv::CalibrationResult;
using agv::CalibSegment;
using agv::deg2rad;
using agv::Status;
using agv::test::CalibSimConfig;
using agv::test::Stats;

namespace {

constexpr int kTrials = 1000;

struct ParamStats {
  Stats sw;      // relative [-]
  Stats alphaF;  // [rad]
  Stats alphaB;  // [rad]
  Stats lx;      // [m]
  Stats ly;      // [m]
  Stats lt;      // [rad]
};

CalibSimConfig noisyConfig(bool asymmetric, const agv::Pose2d& laser) {
  CalibSimConfig cfg;
  if (!asymmetric) {
    cfg.truth.steerOffsetBackward = cfg.truth.steerOffsetForward;
  }
  cfg.laser = laser;
  cfg.sigmaXY = 5e-3;
  cfg.sigmaTheta = deg2rad(0.1);
  cfg.quantiseTicks = true;
  cfg.steerBits = 14;
  cfg.steerPlacement = deg2rad(0.5);  // the steering controller does not land on a code exactly
  return cfg;
}

void accumulate(ParamStats& st, const CalibrationResult& r, const CalibSimConfig& cfg) {
  st.sw.add(r.params.driveScale / cfg.truth.driveScale - 1.0);
  st.alphaF.add(r.params.steerOffsetForward - cfg.truth.steerOffsetForward);
  st.alphaB.add(r.params.steerOffsetBackward - cfg.truth.steerOffsetBackward);
  st.lx.add(r.laserPose.x - cfg.laser.x);
  st.ly.add(r.laserPose.y - cfg.laser.y);
  st.lt.add(agv::angleDiff(r.laserPose.theta, cfg.laser.theta));
}

void print(const char* name, const ParamStats& st) {
  std::printf("%s (N = %d)\n", name, kTrials);
  std::printf("  s_w     mean %+8.1f ppm  std %7.1f ppm\n", st.sw.mean * 1e6, st.sw.stddev() * 1e6);
  std::printf("  alpha_F mean %+8.3f mdeg std %7.3f mdeg\n", agv::rad2deg(st.alphaF.mean) * 1e3,
              agv::rad2deg(st.alphaF.stddev()) * 1e3);
  std::printf("  alpha_B mean %+8.3f mdeg std %7.3f mdeg\n", agv::rad2deg(st.alphaB.mean) * 1e3,
              agv::rad2deg(st.alphaB.stddev()) * 1e3);
  std::printf("  l_x     mean %+8.4f mm   std %7.4f mm\n", st.lx.mean * 1e3, st.lx.stddev() * 1e3);
  std::printf("  l_y     mean %+8.4f mm   std %7.4f mm\n", st.ly.mean * 1e3, st.ly.stddev() * 1e3);
  std::printf("  l_theta mean %+8.3f mdeg std %7.3f mdeg\n", agv::rad2deg(st.lt.mean) * 1e3,
              agv::rad2deg(st.lt.stddev()) * 1e3);
}

void checkUnbiased(const ParamStats& st) {
  CHECK(st.sw.unbiased());
  CHECK(st.alphaF.unbiased());
  CHECK(st.alphaB.unbiased());
  CHECK(st.lx.unbiased());
  CHECK(st.ly.unbiased());
  CHECK(st.lt.unbiased());
}

void runMonteCarlo(bool asymmetric, const agv::Pose2d& laser, std::uint64_t seed, ParamStats& st) {
  const CalibSimConfig cfg = noisyConfig(asymmetric, laser);
  const agv::CalibrationOptions opt = agv::test::nominalOptions(cfg);
  std::mt19937_64 rng(seed);
  int failures = 0;
  for (int trial = 0; trial < kTrials; ++trial) {
    const std::vector<CalibSegment> segs = simulateCalibration(cfg, rng);
    CalibrationResult r;
    const agv::Span<const CalibSegment> view(segs.data(), segs.size());
    const Status s = asymmetric ? agv::calibrateAtc(view, opt, r) : agv::calibrateStc(view, opt, r);
    if (s != Status::Ok) {
      ++failures;
      continue;
    }
    accumulate(st, r, cfg);
  }
  CHECK(failures == 0);
}

const agv::Pose2d kFront{1.6, 0.4, deg2rad(5.0)};
const agv::Pose2d kRear{-0.8, 0.3, deg2rad(175.0)};

}  // namespace

TEST_CASE("Monte-Carlo: STC closed form is unbiased and within the bounds", "[calib][montecarlo]") {
  for (const agv::Pose2d& laser : {kFront, kRear}) {
    ParamStats st;
    runMonteCarlo(false, laser, laser.x > 0 ? 0x5EC0ULL : 0x5EC1ULL, st);
    print(laser.x > 0 ? "STC closed form, front laser" : "STC closed form, rear laser", st);
    checkUnbiased(st);
    CHECK(st.sw.stddev() < 160e-6);
    CHECK(st.alphaF.stddev() < deg2rad(5e-3));
    CHECK(st.lx.stddev() < 0.8e-3);
    CHECK(st.ly.stddev() < 1.0e-3);
    CHECK(st.lt.stddev() < deg2rad(17e-3));
  }
}

TEST_CASE("Monte-Carlo: ATC closed form is unbiased and within the bounds", "[calib][montecarlo]") {
  for (const agv::Pose2d& laser : {kFront, kRear}) {
    ParamStats st;
    runMonteCarlo(true, laser, laser.x > 0 ? 0xA7C0ULL : 0xA7C1ULL, st);
    print(laser.x > 0 ? "ATC closed form, front laser" : "ATC closed form, rear laser", st);
    checkUnbiased(st);
    CHECK(st.sw.stddev() < 160e-6);
    CHECK(st.alphaF.stddev() < deg2rad(7.5e-3));
    CHECK(st.alphaB.stddev() < deg2rad(7.5e-3));
    CHECK(st.lx.stddev() < 0.8e-3);
    CHECK(st.ly.stddev() < 1.0e-3);
    CHECK(st.lt.stddev() < deg2rad(23e-3));
  }
}
