// Portable calibration check (also runs in the bare-metal Cortex-M7 image): a small noise-free
// ATC/STC run built with fixed arrays, solved exactly, and a degenerate run refused.
#include "agv/calib/calibration.hpp"
#include "agv_test.hpp"

namespace {

constexpr int kSegs = 8;

/// Half circles forward and backward at 20/45 deg left and right, laser at (1.6, 0.4, 5 deg).
void makeRun(agv::CalibSegment (&segs)[kSegs], const agv::TricycleParams& truth, const agv::Pose2d& laser) {
  const double steer[4] = {agv::deg2rad(20.0), agv::deg2rad(-20.0), agv::deg2rad(45.0), agv::deg2rad(-45.0)};
  for (int k = 0; k < kSegs; ++k) {
    const double dir = k < 4 ? 1.0 : -1.0;
    const double offset = dir > 0 ? truth.steerOffsetForward : truth.steerOffsetBackward;
    const double alpha = steer[k % 4];
    const double ticks =
        std::round(dir * agv::kPi<double> * truth.wheelbase / std::fabs(std::sin(alpha)) / truth.driveScale);
    segs[k].ticks = static_cast<std::int64_t>(ticks);
    segs[k].steering = alpha - offset;
    const agv::Pose2d arc = agv::tricycleArc(ticks * truth.driveScale, alpha, truth.wheelbase);
    segs[k].egomotion = laser.inverse().compose(arc).compose(laser);
  }
}

}  // namespace

TEST_CASE("calibration (portable): noise-free ATC is exact, one steering angle is refused", "[calib]") {
  const agv::TricycleParams truth{1.5, 5e-4, agv::deg2rad(1.0), agv::deg2rad(-0.5)};
  const agv::Pose2d laser{1.6, 0.4, agv::deg2rad(5.0)};
  static agv::CalibSegment segs[kSegs];
  makeRun(segs, truth, laser);
  agv::CalibrationOptions opt;
  opt.nominal.wheelbase = truth.wheelbase;
  opt.nominal.driveScale = 5.1e-4;
  static agv::CalibrationResult r;
  REQUIRE(agv::calibrateAtc(agv::Span<const agv::CalibSegment>(segs, kSegs), opt, r) == agv::Status::Ok);
  AGV_CHECK_NEAR(r.params.driveScale, truth.driveScale, 1e-9 * truth.driveScale);
  AGV_CHECK_NEAR(r.params.steerOffsetForward, truth.steerOffsetForward, 1e-9 * truth.steerOffsetForward);
  AGV_CHECK_NEAR(r.params.steerOffsetBackward, truth.steerOffsetBackward, 1e-9 * 0.5 * truth.steerOffsetForward);
  AGV_CHECK_NEAR(r.laserPose.x, laser.x, 1e-9 * laser.x);
  AGV_CHECK_NEAR(r.laserPose.y, laser.y, 1e-9 * laser.y);
  AGV_CHECK_NEAR(r.laserPose.theta, laser.theta, 1e-9 * laser.theta);

  for (int k = 0; k < kSegs; ++k) {
    segs[k].steering = segs[0].steering;
  }
  CHECK(agv::calibrateStc(agv::Span<const agv::CalibSegment>(segs, kSegs), opt, r) == agv::Status::Unobservable);
  CHECK(r.report.failed == agv::CalibCondition::SteeringDiversity);
}
