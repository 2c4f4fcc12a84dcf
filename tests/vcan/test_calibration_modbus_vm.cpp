// agvnav-vehicle's whole calibration routine on the real Linux CAN stack, in the vcan VM
// (docs/vcan-testing.md), started by the PLC over Modbus TCP: the vehicle's PLC link is the
// program's Modbus server (`drivers::ModbusPlcLink`, libmodbus) on the VM's loopback, and a
// libmodbus client thread plays the PLC: it writes Localize and then Calibrate into the command
// block and reads the status block (registers 0-48) every 50 ms, moving its heartbeat register.
// The bench (calibration_vm_bench.hpp) is the one of the scripted cases. A second case runs the
// same routine with both sides as programs: `agvnav-vehicle` (its configuration pointing at vcan0
// and the NAV350 port) against `agvnav-sim-drives --vehicle` (drives, encoders, simulated tricycle
// and NAV350), the PLC the same libmodbus client. This binary is linked
// dynamically (Debian ships libmodbus as a shared library only): run-vcan-vm.sh copies it with
// its shared libraries into the VM (`--companion`) and runs it after the static test program.
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>
#include <thread>

#include "agv/drivers/linux/loopback_server.hpp"
#include "agv/drivers/linux/modbus_plc_link.hpp"
#include "calibration_vm_bench.hpp"
#include "plc_modbus_client.hpp"
#include "sim_drive_side.hpp"
#include "vcan_programs.hpp"

using agv::Duration;
using agv::Status;
using agv::Timestamp;
using agv::drivers::monotonicNow;
using agv::drivers::plc::unpackFloat;
using agv::drivers::plc::WordOrder;
using agv::test::vmcal::kStart;
using agv::test::vmcal::VmCalibrationBench;
namespace cal = agv::calibration;
namespace hal = agv::hal;

