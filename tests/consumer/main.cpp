// Uses the installed agv::core: a pose round trip and a status name. Exit code 0 = pass.
#include <agv/core/pose2.hpp>
#include <agv/core/status.hpp>

#include <cmath>
#include <cstdio>
#include <cstring>

int main() {
  const agv::Pose2d laser_in_vehicle{1.6, 0.4, agv::deg2rad(5.0)};
  const agv::Pose2d vehicle{10.0, -2.0, agv::deg2rad(170.0)};
  const agv::Pose2d laser = vehicle.compose(laser_in_vehicle);
  const agv::Pose2d back = agv::between(vehicle, laser);
  const double err = std::fabs(back.x - laser_in_vehicle.x) + std::fabs(back.y - laser_in_vehicle.y) +
                     std::fabs(back.theta - laser_in_vehicle.theta);
  const bool ok = err < 1e-12 && std::strcmp(agv::toString(agv::Status::CapacityExceeded), "capacity exceeded") == 0;
  std::printf("agvnav consumer: laser at (%.3f, %.3f, %.2f deg), round-trip error %.1e: %s\n", laser.x, laser.y,
              agv::rad2deg(laser.theta), err, ok ? "ok" : "FAILED");
  return ok ? 0 : 1;
}
