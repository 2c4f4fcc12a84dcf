// agvnav-vehicle's calibration routine on the real Linux CAN stack, in the vcan VM
// (docs/vcan-testing.md), with both sides as programs: `agvnav-vehicle` (its configuration pointing
// at vcan0 and the NAV350 port, its Modbus server on the VM's loopback) against
// `agvnav-sim-drives --vehicle` (the two CiA 402 drives, the encoders, the simulated tricycle and
// its NAV350), started by a libmodbus client playing the PLC: it writes Localize and then Calibrate
// into the command block and reads the status block (registers 0-49) every 50 ms, moving its
// heartbeat register. A monitor socket on vcan0 records every frame with its kernel stamp. Cases:
// the whole routine (all phases, a calibration file within the tolerance of the simulator's
// truth); a plan that does not fit the free area (refused before any frame to the drives); a PLC
// Stop mid-segment (the traction quick stop within one control cycle of the Stop); the traction
// node's heartbeat lost and the traction drive's fault, injected by agvnav-sim-drives into the
// first segment (`--silence 1@T`, `--fault 1:2310@T`): each aborted with the reason and the fault
// code on the registers and the calibration file byte for byte as before. Nothing of the vehicle
// runs in the test process. This binary is linked dynamically (Debian ships libmodbus as a shared
// library only): run-vcan-vm.sh copies it with its shared libraries into the VM (`--companion`)
// and runs it after the static test program.
#include <sys/resource.h>
#include <sys/stat.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "agv/calibration/calibration_routine.hpp"
#include "agv/drivers/linux/loopback_server.hpp"
#include "agv/drivers/linux/monotonic_clock.hpp"
#include "agv/drivers/linux/socketcan_bus.hpp"
#include "agv/drivers/protocol/canopen/cia402.hpp"
#include "agv/sim/world.hpp"
#include "calibration_check.hpp"
#include "cia402_frames.hpp"
#include "plc_modbus_client.hpp"
#include "sim_drive_side.hpp"
#include "vcan_peer.hpp"
#include "vcan_programs.hpp"

using agv::Duration;
using agv::Pose2d;
using agv::Status;
using agv::Timestamp;
using agv::drivers::CanFrame;
using agv::drivers::monotonicNow;
using agv::drivers::canopen::decodeStatusword;
using agv::drivers::canopen::PowerState;
using agv::drivers::plc::unpackFloat;
using agv::drivers::plc::WordOrder;
using agv::test::i32;
using agv::test::isQuickStop;
using agv::test::kTractionRpdo;
using agv::test::u16;
namespace cal = agv::calibration;
namespace hal = agv::hal;

