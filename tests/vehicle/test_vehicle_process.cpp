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
#include "agv/drivers/plc/plc_register_map.hpp"
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

}  // namespace

TEST_CASE("agvnav-vehicle runs without its CAN interface, reports the encoder fault and stops on SIGTERM",
          "[vehicle][modbus][laser]") {
  agv::test::TempFolder dir;
  REQUIRE(dir.ok());
  // The laser: a CoLa A server streaming a scan every 40 ms once subscribed, until the vehicle goes.
  agv::test::LoopbackServer laser;
  REQUIRE(laser.ok());
  const auto subscribe = agv::test::stxEtx("sEN LMDscandata 1");
  std::atomic<int> subscriptions{0};
  std::atomic<bool> stopLaser{false};
  laser.start([&](agv::test::LoopbackServer& s) {
    const int fd = s.accept(10000);
    if (fd < 0)
      return;
    if (s.read(fd, subscribe.size()) == subscribe)
      ++subscriptions;
    for (std::uint32_t i = 1; i < 1000 && !stopLaser.load(); ++i) {
      const auto t = agv::test::colaScanTelegram(i, 4000, 541, false);
      if (::send(fd, t.data(), t.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(t.size()))
        break;  // the vehicle went away
      std::this_thread::sleep_for(std::chrono::milliseconds(40));
    }
    ::close(fd);
  });

  const std::uint16_t modbusPort = agv::test::closedPort();
  const std::string conf =
      dir.write("vehicle.conf", agv::test::goodVehicleConfig("agvcan7", "127.0.0.1", laser.port(), modbusPort));
  dir.write("calibration.txt", agv::test::goodCalibration());
  dir.write("landmarks.txt", agv::test::goodMap());
  const std::string logPath = dir.track("vehicle.log");
  const pid_t pid = startVehicle({"--config", conf}, logPath);
  REQUIRE(pid > 0);

  // The PLC: a libmodbus client polling the status block.
  modbus_t* plc = modbus_new_tcp("127.0.0.1", modbusPort);
  REQUIRE(plc != nullptr);
  bool connected = false;
  for (int i = 0; i < 100 && !connected; ++i) {
    connected = modbus_connect(plc) == 0;
    if (!connected)
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  REQUIRE(connected);
  std::uint16_t regs[40] = {};
  bool faultSeen = false;
  bool laserOkSeen = false;
  for (int i = 0; i < 100 && !(faultSeen && laserOkSeen); ++i) {
    if (modbus_read_registers(plc, 0, 40, regs) == 40) {
      faultSeen = (regs[2] & static_cast<std::uint16_t>(PlcHealthBit::DeviceFault)) != 0U;
      laserOkSeen = (regs[2] & static_cast<std::uint16_t>(PlcHealthBit::LaserOk)) != 0U;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  CHECK(faultSeen);
  CHECK(laserOkSeen);
  const std::uint16_t health = regs[2];
  CHECK((health & static_cast<std::uint16_t>(PlcHealthBit::EncodersOk)) == 0U);
  CHECK((health & static_cast<std::uint16_t>(PlcHealthBit::MapLoaded)) != 0U);
  CHECK((health & static_cast<std::uint16_t>(PlcHealthBit::CalibrationValid)) != 0U);
  CHECK((health & static_cast<std::uint16_t>(PlcHealthBit::LaserTimeout)) == 0U);
  CHECK(regs[3] == static_cast<std::uint16_t>(agv::Status::DeviceFault));  // last status code
  CHECK(regs[1] == 3U);  // lost: localizing from the configured initial pose, but without encoders
  // Calibration published from the file: wheelbase 1.5 m (registers 38-39, ABCD).
  CHECK(modbus_get_float_abcd(regs + 38) == Approx(1.5f));
  CHECK(modbus_get_float_abcd(regs + 26) == Approx(0.0005f));

  // Still running: the heartbeat counter moves.
  const std::uint16_t beat = regs[0];
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  REQUIRE(modbus_read_registers(plc, 0, 4, regs) == 4);
  CHECK(regs[0] != beat);
  modbus_close(plc);
  modbus_free(plc);

  // SIGTERM: exit 0 within 1 s, links closed.
  REQUIRE(::kill(pid, SIGTERM) == 0);
  bool exited = false;
  const int rc = waitExit(pid, 1000, exited);
  if (!exited) {
    ::kill(pid, SIGKILL);
    ::waitpid(pid, nullptr, 0);
  }
  CHECK(exited);
  CHECK(rc == 0);
  stopLaser = true;
  laser.join();
  CHECK(subscriptions.load() == 1);
  const std::string log = readFile(logPath);
  INFO(log);
  CHECK(log.find("agvcan7") != std::string::npos);  // the missing interface is named
  CHECK(log.find("stopped after") != std::string::npos);
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
