// agvnav-sim-drives without sockets: the injection syntax, and `SimDrives` (the two nodes as the
// program runs them, each hearing the other) brought up by the drive controller in-process, with a
// scheduled fault that the controller must see as a drive fault with its code.
#include <cstdio>
#include <string>

#include "agv/drivers/protocol/canopen/cia402_drive.hpp"
#include "agv_test.hpp"
#include "sim_drives.hpp"

using namespace agv;
using namespace agv::drivers;
using namespace agv::drivers::canopen;
using agv::simdrives::Injection;
using agv::simdrives::parseInjection;
using agv::simdrives::SimDrives;
using agv::simdrives::SimDrivesOptions;

TEST_CASE("injections parse as NODE:CODE@SECONDS and NODE@SECONDS", "[drives]") {
  Injection in;
  std::string error;
  REQUIRE(parseInjection("1:2310@2.5", Injection::Kind::Fault, in, error));
  CHECK(in.nodeId == 1);
  CHECK(in.errorCode == 0x2310);
  CHECK(in.atSeconds == 2.5);
  REQUIRE(parseInjection("2:0x7305@0", Injection::Kind::Fault, in, error));
  CHECK(in.errorCode == 0x7305);
  REQUIRE(parseInjection("127@10", Injection::Kind::Silence, in, error));
  CHECK(in.nodeId == 127);
  CHECK(in.kind == Injection::Kind::Silence);
  CHECK_FALSE(parseInjection("1@2", Injection::Kind::Fault, in, error));  // no code
  CHECK(error.find("NODE:CODE@SECONDS") != std::string::npos);
  CHECK_FALSE(parseInjection("1:0@2", Injection::Kind::Fault, in, error));  // code 0 is "no error"
  CHECK_FALSE(parseInjection("1:10000@2", Injection::Kind::Fault, in, error));
  CHECK_FALSE(parseInjection("0@2", Injection::Kind::Silence, in, error));
  CHECK_FALSE(parseInjection("128@2", Injection::Kind::Silence, in, error));
  CHECK_FALSE(parseInjection("1@-1", Injection::Kind::Silence, in, error));
  CHECK_FALSE(parseInjection("1@x", Injection::Kind::Silence, in, error));
  CHECK_FALSE(parseInjection("1", Injection::Kind::Silence, in, error));
}

TEST_CASE("the program's two nodes are brought up by the controller; a scheduled fault stops traction", "[drives]") {
  SimDrivesOptions options;
  Injection fault;
  std::string error;
  REQUIRE(parseInjection("3:7305@1.5", Injection::Kind::Fault, fault, error));
  options.injections.push_back(fault);
  std::FILE* log = std::tmpfile();
  REQUIRE(log != nullptr);
  SimDrives drives(options, log);
  Cia402DriveController ctl{Cia402DriveConfig{}};
  Timestamp now = Timestamp::fromSeconds(5.0);
  REQUIRE(ctl.start(now) == Status::Ok);
  CanFrame buf[SimDrives::kMaxFrames];
  bool enabled = false;
  for (int i = 0; i < 300; ++i) {  // 3 s in 10 ms cycles
    now = now + Duration::fromMilliseconds(10);
    const std::size_t n = drives.step(now, Span<CanFrame>(buf));
    for (std::size_t k = 0; k < n; ++k) {
      ctl.onFrame(buf[k]);
    }
    if (ctl.state() == DriveControllerState::Enabled) {
      enabled = true;
      hal::DriveCommand c;
      c.speed = 0.3;
      REQUIRE(ctl.command(c) == Status::Ok);
    }
    ctl.poll(now);
    const std::size_t m = ctl.takeFrames(Span<CanFrame>(buf));
    for (std::size_t k = 0; k < m; ++k) {
      drives.receive(buf[k], now);
    }
  }
  CHECK(enabled);
  CHECK(ctl.state() == DriveControllerState::SafeStop);
  CHECK(ctl.safeStopReason() == SafeStopReason::DriveFault);
  CHECK(ctl.steering().errorCode() == 0x7305);
  CHECK(drives.steering().state() == PowerState::Fault);
  CHECK(drives.traction().state() == PowerState::SwitchOnDisabled);  // quick-stopped, then disabled
  // The log names the states and the injection.
  std::rewind(log);
  std::string text;
  char line[256];
  while (std::fgets(line, sizeof line, log) != nullptr) {
    text += line;
  }
  std::fclose(log);
  CHECK(text.find("node 1: Operation enabled (mode 3") != std::string::npos);
  CHECK(text.find("node 3: Operation enabled (mode 1") != std::string::npos);
  CHECK(text.find("node 3: injected fault 0x7305") != std::string::npos);
  CHECK(text.find("node 1: Quick stop active") != std::string::npos);
  CHECK(text.find("node 3: Fault") != std::string::npos);
}
