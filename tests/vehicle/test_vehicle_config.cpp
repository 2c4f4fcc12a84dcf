// The agvnav-vehicle configuration file: a good file and what it sets, every key with a bad value
// (refused with the file, line and key named), unknown, repeated and missing keys, checks across
// keys, a missing file, and the calibration and map files it names.
#include <arpa/inet.h>
#include <sys/stat.h>

#include <cmath>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "agv_test.hpp"
#include "vehicle_config.hpp"
#include "vehicle_files.hpp"
#include "vehicle_runtime.hpp"

using agv::test::withValue;
using agv::vehicle::ConfigError;
using agv::vehicle::parseVehicleConfig;
using agv::vehicle::VehicleConfig;

namespace {

std::string withoutKey(const std::string& text, const std::string& key) {
  std::istringstream in(text);
  std::string out;
  std::string l;
  while (std::getline(in, l)) {
    if (l.rfind(key + " ", 0) != 0) {
      out += l + "\n";
    }
  }
  return out;
}

}  // namespace

TEST_CASE("a good configuration sets every value it names and the defaults of the rest", "[vehicle]") {
  VehicleConfig c;
  ConfigError e;
  REQUIRE(parseVehicleConfig(agv::test::goodVehicleConfig(), "/etc/agvnav/vehicle.conf", c, e));
  CHECK(c.canInterface == "can0");
  const auto& co = c.can.canopen;
  CHECK(co.drive.nodeId == 1);
  CHECK(co.drive.direction == -1);
  CHECK(co.drive.pdo.cobId == 0x181);  // default TPDO1 of the node
  CHECK(co.drive.pdo.size == 4);
  CHECK(co.steering.nodeId == 2);
  CHECK(co.steering.pdo.cobId == 0x182);
  CHECK(co.steering.pdo.byteOffset == 2);
  CHECK(co.steering.pdo.size == 2);
  CHECK(co.steering.radiansPerCount == Approx(2.0 * 3.14159265358979323846 / 8192.0).epsilon(1e-12));
  CHECK(co.steering.zeroCount == 4096U);
  CHECK(co.steering.countsPerRevolution == 8192U);
  CHECK(co.heartbeatTimeout == agv::Duration::fromMilliseconds(300));
  CHECK(co.syncPeriod == agv::Duration::fromMilliseconds(10));
  CHECK(co.pairingWindow == agv::Duration::fromMilliseconds(3));  // the decoder's default
  CHECK(co.trigger == agv::drivers::canopen::SampleTrigger::BothUpdated);
  CHECK(c.laser.model == agv::drivers::SickLaserModel::Lms1xx);
  CHECK(std::string(c.laser.tcp.host) == "192.168.0.10");
  CHECK(c.laser.tcp.port == 2111);
  CHECK(c.laser.scanTimeout == agv::Duration::fromMilliseconds(500));
  CHECK(c.laser.scan.rangeMax == Approx(20.0));  // LMS1xx range
  CHECK(c.modbus.role == agv::drivers::PlcLinkRole::Server);
  CHECK(std::string(c.modbus.address) == "127.0.0.1");
  CHECK(c.modbus.port == 1502);
  CHECK(c.modbus.map.wordOrder == agv::drivers::plc::WordOrder::ABCD);
  CHECK(c.calibrationFile == "/etc/agvnav/calibration.txt");  // relative to the configuration's folder
  CHECK(c.mapFile == "/etc/agvnav/landmarks.txt");
  CHECK(c.mapMode == agv::MapMode::Static);
  REQUIRE(c.haveInitialPose);
  CHECK(c.initialPose.x == Approx(1.0));
  CHECK(c.initialPose.y == Approx(2.0));
  CHECK(c.initialPose.theta == Approx(0.5));
  CHECK(c.cyclePeriod == agv::Duration::fromMilliseconds(1));
  // The decoder accepts what the file describes.
  agv::drivers::canopen::CanopenEncoders decoder(co);
  CHECK(decoder.validate() == agv::Status::Ok);
}

