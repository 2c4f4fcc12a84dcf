#pragma once
// agvnav-vehicle as a process for tests: start it with a configuration, wait for its exit, and
// RunningVehicle, the program against a loopback CoLa A laser streaming scans, polled by a
// libmodbus client as the PLC, with no CAN interface. Used by vehicle.process and the
// vehicle.reliability tests.
#include <modbus.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "agv/drivers/protocol/plc/plc_register_map.hpp"
#include "agv_test.hpp"
#include "loopback_server.hpp"
#include "plc_modbus_client.hpp"
#include "sick_telegrams.hpp"
#include "spawn_logged.hpp"
#include "vehicle_files.hpp"

namespace agv::test {

using agv::drivers::plc::PlcHealthBit;

/// Starts agvnav-vehicle with `args`, stdout and stderr into `logPath`. Returns the pid (or -1).
inline pid_t startVehicle(const std::vector<std::string>& args, const std::string& logPath) {
  std::vector<std::string> argv = {AGVNAV_VEHICLE_EXE};
  argv.insert(argv.end(), args.begin(), args.end());
  return spawnLogged(std::move(argv), logPath);
}

/// Waits up to `ms` for `pid` to exit; its exit code, or -1 when it did not exit normally in time.
inline int waitExit(pid_t pid, int ms, bool& exited) {
  exited = false;
  for (int i = 0; i <= ms; ++i) {
    int status = 0;
    const pid_t r = ::waitpid(pid, &status, WNOHANG);
    if (r == pid) {
      exited = true;
      return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return -1;
}

inline std::string readFile(const std::string& p) {
  std::ifstream f(p);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

/// Runs agvnav-vehicle to completion (bounded) on `args`; returns the exit code, output in `log`.
inline int runVehicle(const std::vector<std::string>& args, agv::test::TempFolder& dir, std::string& log) {
  const std::string logPath = dir.track("run.log");
  const pid_t pid = startVehicle(args, logPath);
  if (pid < 0)
    return -100;
  bool exited = false;
  const int rc = waitExit(pid, 10000, exited);
  if (!exited) {
    ::kill(pid, SIGKILL);
    ::waitpid(pid, nullptr, 0);
  }
  log = readFile(logPath);
  return rc;
}

/// The CoLa A laser of a RunningVehicle on connection `fd`: reads the subscription (counted in
/// `subscriptions`), then sends a 541-beam scan of 4 m every 40 ms (no reflector, no corner) until
/// `more()` turns false, the vehicle goes away or 1000 scans were sent. Does not close `fd`.
template <typename More>
void streamColaScans(LoopbackServer& s, int fd, std::atomic<int>& subscriptions, More more) {
  const auto subscribe = stxEtx("sEN LMDscandata 1");
  if (s.read(fd, subscribe.size()) == subscribe)
    ++subscriptions;
  for (std::uint32_t i = 1; i < 1000 && more(); ++i) {
    const auto t = colaScanTelegram(i, 4000, 541, false);
    if (::send(fd, t.data(), t.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(t.size()))
      break;  // the vehicle went away
    std::this_thread::sleep_for(std::chrono::milliseconds(40));
  }
}

/// How a RunningVehicle is set up beyond the test configuration.
struct VehicleSetup {
  /// Configuration keys set to a value (the line replaced, or appended), e.g. {"laser.model", "nav350"}.
  std::vector<std::pair<std::string, std::string>> settings;
  /// The laser's script on the loopback server, until `stop`; empty: one connection streaming CoLa
  /// A scans (`streamColaScans`).
  std::function<void(LoopbackServer&, const std::atomic<bool>& stop)> laser;
  /// False: the laser's port refuses connections when the program starts (a laser still booting;
  /// the script calls `listenAgain`), and `ready()` does not wait for "laser ok".
  bool laserUp = true;
};

/// agvnav-vehicle running against a loopback laser (by default CoLa A, `streamColaScans`) and
/// polled by a libmodbus client as the PLC; no CAN interface (`agvcan7` does not exist). The PLC
/// waits until the status block shows the device fault and the laser ok (unless the laser is
/// down at start).
class RunningVehicle {
 public:
  /// `extraConfig`: lines appended to the test configuration (e.g. modbus.idle_timeout).
  explicit RunningVehicle(const std::string& extraConfig = "", const VehicleSetup& setup = {}) {
    if (!dir.ok() || !laser.ok())
      return;
    if (!setup.laserUp)
      laser.stopListening();
    if (setup.laser) {
      laser.start([this, script = setup.laser](LoopbackServer& s) { script(s, stopLaser_); });
    } else {
      laser.start([this](LoopbackServer& s) { serveLaser(s); });
    }
    const std::uint16_t modbusPort = agv::test::closedPort();
    std::string text = agv::test::goodVehicleConfig("agvcan7", "127.0.0.1", laser.port(), modbusPort);
    for (const auto& kv : setup.settings)
      text = withValue(text, kv.first, kv.second);
    const std::string conf = dir.write("vehicle.conf", text + extraConfig);
    dir.write("calibration.txt", agv::test::goodCalibration());
    dir.write("landmarks.txt", agv::test::goodMap());
    logPath_ = dir.track("vehicle.log");
    pid_ = startVehicle({"--config", conf}, logPath_);
    if (pid_ <= 0)
      return;
    modbusPort_ = modbusPort;
    plc = modbus_new_tcp("127.0.0.1", modbusPort);
    if (plc == nullptr)
      return;
    bool connected = false;
    for (int i = 0; i < 100 && !connected; ++i) {
      connected = modbus_connect(plc) == 0;
      if (!connected)
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    if (!connected)
      return;
    bool faultSeen = false;
    bool laserOkSeen = false;
    for (int i = 0; i < 100 && !(faultSeen && laserOkSeen); ++i) {
      if (modbus_read_registers(plc, 0, 40, regs) == 40) {
        faultSeen = hasBit(PlcHealthBit::DeviceFault);
        laserOkSeen = hasBit(PlcHealthBit::LaserOk) || !setup.laserUp;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    ready_ = faultSeen && laserOkSeen;
  }
  ~RunningVehicle() {
    if (plc != nullptr) {
      modbus_close(plc);
      modbus_free(plc);
    }
    if (pid_ > 0 && !exited_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
    stopLaser_ = true;
    laser.join();
  }
  RunningVehicle(const RunningVehicle&) = delete;
  RunningVehicle& operator=(const RunningVehicle&) = delete;

  /// The program started, the PLC is connected and the status block shows the start-up state.
  bool ready() const { return ready_; }
  bool hasBit(PlcHealthBit b) const { return (regs[2] & static_cast<std::uint16_t>(b)) != 0U; }
  /// Reads the status block into `regs`.
  bool poll() { return modbus_read_registers(plc, 0, 40, regs) == 40; }
  /// Writes the whole command block in one request (code, a new sequence, set-pose, heartbeat).
  bool command(agv::hal::PlcCommandKind kind, float x = 0.0F, float y = 0.0F, float theta = 0.0F) {
    return agv::test::writePlcCommand(plc, ++sequence_, kind, x, y, theta);
  }
  /// Polls until `done()` holds on the status block or about 2 s passed (the loop publishes every
  /// 20 ms); true when it held.
  template <typename Done>
  bool waitFor(Done done) {
    for (int i = 0; i < 100; ++i) {
      if (poll() && done())
        return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return false;
  }
  /// SIGTERM; the exit code, or -1 when the program did not exit normally within 1 s.
  int terminate() {
    if (::kill(pid_, SIGTERM) != 0)
      return -1;
    return waitExit(pid_, 1000, exited_);
  }
  std::string log() const { return readFile(logPath_); }
  pid_t pid() const { return pid_; }
  std::uint16_t modbusPort() const { return modbusPort_; }

  agv::test::TempFolder dir;
  agv::test::LoopbackServer laser;
  modbus_t* plc = nullptr;
  std::uint16_t regs[40] = {};
  std::atomic<int> subscriptions{0};

 private:
  void serveLaser(LoopbackServer& s) {
    const int fd = s.accept(10000);
    if (fd < 0)
      return;
    streamColaScans(s, fd, subscriptions, [this] { return !stopLaser_.load(); });
    ::close(fd);
  }

  std::string logPath_;
  pid_t pid_ = -1;
  std::uint16_t modbusPort_ = 0;
  bool ready_ = false;
  bool exited_ = false;
  std::uint16_t sequence_ = 0;
  std::atomic<bool> stopLaser_{false};
};

}  // namespace agv::test
