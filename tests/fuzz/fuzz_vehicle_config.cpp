// libFuzzer target: agvnav-vehicle's configuration parser (apps/vehicle/vehicle_config.cpp) on
// arbitrary text. Invariants: it never throws or crashes; a refusal names the file (and the line
// and key when there is one); an accepted file has every value inside the range docs/vehicle.md
// states for its key (the checks the parser promises, re-checked from outside).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_support.hpp"
#include "vehicle_config.hpp"

using agv::fuzz::check;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  agv::vehicle::VehicleConfig c;
  agv::vehicle::ConfigError e;
  if (!agv::vehicle::parseVehicleConfig(text, "/etc/agvnav/fuzz.conf", c, e)) {
    check(e.text().rfind("/etc/agvnav/fuzz.conf", 0) == 0);
    check(!e.message.empty());
    return 0;
  }
  check(!c.canInterface.empty() && c.canInterface.size() <= 15U);
  check(c.modbus.port >= 1U);
  check(c.modbus.maxConnections >= 1 && c.modbus.maxConnections <= 8);
  check(c.modbus.allowedPeerCount >= 0 && c.modbus.allowedPeerCount <= 4);
  check(c.modbus.responseTimeout.ns >= 990000 && c.modbus.responseTimeout.ns <= 10100000000LL);  // 1 % for rounding
  check(c.modbus.idleTimeout.ns >= 99000000 && c.modbus.idleTimeout.ns <= 3636000000000LL);
  check(c.laser.tcp.port >= 1U);
  check(c.laser.scanTimeout.ns > 0 && c.laser.connectBudget.ns > 0);
  check(c.cyclePeriod.ns >= 198000 && c.cyclePeriod.ns <= 101000000);
  check(c.publishPeriod.ns >= 990000 && c.publishPeriod.ns <= 1010000000);
  check(!c.calibrationFile.empty() && !c.mapFile.empty());
  if (c.haveInitialPose) {
    check(std::isfinite(c.initialPose.x) && std::isfinite(c.initialPose.y) && std::isfinite(c.initialPose.theta));
  }
  return 0;
}