TEST_CASE("defaults follow the laser model and the node ids", "[vehicle]") {
  std::size_t line = 0;
  std::string text = withoutKey(agv::test::goodVehicleConfig(), "laser.port");
  text = withValue(text, "laser.model", "nav350", line);
  text = withValue(text, "can.drive.node", "0x10", line);
  text = withValue(text, "modbus.allowed_peers", "192.168.1.10  10.0.0.2", line);
  text = withValue(text, "modbus.idle_timeout", "2.5", line);
  VehicleConfig c;
  ConfigError e;
  REQUIRE(parseVehicleConfig(text, "vehicle.conf", c, e));
  CHECK(c.relocalize);  // the default
  VehicleConfig noReloc;
  REQUIRE(parseVehicleConfig(withValue(text, "localization.relocalize", "false", line), "vehicle.conf", noReloc, e));
  CHECK_FALSE(noReloc.relocalize);
  CHECK_FALSE(c.useSurfaceMap);  // the default
  VehicleConfig surfaces;
  REQUIRE(parseVehicleConfig(withValue(text, "localization.surface_map", "true", line), "vehicle.conf", surfaces, e));
  CHECK(surfaces.useSurfaceMap);
  CHECK(c.laser.tcp.port == 2112);
  CHECK(c.laser.nav.rangeMax == Approx(250.0));
  CHECK(c.can.canopen.drive.pdo.cobId == 0x190);
  CHECK(c.calibrationFile == "calibration.txt");  // no folder in the configuration's path
  REQUIRE(c.modbus.allowedPeerCount == 2);
  CHECK(c.modbus.allowedPeers[0] == htonl(0xC0A8010AU));  // 192.168.1.10
  CHECK(c.modbus.allowedPeers[1] == htonl(0x0A000002U));
  CHECK(c.modbus.idleTimeout.ns == 2500000000LL);
}

TEST_CASE("numbers are decimal: a leading zero is not octal, 0x is hexadecimal", "[vehicle]") {
  // strtoll(..., 0) read "010" as octal 8 and "0502" as 322: a node id or port the user did not write.
  std::size_t line = 0;
  std::string text = withValue(agv::test::goodVehicleConfig(), "can.drive.node", "010", line);
  text = withValue(text, "can.steering.node", "+011", line);
  text = withValue(text, "modbus.port", "0502", line);
  text = withValue(text, "laser.port", "02112", line);
  text = withValue(text, "can.steering.pdo_cob_id", "0x18B", line);
  text = withValue(text, "can.steering.rad_per_count", "1.5E-4", line);
  text = withValue(text, "localization.initial_pose", " 01.5\t-2e0  .25 ", line);
  VehicleConfig c;
  ConfigError e;
  REQUIRE(parseVehicleConfig(text, "vehicle.conf", c, e));
  CHECK(c.can.canopen.drive.nodeId == 10);
  CHECK(c.can.canopen.drive.pdo.cobId == 0x180 + 10);
  CHECK(c.can.canopen.steering.nodeId == 11);
  CHECK(c.can.canopen.steering.pdo.cobId == 0x18B);
  CHECK(c.modbus.port == 502);
  CHECK(c.laser.tcp.port == 2112);
  CHECK(c.can.canopen.steering.radiansPerCount == 1.5e-4);
  CHECK(c.haveInitialPose);
  CHECK(c.initialPose.x == 1.5);
  CHECK(c.initialPose.y == -2.0);
  CHECK(c.initialPose.theta == 0.25);

  // What the parser refuses: not decimal, trailing text, out of range, octal-looking hex.
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"modbus.port", "0502x"},
      {"modbus.port", "5e2"},
      {"modbus.port", "502.0"},
      {"modbus.port", "99999999999999999999"},
      {"can.drive.node", "0o10"},
      {"can.drive.node", "0x"},
      {"can.steering.rad_per_count", "0x1p-12"},
      {"can.steering.rad_per_count", "1e-400"},
      {"can.steering.rad_per_count", "inf"},
      {"can.steering.rad_per_count", "1,5e-4"},
      {"localization.initial_pose", "1 2"},
      {"localization.initial_pose", "1 2 0.1 4"},
      {"localization.initial_pose", "1 2 nan"},
  };
  for (const auto& [key, value] : bad) {
    INFO(key << " = " << value);
    VehicleConfig r;
    ConfigError err;
    CHECK_FALSE(parseVehicleConfig(withValue(agv::test::goodVehicleConfig(), key, value, line), "v.conf", r, err));
    CHECK(err.key == key);
  }
}