namespace {

/// What the PLC (the libmodbus client) did and read. Written by its thread, read after `done`.
struct PlcClientRecord {
  std::atomic<bool> done{false};
  std::string failure;       ///< the first thing that went wrong (empty: none)
  bool localized = false;    ///< the set-pose showed in the status block after the Localize
  bool calibrating = false;  ///< register 1 showed calibrating after the Calibrate
  bool stateSeen[16] = {};   ///< values of register 44 read
  int reads = 0;             ///< status blocks read
  std::uint16_t last[49] = {};
};

/// The PLC: Localize at the start pose, then Calibrate, then polls until register 44 shows done
/// (7) or aborted (8), or `limit` passed.
void runPlc(std::uint16_t port, Duration limit, PlcClientRecord& r) {
  modbus_t* plc = modbus_new_tcp("127.0.0.1", port);
  if (plc == nullptr) {
    r.failure = "modbus_new_tcp failed";
    r.done = true;
    return;
  }
  modbus_set_response_timeout(plc, 1, 0);
  bool connected = false;
  for (int i = 0; i < 50 && !connected; ++i) {
    connected = modbus_connect(plc) == 0;
    if (!connected) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  std::uint16_t heartbeat = 0;
  const auto poll = [&]() {
    if (modbus_read_registers(plc, 0, 49, r.last) != 49) {
      return false;
    }
    ++r.reads;
    r.stateSeen[r.last[44] & 15U] = true;
    static_cast<void>(modbus_write_register(plc, 108, ++heartbeat));  // the PLC is alive
    return true;
  };
  const Timestamp end = monotonicNow() + limit;
  if (!connected) {
    r.failure = std::string("cannot connect: ") + modbus_strerror(errno);
  } else if (!agv::test::writePlcCommand(plc, 1, hal::PlcCommandKind::Localize, static_cast<float>(kStart.x),
                                         static_cast<float>(kStart.y), static_cast<float>(kStart.theta))) {
    r.failure = std::string("Localize not written: ") + modbus_strerror(errno);
  } else {
    const Timestamp localizeBy = monotonicNow() + Duration::fromSeconds(5.0);
    while (!r.localized && monotonicNow() < localizeBy) {
      // The set-pose taken: published (registers 4-7), the mode no longer idle. (Localizing, or
      // Lost: the drive encoder is the traction node's TPDO1, which only the drive controller's
      // bring-up at Calibrate maps with the position and gives a heartbeat; until then the
      // encoder source times out.)
      r.localized = poll() && r.last[1] != static_cast<std::uint16_t>(hal::NavMode::Idle) &&
                    std::fabs(unpackFloat(&r.last[4], WordOrder::ABCD) - kStart.x) < 0.05 &&
                    std::fabs(unpackFloat(&r.last[6], WordOrder::ABCD) - kStart.y) < 0.05;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    std::printf("PLC: after Localize, mode %u, health bits 0x%04X\n", static_cast<unsigned>(r.last[1]),
                static_cast<unsigned>(r.last[2]));
    if (!r.localized) {
      r.failure = "the set-pose never showed in registers 1 and 4-7 (mode " + std::to_string(r.last[1]) + ")";
    } else if (!agv::test::writePlcCommand(plc, 2, hal::PlcCommandKind::Calibrate)) {
      r.failure = std::string("Calibrate not written: ") + modbus_strerror(errno);
    } else {
      while (monotonicNow() < end) {
        if (poll()) {
          r.calibrating = r.calibrating || r.last[1] == static_cast<std::uint16_t>(hal::NavMode::Calibrating);
          if (r.last[44] == static_cast<std::uint16_t>(cal::RoutineState::Done) ||
              r.last[44] == static_cast<std::uint16_t>(cal::RoutineState::Aborted)) {
            break;
          }
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
      }
    }
  }
  modbus_close(plc);
  modbus_free(plc);
  r.done = true;
}

}  // namespace

TEST_CASE("calibration routine on vcan, started by a libmodbus client: CiA 402 drives, all phases, a file",
          "[calibration][modbus]") {
  agv::drivers::ModbusPlcLinkConfig mc;
  std::strcpy(mc.address, "127.0.0.1");
  mc.port = 0;  // a free port
  agv::drivers::ModbusPlcLink link(mc);
  REQUIRE(link.open() == Status::Ok);
  VmCalibrationBench b("/tmp/agv_vm_calibration.txt", cal::FreeArea{}, &link);
  b.runCycles(100);  // the encoder decoder's first samples
  PlcClientRecord plc;
  std::thread client([&] { runPlc(link.boundPort(), Duration::fromSeconds(110.0), plc); });
  const Timestamp t0 = monotonicNow();
  int lastSegment = -1;
  int lastState = -1;
  while (!plc.done) {
    b.cycle();
    const cal::SessionProgress& pr = b.routine->progress();
    if (static_cast<int>(pr.state) != lastState || pr.segment != lastSegment) {
      lastState = static_cast<int>(pr.state);
      lastSegment = pr.segment;
      std::printf("%.2f s: %s, segment %u of %u\n", (monotonicNow() - t0).seconds(), cal::routineStateName(pr.state),
                  pr.segment, pr.total);
    }
  }
  client.join();
  INFO(plc.failure);
  INFO(b.routine->session()->lastMessage());
  std::printf("routine %s after %.1f s; PLC: %d status reads, %u commands; %s\n",
              cal::routineStateName(b.routine->progress().state), (monotonicNow() - t0).seconds(), plc.reads,
              link.counters().commands, b.routine->session()->lastMessage().c_str());
  REQUIRE(plc.failure.empty());
  // The commands came through the vehicle's Modbus server; the PLC read the progress.
  CHECK(link.counters().commands == 2U);
  CHECK(link.counters().rejectedWrites == 0U);
  CHECK(plc.localized);
  CHECK(plc.calibrating);
  for (cal::RoutineState s : {cal::RoutineState::Settling, cal::RoutineState::Steering, cal::RoutineState::Driving,
                              cal::RoutineState::Stopping, cal::RoutineState::Observing, cal::RoutineState::Done}) {
    CHECK(plc.stateSeen[static_cast<int>(s)]);
  }
  CHECK(plc.last[44] == static_cast<std::uint16_t>(cal::RoutineState::Done));
  CHECK(plc.last[47] == 8U);
  CHECK(plc.last[48] == 0U);
  CHECK(b.routine->progress().state == cal::RoutineState::Done);
  REQUIRE(b.wrote);
  b.checkWrittenCalibration();
}

namespace {

/// The configuration of `agvnav-vehicle` for the case below: the drives and encoders of
/// `agvnav-sim-drives --vehicle` on `canIf` (traction node 1 is the drive encoder at {0x181, 2, 4},
/// steering encoder node 2: 4 bytes, 2 pi / 16384 rad per count), its NAV350 on 127.0.0.1:
/// `laserPort`, the Modbus server on `modbusPort`, and the plan of the bench (8 segments of 90 deg
/// at 40..50 deg, 0.8 m/s) in the open floor of the built-in warehouse.
std::string programConfig(const std::string& canIf, std::uint16_t laserPort, std::uint16_t modbusPort,
                          const std::string& dir) {
  char radPerCount[32];
  std::snprintf(radPerCount, sizeof radPerCount, "%.17g", agv::simdrives::kSteerEncoderRadPerCount);
  return "can.interface = " + canIf +
         "\n"
         "can.drive.node = 1\n"
         "can.steering.node = 2\n"
         "can.steering.pdo_offset = 0\n"
         "can.steering.pdo_size = 4\n"
         "can.steering.rad_per_count = " +
         radPerCount +
         "\n"
         "can.heartbeat_timeout = 0.5\n"
         "can.trigger = drive\n"
         "laser.model = nav350\n"
         "laser.address = 127.0.0.1\n"
         "laser.port = " +
         std::to_string(laserPort) +
         "\n"
         "laser.scan_timeout = 1.0\n"
         "modbus.role = server\n"
         "modbus.address = 127.0.0.1\n"
         "modbus.port = " +
         std::to_string(modbusPort) +
         "\n"
         "calibration.file = " +
         dir +
         "/calibration.txt\n"
         "map.file = " +
         dir +
         "/landmarks.txt\n"
         "map.mode = static\n"
         "localization.relocalize = false\n"
         "drives.enabled = true\n"
         "calibration.area = 2.5 0.5 24.0 23.0\n"
         "calibration.segments = 2\n"
         "calibration.min_steering = 0.6981317\n"
         "calibration.max_steering = 0.8726646\n"
         "calibration.rotation = 1.5707963\n"
         "calibration.speed = 0.8\n";
}

}  // namespace

TEST_CASE("the agvnav-vehicle program calibrates against agvnav-sim-drives --vehicle, started by a libmodbus client",
          "[calibration][modbus][program]") {
  const std::string dir = "/tmp/agv-vm-program";
  static_cast<void>(std::system(("mkdir -p " + dir).c_str()));
  const std::string file = dir + "/calibration.txt";
  // The calibration the vehicle starts with: nominal values (the truth is 0.85 % off in s_w,
  // 0.55 / 0.35 deg in the offsets, the laser 20 mm, 25 mm and 0.7 deg off).
  const std::string old =
      "agvnav-calibration 2\nwheelbase 1.5\ndrive_scale 0.0001 0.00000003\nsteer_offset_forward 0.0\n"
      "steer_offset_backward 0.0\nlaser_x 1.6\nlaser_y 0.0\nlaser_theta 0.0\nend 7\n";
  {
    std::ofstream(file, std::ios::trunc) << old;
    std::remove((file + ".bak").c_str());
    agv::sim::World world;
    agv::sim::WorldParseError perr;
    REQUIRE(agv::sim::parseWorld(agv::sim::defaultWorldText(), world, perr) == Status::Ok);
    std::ofstream map(dir + "/landmarks.txt", std::ios::trunc);
    map << "agvnav-landmarks 2\n";
    int n = 0;
    for (const agv::sim::Circle& c : world.circles) {
      if (c.kind == agv::sim::ObstacleKind::Reflector) {
        map << "reflector " << ++n << ' ' << c.centre.x << ' ' << c.centre.y << " 0.005\n";
      }
    }
    map << "end " << n << "\n";
  }
  const std::string canIf = agv::test::vcanInterface();
  const std::uint16_t laserPort = agv::drivers::closedPort();
  const std::uint16_t modbusPort = agv::drivers::closedPort();
  const std::string conf = dir + "/vehicle.conf";
  std::ofstream(conf, std::ios::trunc) << programConfig(canIf, laserPort, modbusPort, dir);

  const Timestamp t0 = monotonicNow();
  agv::test::Child drives(
      agv::test::programPath("agvnav-sim-drives"),
      {"--interface", canIf, "--vehicle", "--laser-port", std::to_string(laserPort), "--start", "10,12.5,0"});
  REQUIRE(drives.started());
  const auto pollBoth = [&](agv::test::Child* vehicle, Duration d) {
    const Timestamp end = monotonicNow() + d;
    do {
      drives.poll();
      if (vehicle != nullptr) {
        vehicle->poll();
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    } while (monotonicNow() < end);
  };
  for (int i = 0; i < 100 && !drives.said("NAV350 on"); ++i) {
    pollBoth(nullptr, Duration::fromMilliseconds(50));
  }
  REQUIRE(drives.said("NAV350 on"));
  agv::test::Child vehicle(agv::test::programPath("agvnav-vehicle"), {"--config", conf}, true);
  REQUIRE(vehicle.started());
  PlcClientRecord plc;
  std::thread client([&] { runPlc(modbusPort, Duration::fromSeconds(120.0), plc); });
  while (!plc.done) {
    pollBoth(&vehicle, Duration::fromMilliseconds(100));
  }
  client.join();
  const double seconds = (monotonicNow() - t0).seconds();
  vehicle.signal(SIGTERM);
  drives.signal(SIGTERM);
  for (int i = 0; i < 100 && (vehicle.running() || drives.running()); ++i) {
    pollBoth(&vehicle, Duration::fromMilliseconds(20));
  }
  INFO(plc.failure);
  std::printf("program routine: register 44 = %u after %.1f s from the start of the programs; PLC: %d status reads\n",
              static_cast<unsigned>(plc.last[44]), seconds, plc.reads);
  REQUIRE(plc.failure.empty());
  CHECK(plc.localized);
  CHECK(plc.calibrating);
  for (cal::RoutineState s : {cal::RoutineState::Settling, cal::RoutineState::Steering, cal::RoutineState::Driving,
                              cal::RoutineState::Stopping, cal::RoutineState::Observing, cal::RoutineState::Done}) {
    CHECK(plc.stateSeen[static_cast<int>(s)]);
  }
  CHECK(plc.last[44] == static_cast<std::uint16_t>(cal::RoutineState::Done));
  CHECK(plc.last[47] == 8U);
  CHECK(plc.last[48] == 0U);
  CHECK_FALSE(vehicle.running());
  CHECK(vehicle.exitCode() == 0);
  CHECK_FALSE(drives.running());
  CHECK(drives.exitCode() == 0);
  agv::test::vmcal::checkCalibrationFile(file, agv::sim::SimVehicleParams{}, "program routine", old);
}
