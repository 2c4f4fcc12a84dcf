// vcan-drive-controller: the vehicle's CiA 402 drive controller (`drivers::SocketCanDriveControl`,
// the same code agvnav-vehicle runs) as a process of its own on a CAN interface, for the vcan VM's
// cases where the controller side must be a real process: it exits, is killed, stopped, or its
// socket sees a bus-off (tests/vcan/test_drive_processes_vm.cpp, docs/vcan-testing.md).
//
// usage: vcan-drive-controller [--interface vcan0] [--speed M_PER_S] [--stale-after SECONDS]
//                              [--exit-after SECONDS] [--duration SECONDS]
//
// Opens the interface, brings the drives up, and once both are enabled commands `--speed` straight
// ahead in every 10 ms cycle. `--stale-after`: stops calling command() that long after the enable
// (the cycles go on: the watchdog's case). `--exit-after`: leaves the loop that long after the
// enable and returns from main (the destructor's quick stop). SIGTERM / SIGINT:
// quickStop(Shutdown), then the same return. `--duration` bounds the whole run (default 60 s).
//
// stdout, one line per event, the first field the CLOCK_MONOTONIC time in nanoseconds (the clock
// the test's monitor socket stamps frames on): `<ns> STATE <state>`, `<ns> SAFE-STOP <reason>`,
// `<ns> ERROR-CODE <traction|steering> 0x<code>`, `<ns> LAST-SETPOINT <ns of the cycle that took
// the last command>`, `<ns> SIGNAL`, `<ns> EXIT`. Exit status 0, or 2 when the interface cannot
// be opened or an argument is bad.
#include <time.h>

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "agv/drivers/linux/monotonic_clock.hpp"
#include "agv/drivers/linux/socketcan_drive_control.hpp"

namespace {

volatile std::sig_atomic_t gSignal = 0;
void onSignal(int) {
  gSignal = 1;
}

long long ns(agv::Timestamp t) {
  return static_cast<long long>(t.ns);
}

bool parseSeconds(const char* text, double& out) {
  char* end = nullptr;
  out = std::strtod(text, &end);
  return end != text && *end == '\0' && out >= 0.0;
}

// Stable names for the test to match (`toString` gives the log's wording).
const char* stateName(agv::drivers::canopen::DriveControllerState s) {
  using S = agv::drivers::canopen::DriveControllerState;
  switch (s) {
    case S::Idle:
      return "Idle";
    case S::BringingUp:
      return "BringingUp";
    case S::Enabled:
      return "Enabled";
    case S::SafeStop:
      return "SafeStop";
    case S::Failed:
      return "Failed";
    case S::Released:
      return "Released";
  }
  return "?";
}
const char* reasonName(agv::drivers::canopen::SafeStopReason r) {
  using R = agv::drivers::canopen::SafeStopReason;
  switch (r) {
    case R::None:
      return "None";
    case R::DriveHeartbeatLost:
      return "DriveHeartbeatLost";
    case R::DriveFault:
      return "DriveFault";
    case R::BusOff:
      return "BusOff";
    case R::PlcStop:
      return "PlcStop";
    case R::SetpointTimeout:
      return "SetpointTimeout";
    case R::Shutdown:
      return "Shutdown";
    case R::Requested:
      return "Requested";
  }
  return "?";
}

}  // namespace

