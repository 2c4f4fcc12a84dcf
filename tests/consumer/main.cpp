// Uses the installed package: agv::core (a pose round trip and a status name) and
// agv::drivers_protocol (a CoLa A scan telegram decoded). Exit code 0 = pass.
#include <agv/core/pose2.hpp>
#include <agv/core/status.hpp>
#include <agv/drivers/protocol/sick/cola_a_scan.hpp>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>

namespace {
// LMDscandata with three beams: -45 deg device angle, 0.5 deg step, 450 mm, no echo, 3000 mm.
constexpr char kScan[] =
    "sRA LMDscandata 1 1 89A27F 0 0 343 347 27477BA9 2747813B 0 0 7 0 0 1388 168 0 1 DIST1 3F800000 00000000 "
    "FFF92230 1388 3 1C2 0 BB8 0 0 0 0 0 0";

bool decodesScan() {
  static agv::LaserScan scan;
  const agv::Span<const std::uint8_t> telegram(reinterpret_cast<const std::uint8_t*>(kScan), sizeof kScan - 1);
  const agv::Status s = agv::drivers::sick::parseColaAScan(telegram, agv::drivers::sick::ColaAScanConfig{},
                                                           agv::Timestamp::fromSeconds(1.0), scan);
  const bool ok = s == agv::Status::Ok && scan.size() == 3U && std::fabs(scan.ranges[0] - 0.45F) < 1e-6F &&
                  !scan.isValid(1) && std::fabs(scan.ranges[2] - 3.0F) < 1e-6F &&
                  std::fabs(agv::rad2deg(static_cast<double>(scan.angleMin)) + 135.0) < 1e-4;
  std::printf("agvnav consumer: CoLa A scan %s, %zu beams from %.1f deg: %s\n", agv::toString(s), scan.size(),
              agv::rad2deg(static_cast<double>(scan.angleMin)), ok ? "ok" : "FAILED");
  return ok;
}
}  // namespace

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
  const bool scanOk = decodesScan();
  return ok && scanOk ? 0 : 1;
}