TEST_CASE("every key with a bad value is refused, naming the file, line and key", "[vehicle]") {
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"can.interface", ""},
      {"can.interface", "a-name-longer-than-15"},
      {"can.drive.node", "0"},
      {"can.drive.node", "128"},
      {"can.drive.node", "one"},
      {"can.drive.pdo_cob_id", "0x100"},
      {"can.drive.pdo_offset", "8"},
      {"can.drive.pdo_size", "5"},
      {"can.drive.direction", "2"},
      {"can.steering.node", "-1"},
      {"can.steering.pdo_cob_id", "0x800"},
      {"can.steering.pdo_offset", "-1"},
      {"can.steering.pdo_size", "0"},
      {"can.steering.direction", "0"},
      {"can.steering.rad_per_count", "0"},
      {"can.steering.rad_per_count", "nan"},
      {"can.steering.zero_count", "4294967296"},
      {"can.steering.counts_per_revolution", "-5"},
      {"can.heartbeat_timeout", "-0.1"},
      {"can.heartbeat_timeout", "11"},
      {"can.sync_period", "2"},
      {"can.pairing_window", "-1"},
      {"can.trigger", "sometimes"},
      {"laser.model", "lms200"},
      {"laser.address", "laser.local"},
      {"laser.address", "300.1.1.1"},
      {"laser.port", "0"},
      {"laser.port", "65536"},
      {"laser.scan_timeout", "0"},
      {"laser.connect_timeout", "100"},
      {"laser.reconnect_interval", "0"},
      {"laser.angle_offset", "7"},
      {"modbus.role", "master"},
      {"modbus.address", "localhost"},
      {"modbus.port", "0"},
      {"modbus.word_order", "abdc"},
      {"modbus.remote_status_base", "65500"},
      {"modbus.remote_status_base", "65487"},  // the 50 status registers would pass 65535
      {"modbus.remote_command_base", "65530"},
      {"modbus.max_abs_position", "0"},
      {"modbus.response_timeout", "0"},
      {"modbus.reconnect_interval", "1e9"},
      {"modbus.plc_heartbeat_timeout", "inf"},
      {"modbus.max_connections", "9"},
      {"modbus.idle_timeout", "0.01"},
      {"modbus.allowed_peers", "plc.local"},
      {"modbus.allowed_peers", "10.0.0.1 10.0.0.2 10.0.0.3 10.0.0.4 10.0.0.5"},
      {"calibration.file", ""},
      {"map.file", ""},
      {"map.mode", "frozen"},
      {"localization.corners", "yes"},
      {"localization.surface_map", "1"},
      {"localization.relocalize", "on"},
      {"localization.initial_pose", "1 2"},
      {"localization.initial_pose", "1 2 3 4"},
      {"localization.initial_pose", "1 2 x"},
      {"loop.period", "0"},
      {"loop.publish_period", "5"},
  };
  for (const auto& [key, value] : bad) {
    std::size_t line = 0;
    const std::string text = withValue(agv::test::goodVehicleConfig(), key, value, line);
    VehicleConfig c;
    ConfigError e;
    INFO(key << " = '" << value << "'");
    CHECK_FALSE(parseVehicleConfig(text, "vehicle.conf", c, e));
    CHECK(e.key == key);
    CHECK(e.where == "vehicle.conf:" + std::to_string(line));
    CHECK_FALSE(e.message.empty());
    const std::string t = e.text();
    CHECK(t.find("vehicle.conf:" + std::to_string(line) + ": " + key + ": ") == 0U);
  }
}

TEST_CASE("unknown, repeated, malformed and missing keys are refused", "[vehicle]") {
  VehicleConfig c;
  ConfigError e;
  const std::string good = agv::test::goodVehicleConfig();
  CHECK_FALSE(parseVehicleConfig(good + "can.bitrate = 500000\n", "v.conf", c, e));
  CHECK(e.key == "can.bitrate");
  CHECK(e.where == "v.conf:27");
  CHECK(e.message == "unknown key");

  CHECK_FALSE(parseVehicleConfig(good + "laser.model = tim\n", "v.conf", c, e));
  CHECK(e.key == "laser.model");
  CHECK(e.where == "v.conf:27");
  CHECK(e.message.find("line 14") != std::string::npos);

  CHECK_FALSE(parseVehicleConfig(good + "laser.model tim\n", "v.conf", c, e));
  CHECK(e.where == "v.conf:27");
  CHECK(e.key.empty());

  for (const char* key : {"can.interface", "can.steering.rad_per_count", "laser.model", "laser.address", "modbus.role",
                          "calibration.file", "map.file"}) {
    INFO(key);
    CHECK_FALSE(parseVehicleConfig(withoutKey(good, key), "v.conf", c, e));
    CHECK(e.key == key);
    CHECK(e.where == "v.conf");
    CHECK(e.message.find("missing") != std::string::npos);
  }
  CHECK_FALSE(parseVehicleConfig("", "v.conf", c, e));
  CHECK(e.message.find("missing") != std::string::npos);
}

