// agvnav-sim-drives: the traction and steering drives of the vehicle played as two simulated
// CiA 402 nodes on a SocketCAN interface (docs/drives.md), for tests of the drive controller
// against a real kernel CAN stack. Logs every state change on stdout; runs until SIGINT/SIGTERM
// or --duration.
#include <CLI/CLI.hpp>

#include <csignal>
#include <cstdio>
#include <string>
#include <vector>

#include "agv/drivers/linux/monotonic_clock.hpp"
#include "agv/drivers/linux/socketcan_bus.hpp"
#include "sim_drives.hpp"

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
  CLI11_PARSE(app, argc, argv);
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
  const agv::Status opened = bus.open(config);
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
  agv::Timestamp next = start;
  std::uint64_t sent = 0;
  std::uint64_t refused = 0;
  std::uint64_t received = 0;
  agv::drivers::CanFrame out[agv::simdrives::SimDrives::kMaxFrames];
  while (gStop == 0) {
    agv::Timestamp now = agv::drivers::monotonicNow();
    if (duration > 0.0 && (now - start).seconds() >= duration) {
      break;
    }
    if (now >= next) {
      const std::size_t n = drives.step(now, agv::Span<agv::drivers::CanFrame>(out));
      for (std::size_t i = 0; i < n; ++i) {
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
    if (bus.receive(f, next - now) == agv::Status::Ok && !f.error) {
      ++received;
      drives.receive(f, agv::drivers::monotonicNow());
    }
  }
  std::printf("agvnav-sim-drives: %llu frames sent, %llu refused, %llu received\n",
              static_cast<unsigned long long>(sent), static_cast<unsigned long long>(refused),
              static_cast<unsigned long long>(received));
  return 0;
}
