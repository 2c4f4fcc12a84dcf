#pragma once
// Files of a complete agvnav-vehicle set-up for tests: a configuration, a calibration and a
// landmark map, written into a fresh temporary folder.
#include <stdlib.h>
#include <unistd.h>

#include <cstdint>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace agv::test {

/// A valid configuration (line numbers matter to the tests: see `kConfigLines`).
inline std::string goodVehicleConfig(const std::string& canIf = "can0",
                                     const std::string& laserAddress = "192.168.0.10", std::uint16_t laserPort = 2111,
                                     std::uint16_t modbusPort = 1502) {
  return "# agvnav-vehicle test configuration\n"  // 1
         "can.interface = " +
         canIf +
         "\n"                                                   // 2
         "can.drive.node = 1\n"                                 // 3
         "can.drive.direction = -1\n"                           // 4
         "can.steering.node = 2\n"                              // 5
         "can.steering.pdo_offset = 2\n"                        // 6
         "can.steering.pdo_size = 2\n"                          // 7
         "can.steering.rad_per_count = 0.000766990393942821\n"  // 8
         "can.steering.zero_count = 4096\n"                     // 9
         "can.steering.counts_per_revolution = 8192\n"          // 10
         "can.heartbeat_timeout = 0.3\n"                        // 11
         "can.sync_period = 0.01   # 100 Hz SYNC\n"             // 12
         "\n"                                                   // 13
         "laser.model = lms1xx\n"                               // 14
         "laser.address = " +
         laserAddress +
         "\n"  // 15
         "laser.port = " +
         std::to_string(laserPort) +
         "\n"                            // 16
         "laser.scan_timeout = 0.5\n"    // 17
         "modbus.role = server\n"        // 18
         "modbus.address = 127.0.0.1\n"  // 19
         "modbus.port = " +
         std::to_string(modbusPort) +
         "\n"                                         // 20
         "modbus.word_order = abcd\n"                 // 21
         "calibration.file = calibration.txt\n"       // 22
         "map.file = landmarks.txt\n"                 // 23
         "map.mode = static\n"                        // 24
         "localization.initial_pose = 1.0 2.0 0.5\n"  // 25
         "loop.period = 0.001\n";                     // 26
}

/// `text` with the line of `key` replaced by `key = value` (appended when the key is absent).
/// `line` receives its 1-based line number.
inline std::string withValue(const std::string& text, const std::string& key, const std::string& value,
                             std::size_t& line) {
  std::istringstream in(text);
  std::string out;
  std::string l;
  std::size_t n = 0;
  line = 0;
  while (std::getline(in, l)) {
    ++n;
    if (l.rfind(key + " ", 0) == 0 || l.rfind(key + "=", 0) == 0) {
      l = key + " = " + value;
      line = n;
    }
    out += l + "\n";
  }
  if (line == 0) {
    out += key + " = " + value + "\n";
    line = n + 1;
  }
  return out;
}

/// `text` with the line of `key` replaced by `key = value` (appended when the key is absent).
inline std::string withValue(const std::string& text, const std::string& key, const std::string& value) {
  std::size_t line = 0;
  return withValue(text, key, value, line);
}

inline const char* goodCalibration() {
  return "agvnav-calibration 2\n"
         "wheelbase 1.5\n"
         "drive_scale 0.0005 0.00000003\n"
         "steer_offset_forward 0.017455\n"
         "steer_offset_backward -0.008727\n"
         "laser_x 1.6\n"
         "laser_y 0.0\n"
         "laser_theta 0.0\n"
         "end 7\n";
}

inline const char* goodMap() {
  return "agvnav-landmarks 2\n"
         "reflector 1 5.0 1.0 0.002\n"
         "reflector 2 6.0 -2.0 0.002\n"
         "reflector 3 9.0 3.0 0.002\n"
         "end 3\n";
}

/// A fresh folder under /tmp, removed (with the files written by `write`) by the destructor.
class TempFolder {
 public:
  TempFolder() {
    char tmpl[] = "/tmp/agvnav-vehicle-test-XXXXXX";
    const char* d = ::mkdtemp(tmpl);
    path_ = d != nullptr ? d : "";
  }
  ~TempFolder() {
    for (const std::string& f : files_) {
      ::unlink(f.c_str());
    }
    ::rmdir(path_.c_str());
  }
  bool ok() const { return !path_.empty(); }
  const std::string& path() const { return path_; }
  std::string write(const std::string& name, const std::string& content) {
    const std::string p = path_ + "/" + name;
    std::ofstream(p) << content;
    files_.push_back(p);
    return p;
  }
  /// A file name inside the folder that the test creates by other means (removed at the end).
  std::string track(const std::string& name) {
    files_.push_back(path_ + "/" + name);
    return files_.back();
  }

 private:
  std::string path_;
  std::vector<std::string> files_;
};

}  // namespace agv::test