TEST_CASE("checks across keys name the later key and its line", "[vehicle]") {
  const std::string good = agv::test::goodVehicleConfig();
  std::size_t line = 0;
  VehicleConfig c;
  ConfigError e;
  CHECK_FALSE(parseVehicleConfig(withValue(good, "can.steering.node", "1", line), "v.conf", c, e));
  CHECK(e.key == "can.steering.node");
  CHECK(e.where == "v.conf:" + std::to_string(line));
  const std::string sizes =
      withValue(withValue(good, "can.steering.pdo_offset", "6", line), "can.steering.pdo_size", "4", line);
  CHECK_FALSE(parseVehicleConfig(sizes, "v.conf", c, e));
  CHECK(e.key == "can.steering.pdo_size");
  CHECK(e.where == "v.conf:" + std::to_string(line));
  CHECK_FALSE(parseVehicleConfig(withValue(good, "can.steering.pdo_cob_id", "0x181", line), "v.conf", c, e));
  CHECK(e.key == "can.steering.pdo_cob_id");
  CHECK_FALSE(parseVehicleConfig(withValue(good, "can.steering.zero_count", "8192", line), "v.conf", c, e));
  CHECK(e.key == "can.steering.zero_count");
  CHECK(e.where == "v.conf:" + std::to_string(line));
  std::string client = withValue(withoutKey(good, "modbus.address"), "modbus.role", "client", line);
  CHECK_FALSE(parseVehicleConfig(client, "v.conf", c, e));
  CHECK(e.key == "modbus.address");
}

TEST_CASE("a missing configuration file is refused", "[vehicle]") {
  VehicleConfig c;
  ConfigError e;
  CHECK_FALSE(agv::vehicle::loadVehicleConfig("/nonexistent/agvnav/vehicle.conf", c, e));
  CHECK(e.where == "/nonexistent/agvnav/vehicle.conf");
  CHECK(e.message.find("cannot read") != std::string::npos);
}

TEST_CASE("special files and directories are refused at once, naming what they are", "[vehicle]") {
  // /dev/zero used to be read until std::bad_alloc (16-19 s), a FIFO hung, a directory was "cannot read".
  agv::test::TempFolder dir;
  REQUIRE(dir.ok());
  const std::string fifo = dir.track("vehicle.fifo");
  REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
  struct Case {
    std::string path;
    const char* says;
  };
  const Case cases[] = {{"/dev/zero", "not a regular file"}, {fifo, "not a regular file"}, {dir.path(), "a directory"}};
  for (const Case& k : cases) {
    INFO(k.path);
    VehicleConfig c;
    ConfigError e;
    CHECK_FALSE(agv::vehicle::loadVehicleConfig(k.path, c, e));
    CHECK(e.where == k.path);
    CHECK(e.message.find(k.says) != std::string::npos);
    // The same for the calibration and the map file.
    VehicleConfig files;
    files.calibrationFile = k.path;
    files.mapFile = dir.write("landmarks.txt", agv::test::goodMap());
    agv::vehicle::VehicleFiles loaded;
    ConfigError fe;
    CHECK_FALSE(agv::vehicle::loadVehicleFiles(files, loaded, fe));
    CHECK(fe.key == "calibration.file");
    CHECK(fe.message.find(k.says) != std::string::npos);
    files.calibrationFile = dir.write("calibration.txt", agv::test::goodCalibration());
    files.mapFile = k.path;
    CHECK_FALSE(agv::vehicle::loadVehicleFiles(files, loaded, fe));
    CHECK(fe.key == "map.file");
    CHECK(fe.message.find(k.says) != std::string::npos);
  }
}

