#include "vehicle_config.hpp"

#include <arpa/inet.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <functional>
#include <map>
#include <sstream>
#include <vector>

#include "agv/report/number.hpp"
#include "agv/report/text_file.hpp"

namespace agv::vehicle {
namespace {

constexpr double kTwoPi = 6.283185307179586;

std::string trim(const std::string& s) {
  const std::size_t b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) {
    return std::string();
  }
  const std::size_t e = s.find_last_not_of(" \t\r");
  return s.substr(b, e - b + 1);
}

// Numbers through the one parser of the apps' text formats: locale-free, decimal ("010" is ten,
// not octal eight), integers also as 0x.. hexadecimal (COB-IDs); the whole value must be the number.
bool parseDouble(const std::string& v, double& out) {
  return report::toReal(v, out);
}

bool parseInteger(const std::string& v, long long lo, long long hi, long long& out) {
  std::int64_t x = 0;
  if (report::parseIntegerOrHex(v, x) != report::NumberError::None || x < lo || x > hi) {
    return false;
  }
  out = x;
  return true;
}

/// `v` split at blanks (spaces and tabs).
std::vector<std::string> words(const std::string& v) {
  std::vector<std::string> w;
  std::size_t i = 0;
  while (i < v.size()) {
    const std::size_t b = v.find_first_not_of(" \t", i);
    if (b == std::string::npos) {
      break;
    }
    const std::size_t e = std::min(v.find_first_of(" \t", b), v.size());
    w.push_back(v.substr(b, e - b));
    i = e;
  }
  return w;
}

std::string range(double lo, double hi, const char* unit) {
  std::ostringstream s;
  s << lo << " .. " << hi << (unit[0] != '\0' ? " " : "") << unit;
  return s.str();
}

/// One accepted key: how to apply its value (false with `why` when the value is refused).
struct KeySpec {
  bool required;
  std::function<bool(const std::string&, std::string&)> apply;
};

using Specs = std::map<std::string, KeySpec>;

/// A number in [lo, hi] -> `apply(value)`.
KeySpec number(bool required, double lo, double hi, const char* unit, std::function<void(double)> apply) {
  return KeySpec{required, [=](const std::string& v, std::string& why) {
                   double d = 0.0;
                   if (!parseDouble(v, d) || d < lo || d > hi) {
                     why = "expected a number in " + range(lo, hi, unit) + ", got '" + v + "'";
                     return false;
                   }
                   apply(d);
                   return true;
                 }};
}

KeySpec seconds(bool required, double lo, double hi, Duration& target) {
  return number(required, lo, hi, "s", [&target](double d) { target = Duration::fromSeconds(d); });
}

KeySpec integer(bool required, long long lo, long long hi, std::function<void(long long)> apply) {
  return KeySpec{required, [=](const std::string& v, std::string& why) {
                   long long x = 0;
                   if (!parseInteger(v, lo, hi, x)) {
                     why = "expected an integer in " + std::to_string(lo) + " .. " + std::to_string(hi) + ", got '" +
                           v + "'";
                     return false;
                   }
                   apply(x);
                   return true;
                 }};
}

/// One of `names` -> `apply(index)`.
KeySpec choice(bool required, std::vector<std::string> names, std::function<void(std::size_t)> apply) {
  return KeySpec{required, [=](const std::string& v, std::string& why) {
                   for (std::size_t i = 0; i < names.size(); ++i) {
                     if (v == names[i]) {
                       apply(i);
                       return true;
                     }
                   }
                   why = "expected one of";
                   for (const std::string& n : names) {
                     why += " " + n;
                   }
                   why += ", got '" + v + "'";
                   return false;
                 }};
}

KeySpec direction(std::int8_t& target) {
  return KeySpec{false, [&target](const std::string& v, std::string& why) {
                   if (v == "1" || v == "+1") {
                     target = 1;
                   } else if (v == "-1") {
                     target = -1;
                   } else {
                     why = "expected 1 or -1, got '" + v + "'";
                     return false;
                   }
                   return true;
                 }};
}

KeySpec ipv4(bool required, char (&target)[64]) {
  return KeySpec{required, [&target](const std::string& v, std::string& why) {
                   in_addr a{};
                   if (v.size() >= sizeof(target) || inet_pton(AF_INET, v.c_str(), &a) != 1) {
                     why = "expected a numeric IPv4 address (e.g. 192.168.0.10), got '" + v + "'";
                     return false;
                   }
                   std::memcpy(target, v.c_str(), v.size() + 1);
                   return true;
                 }};
}

KeySpec filePath(std::string& target) {
  return KeySpec{true, [&target](const std::string& v, std::string& why) {
                   if (v.empty()) {
                     why = "expected a file path";
                     return false;
                   }
                   target = v;
                   return true;
                 }};
}

std::string directoryOf(const std::string& file) {
  const std::size_t slash = file.rfind('/');
  return slash == std::string::npos ? std::string() : file.substr(0, slash + 1);
}

std::string resolve(const std::string& base, const std::string& p) {
  return (p.empty() || p[0] == '/') ? p : directoryOf(base) + p;
}

using LineOf = std::map<std::string, std::size_t>;

/// The configuration being read, with what the checks across keys need: which optional keys were given, the PDO layouts
/// before they are packed, the angle offset as written.
struct ConfigDraft {
  VehicleConfig c;
  bool driveCob = false;
  bool steerCob = false;
  bool laserPort = false;
  long long driveOffset = 0;
  long long driveSize = 4;
  long long steerOffset = 0;
  long long steerSize = 4;
  bool driveOffsetGiven = false;
  bool velocityUnitsGiven = false;
  std::string angleOffsetText;
};

/// can.interface and the bus timing.
void addCanBusKeys(Specs& specs, ConfigDraft& d) {
  drivers::canopen::CanopenEncodersConfig& co = d.c.can.canopen;
  specs["can.interface"] =
      KeySpec{true, [&d](const std::string& v, std::string& why) {
                if (v.empty() || v.size() > 15 || v.find_first_of(" \t/") != std::string::npos) {
                  why = "expected an interface name of 1..15 characters (e.g. can0), got '" + v + "'";
                  return false;
                }
                d.c.canInterface = v;
                return true;
              }};
  specs["can.heartbeat_timeout"] = seconds(false, 0.0, 10.0, co.heartbeatTimeout);
  specs["can.sync_period"] = seconds(false, 0.0, 1.0, co.syncPeriod);
  specs["can.pairing_window"] = seconds(false, 0.0, 1.0, co.pairingWindow);
  specs["can.trigger"] = choice(false, {"both", "drive"}, [&co](std::size_t i) {
    co.trigger = i == 0 ? drivers::canopen::SampleTrigger::BothUpdated : drivers::canopen::SampleTrigger::DriveUpdated;
  });
}

/// can.drive.*: the drive encoder's node and TPDO.
void addCanDriveKeys(Specs& specs, ConfigDraft& d) {
  drivers::canopen::CanopenEncodersConfig& co = d.c.can.canopen;
  specs["can.drive.node"] =
      integer(false, 1, 127, [&co](long long x) { co.drive.nodeId = static_cast<std::uint8_t>(x); });
  specs["can.drive.pdo_cob_id"] = integer(false, 0x181, 0x57F, [&d, &co](long long x) {
    co.drive.pdo.cobId = static_cast<std::uint16_t>(x);
    d.driveCob = true;
  });
  specs["can.drive.pdo_offset"] = integer(false, 0, 7, [&d](long long x) {
    d.driveOffset = x;
    d.driveOffsetGiven = true;
  });
  specs["can.drive.pdo_size"] = integer(false, 1, 4, [&d](long long x) { d.driveSize = x; });
  specs["can.drive.direction"] = direction(co.drive.direction);
}

/// can.steering.*: the steering encoder's node, TPDO and scaling.
void addCanSteeringKeys(Specs& specs, ConfigDraft& d) {
  drivers::canopen::CanopenEncodersConfig& co = d.c.can.canopen;
  specs["can.steering.node"] =
      integer(false, 1, 127, [&co](long long x) { co.steering.nodeId = static_cast<std::uint8_t>(x); });
  specs["can.steering.pdo_cob_id"] = integer(false, 0x181, 0x57F, [&d, &co](long long x) {
    co.steering.pdo.cobId = static_cast<std::uint16_t>(x);
    d.steerCob = true;
  });
  specs["can.steering.pdo_offset"] = integer(false, 0, 7, [&d](long long x) { d.steerOffset = x; });
  specs["can.steering.pdo_size"] = integer(false, 1, 4, [&d](long long x) { d.steerSize = x; });
  specs["can.steering.direction"] = direction(co.steering.direction);
  specs["can.steering.rad_per_count"] =
      number(true, 1e-9, 1.0, "rad/count", [&co](double v) { co.steering.radiansPerCount = v; });
  specs["can.steering.zero_count"] =
      integer(false, 0, 0xFFFFFFFFLL, [&co](long long x) { co.steering.zeroCount = static_cast<std::uint32_t>(x); });
  specs["can.steering.counts_per_revolution"] = integer(
      false, 0, 0xFFFFFFFFLL, [&co](long long x) { co.steering.countsPerRevolution = static_cast<std::uint32_t>(x); });
}

/// laser.*: the model, its address and the timeouts, the angle offset.
void addLaserKeys(Specs& specs, ConfigDraft& d) {
  VehicleConfig& c = d.c;
  specs["laser.model"] = choice(true, {"lms1xx", "lms5xx", "tim", "nav350"}, [&c](std::size_t i) {
    const drivers::SickLaserModel models[] = {drivers::SickLaserModel::Lms1xx, drivers::SickLaserModel::Lms5xx,
                                              drivers::SickLaserModel::Tim, drivers::SickLaserModel::Nav350};
    c.laser.model = models[i];
  });
  specs["laser.address"] = ipv4(true, c.laser.tcp.host);
  specs["laser.port"] = integer(false, 1, 65535, [&d](long long x) {
    d.c.laser.tcp.port = static_cast<std::uint16_t>(x);
    d.laserPort = true;
  });
  specs["laser.scan_timeout"] = seconds(false, 0.05, 60.0, c.laser.scanTimeout);
  specs["laser.connect_timeout"] = seconds(false, 0.001, 10.0, c.laser.connectBudget);
  specs["laser.reconnect_interval"] = seconds(false, 0.01, 60.0, c.laser.tcp.reconnectInterval);
  specs["laser.angle_offset"] =
      KeySpec{false, [&d](const std::string& v, std::string& why) {
                double x = 0.0;
                if (!parseDouble(v, x) || std::fabs(x) > kTwoPi) {
                  why = "expected a number in " + range(-kTwoPi, kTwoPi, "rad") + ", got '" + v + "'";
                  return false;
                }
                d.angleOffsetText = v;
                d.c.laser.scan.angleOffset = x;
                d.c.laser.nav.angleOffset = x;
                return true;
              }};
}

/// modbus.*: the PLC link's role, address, register layout and timeouts.
void addModbusKeys(Specs& specs, VehicleConfig& c) {
  specs["modbus.role"] = choice(true, {"server", "client"}, [&c](std::size_t i) {
    c.modbus.role = i == 0 ? drivers::PlcLinkRole::Server : drivers::PlcLinkRole::Client;
  });
  specs["modbus.address"] = ipv4(false, c.modbus.address);
  specs["modbus.port"] = integer(false, 1, 65535, [&c](long long x) { c.modbus.port = static_cast<std::uint16_t>(x); });
  specs["modbus.word_order"] = choice(false, {"abcd", "cdab", "badc", "dcba"}, [&c](std::size_t i) {
    const drivers::plc::WordOrder orders[] = {drivers::plc::WordOrder::ABCD, drivers::plc::WordOrder::CDAB,
                                              drivers::plc::WordOrder::BADC, drivers::plc::WordOrder::DCBA};
    c.modbus.map.wordOrder = orders[i];
  });
  specs["modbus.remote_status_base"] = integer(  // the whole status block below 65536
      false, 0, 65536 - drivers::plc::PlcRegisterMap::kStatusCount,
      [&c](long long x) { c.modbus.remoteStatusBase = static_cast<std::uint16_t>(x); });
  specs["modbus.remote_command_base"] =
      integer(false, 0, 65535 - 9, [&c](long long x) { c.modbus.remoteCommandBase = static_cast<std::uint16_t>(x); });
  specs["modbus.max_abs_position"] = number(false, 1.0, 1e6, "m", [&c](double v) { c.modbus.map.maxAbsPosition = v; });
  specs["modbus.response_timeout"] = seconds(false, 0.001, 10.0, c.modbus.responseTimeout);
  specs["modbus.reconnect_interval"] = seconds(false, 0.01, 60.0, c.modbus.reconnectInterval);
  specs["modbus.plc_heartbeat_timeout"] = seconds(false, 0.01, 60.0, c.modbus.plcHeartbeatTimeout);
  specs["modbus.max_connections"] =
      integer(false, 1, 8, [&c](long long x) { c.modbus.maxConnections = static_cast<int>(x); });
  specs["modbus.idle_timeout"] = seconds(false, 0.1, 3600.0, c.modbus.idleTimeout);
  specs["modbus.allowed_peers"] = KeySpec{false, [&c](const std::string& v, std::string& why) {
                                            const std::vector<std::string> list = words(v);
                                            if (list.empty() || list.size() > c.modbus.allowedPeers.size()) {
                                              why = "expected 1 to 4 numeric IPv4 addresses, got '" + v + "'";
                                              return false;
                                            }
                                            for (std::size_t i = 0; i < list.size(); ++i) {
                                              in_addr a{};
                                              if (inet_pton(AF_INET, list[i].c_str(), &a) != 1) {
                                                why = "expected numeric IPv4 addresses, got '" + list[i] + "'";
                                                return false;
                                              }
                                              c.modbus.allowedPeers[i] = a.s_addr;
                                            }
                                            c.modbus.allowedPeerCount = static_cast<int>(list.size());
                                            return true;
                                          }};
}

/// calibration.file, map.file and map.mode.
void addFileKeys(Specs& specs, VehicleConfig& c) {
  specs["calibration.file"] = filePath(c.calibrationFile);
  specs["map.file"] = filePath(c.mapFile);
  specs["map.mode"] = choice(false, {"static", "dynamic"},
                             [&c](std::size_t i) { c.mapMode = i == 0 ? MapMode::Static : MapMode::Dynamic; });
}

/// localization.*: corners as observations, the initial pose.
void addLocalizationKeys(Specs& specs, VehicleConfig& c) {
  specs["localization.corners"] = choice(false, {"false", "true"}, [&c](std::size_t i) { c.useCorners = i == 1; });
  specs["localization.surface_map"] =
      choice(false, {"false", "true"}, [&c](std::size_t i) { c.useSurfaceMap = i == 1; });
  specs["localization.relocalize"] = choice(false, {"false", "true"}, [&c](std::size_t i) { c.relocalize = i == 1; });
  specs["localization.initial_pose"] =
      KeySpec{false, [&c](const std::string& v, std::string& why) {
                const std::vector<std::string> w = words(v);
                double x = 0, y = 0, th = 0;
                if (w.size() != 3 || !parseDouble(w[0], x) || !parseDouble(w[1], y) || !parseDouble(w[2], th) ||
                    std::fabs(x) > 1e6 || std::fabs(y) > 1e6 || std::fabs(th) > kTwoPi) {
                  why = "expected 'x y theta' in m, m, rad (|x|,|y| <= 1e6, |theta| <= 2 pi), got '" + v + "'";
                  return false;
                }
                c.initialPose = Pose2d(x, y, th);
                c.haveInitialPose = true;
                return true;
              }};
}

/// drives.*: the CiA 402 drives the calibration routine commands.
void addDrivesKeys(Specs& specs, ConfigDraft& d) {
  VehicleConfig& c = d.c;
  drivers::canopen::TractionAxisConfig& t = c.drives.traction;
  drivers::canopen::SteeringAxisConfig& st = c.drives.steering;
  specs["drives.enabled"] = choice(false, {"false", "true"}, [&c](std::size_t i) { c.drivesEnabled = i == 1; });
  specs["drives.traction.node"] =
      integer(false, 1, 127, [&t](long long x) { t.nodeId = static_cast<std::uint8_t>(x); });
  specs["drives.traction.counts_per_metre"] = number(false, 1e-3, 1e9, "", [&t](double x) { t.countsPerMetre = x; });
  specs["drives.traction.velocity_units_per_mps"] = number(false, 1e-3, 1e9, "", [&d, &t](double x) {
    t.velocityUnitsPerMps = x;
    d.velocityUnitsGiven = true;
  });
  specs["drives.traction.direction"] = direction(t.direction);
  specs["drives.traction.max_speed"] = number(false, 0.01, 5.0, "m/s", [&t](double x) { t.maxSpeed = x; });
  specs["drives.traction.acceleration"] = number(false, 0.01, 10.0, "m/s^2", [&t](double x) { t.acceleration = x; });
  specs["drives.steering.node"] =
      integer(false, 1, 127, [&st](long long x) { st.nodeId = static_cast<std::uint8_t>(x); });
  specs["drives.steering.counts_per_radian"] =
      number(false, 1e-3, 1e9, "", [&st](double x) { st.countsPerRadian = x; });
  specs["drives.steering.zero_count"] =
      integer(false, -2147483647LL, 2147483647LL, [&st](long long x) { st.zeroCount = static_cast<std::int32_t>(x); });
  specs["drives.steering.direction"] = direction(st.direction);
  specs["drives.steering.max_angle"] = number(false, 0.01, 1.5, "rad", [&st](double x) { st.maxAngle = x; });
}

/// calibration.*: the routine on the PLC's Calibrate (the file is calibration.file).
void addCalibrationKeys(Specs& specs, VehicleConfig& c) {
  calibration::PlanRequest& p = c.calibrationPlan;
  specs["calibration.area"] = KeySpec{false, [&c, &p](const std::string& v, std::string& why) {
                                        const std::vector<std::string> w = words(v);
                                        double a[4] = {};
                                        bool ok = w.size() == 4;
                                        for (std::size_t i = 0; ok && i < 4; ++i) {
                                          ok = parseDouble(w[i], a[i]) && std::fabs(a[i]) <= 1e6;
                                        }
                                        if (!ok || !(a[0] < a[2]) || !(a[1] < a[3])) {
                                          why =
                                              "expected 'xmin ymin xmax ymax' in m with xmin < xmax, ymin < ymax, "
                                              "got '" +
                                              v + "'";
                                          return false;
                                        }
                                        p.area = calibration::FreeArea{a[0], a[1], a[2], a[3]};
                                        c.calibrationAreaSet = true;
                                        return true;
                                      }};
  specs["calibration.segments"] =
      integer(false, 1, 16, [&p](long long x) { p.segmentsPerPhase = static_cast<int>(x); });
  specs["calibration.min_steering"] = number(false, 0.05, 1.5, "rad", [&p](double x) { p.minSteering = x; });
  specs["calibration.max_steering"] = number(false, 0.05, 1.5, "rad", [&p](double x) { p.maxSteering = x; });
  specs["calibration.clearance"] = number(false, 0.0, 10.0, "m", [&p](double x) { p.clearance = x; });
  specs["calibration.front"] = number(false, 0.0, 20.0, "m", [&p](double x) { p.frontOverhang = x; });
  specs["calibration.speed"] = number(false, 0.05, 2.0, "m/s", [&c](double x) { c.calibrationSpeed = x; });
  specs["calibration.rotation"] = number(false, 0.5, 3.2, "rad", [&p](double x) { p.rotation = x; });
  specs["calibration.egomotion"] = choice(false, {"reflectors", "keypoints"}, [&c](std::size_t i) {
    c.calibrationEgomotion =
        i == 0 ? calibration::EgomotionSource::Reflectors : calibration::EgomotionSource::Keypoints;
  });
}

/// loop.*: the cycle and publication periods.
void addLoopKeys(Specs& specs, VehicleConfig& c) {
  specs["loop.period"] = seconds(false, 0.0002, 0.1, c.cyclePeriod);
  specs["loop.publish_period"] = seconds(false, 0.001, 1.0, c.publishPeriod);
}

/// Fills `error` (at `line` of `path`, or the file when 0); always false.
bool fail(ConfigError& error, const std::string& path, std::size_t line, const std::string& key,
          const std::string& message) {
  error.where = line > 0 ? path + ":" + std::to_string(line) : path;
  error.key = key;
  error.message = message;
  return false;
}

/// Applies every `key = value` line of `text` (comments after '#', blank lines skipped); `lineOf` records where each
/// key was given. False at the first malformed line, unknown, repeated or refused key.
bool applyLines(const std::string& text, const std::string& path, const Specs& specs, LineOf& lineOf,
                ConfigError& error) {
  std::istringstream in(text);
  std::string raw;
  std::size_t lineNo = 0;
  while (std::getline(in, raw)) {
    ++lineNo;
    const std::size_t hash = raw.find('#');
    const std::string line = trim(hash == std::string::npos ? raw : raw.substr(0, hash));
    if (line.empty()) {
      continue;
    }
    const std::size_t eq = line.find('=');
    if (eq == std::string::npos) {
      return fail(error, path, lineNo, "", "expected 'key = value', got '" + line + "'");
    }
    const std::string key = trim(line.substr(0, eq));
    const std::string value = trim(line.substr(eq + 1));
    const auto spec = specs.find(key);
    if (spec == specs.end()) {
      return fail(error, path, lineNo, key, "unknown key");
    }
    if (lineOf.count(key) != 0U) {
      return fail(error, path, lineNo, key, "given twice (first on line " + std::to_string(lineOf[key]) + ")");
    }
    lineOf[key] = lineNo;
    std::string why;
    if (!spec->second.apply(value, why)) {
      return fail(error, path, lineNo, key, why);
    }
  }
  for (const auto& [key, spec] : specs) {
    if (spec.required && lineOf.count(key) == 0U) {
      return fail(error, path, 0, key, "missing (required key)");
    }
  }
  return true;
}

/// Packs the CAN encoders' TPDO layouts (default COB-IDs from the node ids), then checks them across keys, reported at
/// the later of the lines involved.
/// The drives against the encoders on the same bus: the traction drive is the drive encoder's node,
/// the steering drive is not the steering encoder's; the controller maps TPDO1 of the traction
/// drive as statusword + position, so the drive encoder's position sits at byte 2 unless
/// `can.drive.pdo_offset` says otherwise (docs/drives.md, "Sharing the bus").
template <typename FailAt>
bool settleDrives(ConfigDraft& d, const FailAt& failAt) {
  VehicleConfig& c = d.c;
  drivers::canopen::CanopenEncodersConfig& co = c.can.canopen;
  if (!d.velocityUnitsGiven) {
    c.drives.traction.velocityUnitsPerMps = c.drives.traction.countsPerMetre;
  }
  if (!c.drivesEnabled) {
    return true;
  }
  if (c.drives.traction.nodeId != co.drive.nodeId) {
    return failAt("drives.traction.node", "must be can.drive.node (the traction drive is the drive encoder)");
  }
  if (c.drives.steering.nodeId == co.steering.nodeId || c.drives.steering.nodeId == co.drive.nodeId) {
    return failAt("drives.steering.node", "same node id as the steering encoder or the traction drive");
  }
  if (!d.driveOffsetGiven) {
    co.drive.pdo.byteOffset = 2;  // TPDO1 = statusword (2 bytes) + position actual value (4 bytes)
    if (co.drive.pdo.byteOffset + co.drive.pdo.size > 8) {
      return failAt("can.drive.pdo_size", "pdo_offset (2 with the drives) + pdo_size exceeds 8 bytes");
    }
  }
  return true;
}

bool settleCan(ConfigDraft& d, const LineOf& lineOf, const std::string& path, ConfigError& error) {
  drivers::canopen::CanopenEncodersConfig& co = d.c.can.canopen;
  co.drive.pdo.byteOffset = static_cast<std::uint8_t>(d.driveOffset);
  co.drive.pdo.size = static_cast<std::uint8_t>(d.driveSize);
  co.steering.pdo.byteOffset = static_cast<std::uint8_t>(d.steerOffset);
  co.steering.pdo.size = static_cast<std::uint8_t>(d.steerSize);
  if (!d.driveCob) {
    co.drive.pdo.cobId = static_cast<std::uint16_t>(0x180U + co.drive.nodeId);
  }
  if (!d.steerCob) {
    co.steering.pdo.cobId = static_cast<std::uint16_t>(0x180U + co.steering.nodeId);
  }
  const auto failAt = [&](const char* k, const std::string& message) {
    const auto it = lineOf.find(k);
    return fail(error, path, it != lineOf.end() ? it->second : std::size_t{0}, k, message);
  };
  if (co.drive.nodeId == co.steering.nodeId) {
    return failAt("can.steering.node", "same node id as can.drive.node");
  }
  if (d.driveOffset + d.driveSize > 8) {
    return failAt("can.drive.pdo_size", "pdo_offset + pdo_size exceeds 8 bytes");
  }
  if (d.steerOffset + d.steerSize > 8) {
    return failAt("can.steering.pdo_size", "pdo_offset + pdo_size exceeds 8 bytes");
  }
  if (co.drive.pdo.cobId == co.steering.pdo.cobId) {
    return failAt("can.steering.pdo_cob_id", "same COB-ID as the drive's TPDO");
  }
  if (co.steering.countsPerRevolution != 0U && co.steering.zeroCount >= co.steering.countsPerRevolution) {
    return failAt("can.steering.zero_count", "must be below can.steering.counts_per_revolution");
  }
  return settleDrives(d, failAt);
}

/// The laser's model defaults (port, range limits; an explicit angle offset survives) and the file paths resolved
/// against the configuration file's folder.
void applyDefaults(ConfigDraft& d, const std::string& path) {
  VehicleConfig& c = d.c;
  if (!d.laserPort) {
    c.laser.tcp.port = drivers::defaultPort(c.laser.model);
  }
  drivers::applyModelRanges(c.laser.model, c.laser.scan, c.laser.nav);
  if (d.angleOffsetText.empty()) {
    c.laser.nav.angleOffset = 0.0;  // the NAV350 reports in its own frame
  }
  c.laser.tcp.connectTimeout = c.laser.connectBudget;
  c.calibrationFile = resolve(path, c.calibrationFile);
  c.mapFile = resolve(path, c.mapFile);
}

}  // namespace