namespace {

const Pose2d kStart{10.0, 12.5, 0.0};

// The CAN identifiers of the vehicle's bus (docs/drives.md): nodes 1 (traction) and 3 (steering),
// the steering encoder node 2, the drive controller's heartbeat 0x77F.
constexpr std::uint32_t kNmt = 0x000;
constexpr std::uint32_t kTractionEmcy = 0x081;
constexpr std::uint32_t kTractionTpdo1 = 0x181;
constexpr std::uint32_t kSteeringRpdo = 0x203;
constexpr std::uint32_t kTractionTpdo2 = 0x281;
constexpr std::uint32_t kTractionSdo = 0x601;
constexpr std::uint32_t kSteeringSdo = 0x603;
constexpr std::uint32_t kTractionHeartbeat = 0x701;
constexpr std::uint32_t kEncoderHeartbeat = 0x702;
constexpr std::uint32_t kControllerHeartbeat = 0x77F;
/// The traction drive's velocity unit: 10000 per m/s (the controller's default, docs/drives.md).
constexpr double kVelocityUnitsPerMps = 10000.0;

/// A frame of the drive controller: NMT other than the encoder source's Start of nodes 1 and 2,
/// RPDOs, SDO requests, its heartbeat.
bool fromDriveController(const CanFrame& f) {
  if (f.id == kNmt) {
    return !(f.dlc == 2 && f.data[0] == 0x01 && (f.data[1] == 1 || f.data[1] == 2));
  }
  return f.id == kTractionRpdo || f.id == kSteeringRpdo || f.id == kTractionSdo || f.id == kSteeringSdo ||
         f.id == kControllerHeartbeat;
}
double ms(Duration d) {
  return 1e3 * d.seconds();
}
std::uint16_t statusCode(Status s) {
  return static_cast<std::uint16_t>(s);
}
std::uint16_t stateCode(cal::RoutineState s) {
  return static_cast<std::uint16_t>(s);
}

/// One status block the PLC read: its time and registers 0-49.
struct PlcRead {
  Timestamp t;
  std::uint16_t r[50] = {};
};

/// What the PLC (the libmodbus client) is to do after its Localize.
struct PlcScript {
  /// Calibrate not before this time (Localize shortly before it: until the drive controller's
  /// bring-up maps the traction node's TPDO1, the drive encoder is silent and the navigation goes
  /// Lost after `can.heartbeat_timeout`). Zero: at once.
  Timestamp calibrateAt{};
  /// Stop once segment 1 has been read as driving for this long (zero: no Stop).
  Duration stopAfterDriving{};
  /// The run ends when register 44 reads done or aborted, or register 48 non-zero (a refusal); then
  /// the PLC reads on for `afterEnd`.
  Duration afterEnd = Duration::fromSeconds(0.5);
  Duration limit = Duration::fromSeconds(30.0);
};

/// What the PLC did and read. Written by its thread, read after `done`.
struct PlcClientRecord {
  std::atomic<bool> done{false};
  std::string failure;         ///< the first thing that went wrong (empty: none)
  bool localized = false;      ///< the set-pose showed in the status block after the Localize
  bool calibrating = false;    ///< register 1 showed calibrating after the Calibrate
  bool stateSeen[16] = {};     ///< values of register 44 read
  std::vector<PlcRead> reads;  ///< every status block read
  Timestamp localizeSent{};
  Timestamp calibrateSent{};
  Timestamp stopSent{};   ///< just before the Stop request was written (zero: none)
  Timestamp stopAcked{};  ///< its reply received
  Timestamp ended{};      ///< the first read of the end (done, aborted, or the refusal)
  const PlcRead& last() const {
    static const PlcRead none{};
    return reads.empty() ? none : reads.back();
  }
  /// The last block read before `t` (null: none).
  const PlcRead* lastBefore(Timestamp t) const {
    const PlcRead* r = nullptr;
    for (const PlcRead& x : reads) {
      if (x.t < t) {
        r = &x;
      }
    }
    return r;
  }
};

/// The PLC: Localize at the start pose, then Calibrate, then as `script` says.
void plcThread(std::uint16_t port, const PlcScript& script, PlcClientRecord& r) {
  modbus_t* plc = modbus_new_tcp("127.0.0.1", port);
  if (plc == nullptr) {
    r.failure = "modbus_new_tcp failed";
    r.done = true;
    return;
  }
  modbus_set_response_timeout(plc, 1, 0);
  bool connected = false;
  for (int i = 0; i < 100 && !connected; ++i) {
    connected = modbus_connect(plc) == 0;
    if (!connected) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  std::uint16_t heartbeat = 0;
  const auto poll = [&]() {
    PlcRead x;
    if (modbus_read_registers(plc, 0, 50, x.r) != 50) {
      return false;
    }
    x.t = monotonicNow();
    r.reads.push_back(x);
    r.stateSeen[x.r[44] & 15U] = true;
    static_cast<void>(modbus_write_register(plc, 108, ++heartbeat));  // the PLC is alive
    return true;
  };
  const auto nap = [] { std::this_thread::sleep_for(std::chrono::milliseconds(50)); };
  if (!connected) {
    r.failure = std::string("cannot connect: ") + modbus_strerror(errno);
    modbus_free(plc);
    r.done = true;
    return;
  }
  // Read until the Localize is due (the vehicle's registers move), then Localize.
  const Duration localizeAhead = Duration::fromSeconds(0.5);
  while (script.calibrateAt.ns != 0 && monotonicNow() < script.calibrateAt - localizeAhead) {
    static_cast<void>(poll());
    nap();
  }
  r.localizeSent = monotonicNow();
  if (!agv::test::writePlcCommand(plc, 1, hal::PlcCommandKind::Localize, static_cast<float>(kStart.x),
                                  static_cast<float>(kStart.y), static_cast<float>(kStart.theta))) {
    r.failure = std::string("Localize not written: ") + modbus_strerror(errno);
  } else {
    const Timestamp localizeBy = monotonicNow() + Duration::fromSeconds(5.0);
    while (!r.localized && monotonicNow() < localizeBy) {
      // The set-pose taken: published (registers 4-7), the mode no longer idle.
      r.localized = poll() && r.last().r[1] != static_cast<std::uint16_t>(hal::NavMode::Idle) &&
                    std::fabs(unpackFloat(&r.last().r[4], WordOrder::ABCD) - kStart.x) < 0.05 &&
                    std::fabs(unpackFloat(&r.last().r[6], WordOrder::ABCD) - kStart.y) < 0.05;
      if (!r.localized) {
        nap();
      }
    }
    std::printf("PLC: after Localize, mode %u, health bits 0x%04X\n", static_cast<unsigned>(r.last().r[1]),
                static_cast<unsigned>(r.last().r[2]));
    while (r.localized && monotonicNow() < script.calibrateAt) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    r.calibrateSent = monotonicNow();
    if (!r.localized) {
      r.failure = "the set-pose never showed in registers 1 and 4-7 (mode " + std::to_string(r.last().r[1]) + ")";
    } else if (!agv::test::writePlcCommand(plc, 2, hal::PlcCommandKind::Calibrate)) {
      r.failure = std::string("Calibrate not written: ") + modbus_strerror(errno);
    } else {
      const Timestamp end = monotonicNow() + script.limit;
      Timestamp drivingSince{};
      while (monotonicNow() < end) {
        if (poll()) {
          const PlcRead& x = r.last();
          r.calibrating = r.calibrating || x.r[1] == static_cast<std::uint16_t>(hal::NavMode::Calibrating);
          if (script.stopAfterDriving.ns > 0 && r.stopSent.ns == 0 &&
              x.r[44] == stateCode(cal::RoutineState::Driving) && x.r[46] == 1U) {
            if (drivingSince.ns == 0) {
              drivingSince = x.t;
            } else if (x.t - drivingSince >= script.stopAfterDriving) {
              r.stopSent = monotonicNow();
              if (!agv::test::writePlcCommand(plc, 3, hal::PlcCommandKind::Stop)) {
                r.failure = std::string("Stop not written: ") + modbus_strerror(errno);
                break;
              }
              r.stopAcked = monotonicNow();
              continue;  // read at once
            }
          }
          const bool end2 = x.r[44] == stateCode(cal::RoutineState::Done) ||
                            x.r[44] == stateCode(cal::RoutineState::Aborted) || x.r[48] != 0U;
          if (end2 && r.ended.ns == 0) {
            r.ended = x.t;
          }
          if (r.ended.ns != 0 && x.t - r.ended >= script.afterEnd) {
            break;
          }
        }
        nap();
      }
      if (r.ended.ns == 0 && r.failure.empty()) {
        r.failure =
            "the routine did not end within the PLC's limit (register 44 = " + std::to_string(r.last().r[44]) + ")";
      }
    }
  }
  modbus_close(plc);
  modbus_free(plc);
  r.done = true;
}

/// The configuration of `agvnav-vehicle`: the drives and encoders of `agvnav-sim-drives --vehicle`
/// on `canIf` (traction node 1 is the drive encoder at {0x181, 2, 4}, steering encoder node 2: 4
/// bytes, 2 pi / 16384 rad per count), its NAV350 on 127.0.0.1:`laserPort`, the Modbus server on
/// `modbusPort`, and the plan (8 segments of 90 deg at 40..50 deg, 0.8 m/s) in `area` (the open
/// floor of the built-in warehouse by default).
std::string programConfig(const std::string& canIf, std::uint16_t laserPort, std::uint16_t modbusPort,
                          const std::string& dir, const std::string& area) {
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
         "calibration.area = " +
         area +
         "\n"
         "calibration.segments = 2\n"
         "calibration.min_steering = 0.6981317\n"
         "calibration.max_steering = 0.8726646\n"
         "calibration.rotation = 1.5707963\n"
         "calibration.speed = 0.8\n";
}

/// The calibration the vehicle starts with: nominal values (the truth is 0.85 % off in s_w,
/// 0.55 / 0.35 deg in the offsets, the laser 20 mm, 25 mm and 0.7 deg off).
const char* const kOldCalibration =
    "agvnav-calibration 2\nwheelbase 1.5\ndrive_scale 0.0001 0.00000003\nsteer_offset_forward 0.0\n"
    "steer_offset_backward 0.0\nlaser_x 1.6\nlaser_y 0.0\nlaser_theta 0.0\nend 7\n";

/// The programs, their files, the monitor socket and the PLC's thread; see the file comment.
class ProgramBench {
 public:
  /// `area`: the `calibration.area`; `driveArgs`: more arguments of agvnav-sim-drives (injections).
  ProgramBench(const std::string& name, const std::string& area, const std::vector<std::string>& driveArgs) {
    dir = "/tmp/agv-vm-" + name;
    ::mkdir(dir.c_str(), 0755);
    file = dir + "/calibration.txt";
    std::ofstream(file, std::ios::trunc | std::ios::binary) << kOldCalibration;
    std::remove((file + ".bak").c_str());
    std::remove((file + ".tmp").c_str());
    agv::sim::World world;
    agv::sim::WorldParseError perr;
    REQUIRE(agv::sim::parseWorld(agv::sim::defaultWorldText(), world, perr) == Status::Ok);
    {
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
    const std::uint16_t laserPort = agv::drivers::closedPort();
    modbusPort = agv::drivers::closedPort();
    const std::string conf = dir + "/vehicle.conf";
    std::ofstream(conf, std::ios::trunc) << programConfig(canIf_, laserPort, modbusPort, dir, area);

    agv::drivers::SocketCanConfig mc;
    mc.interfaceName = canIf_.c_str();
    mc.receiveErrorFrames = false;
    mc.receiveBufferBytes = 1 << 21;
    // What the checks read: NMT, the traction drive's EMCY, TPDO1 (statusword) and TPDO2 (velocity),
    // heartbeat, the RPDOs and SDO requests to both drives, the steering encoder's heartbeat, the
    // controller's heartbeat (the kernel filters the rest: less work for the VM's one CPU).
    for (std::uint32_t id : {kNmt, kTractionEmcy, kTractionTpdo1, kTractionTpdo2, kTractionRpdo, kSteeringRpdo,
                             kTractionSdo, kSteeringSdo, kTractionHeartbeat, kEncoderHeartbeat, kControllerHeartbeat}) {
      REQUIRE(mc.filters.push_back(agv::drivers::CanFilter{id, 0x7FFU, false}) == Status::Ok);
    }
    REQUIRE(monitor_.open(mc) == Status::Ok);
    std::vector<std::string> args = {
        "--interface", canIf_,      "--vehicle", "--laser-port", std::to_string(laserPort), "--start",
        "10,12.5,0",   "--step-ms", "2"};
    args.insert(args.end(), driveArgs.begin(), driveArgs.end());
    // The programs at the default priority, this process (the monitor, the PLC's thread) below
    // them: on the VM's one emulated CPU the programs, not the test's bookkeeping, keep their cycles.
    static_cast<void>(::setpriority(PRIO_PROCESS, 0, 0));
    drives = std::make_unique<agv::test::Child>(agv::test::programPath("agvnav-sim-drives"), args);
    REQUIRE(drives->started());
    // The program's clock (its injection times, its log) starts at its first step, which sends the
    // traction node's boot-up message (after the NAV350's port is open).
    const auto bootUp = [](const CanFrame& f) { return f.id == kTractionHeartbeat && f.dlc == 1 && f.data[0] == 0; };
    REQUIRE(runUntil([&] { return drives->said("NAV350 on") && firstAfter(Timestamp{}, bootUp) != nullptr; },
                     Duration::fromSeconds(10.0)));
    origin = firstAfter(Timestamp{}, bootUp)->stamp;
    vehicle = std::make_unique<agv::test::Child>(agv::test::programPath("agvnav-vehicle"),
                                                 std::vector<std::string>{"--config", conf}, true);
    REQUIRE(vehicle->started());
    static_cast<void>(::setpriority(PRIO_PROCESS, 0, 10));
  }
  ~ProgramBench() {
    if (client_.joinable()) {
      client_.join();
    }
  }
  ProgramBench(const ProgramBench&) = delete;
  ProgramBench& operator=(const ProgramBench&) = delete;

  /// Polls both programs and records the bus until `done` or `max`.
  template <typename F>
  bool runUntil(F done, Duration max) {
    const Timestamp end = monotonicNow() + max;
    for (;;) {
      drives->poll();
      if (vehicle) {
        vehicle->poll();
      }
      if (done()) {
        return true;
      }
      const Timestamp now = monotonicNow();
      if (now >= end) {
        return false;
      }
      // At most 20 ms of frames (about 600 a second) before the programs' output is read again.
      const Timestamp slice = now + Duration::fromMilliseconds(20);
      CanFrame f;
      for (Timestamp t = now; t < slice && monitor_.receive(f, slice - t) == Status::Ok; t = monotonicNow()) {
        seen.push_back(f);
      }
    }
  }
  void pump(Duration d) {
    runUntil([] { return false; }, d);
  }

  /// The PLC's thread runs `script`; returns when it is done, the programs polled meanwhile.
  void runPlc(const PlcScript& script) {
    client_ = std::thread([this, script] { plcThread(modbusPort, script, plc); });
    REQUIRE(runUntil([&] { return plc.done.load(); }, script.limit + Duration::fromSeconds(20.0)));
    client_.join();
    INFO(plc.failure);
    REQUIRE(plc.failure.empty());
    REQUIRE(plc.localized);
  }

  /// SIGTERM to both programs; both must exit 0.
  void stopPrograms() {
    terminated = monotonicNow();
    vehicle->signal(SIGTERM);
    drives->signal(SIGTERM);
    runUntil([&] { return !vehicle->running() && !drives->running(); }, Duration::fromSeconds(3.0));
    CHECK_FALSE(vehicle->running());
    CHECK(vehicle->exitCode() == 0);
    CHECK_FALSE(drives->running());
    CHECK(drives->exitCode() == 0);
  }

  /// The calibration file byte for byte as before, no temporary or backup left.
  void checkFileUntouched() const {
    CHECK(agv::test::readFile(file) == kOldCalibration);
    CHECK_FALSE(agv::test::fileExists(file + ".tmp"));
    CHECK_FALSE(agv::test::fileExists(file + ".bak"));
  }

  /// The vehicle's travel as agvnav-sim-drives printed it at exit ("... after D m;"), or -1.
  double distanceDriven() const {
    for (const std::string& l : drives->lines()) {
      const std::size_t at = l.find(" deg after ");
      if (l.find("vehicle at") != std::string::npos && at != std::string::npos) {
        return std::strtod(l.c_str() + at + 11, nullptr);
      }
    }
    return -1.0;
  }

  template <typename F>
  const CanFrame* firstAfter(Timestamp t, F match) const {
    for (const CanFrame& f : seen) {
      if (f.stamp >= t && match(f)) {
        return &f;
      }
    }
    return nullptr;
  }
  template <typename F>
  const CanFrame* lastBefore(Timestamp t, F match) const {
    const CanFrame* last = nullptr;
    for (const CanFrame& f : seen) {
      if (f.stamp < t && match(f)) {
        last = &f;
      }
    }
    return last;
  }
  template <typename F>
  int count(Timestamp from, Timestamp to, F match) const {
    int n = 0;
    for (const CanFrame& f : seen) {
      n += (f.stamp >= from && f.stamp < to && match(f)) ? 1 : 0;
    }
    return n;
  }
  /// The traction drive's velocity [m/s] in its last TPDO2 before `t` (NaN: none).
  double tractionSpeedBefore(Timestamp t) const {
    const CanFrame* v = lastBefore(t, [](const CanFrame& f) { return f.id == kTractionTpdo2 && f.dlc >= 4; });
    return v == nullptr ? std::nan("") : i32(*v, 0) / kVelocityUnitsPerMps;
  }
  /// The longest gap between consecutive frames `id` on the bus in [`from`, `until`) [ms], and its end.
  double longestGap(std::uint32_t id, Timestamp from, Timestamp until, Timestamp* at = nullptr) const {
    double worst = 0.0;
    const CanFrame* prev = nullptr;
    for (const CanFrame& f : seen) {
      if (f.id != id || f.stamp < from || f.stamp >= until) {
        continue;
      }
      if (prev != nullptr && ms(f.stamp - prev->stamp) > worst) {
        worst = ms(f.stamp - prev->stamp);
        if (at != nullptr) {
          *at = f.stamp;
        }
      }
      prev = &f;
    }
    return worst;
  }
  /// The routine's timeline as the PLC read it, relative to the Calibrate (one line per change of
  /// registers 44 / 46).
  void printTimeline() const {
    int state = -1;
    int segment = -1;
    for (const PlcRead& x : plc.reads) {
      if (x.r[44] != state || x.r[46] != segment) {
        state = x.r[44];
        segment = x.r[46];
        std::printf("  %+.2f s after Calibrate (%.2f s on agvnav-sim-drives' clock): %s, segment %u\n",
                    (x.t - plc.calibrateSent).seconds(), (x.t - origin).seconds(),
                    cal::routineStateName(static_cast<cal::RoutineState>(state)), static_cast<unsigned>(segment));
      }
    }
  }

  std::string dir;
  std::string file;
  std::uint16_t modbusPort = 0;
  Timestamp origin{};      ///< agvnav-sim-drives' time zero on CLOCK_MONOTONIC
  Timestamp terminated{};  ///< SIGTERM sent to both programs (the vehicle then quick-stops too)
  std::vector<CanFrame> seen;
  std::unique_ptr<agv::test::Child> drives;
  std::unique_ptr<agv::test::Child> vehicle;
  PlcClientRecord plc;

 private:
  std::string canIf_ = agv::test::vcanInterface();
  agv::drivers::SocketCanBus monitor_;
  std::thread client_;
};

/// The open floor of the built-in warehouse (the plan fits).
const char* const kOpenFloor = "2.5 0.5 24.0 23.0";

/// Calibrate at 3 s on agvnav-sim-drives' clock: the programs are up, connected and past their
/// start-up work by then (a Calibrate 1.3 s in, with the VM's one CPU busy with both start-ups, saw
/// the drives' bring-up fail on a late heartbeat in three of four runs at host load 7 - 8). The
/// first segment (90 deg at 40 deg steering: 2.8 m) is then driven from about 6.8 s (bring-up
/// 0.7 - 0.8 s, settling, steering; printed by every case: `printTimeline`): 0.8 m/s from 8.4 s
/// (0.5 m/s^2), braking from about 10.3 s, above 0.4 m/s from 7.6 s to 11 s. The injections come
/// at 9 s.
constexpr double kCalibrateAt = 3.0;
constexpr double kInjectAt = 9.0;

/// The registers of an aborted run: state aborted, the reason, the drive's fault code, not
/// calibrating; segment 1 of 8.
void checkAbortedRegisters(const PlcRead& x, Status reason, std::uint16_t faultCode) {
  CHECK(x.r[44] == stateCode(cal::RoutineState::Aborted));
  CHECK(x.r[46] == 1U);
  CHECK(x.r[47] == 8U);
  CHECK(x.r[48] == statusCode(reason));
  CHECK(x.r[49] == faultCode);
  CHECK(x.r[1] != static_cast<std::uint16_t>(hal::NavMode::Calibrating));
}

/// The injection at `tInject` fell into segment 1 driven at more than half the routine's speed:
/// the PLC's last read before it showed segment 1 driving, and so did the bus (the traction
/// drive's velocity).
void checkMidSegment(const ProgramBench& b, Timestamp tInject) {
  const PlcRead* before = b.plc.lastBefore(tInject);
  REQUIRE(before != nullptr);
  CHECK(before->r[44] == stateCode(cal::RoutineState::Driving));
  CHECK(before->r[46] == 1U);
  const double v = b.tractionSpeedBefore(tInject);
  std::printf("  traction at %.2f m/s when injected\n", v);
  CHECK(std::fabs(v) > 0.4);
}

}  // namespace

TEST_CASE("programs on vcan: a plan that does not fit the free area is refused before any frame to the drives",
          "[calibration][modbus][program]") {
  // The start (10, 12.5) fits with its 0.8 m clearance; the left circles (radius 1.8 m at 40 deg)
  // reach y = 14.3.
  ProgramBench b("refused", "8.0 11.0 13.0 14.0", {});
  PlcScript script;
  script.calibrateAt = b.origin + Duration::fromSeconds(kCalibrateAt);
  script.afterEnd = Duration::fromSeconds(1.0);
  script.limit = Duration::fromSeconds(5.0);
  b.runPlc(script);
  b.stopPrograms();
  const PlcRead& x = b.plc.last();
  std::printf("refused plan: register 48 = %u %.0f ms after the Calibrate; mode %u, health bits 0x%04X\n",
              static_cast<unsigned>(x.r[48]), ms(b.plc.ended - b.plc.calibrateSent), static_cast<unsigned>(x.r[1]),
              static_cast<unsigned>(x.r[2]));
  CHECK(x.r[48] == statusCode(Status::OutOfRange));
  CHECK(x.r[49] == 0U);
  CHECK(x.r[44] == stateCode(cal::RoutineState::Idle));
  CHECK(x.r[47] == 0U);
  CHECK(hal::hasBit(x.r[2], hal::HealthBit::CommandRejected));
  CHECK_FALSE(b.plc.calibrating);
  CHECK(b.vehicle->said("leaves the free area"));
  // The drive controller sent nothing at all: no NMT pre-operational or start, no SDO, no RPDO, no
  // heartbeat. (The encoder source's NMT Start of nodes 1 and 2 is the encoders' own.) The monitor
  // did receive: the steering encoder's heartbeats.
  CHECK(b.count(Timestamp{}, b.terminated, fromDriveController) == 0);
  CHECK(b.count(Timestamp{}, b.terminated, [](const CanFrame& f) { return f.id == kEncoderHeartbeat; }) > 50);
  CHECK(b.count(Timestamp{}, b.terminated, [](const CanFrame& f) {
    return f.id == kTractionTpdo1 && f.dlc >= 2 && decodeStatusword(u16(f, 0)) == PowerState::OperationEnabled;
  }) == 0);
  CHECK(b.distanceDriven() == 0.0);
  b.checkFileUntouched();
}

TEST_CASE("programs on vcan: a PLC Stop mid-segment quick-stops the traction within one control cycle",
          "[calibration][modbus][program]") {
  ProgramBench b("stop", kOpenFloor, {});
  PlcScript script;
  script.calibrateAt = b.origin + Duration::fromSeconds(kCalibrateAt);
  script.stopAfterDriving = Duration::fromSeconds(1.5);  // 0.5 m/s^2: at speed
  script.afterEnd = Duration::fromSeconds(1.0);
  b.runPlc(script);
  b.printTimeline();
  b.stopPrograms();
  REQUIRE(b.plc.stopSent.ns != 0);
  const Timestamp tStop = b.plc.stopSent;
  // Mid-segment: the PLC's last read before the Stop showed segment 1 driving, and the traction
  // drive reported more than half the routine's speed.
  const PlcRead* before = b.plc.lastBefore(tStop);
  REQUIRE(before != nullptr);
  CHECK(before->r[44] == stateCode(cal::RoutineState::Driving));
  CHECK(before->r[46] == 1U);
  const double v = b.tractionSpeedBefore(tStop);
  CHECK(std::fabs(v) > 0.4);
  // The quick stop (target 0) within one control cycle (10 ms) of the vehicle's having the Stop:
  // it answers the PLC's request after the cycle in which it read it (service()), and quick-stops at
  // once in the next cycle (2 ms period), which takes the command. Seen from the PLC: no later than
  // 10 ms after the reply came back (and after the request went out; the request's round trip is
  // the Modbus link's under TCG, up to 50 ms allowed). At most one ordinary RPDO in between (a
  // 10 ms cycle that was due while the request was on its way); none after it.
  const CanFrame* first = b.firstAfter(tStop, isQuickStop);
  REQUIRE(first != nullptr);
  const Duration latency = first->stamp - tStop;
  const int between = b.count(tStop, first->stamp, [](const CanFrame& f) { return f.id == kTractionRpdo; });
  std::printf(
      "PLC Stop at %.2f m/s -> quick stop on the bus %.2f ms after the request (%.2f ms after its reply), "
      "%d set-point(s) in between\n",
      v, ms(latency), ms(first->stamp - b.plc.stopAcked), between);
  CHECK(i32(*first, 2) == 0);
  CHECK(first->stamp - b.plc.stopAcked < Duration::fromMilliseconds(10));
  CHECK(latency < Duration::fromMilliseconds(50));
  CHECK(between <= 1);
  // Every later traction RPDO repeats it: no set-point after the Stop.
  const int rpdos = b.count(first->stamp, b.terminated, [](const CanFrame& f) { return f.id == kTractionRpdo; });
  const int others = b.count(first->stamp, b.terminated, [](const CanFrame& f) {
    return f.id == kTractionRpdo && !(isQuickStop(f) && i32(f, 2) == 0);
  });
  CHECK(rpdos > 20);
  CHECK(others == 0);
  // The drive ramps down on its quick-stop deceleration (2 m/s^2: 0.4 s from 0.8 m/s) and ends in
  // Switch on disabled.
  const CanFrame* still =
      b.firstAfter(first->stamp, [](const CanFrame& f) { return f.id == kTractionTpdo2 && i32(f, 0) == 0; });
  REQUIRE(still != nullptr);
  std::printf("  traction at velocity 0 %.0f ms after the quick stop\n", ms(still->stamp - first->stamp));
  CHECK(still->stamp - first->stamp < Duration::fromMilliseconds(700));
  const CanFrame* lastState = b.lastBefore(b.terminated, [](const CanFrame& f) { return f.id == kTractionTpdo1; });
  REQUIRE(lastState != nullptr);
  CHECK(decodeStatusword(u16(*lastState, 0)) == PowerState::SwitchOnDisabled);
  // Aborted on request: no fault reason, no code; the Stop reached the navigation too (idle).
  checkAbortedRegisters(b.plc.last(), Status::Ok, 0);
  CHECK(b.plc.last().r[1] == static_cast<std::uint16_t>(hal::NavMode::Idle));
  b.checkFileUntouched();
}

TEST_CASE("programs on vcan: the traction node's heartbeat lost mid-segment aborts the routine and stops the vehicle",
          "[calibration][modbus][program]") {
  char silence[32];
  char speak[32];
  std::snprintf(silence, sizeof silence, "1@%.1f", kInjectAt);
  std::snprintf(speak, sizeof speak, "1@%.1f", kInjectAt + 1.5);  // to read its state and velocity
  ProgramBench b("heartbeat", kOpenFloor, {"--silence", silence, "--speak", speak});
  PlcScript script;
  script.calibrateAt = b.origin + Duration::fromSeconds(kCalibrateAt);
  script.afterEnd = Duration::fromSeconds(2.0);
  b.runPlc(script);
  b.printTimeline();
  b.stopPrograms();
  REQUIRE(b.drives->said("node 1: injected silent"));
  // The node's last heartbeat before the silence, then nothing from it until it speaks again.
  const Timestamp tSilent = b.origin + Duration::fromSeconds(kInjectAt);
  const Timestamp tSpeak = b.origin + Duration::fromSeconds(kInjectAt + 1.5);
  // (Half-way through the silence: `origin` is the kernel stamp of the program's first frame, a few
  // ms after its clock's zero.)
  const Timestamp midSilence = tSilent + Duration::fromSeconds(0.75);
  const CanFrame* hb = b.lastBefore(midSilence, [](const CanFrame& f) { return f.id == kTractionHeartbeat; });
  REQUIRE(hb != nullptr);
  const CanFrame* lastOf1 = b.lastBefore(midSilence, [](const CanFrame& f) {
    return f.id == kTractionHeartbeat || f.id == kTractionTpdo1 || f.id == kTractionTpdo2 || f.id == kTractionEmcy;
  });
  REQUIRE(lastOf1 != nullptr);
  CHECK(lastOf1->stamp < tSilent + Duration::fromMilliseconds(50));
  checkMidSegment(b, hb->stamp);
  // The drive controller's consumer: 150 ms after the last heartbeat, seen by the vehicle's next
  // 10 ms control cycle; 100 ms allowed for the emulated CPU (the vehicle's cycles run late under
  // TCG). The axis stamps a heartbeat with the time of its poll before, up to a cycle early.
  const CanFrame* qs = b.firstAfter(hb->stamp, isQuickStop);
  REQUIRE(qs != nullptr);
  const Duration latency = qs->stamp - hb->stamp;
  std::printf("traction heartbeat lost: quick stop %.1f ms after the node's last heartbeat\n", ms(latency));
  CHECK(latency > Duration::fromMilliseconds(130));
  CHECK(latency < Duration::fromMilliseconds(250));
  CHECK(b.count(Timestamp{}, hb->stamp, isQuickStop) == 0);
  // Speaking again 1.5 s later, the drive reports that it stopped on the quick stop: velocity 0,
  // not Operation enabled.
  const CanFrame* v = b.firstAfter(tSpeak, [](const CanFrame& f) { return f.id == kTractionTpdo2; });
  REQUIRE(v != nullptr);
  CHECK(i32(*v, 0) == 0);
  const CanFrame* st = b.firstAfter(tSpeak, [](const CanFrame& f) { return f.id == kTractionTpdo1; });
  REQUIRE(st != nullptr);
  CHECK(decodeStatusword(u16(*st, 0)) != PowerState::OperationEnabled);
  // Registers: aborted, Timeout, no fault code; the encoder timeout (node 1 is the drive encoder)
  // before the node spoke again.
  const PlcRead* x = b.plc.lastBefore(tSpeak - Duration::fromMilliseconds(100));
  REQUIRE(x != nullptr);
  checkAbortedRegisters(*x, Status::Timeout, 0);
  CHECK(hal::hasBit(x->r[2], hal::HealthBit::EncoderTimeout));
  checkAbortedRegisters(b.plc.last(), Status::Timeout, 0);
  CHECK(b.vehicle->said("heartbeat"));
  b.checkFileUntouched();
}

TEST_CASE("programs on vcan: a traction drive fault mid-segment aborts the routine with its code on register 49",
          "[calibration][modbus][program]") {
  char fault[32];
  std::snprintf(fault, sizeof fault, "1:2310@%.1f", kInjectAt);
  ProgramBench b("fault", kOpenFloor, {"--fault", fault});
  PlcScript script;
  script.calibrateAt = b.origin + Duration::fromSeconds(kCalibrateAt);
  script.afterEnd = Duration::fromSeconds(1.0);
  b.runPlc(script);
  b.printTimeline();
  b.stopPrograms();
  const CanFrame* emcy = b.firstAfter(
      Timestamp{}, [](const CanFrame& f) { return f.id == kTractionEmcy && f.dlc == 8 && u16(f, 0) == 0x2310; });
  REQUIRE(emcy != nullptr);
  checkMidSegment(b, emcy->stamp);
  CHECK(b.count(Timestamp{}, emcy->stamp, isQuickStop) == 0);
  // The quick stop in the vehicle's next control cycle (10 ms; 50 ms for the emulated CPU, as for
  // the Stop: at host load 12 the vehicle program's cycles ran up to 97 ms and this took 39 ms),
  // then the error code read back by SDO upload of 0x603F.
  const CanFrame* qs = b.firstAfter(emcy->stamp, isQuickStop);
  REQUIRE(qs != nullptr);
  std::printf("traction fault: quick stop %.2f ms after the EMCY\n", ms(qs->stamp - emcy->stamp));
  CHECK(qs->stamp - emcy->stamp < Duration::fromMilliseconds(50));
  CHECK(b.firstAfter(emcy->stamp, [](const CanFrame& f) {
    return f.id == kTractionSdo && f.data[0] == 0x40 && u16(f, 1) == 0x603F && f.data[3] == 0;
  }) != nullptr);
  // The drive stopped by its fault reaction and stays in Fault (no reset).
  const CanFrame* still =
      b.firstAfter(emcy->stamp, [](const CanFrame& f) { return f.id == kTractionTpdo2 && i32(f, 0) == 0; });
  REQUIRE(still != nullptr);
  CHECK(still->stamp - emcy->stamp < Duration::fromMilliseconds(700));
  const CanFrame* lastState = b.lastBefore(b.terminated, [](const CanFrame& f) { return f.id == kTractionTpdo1; });
  REQUIRE(lastState != nullptr);
  CHECK(decodeStatusword(u16(*lastState, 0)) == PowerState::Fault);
  CHECK(b.count(emcy->stamp, b.terminated,
                [](const CanFrame& f) { return f.id == kTractionRpdo && (u16(f, 0) & 0x0080U) != 0; }) == 0);
  // Registers: aborted, DeviceFault, the drive's code 0x2310 on 49, device fault bit 6 (the
  // encoder source saw the EMCY of node 1).
  const PlcRead& x = b.plc.last();
  std::printf("  registers: 44 = %u, 48 = %u, 49 = 0x%04X, health 0x%04X\n", static_cast<unsigned>(x.r[44]),
              static_cast<unsigned>(x.r[48]), static_cast<unsigned>(x.r[49]), static_cast<unsigned>(x.r[2]));
  checkAbortedRegisters(x, Status::DeviceFault, 0x2310);
  CHECK(hal::hasBit(x.r[2], hal::HealthBit::DeviceFault));
  CHECK(b.vehicle->said("0x2310"));
  b.checkFileUntouched();
}

// Last: the first program case of the boot has run into the drives' bring-up failing on a late
// heartbeat more often than the others (the VM still busy after the static program); the refused
// plan, which brings nothing up, goes first.
TEST_CASE("the agvnav-vehicle program calibrates against agvnav-sim-drives --vehicle, started by a libmodbus client",
          "[calibration][modbus][program]") {
  ProgramBench b("program", kOpenFloor, {});
  PlcScript script;
  script.calibrateAt = b.origin + Duration::fromSeconds(kCalibrateAt);
  script.limit = Duration::fromSeconds(120.0);
  b.runPlc(script);
  b.printTimeline();
  std::printf("program routine: register 44 = %u %.1f s after the Calibrate; PLC: %zu status reads\n",
              static_cast<unsigned>(b.plc.last().r[44]), (b.plc.ended - b.plc.calibrateSent).seconds(),
              b.plc.reads.size());
  b.stopPrograms();
  // On the bus: the longest gaps of the traction node's heartbeat (50 ms producer, 150 ms consumer
  // in the vehicle) and of the vehicle's controller heartbeat (50 ms, 200 ms consumer in the
  // drives): under a loaded host the VM's processes stall.
  const CanFrame* startNmt =
      b.firstAfter(Timestamp{}, [](const CanFrame& f) { return f.id == kNmt && f.data[0] == 0x01 && f.data[1] == 1; });
  std::printf("  longest heartbeat gaps from the drives' start to the end: traction %.1f ms, controller %.1f ms\n",
              b.longestGap(kTractionHeartbeat, startNmt != nullptr ? startNmt->stamp : Timestamp{}, b.terminated),
              b.longestGap(kControllerHeartbeat, startNmt != nullptr ? startNmt->stamp : Timestamp{}, b.terminated));
  CHECK(b.plc.calibrating);
  for (cal::RoutineState s : {cal::RoutineState::Settling, cal::RoutineState::Steering, cal::RoutineState::Driving,
                              cal::RoutineState::Stopping, cal::RoutineState::Observing, cal::RoutineState::Done}) {
    CHECK(b.plc.stateSeen[static_cast<int>(s)]);
  }
  const PlcRead& x = b.plc.last();
  CHECK(x.r[44] == stateCode(cal::RoutineState::Done));
  CHECK(x.r[47] == 8U);
  CHECK(x.r[48] == 0U);
  CHECK(x.r[49] == 0U);
  // The drive controller's sequence on the bus: NMT pre-operational and start of node 1, the
  // enable steps (shutdown, switch on, enable operation), moving set-points, no quick stop.
  const auto rpdo = [](std::uint16_t cw) {
    return [cw](const CanFrame& f) { return f.id == kTractionRpdo && f.dlc == 6 && u16(f, 0) == cw; };
  };
  const CanFrame* preop =
      b.firstAfter(Timestamp{}, [](const CanFrame& f) { return f.id == kNmt && f.data[0] == 0x80 && f.data[1] == 1; });
  REQUIRE(preop != nullptr);
  const CanFrame* start =
      b.firstAfter(preop->stamp, [](const CanFrame& f) { return f.id == kNmt && f.data[0] == 0x01 && f.data[1] == 1; });
  REQUIRE(start != nullptr);
  const CanFrame* shutdown = b.firstAfter(start->stamp, rpdo(0x0006));
  REQUIRE(shutdown != nullptr);
  const CanFrame* switchOn = b.firstAfter(shutdown->stamp, rpdo(0x0007));
  REQUIRE(switchOn != nullptr);
  const CanFrame* enable = b.firstAfter(switchOn->stamp, rpdo(0x000F));
  REQUIRE(enable != nullptr);
  CHECK(b.count(enable->stamp, b.terminated, [](const CanFrame& f) {
    return f.id == kTractionRpdo && u16(f, 0) == 0x000F && i32(f, 2) > 4000;
  }) > 100);
  // No quick stop at all: the routine's end hands the drives back with "disable operation"
  // (controlword 0x0007, target 0) instead of leaving the standing traction to the set-point
  // watchdog (docs/drives.md), and the traction drive reports Switched on (statusword 0x23).
  CHECK(b.count(Timestamp{}, b.terminated, isQuickStop) == 0);
  const CanFrame* released = b.firstAfter(enable->stamp, [](const CanFrame& f) {
    return f.id == kTractionRpdo && f.dlc == 6 && u16(f, 0) == 0x0007 && i32(f, 2) == 0;
  });
  REQUIRE(released != nullptr);
  const CanFrame* switchedOn = b.firstAfter(released->stamp, [](const CanFrame& f) {
    return f.id == kTractionTpdo1 && f.dlc >= 2 && (u16(f, 0) & 0x006FU) == 0x0023U;
  });
  CHECK(switchedOn != nullptr);
  CHECK(b.count(released->stamp, b.terminated, [](const CanFrame& f) {
    return (f.id == kTractionRpdo || f.id == kSteeringRpdo) && f.dlc == 6 && u16(f, 0) != 0x0007;
  }) == 0);
  const PlcRead* doneRead = nullptr;
  for (const PlcRead& read : b.plc.reads) {
    if (read.r[44] == stateCode(cal::RoutineState::Done)) {
      doneRead = &read;
      break;
    }
  }
  REQUIRE(doneRead != nullptr);
  std::printf("  drives released %.1f ms before the PLC read done (Switched on %.1f ms after the release)\n",
              ms(doneRead->t - released->stamp),
              switchedOn != nullptr ? ms(switchedOn->stamp - released->stamp) : -1.0);
  agv::test::checkCalibrationFile(b.file, agv::sim::SimVehicleParams{}, "program routine", 2.0);
  CHECK(agv::test::readFile(b.file + ".bak") == kOldCalibration);
}