TEST_CASE("the calibration and map files are loaded, a bad one is refused by file, line and key", "[vehicle]") {
  agv::test::TempFolder dir;
  REQUIRE(dir.ok());
  const std::string conf = dir.write("vehicle.conf", agv::test::goodVehicleConfig());
  dir.write("calibration.txt", agv::test::goodCalibration());
  dir.write("landmarks.txt", agv::test::goodMap());
  VehicleConfig c;
  ConfigError e;
  REQUIRE(agv::vehicle::loadVehicleConfig(conf, c, e));
  {
    agv::vehicle::VehicleFiles files;
    REQUIRE(agv::vehicle::loadVehicleFiles(c, files, e));
    CHECK(files.map->size() == 3U);
    CHECK(files.calibration.params.wheelbase == Approx(1.5));
    CHECK(files.calibration.laserPose.x == Approx(1.6));
  }
  {
    // A calibration without laser_theta: the file and the missing key are named.
    std::string cal = agv::test::goodCalibration();
    cal = cal.substr(0, cal.find("laser_theta")) + "end 6\n";
    dir.write("calibration.txt", cal);
    agv::vehicle::VehicleFiles files;
    CHECK_FALSE(agv::vehicle::loadVehicleFiles(c, files, e));
    CHECK(e.key == "calibration.file");
    CHECK(e.where == dir.path() + "/calibration.txt");
    CHECK(e.message.find("laser_theta") != std::string::npos);
    // Cut inside its last value: refused as cut short, naming the line where the file ends.
    cal = agv::test::goodCalibration();
    dir.write("calibration.txt", cal.substr(0, cal.find("laser_theta 0.0") + 13U));
    CHECK_FALSE(agv::vehicle::loadVehicleFiles(c, files, e));
    CHECK(e.where == dir.path() + "/calibration.txt:8");
    CHECK(e.message.find("cut short") != std::string::npos);
    dir.write("calibration.txt", agv::test::goodCalibration());
  }
  {
    std::string map = agv::test::goodMap();
    dir.write("landmarks.txt", map.substr(0, map.find("end")) + "pole 4 1 1 0.01\nend 4\n");
    agv::vehicle::VehicleFiles files;
    CHECK_FALSE(agv::vehicle::loadVehicleFiles(c, files, e));
    CHECK(e.key == "map.file");
    CHECK(e.where == dir.path() + "/landmarks.txt:5");
    // Cut after its second landmark: refused, naming the line where the file ends.
    dir.write("landmarks.txt", map.substr(0, map.find("reflector 3")));
    CHECK_FALSE(agv::vehicle::loadVehicleFiles(c, files, e));
    CHECK(e.where == dir.path() + "/landmarks.txt:3");
    CHECK(e.message.find("without its 'end <count>' line") != std::string::npos);
    // The count does not match.
    dir.write("landmarks.txt", map.substr(0, map.find("end")) + "end 4\n");
    CHECK_FALSE(agv::vehicle::loadVehicleFiles(c, files, e));
    CHECK(e.where == dir.path() + "/landmarks.txt:5");
    CHECK(e.message.find("count of 'end'") != std::string::npos);
  }
  {
    // Version 1 files (no end line) load, with one warning each naming the file and the fix.
    std::string map = agv::test::goodMap();
    map = "agvnav-landmarks 1" + map.substr(18, map.find("end") - 18);
    std::string cal = agv::test::goodCalibration();
    cal = "agvnav-calibration 1" + cal.substr(20, cal.find("end") - 20);
    dir.write("landmarks.txt", map);
    dir.write("calibration.txt", cal);
    agv::vehicle::VehicleFiles files;
    REQUIRE(agv::vehicle::loadVehicleFiles(c, files, e));
    CHECK(files.map->size() == 3U);
    REQUIRE(files.warnings.size() == 2U);
    CHECK(files.warnings[0].find(dir.path() + "/calibration.txt: calibration.file: format version 1") == 0U);
    CHECK(files.warnings[0].find("'end 7'") != std::string::npos);
    CHECK(files.warnings[1].find(dir.path() + "/landmarks.txt: map.file: format version 1") == 0U);
    CHECK(files.warnings[1].find("'agvnav-landmarks 2'") != std::string::npos);
    CHECK(files.warnings[1].find("'end 3'") != std::string::npos);
    dir.write("landmarks.txt", agv::test::goodMap());
    dir.write("calibration.txt", agv::test::goodCalibration());
    REQUIRE(agv::vehicle::loadVehicleFiles(c, files, e));
    CHECK(files.warnings.empty());
  }
  {
    c.mapFile = dir.path() + "/absent.txt";
    agv::vehicle::VehicleFiles files;
    CHECK_FALSE(agv::vehicle::loadVehicleFiles(c, files, e));
    CHECK(e.key == "map.file");
    CHECK(e.message.find("cannot read") != std::string::npos);
  }
}