std::string ConfigError::text() const {
  std::string t = where + ": ";
  if (!key.empty()) {
    t += key + ": ";
  }
  return t + message;
}

bool parseVehicleConfig(const std::string& text, const std::string& path, VehicleConfig& out, ConfigError& error) {
  ConfigDraft d;
  Specs specs;
  addCanBusKeys(specs, d);
  addCanDriveKeys(specs, d);
  addCanSteeringKeys(specs, d);
  addLaserKeys(specs, d);
  addModbusKeys(specs, d.c);
  addFileKeys(specs, d.c);
  addLocalizationKeys(specs, d.c);
  addLoopKeys(specs, d.c);
  addDrivesKeys(specs, d);
  addCalibrationKeys(specs, d.c);

  LineOf lineOf;
  if (!applyLines(text, path, specs, lineOf, error) || !settleCan(d, lineOf, path, error)) {
    return false;
  }
  if (d.c.modbus.role == drivers::PlcLinkRole::Client && lineOf.count("modbus.address") == 0U) {
    return fail(error, path, 0, "modbus.address", "missing (required with modbus.role = client: the PLC's address)");
  }
  applyDefaults(d, path);
  out = d.c;
  out.can.interfaceName = nullptr;  // set by the user of the config from canInterface (stable storage)
  return true;
}

bool loadVehicleConfig(const std::string& path, VehicleConfig& out, ConfigError& error) {
  std::string text;
  std::string why;
  if (!report::readTextFile(path, text, why)) {
    error.where = path;
    error.key.clear();
    error.message = "configuration file refused: " + why;
    return false;
  }
  return parseVehicleConfig(text, path, out, error);
}

}  // namespace agv::vehicle
