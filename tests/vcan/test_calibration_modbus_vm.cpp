// agvnav-vehicle's whole calibration routine on the real Linux CAN stack, in the vcan VM
// (docs/vcan-testing.md), started by the PLC over Modbus TCP: the vehicle's PLC link is the
// program's Modbus server (`drivers::ModbusPlcLink`, libmodbus) on the VM's loopback, and a
// libmodbus client thread plays the PLC: it writes Localize and then Calibrate into the command
// block and reads the status block (registers 0-48) every 50 ms, moving its heartbeat register.
// The bench (calibration_vm_bench.hpp) is the one of the scripted cases. This binary is linked
// dynamically (Debian ships libmodbus as a shared library only): run-vcan-vm.sh copies it with
// its shared libraries into the VM (`--companion`) and runs it after the static test program.
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <thread>

#include "agv/drivers/linux/modbus_plc_link.hpp"
#include "calibration_vm_bench.hpp"
#include "plc_modbus_client.hpp"

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