TEST_CASE("drives and calibration keys: the drive encoder moves to byte 2 of TPDO1 with the drives", "[vehicle]") {
  const std::string good = agv::test::goodVehicleConfig();
  VehicleConfig plain;
  ConfigError e;
  REQUIRE(parseVehicleConfig(good, "v.conf", plain, e));
  CHECK_FALSE(plain.drivesEnabled);
  CHECK_FALSE(plain.calibrationAreaSet);
  CHECK(plain.can.canopen.drive.pdo.byteOffset == 0);  // a drive mapping the position alone
  std::string text = withValue(good, "drives.enabled", "true");
  text = withValue(text, "drives.traction.counts_per_metre", "9915.7");
  text = withValue(text, "drives.steering.counts_per_radian", "20000");
  text = withValue(text, "drives.steering.zero_count", "-1200");
  text = withValue(text, "calibration.area", "2.5 0.5 24 23");
  text = withValue(text, "calibration.segments", "4");
  text = withValue(text, "calibration.rotation", "1.5707963");
  text = withValue(text, "calibration.egomotion", "keypoints");
  VehicleConfig c;
  REQUIRE(parseVehicleConfig(text, "v.conf", c, e));
  CHECK(c.drivesEnabled);
  // The controller maps TPDO1 0x181 as statusword (2 bytes) + position: the decoder reads {0x181, 2, 4}.
  CHECK(c.can.canopen.drive.pdo.cobId == 0x181);
  CHECK(c.can.canopen.drive.pdo.byteOffset == 2);
  CHECK(c.can.canopen.drive.pdo.size == 4);
  CHECK(c.drives.traction.nodeId == 1);
  CHECK(c.drives.steering.nodeId == 3);
  CHECK(c.drives.traction.countsPerMetre == Approx(9915.7));
  CHECK(c.drives.traction.velocityUnitsPerMps == Approx(9915.7));  // default: position units per second
  CHECK(c.drives.steering.zeroCount == -1200);
  CHECK(c.calibrationAreaSet);
  CHECK(c.calibrationPlan.area.xMax == Approx(24.0));
  CHECK(c.calibrationPlan.segmentsPerPhase == 4);
  CHECK(c.calibrationPlan.rotation == Approx(1.5707963));
  CHECK(c.calibrationEgomotion == agv::calibration::EgomotionSource::Keypoints);
  // An explicit offset wins.
  VehicleConfig explicitOffset;
  REQUIRE(parseVehicleConfig(withValue(text, "can.drive.pdo_offset", "0"), "v.conf", explicitOffset, e));
  CHECK(explicitOffset.can.canopen.drive.pdo.byteOffset == 0);
  // The traction drive is the drive encoder's node; the steering drive is neither encoder.
  std::size_t line = 0;
  CHECK_FALSE(parseVehicleConfig(withValue(text, "drives.traction.node", "5", line), "v.conf", c, e));
  CHECK(e.key == "drives.traction.node");
  CHECK(e.where == "v.conf:" + std::to_string(line));
  CHECK_FALSE(parseVehicleConfig(withValue(text, "drives.steering.node", "2"), "v.conf", c, e));
  CHECK(e.key == "drives.steering.node");
  CHECK_FALSE(parseVehicleConfig(withValue(text, "calibration.area", "5 5 4 9"), "v.conf", c, e));
  CHECK(e.key == "calibration.area");
  CHECK_FALSE(parseVehicleConfig(withValue(text, "calibration.segments", "17"), "v.conf", c, e));
  CHECK(e.key == "calibration.segments");
  CHECK_FALSE(parseVehicleConfig(withValue(text, "calibration.rotation", "3.3"), "v.conf", c, e));
  CHECK(e.key == "calibration.rotation");
}
