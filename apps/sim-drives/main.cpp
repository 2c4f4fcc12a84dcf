// agvnav-sim-drives: the traction and steering drives of the vehicle played as two simulated
// CiA 402 nodes on a SocketCAN interface (docs/drives.md), for tests of the drive controller
// against a real kernel CAN stack. With --vehicle the drives move the simulated tricycle, the
// traction node reports its wheel counts, the steering encoder (node 2) is on the bus and the
// simulated NAV350 is served on a TCP port of 127.0.0.1 (sim_vehicle_side.hpp); `--interface none`
// runs without CAN (the vehicle moved by --move only). Logs every state change on stdout; runs
// until SIGINT/SIGTERM or --duration.
#include <CLI/CLI.hpp>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "agv/drivers/linux/monotonic_clock.hpp"
#include "agv/drivers/linux/socketcan_bus.hpp"
#include "sim_drives.hpp"
#include "sim_vehicle_side.hpp"

namespace {
volatile std::sig_atomic_t gStop = 0;
void onSignal(int) {
  gStop = 1;
}
}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"agvnav-sim-drives: two simulated CiA 402 drives on a SocketCAN interface"};
  std::string interfaceName = "vcan0";
  agv::simdrives::SimDrivesOptions options;
  unsigned traction = 1;
  unsigned steering = 3;
  double stepMs = 1.0;
  double duration = 0.0;
  std::vector<std::string> faults;
  std::vector<std::string> silences;
  std::vector<std::string> speaks;
  bool withVehicle = false;
  agv::simdrives::SimVehicleSideOptions vehicleOptions;
  std::string startText = "10,12.5,0";
  std::vector<std::string> moves;
  unsigned laserPort = vehicleOptions.laserPort;
  app.add_option("--interface", interfaceName, "CAN interface (default vcan0)");
  app.add_option("--traction-node", traction, "node id of the traction drive (profile velocity)")
      ->check(CLI::Range(1, 127));
  app.add_option("--steering-node", steering, "node id of the steering drive (profile position)")
      ->check(CLI::Range(1, 127));
  app.add_option("--steering-position", options.steeringInitialPosition, "steering position at power-on [units]");
  app.add_option("--step-ms", stepMs, "simulation step [ms] (default 1)")->check(CLI::Range(0.1, 100.0));
  app.add_option("--duration", duration, "[s] stop after this long (0: until SIGINT/SIGTERM)")
      ->check(CLI::Range(0.0, 1e6));
  app.add_option("--fault", faults, "NODE:CODE@SECONDS: EMCY + Fault with the hexadecimal error code");
  app.add_option("--silence", silences, "NODE@SECONDS: the node stops transmitting");
  app.add_option("--speak", speaks, "NODE@SECONDS: the node transmits again");
  app.add_flag("--vehicle", withVehicle,
               "move the simulated tricycle with the drives, report its wheel counts in the traction "
               "TPDO, send the steering encoder (node 2) and serve its NAV350 on --laser-port");
  app.add_option("--laser-port", laserPort, "--vehicle: TCP port of the NAV350 on 127.0.0.1 (0: any, printed)")
      ->check(CLI::Range(0, 65535));
  app.add_option("--world", vehicleOptions.worldFile, "--vehicle: world file (default: the built-in warehouse)");
  app.add_option("--start", startText, "--vehicle: X,Y,THETA_DEG start of the logical point (default 10,12.5,0)");
  app.add_option("--laser-resolution", vehicleOptions.laserResolutionDeg, "--vehicle: beam spacing [deg] (default 1)")
      ->check(CLI::Range(0.1, 5.0));
  app.add_option("--steering-counts-per-rad", vehicleOptions.drives.steering.countsPerRadian,
                 "--vehicle: the steering axis' position units per radian (as drives.steering.counts_per_rad)")
      ->check(CLI::PositiveNumber);
  app.add_option("--steering-zero", vehicleOptions.drives.steering.zeroCount,
                 "--vehicle: the steering axis' position at straight ahead");
  app.add_option("--move", moves,
                 "--vehicle: SPEED:STEER_DEG@FROM-TO: drive the vehicle directly (no drive set-point), "
                 "seconds after the start");
  CLI11_PARSE(app, argc, argv);
  {
    std::istringstream in(startText);
    char c1 = 0;
    char c2 = 0;
    double thetaDeg = 0.0;
    if (!(in >> vehicleOptions.start.x >> c1 >> vehicleOptions.start.y >> c2 >> thetaDeg) || c1 != ',' || c2 != ',') {
      std::fprintf(stderr, "agvnav-sim-drives: --start '%s': expected X,Y,THETA_DEG\n", startText.c_str());
      return 2;
    }
    vehicleOptions.start.theta = agv::deg2rad(thetaDeg);
  }
  vehicleOptions.laserPort = static_cast<std::uint16_t>(laserPort);
  for (const std::string& text : moves) {
    agv::simdrives::DirectMove m;
    std::string error;
    if (!agv::simdrives::parseDirectMove(text, m, error)) {
      std::fprintf(stderr, "agvnav-sim-drives: %s\n", error.c_str());
      return 2;
    }
    vehicleOptions.moves.push_back(m);
  }
  const bool withCan = interfaceName != "none";
  if (!withCan && !withVehicle) {
    std::fprintf(stderr, "agvnav-sim-drives: --interface none needs --vehicle\n");
    return 2;
  }
  if (traction == steering) {
    std::fprintf(stderr, "agvnav-sim-drives: the traction and steering nodes must differ\n");
    return 2;
  }
  options.tractionNode = static_cast<std::uint8_t>(traction);
  options.steeringNode = static_cast<std::uint8_t>(steering);
  using Kind = agv::simdrives::Injection::Kind;
  const std::pair<const std::vector<std::string>*, Kind> lists[] = {
      {&faults, Kind::Fault}, {&silences, Kind::Silence}, {&speaks, Kind::Speak}};
  for (const auto& list : lists) {
    for (const std::string& text : *list.first) {
      agv::simdrives::Injection in;
      std::string error;
      if (!agv::simdrives::parseInjection(text, list.second, in, error)) {
        std::fprintf(stderr, "agvnav-sim-drives: %s\n", error.c_str());
        return 2;
      }
      options.injections.push_back(in);
    }
  }

  agv::drivers::SocketCanConfig config;
  config.interfaceName = interfaceName.c_str();
  // The nodes' own CAN controllers are not the one whose state an error frame on the interface
  // reports (the vcan VM's bus-off case writes one for the drive controller's socket): without the
  // subscription a bus-off report does not make this program refuse to transmit.
  config.receiveErrorFrames = false;
  agv::drivers::SocketCanBus bus;
  const agv::Status opened = withCan ? bus.open(config) : agv::Status::Ok;
  if (opened != agv::Status::Ok) {
    std::fprintf(stderr, "agvnav-sim-drives: CAN interface '%s': %s\n", interfaceName.c_str(),
                 opened == agv::Status::NotFound ? "not found" : agv::toString(opened));
    return 2;
  }
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  std::setvbuf(stdout, nullptr, _IOLBF, 0);

  agv::simdrives::SimDrives drives(options, stdout);
  const agv::Duration step = agv::Duration::fromSeconds(stepMs * 1e-3);
  const agv::Timestamp start = agv::drivers::monotonicNow();
  std::unique_ptr<agv::simdrives::SimVehicleSide> vehicle;
  if (withVehicle) {
    vehicle = std::make_unique<agv::simdrives::SimVehicleSide>(vehicleOptions, start, stdout);
    if (vehicle->status() != agv::Status::Ok) {
      std::fprintf(stderr, "agvnav-sim-drives: %s\n", vehicle->error().c_str());
      return 2;
    }
    std::printf("agvnav-sim-drives: vehicle at %.3f %.3f %.2f deg, NAV350 on 127.0.0.1:%u\n", vehicleOptions.start.x,
                vehicleOptions.start.y, agv::rad2deg(vehicleOptions.start.theta),
                static_cast<unsigned>(vehicle->laserPort()));
  }
  agv::Timestamp next = start;
  std::uint64_t sent = 0;
  std::uint64_t refused = 0;
  std::uint64_t received = 0;
  agv::drivers::CanFrame out[agv::simdrives::SimDrives::kMaxFrames + 2];  // + the steering encoder's
  while (gStop == 0) {
    agv::Timestamp now = agv::drivers::monotonicNow();
    if (duration > 0.0 && (now - start).seconds() >= duration) {
      break;
    }
    if (now >= next) {
      // The frames that arrived while this process did not run are the nodes' before the step,
      // at their kernel receive stamps: a real drive takes a frame when it is on the bus, and a
      // simulator descheduled for longer than the controller's heartbeat consumer time (a loaded
      // VM) would otherwise step first and fault its nodes on a heartbeat already queued.
      agv::drivers::CanFrame pending;
      while (withCan && bus.receive(pending, agv::Duration{}) == agv::Status::Ok) {
        if (!pending.error) {
          ++received;
          drives.receive(pending, pending.stamp);
        }
      }
      std::size_t n = 0;
      if (vehicle) {
        n = vehicle->step(now, drives, agv::Span<agv::drivers::CanFrame>(out), n);
      }
      n += drives.step(now, agv::Span<agv::drivers::CanFrame>(out + n, agv::simdrives::SimDrives::kMaxFrames));
      for (std::size_t i = 0; i < n && withCan; ++i) {
        if (bus.send(out[i]) == agv::Status::Ok) {
          ++sent;
        } else {
          ++refused;
        }
      }
      next = next + step;
      if (next <= now) {
        next = now + step;  // late: no burst of steps
      }
      continue;
    }
    agv::drivers::CanFrame f;
    if (!withCan) {
      std::this_thread::sleep_for(std::chrono::nanoseconds((next - now).ns));
      continue;
    }
    if (bus.receive(f, next - now) == agv::Status::Ok && !f.error) {
      ++received;
      drives.receive(f, f.stamp);  // the kernel's receive stamp (CLOCK_MONOTONIC)
    }
  }
  std::printf("agvnav-sim-drives: %llu frames sent, %llu refused, %llu received\n",
              static_cast<unsigned long long>(sent), static_cast<unsigned long long>(refused),
              static_cast<unsigned long long>(received));
  if (vehicle) {
    const agv::Pose2d& p = vehicle->vehicle().truePose();
    std::printf("agvnav-sim-drives: vehicle at %.3f %.3f %.2f deg after %.2f m; %llu sweeps, %llu laser replies\n", p.x,
                p.y, agv::rad2deg(p.theta), vehicle->vehicle().odometer(),
                static_cast<unsigned long long>(vehicle->sweeps()),
                static_cast<unsigned long long>(vehicle->replies()));
  }
  return 0;
}
