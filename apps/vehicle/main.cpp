// agvnav-vehicle: the localizer on the real drivers (CANopen encoders over SocketCAN, a SICK laser
// over TCP, the PLC link over Modbus TCP), configured by one file (docs/vehicle.md).
//
// Exit status: 0 after SIGINT/SIGTERM (links closed) or a successful --check; 1 when the PLC link
// cannot be set up; 2 for a bad command line, configuration, calibration or map file.
#include <CLI/CLI.hpp>
#include <csignal>
#include <cstdio>
#include <string>

#include "vehicle_config.hpp"
#include "vehicle_runtime.hpp"

namespace {

volatile std::sig_atomic_t gStop = 0;

void onSignal(int) {
  gStop = 1;
}

void installHandlers() {
  struct sigaction sa {};
  sa.sa_handler = onSignal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = 0;  // no SA_RESTART: the loop's wait ends at once
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  std::signal(SIGPIPE, SIG_IGN);
  // Blocked except inside the loop's one wait (ppoll unblocks them): a signal either arrives
  // before the wait and ends it at once, or during it; never lost between the flag test and the wait.
  sigset_t block;
  sigemptyset(&block);
  sigaddset(&block, SIGINT);
  sigaddset(&block, SIGTERM);
  sigprocmask(SIG_BLOCK, &block, nullptr);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "agvnav-vehicle: localization on the vehicle's real drivers (CANopen encoders, SICK laser, Modbus PLC link)"};
  std::string configPath;
  bool checkOnly = false;
  app.add_option("-c,--config", configPath, "configuration file (format: docs/vehicle.md)")->required();
  app.add_flag("--check", checkOnly, "check the configuration, calibration and map files, then exit");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? 0 : 2;
  }

  agv::vehicle::VehicleConfig config;
  agv::vehicle::ConfigError error;
  if (!agv::vehicle::loadVehicleConfig(configPath, config, error)) {
    std::fprintf(stderr, "agvnav-vehicle: bad configuration: %s\n", error.text().c_str());
    return 2;
  }
  agv::vehicle::VehicleFiles files;
  if (!agv::vehicle::loadVehicleFiles(config, files, error)) {
    std::fprintf(stderr, "agvnav-vehicle: bad configuration: %s\n", error.text().c_str());
    return 2;
  }
  for (const std::string& w : files.warnings) {
    std::fprintf(stderr, "agvnav-vehicle: warning: %s\n", w.c_str());
  }
  if (checkOnly) {
    std::printf("agvnav-vehicle: %s: configuration ok (%zu landmarks)\n", configPath.c_str(), files.map->size());
    return 0;
  }

  installHandlers();
  agv::vehicle::VehicleRuntime runtime(config, std::move(files));
  std::string openError;
  if (!runtime.open(openError)) {
    std::fprintf(stderr, "agvnav-vehicle: %s\n", openError.c_str());
    return 1;
  }
  std::fprintf(stderr, "agvnav-vehicle: running (CAN %s, laser %s %s:%u, Modbus %s %s:%u)\n",
               config.canInterface.c_str(), agv::drivers::toString(config.laser.model), config.laser.tcp.host,
               static_cast<unsigned>(config.laser.tcp.port),
               config.modbus.role == agv::drivers::PlcLinkRole::Server ? "server" : "client", config.modbus.address,
               static_cast<unsigned>(config.modbus.port));
  runtime.run(gStop);
  const agv::vehicle::VehicleRuntime::LoopStats& loop = runtime.loopStats();
  std::fprintf(stderr, "agvnav-vehicle: loop: %llu cycles, %llu input wakes, %llu overruns, longest cycle %.3f ms\n",
               static_cast<unsigned long long>(loop.cycles), static_cast<unsigned long long>(loop.inputWakes),
               static_cast<unsigned long long>(loop.overruns), static_cast<double>(loop.longestCycleNs) * 1e-6);
  const agv::drivers::PlcLinkCounters& p = runtime.plcCounters();
  std::fprintf(stderr,
               "agvnav-vehicle: modbus: %u requests, %u connects, %u refused connections, %u refused peers, %u "
               "evictions, %u request timeouts, %u idle timeouts, %u send failures, %u refused requests, %u refused "
               "writes\n",
               p.requests, p.connects, p.connectFailures, p.refusedPeers, p.evictions, p.requestTimeouts,
               p.idleTimeouts, p.sendFailures, p.refusedRequests, p.rejectedWrites);
  const agv::nav::PipelineCounters& c = runtime.counters();
  std::fprintf(stderr,
               "agvnav-vehicle: stopped after %llu cycles (%llu encoder samples, %llu sweeps, %llu corrections, "
               "%llu publications, %llu PLC commands, %llu refused)\n",
               static_cast<unsigned long long>(c.cycles), static_cast<unsigned long long>(c.encoderSamples),
               static_cast<unsigned long long>(c.sweeps), static_cast<unsigned long long>(c.corrections),
               static_cast<unsigned long long>(c.publications), static_cast<unsigned long long>(c.commands),
               static_cast<unsigned long long>(c.refusedCommands));
  return 0;
}
