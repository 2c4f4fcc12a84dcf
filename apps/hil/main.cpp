// agvnav-hil: the hardware-in-the-loop simulation, the library's main job.
//
// The simulated warehouse, vehicle, sensors and localizer are being built (see docs/); until they
// land this program runs what the core offers today and says what is missing. It drives a
// rectangular block-storage loop by composing SE(2) increments, carries a front-mounted laser
// along, and checks that the loop closes to the 2 cm / 0.1 deg requirement numerically.
#include <cmath>
#include <cstdio>

#include "agv/core/angle.hpp"
#include "agv/core/fixed_vector.hpp"
#include "agv/core/pose2.hpp"
#include "agv/core/status.hpp"

namespace {
constexpr double kPositionRequirement = 0.02;   // [m]
constexpr double kHeadingRequirementDeg = 0.1;  // [deg]
}  // namespace

int main() {
  std::printf("agvnav-hil: core demo (the HIL simulation, calibration and localizer are not built yet)\n");

  // A 12 m x 7 m loop in 0.1 m steps with four 90 deg turns, as pose increments.
  agv::FixedVector<agv::Pose2d, 512> increments;
  const double step = 0.1;
  const double sides[4] = {12.0, 7.0, 12.0, 7.0};
  for (double side : sides) {
    const int n = static_cast<int>(std::lround(side / step));
    for (int i = 0; i < n; ++i) {
      if (increments.push_back(agv::Pose2d{step, 0.0, 0.0}) != agv::Status::Ok) {
        std::fprintf(stderr, "increment buffer: %s\n", agv::toString(agv::Status::CapacityExceeded));
        return 2;
      }
    }
    if (increments.push_back(agv::Pose2d{0.0, 0.0, agv::kPi<double> / 2.0}) != agv::Status::Ok) {
      std::fprintf(stderr, "increment buffer: %s\n", agv::toString(agv::Status::CapacityExceeded));
      return 2;
    }
  }

  const agv::Pose2d laserMount{1.6, 0.4, agv::deg2rad(5.0)};  // laser in the vehicle frame
  agv::Pose2d vehicle{};
  for (const agv::Pose2d& inc : increments) {
    vehicle = vehicle.compose(inc);
  }
  const agv::Pose2d laser = vehicle.compose(laserMount);
  const double posErr = std::hypot(vehicle.x, vehicle.y);
  const double headErrDeg = std::fabs(agv::rad2deg(vehicle.theta));
  std::printf(
      "loop of %zu increments: final vehicle pose (%.2e m, %.2e m, %.2e deg), laser at (%.3f, %.3f, %.2f deg)\n",
      increments.size(), vehicle.x, vehicle.y, agv::rad2deg(vehicle.theta), laser.x, laser.y,
      agv::rad2deg(laser.theta));
  const bool met = posErr <= kPositionRequirement && headErrDeg <= kHeadingRequirementDeg;
  std::printf("loop closure %.2e m / %.2e deg against %.2f m / %.1f deg: %s\n", posErr, headErrDeg,
              kPositionRequirement, kHeadingRequirementDeg, met ? "met" : "NOT met");
  return met ? 0 : 1;
}