int main(int argc, char** argv) {
  const char* interfaceName = "vcan0";
  double speed = 0.3;
  double staleAfter = -1.0;
  double exitAfter = -1.0;
  double duration = 60.0;
  for (int i = 1; i < argc; ++i) {
    const bool hasValue = i + 1 < argc;
    bool ok = hasValue;
    if (hasValue && std::strcmp(argv[i], "--interface") == 0) {
      interfaceName = argv[++i];
    } else if (hasValue && std::strcmp(argv[i], "--speed") == 0) {
      ok = parseSeconds(argv[++i], speed);
    } else if (hasValue && std::strcmp(argv[i], "--stale-after") == 0) {
      ok = parseSeconds(argv[++i], staleAfter);
    } else if (hasValue && std::strcmp(argv[i], "--exit-after") == 0) {
      ok = parseSeconds(argv[++i], exitAfter);
    } else if (hasValue && std::strcmp(argv[i], "--duration") == 0) {
      ok = parseSeconds(argv[++i], duration);
    } else {
      ok = false;
    }
    if (!ok) {
      std::fprintf(stderr, "vcan-drive-controller: bad argument '%s'\n", argv[i]);
      return 2;
    }
  }
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  struct sigaction sa {};
  sa.sa_handler = onSignal;  // no SA_RESTART: the cycle's sleep ends at once
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);

  namespace canopen = agv::drivers::canopen;
  agv::drivers::SocketCanDriveControlConfig config;
  config.interfaceName = interfaceName;
  agv::drivers::SocketCanDriveControl drives(config);
  const agv::Timestamp t0 = agv::drivers::monotonicNow();
  const agv::Status opened = drives.open(t0);
  if (opened != agv::Status::Ok) {
    std::fprintf(stderr, "vcan-drive-controller: CAN interface '%s': %s\n", interfaceName, agv::toString(opened));
    return 2;
  }
  (void)drives.start(t0);

  const agv::Duration period = agv::Duration::fromMilliseconds(10);
  canopen::DriveControllerState lastState = canopen::DriveControllerState::Idle;
  canopen::SafeStopReason lastReason = canopen::SafeStopReason::None;
  std::uint16_t lastCodes[2] = {0, 0};
  bool enabledOnce = false;
  bool commanding = true;
  agv::Timestamp enabledAt{};
  agv::Timestamp lastCommandCycle{};
  agv::Timestamp next = t0;
  for (;;) {
    const agv::Timestamp now = agv::drivers::monotonicNow();
    if (gSignal != 0) {
      std::printf("%lld SIGNAL\n", ns(now));
      drives.quickStop(canopen::SafeStopReason::Shutdown);
      const canopen::SafeStopReason reason = drives.controller().safeStopReason();
      std::printf("%lld SAFE-STOP %s (%s)\n", ns(agv::drivers::monotonicNow()), reasonName(reason),
                  canopen::toString(reason));
      break;
    }
    if ((now - t0).seconds() >= duration) {
      break;
    }
    if (enabledOnce && exitAfter >= 0.0 && (now - enabledAt).seconds() >= exitAfter) {
      break;
    }
    if (enabledOnce && commanding && staleAfter >= 0.0 && (now - enabledAt).seconds() >= staleAfter) {
      commanding = false;
      std::printf("%lld LAST-SETPOINT %lld\n", ns(now), ns(lastCommandCycle));
    }
    agv::hal::DriveCommand cmd;
    cmd.stamp = now;
    cmd.speed = speed;
    cmd.steeringAngle = 0.0;
    const bool commanded = commanding && drives.controller().state() == canopen::DriveControllerState::Enabled &&
                           drives.command(cmd) == agv::Status::Ok;
    (void)drives.cycle(now);
    if (commanded) {
      lastCommandCycle = now;  // the poll of this cycle stamped the command
    }
    const canopen::Cia402DriveController& c = drives.controller();
    if (c.state() != lastState) {
      lastState = c.state();
      std::printf("%lld STATE %s (%s)\n", ns(now), stateName(lastState), canopen::toString(lastState));
      if (lastState == canopen::DriveControllerState::Enabled && !enabledOnce) {
        enabledOnce = true;
        enabledAt = now;
      }
    }
    if (c.safeStopReason() != lastReason) {
      lastReason = c.safeStopReason();
      std::printf("%lld SAFE-STOP %s (%s)\n", ns(now), reasonName(lastReason), canopen::toString(lastReason));
    }
    const canopen::Cia402Axis* axes[2] = {&c.traction(), &c.steering()};
    for (int a = 0; a < 2; ++a) {
      if (axes[a]->errorCode() != lastCodes[a]) {
        lastCodes[a] = axes[a]->errorCode();
        std::printf("%lld ERROR-CODE %s 0x%04X\n", ns(now), a == 0 ? "traction" : "steering",
                    static_cast<unsigned>(lastCodes[a]));
      }
    }
    next = next + period;
    const agv::Timestamp after = agv::drivers::monotonicNow();
    if (next <= after) {
      next = after + period;  // late: no burst of cycles
    }
    timespec until{};
    until.tv_sec = static_cast<time_t>(next.ns / 1000000000LL);
    until.tv_nsec = static_cast<long>(next.ns % 1000000000LL);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &until, nullptr) == EINTR && gSignal == 0) {
    }
  }
  std::printf("%lld EXIT\n", ns(agv::drivers::monotonicNow()));
  return 0;  // ~SocketCanDriveControl: the last traction quick stop
}
