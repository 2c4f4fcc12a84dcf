// agvnav-vehicle as a process on this host: the laser points at a loopback SICK CoLa A server, the
// PLC link is a Modbus server on a free loopback port read by a libmodbus client, and the CAN
// interface does not exist. The program must keep running, publish the encoder fault and the laser
// state in the health registers, and exit 0 within 1 s of SIGTERM. A bad configuration makes it
// exit 2 with the file, line and key on stderr.
#include <fcntl.h>
#include <modbus.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "agv/core/status.hpp"
#include "agv/drivers/protocol/plc/plc_register_map.hpp"
#include "agv_test.hpp"
#include "loopback_server.hpp"
#include "sick_telegrams.hpp"
#include "vehicle_files.hpp"

extern char** environ;

namespace {

using agv::drivers::plc::PlcHealthBit;

/// Starts agvnav-vehicle with `args`, stdout and stderr into `logPath`. Returns the pid (or -1).
pid_t startVehicle(const std::vector<std::string>& args, const std::string& logPath) {
  std::vector<std::string> storage = {AGVNAV_VEHICLE_EXE};
  storage.insert(storage.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& a : storage)
    argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, logPath.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, argv[0], &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  return rc == 0 ? pid : -1;
}

/// Waits up to `ms` for `pid` to exit; its exit code, or -1 when it did not exit normally in time.
int waitExit(pid_t pid, int ms, bool& exited) {
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

std::string readFile(const std::string& p) {
  std::ifstream f(p);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

/// Runs agvnav-vehicle to completion (bounded) on `args`; returns the exit code, output in `log`.
int runVehicle(const std::vector<std::string>& args, agv::test::TempFolder& dir, std::string& log) {
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

/// agvnav-vehicle running against a loopback CoLa A laser (a 541-beam scan of 4 m every 40 ms once
/// subscribed: no reflector, no corner) and polled by a libmodbus client as the PLC; no CAN
/// interface (`agvcan7` does not exist). The PLC waits until the status block shows the device
/// fault and the laser ok.
class RunningVehicle {
 public:
  RunningVehicle() {
    if (!dir.ok() || !laser.ok())
      return;
    laser.start([this](agv::test::LoopbackServer& s) { serveLaser(s); });
    const std::uint16_t modbusPort = agv::test::closedPort();
    const std::string conf =
        dir.write("vehicle.conf", agv::test::goodVehicleConfig("agvcan7", "127.0.0.1", laser.port(), modbusPort));
    dir.write("calibration.txt", agv::test::goodCalibration());
    dir.write("landmarks.txt", agv::test::goodMap());
    logPath_ = dir.track("vehicle.log");
    pid_ = startVehicle({"--config", conf}, logPath_);
    if (pid_ <= 0)
      return;
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
        laserOkSeen = hasBit(PlcHealthBit::LaserOk);
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
    std::uint16_t cmd[9] = {};
    cmd[0] = static_cast<std::uint16_t>(kind);
    cmd[1] = ++sequence_;
    // Our packing: libmodbus' setters write ABCD byte-swapped (docs/plc-link.md).
    using agv::drivers::plc::WordOrder;
    agv::drivers::plc::packFloat(x, WordOrder::ABCD, &cmd[2]);
    agv::drivers::plc::packFloat(y, WordOrder::ABCD, &cmd[4]);
    agv::drivers::plc::packFloat(theta, WordOrder::ABCD, &cmd[6]);
    cmd[8] = sequence_;  // the PLC heartbeat moves too
    return modbus_write_registers(plc, 100, 9, cmd) == 9;
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

  agv::test::TempFolder dir;
  agv::test::LoopbackServer laser;
  modbus_t* plc = nullptr;
  std::uint16_t regs[40] = {};
  std::atomic<int> subscriptions{0};

 private:
  void serveLaser(agv::test::LoopbackServer& s) {
    const auto subscribe = agv::test::stxEtx("sEN LMDscandata 1");
    const int fd = s.accept(10000);
    if (fd < 0)
      return;
    if (s.read(fd, subscribe.size()) == subscribe)
      ++subscriptions;
    for (std::uint32_t i = 1; i < 1000 && !stopLaser_.load(); ++i) {
      const auto t = agv::test::colaScanTelegram(i, 4000, 541, false);
      if (::send(fd, t.data(), t.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(t.size()))
        break;  // the vehicle went away
      std::this_thread::sleep_for(std::chrono::milliseconds(40));
    }
    ::close(fd);
  }

  std::string logPath_;
  pid_t pid_ = -1;
  bool ready_ = false;
  bool exited_ = false;
  std::uint16_t sequence_ = 0;
  std::atomic<bool> stopLaser_{false};
};

}  // namespace

TEST_CASE("agvnav-vehicle runs without its CAN interface, reports the encoder fault and stops on SIGTERM",
          "[vehicle][modbus][laser]") {
  RunningVehicle v;
  REQUIRE(v.ready());
  CHECK_FALSE(v.hasBit(PlcHealthBit::EncodersOk));
  CHECK(v.hasBit(PlcHealthBit::MapLoaded));
  CHECK(v.hasBit(PlcHealthBit::CalibrationValid));
  CHECK_FALSE(v.hasBit(PlcHealthBit::LaserTimeout));
  CHECK_FALSE(v.hasBit(PlcHealthBit::CommandRejected));
  CHECK(v.regs[3] == static_cast<std::uint16_t>(agv::Status::DeviceFault));  // last status code
  CHECK(v.regs[1] == 3U);  // lost: localizing from the configured initial pose, but without encoders
  // Calibration published from the file: wheelbase 1.5 m (registers 38-39, ABCD).
  CHECK(modbus_get_float_abcd(v.regs + 38) == Approx(1.5f));
  CHECK(modbus_get_float_abcd(v.regs + 26) == Approx(0.0005f));

  // Still running: the heartbeat counter moves.
  const std::uint16_t beat = v.regs[0];
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  REQUIRE(v.poll());
  CHECK(v.regs[0] != beat);

  // SIGTERM: exit 0 within 1 s, links closed.
  CHECK(v.terminate() == 0);
  const std::string log = v.log();
  INFO(log);
  CHECK(v.subscriptions.load() == 1);
  CHECK(log.find("agvcan7") != std::string::npos);  // the missing interface is named
  CHECK(log.find("stopped after") != std::string::npos);
}

TEST_CASE("agvnav-vehicle carries out the PLC's Stop and Localize and refuses Calibrate visibly",
          "[vehicle][modbus][laser]") {
  RunningVehicle v;
  REQUIRE(v.ready());
  using agv::hal::PlcCommandKind;
  const auto mode = [&v]() { return v.regs[1]; };
  REQUIRE(mode() == 3U);  // lost (no encoders), localizing from the configured initial pose

  // Stop: idle.
  REQUIRE(v.command(PlcCommandKind::Stop));
  CHECK(v.waitFor([&]() { return mode() == 0U; }));
  CHECK_FALSE(v.hasBit(PlcHealthBit::CommandRejected));

  // Calibrate: refused, bit 8 set, the mode stays idle, and the log says why.
  REQUIRE(v.command(PlcCommandKind::Calibrate));
  CHECK(v.waitFor([&]() { return v.hasBit(PlcHealthBit::CommandRejected); }));
  CHECK(mode() == 0U);
  CHECK(v.regs[3] == static_cast<std::uint16_t>(agv::Status::DeviceFault));  // the encoder fault comes first
  // Still set a few publications later: it lasts until the next command.
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  REQUIRE(v.poll());
  CHECK(v.hasBit(PlcHealthBit::CommandRejected));

  // Localize from a set-pose: carried out, bit 8 cleared, the published pose is the set-pose
  // (no odometry and no landmark in view move it).
  REQUIRE(v.command(PlcCommandKind::Localize, 3.25F, -1.5F, 0.75F));
  CHECK(v.waitFor([&]() { return mode() == 3U && !v.hasBit(PlcHealthBit::CommandRejected); }));
  CHECK(modbus_get_float_abcd(v.regs + 4) == Approx(3.25F).margin(1e-6));
  CHECK(modbus_get_float_abcd(v.regs + 6) == Approx(-1.5F).margin(1e-6));
  CHECK(modbus_get_float_abcd(v.regs + 8) == Approx(0.75F).margin(1e-6));

  // Calibrate while localizing: refused, localization goes on from the same pose.
  REQUIRE(v.command(PlcCommandKind::Calibrate));
  CHECK(v.waitFor([&]() { return v.hasBit(PlcHealthBit::CommandRejected); }));
  CHECK(mode() == 3U);
  CHECK(modbus_get_float_abcd(v.regs + 4) == Approx(3.25F).margin(1e-6));

  CHECK(v.terminate() == 0);
  const std::string log = v.log();
  INFO(log);
  CHECK(log.find("PLC command 2 (calibrate) refused") != std::string::npos);
  CHECK(log.find("4 PLC commands, 2 refused") != std::string::npos);
}

TEST_CASE("agvnav-vehicle refuses a bad configuration with exit 2, naming file, line and key", "[vehicle]") {
  agv::test::TempFolder dir;
  REQUIRE(dir.ok());
  dir.write("calibration.txt", agv::test::goodCalibration());
  dir.write("landmarks.txt", agv::test::goodMap());
  std::string text = agv::test::goodVehicleConfig();
  text.replace(text.find("can.drive.node = 1"), std::strlen("can.drive.node = 1"), "can.drive.node = 300");
  const std::string conf = dir.write("bad.conf", text);
  std::string log;
  CHECK(runVehicle({"--config", conf}, dir, log) == 2);
  CHECK(log.find(conf + ":3: can.drive.node: ") != std::string::npos);

  CHECK(runVehicle({"--config", dir.path() + "/absent.conf"}, dir, log) == 2);
  CHECK(log.find("absent.conf") != std::string::npos);

  dir.write("landmarks.txt", "agvnav-landmarks 1\nreflector 1 5.0\n");
  const std::string good = dir.write("good.conf", agv::test::goodVehicleConfig());
  CHECK(runVehicle({"--config", good}, dir, log) == 2);
  CHECK(log.find("landmarks.txt:2: map.file: ") != std::string::npos);

  dir.write("landmarks.txt", agv::test::goodMap());
  CHECK(runVehicle({"--config", good, "--check"}, dir, log) == 0);
  CHECK(log.find("configuration ok (3 landmarks)") != std::string::npos);

  CHECK(runVehicle({"--no-such-option"}, dir, log) == 2);
}
