// `agvnav-sim-drives --vehicle` as a process on the build host (loopback, no CAN interface:
// `--interface none`, the vehicle moved by `--move` instead of the drives' set-points), read by
// the laser driver of agvnav-vehicle (`SickLaserSource`, NAV350 model) on its TCP port: sweeps
// arrive at the NAV350's 8 Hz, decode, carry the reflectors of the built-in warehouse where the
// simulated truth puts them, and change when the vehicle moves.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "agv/core/angle.hpp"
#include "agv/core/pose2.hpp"
#include "agv/drivers/linux/loopback_server.hpp"
#include "agv/drivers/linux/monotonic_clock.hpp"
#include "agv/drivers/linux/sick_laser_source.hpp"
#include "agv/sim/sim_vehicle.hpp"
#include "agv/sim/world.hpp"
#include "agv_test.hpp"
#include "spawn_logged.hpp"

using agv::Pose2d;
using agv::Status;
using agv::drivers::monotonicNow;

namespace {

struct Sweep {
  double t = 0.0;  ///< [s] after the program's start
  std::vector<float> ranges;
  std::vector<Pose2d> reflectors;  ///< sensor frame (theta unused)
  float angleMin = 0.0F;
  float angleIncrement = 0.0F;
};

/// Mean |difference| of the ranges valid in both sweeps [m].
double meanRangeChange(const Sweep& a, const Sweep& b) {
  double sum = 0.0;
  int n = 0;
  for (std::size_t i = 0; i < a.ranges.size() && i < b.ranges.size(); ++i) {
    if (a.ranges[i] > 0.5F && a.ranges[i] < 49.0F && b.ranges[i] > 0.5F && b.ranges[i] < 49.0F) {
      sum += std::fabs(static_cast<double>(a.ranges[i] - b.ranges[i]));
      ++n;
    }
  }
  return n > 0 ? sum / n : 1e9;
}

/// Largest distance of a sweep's reflectors, placed in the world from the laser at `laser`, to
/// the nearest reflector of `world` [m].
double worstReflectorError(const Sweep& s, const Pose2d& laser, const agv::sim::World& world) {
  double worst = 0.0;
  for (const Pose2d& r : s.reflectors) {
    const Pose2d w = laser.compose(Pose2d{r.x, r.y, 0.0});
    double best = 1e9;
    for (const agv::sim::Circle& c : world.circles) {
      if (c.kind == agv::sim::ObstacleKind::Reflector) {
        best = std::min(best, std::hypot(w.x - c.centre.x, w.y - c.centre.y));
      }
    }
    worst = std::max(worst, best);
  }
  return worst;
}

std::string readAll(const std::string& path) {
  std::ifstream f(path);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

}  // namespace

TEST_CASE("agvnav-sim-drives --vehicle serves NAV350 sweeps that follow the simulated vehicle", "[simdrives]") {
  const std::uint16_t port = agv::drivers::closedPort();
  const std::string logPath = "/tmp/agvnav-simdrives-vehicle-" + std::to_string(::getpid()) + ".log";
  const std::string portText = std::to_string(port);
  // 1.5 s at rest, 1.5 s at 0.6 m/s on a 25 deg arc, then at rest again until 6 s.
  const auto t0 = monotonicNow();
  const pid_t pid = agv::test::spawnLogged({AGVNAV_SIM_DRIVES_EXE, "--interface", "none", "--vehicle", "--laser-port",
                                            portText, "--move", "0.6:25@1.5-3", "--duration", "6"},
                                           logPath);
  REQUIRE(pid > 0);

  agv::drivers::SickLaserSourceConfig config;
  config.model = agv::drivers::SickLaserModel::Nav350;
  std::strcpy(config.tcp.host, "127.0.0.1");
  config.tcp.port = port;
  config.tcp.reconnectInterval = agv::Duration::fromMilliseconds(100);
  agv::drivers::applyModelRanges(config.model, config.scan, config.nav);
  agv::drivers::SickLaserSource laser(config);
  std::vector<Sweep> sweeps;
  agv::hal::LaserMeasurement m;
  while ((monotonicNow() - t0).seconds() < 5.8) {
    if (laser.read(m) == Status::Ok) {
      Sweep s;
      s.t = (monotonicNow() - t0).seconds();
      s.angleMin = m.scan.angleMin;
      s.angleIncrement = m.scan.angleIncrement;
      s.ranges.assign(m.scan.ranges.begin(), m.scan.ranges.end());
      for (const agv::hal::ReflectorObservation& o : m.reflectors) {
        s.reflectors.push_back(Pose2d{o.x, o.y, 0.0});
      }
      sweeps.push_back(s);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  int status = 0;
  pid_t r = 0;
  for (int i = 0; i < 3000 && r != pid; ++i) {
    r = ::waitpid(pid, &status, WNOHANG);
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  if (r != pid) {
    ::kill(pid, SIGKILL);
    ::waitpid(pid, &status, 0);
  }
  const std::string log = readAll(logPath);
  std::remove(logPath.c_str());
  INFO(log);
  REQUIRE(r == pid);
  CHECK(WIFEXITED(status));
  CHECK(WEXITSTATUS(status) == 0);

  // The simulated truth: the start, and the end pose the program prints when it exits.
  agv::sim::World world;
  agv::sim::WorldParseError perr;
  REQUIRE(agv::sim::parseWorld(agv::sim::defaultWorldText(), world, perr) == Status::Ok);
  const Pose2d mount = agv::sim::SimVehicleParams{}.laserMount;
  const Pose2d startLaser = Pose2d{10.0, 12.5, 0.0}.compose(mount);
  Pose2d end;
  double thetaDeg = 0.0;
  double odometer = 0.0;
  const std::size_t at = log.find("vehicle at ", log.find("frames sent"));
  REQUIRE(at != std::string::npos);
  REQUIRE(std::sscanf(log.c_str() + at, "vehicle at %lf %lf %lf deg after %lf m", &end.x, &end.y, &thetaDeg,
                      &odometer) == 4);
  end.theta = agv::deg2rad(thetaDeg);
  const Pose2d endLaser = end.compose(mount);

  std::vector<const Sweep*> before;
  std::vector<const Sweep*> after;
  for (const Sweep& s : sweeps) {
    if (s.t < 1.5) {
      before.push_back(&s);
    }
    if (s.t > 4.5) {  // the move ended at 3 s; stopped within the deceleration
      after.push_back(&s);
    }
  }
  const double rate = sweeps.size() > 1 ? (sweeps.size() - 1) / (sweeps.back().t - sweeps.front().t) : 0.0;
  std::printf(
      "simdrives.vehicle: %zu sweeps (first at %.3f s, %.2f Hz), %zu beams, %zu / %zu reflectors "
      "before / after; moved %.3f m to %.3f %.3f %.2f deg\n",
      sweeps.size(), sweeps.empty() ? 0.0 : sweeps.front().t, rate,
      sweeps.empty() ? std::size_t{0} : sweeps.front().ranges.size(),
      before.empty() ? std::size_t{0} : before.back()->reflectors.size(),
      after.empty() ? std::size_t{0} : after.back()->reflectors.size(), odometer, end.x, end.y, thetaDeg);
  REQUIRE(before.size() >= 5);
  REQUIRE(after.size() >= 5);
  CHECK(rate > 7.5);
  CHECK(rate < 8.5);
  CHECK(odometer > 0.5);
  for (const Sweep& s : sweeps) {
    CHECK(s.ranges.size() == 360U);
    CHECK(std::fabs(s.angleIncrement - static_cast<float>(agv::deg2rad(1.0))) < 1e-5F);
  }

  // At rest, consecutive sweeps differ by the range noise only (1 cm std: mean |diff| ~1.1 cm);
  // after the move every sweep differs from the ones before it.
  const double still = meanRangeChange(*before[before.size() - 2], *before.back());
  const double stillAfter = meanRangeChange(*after[after.size() - 2], *after.back());
  const double moved = meanRangeChange(*before.back(), *after.front());
  std::printf(
      "simdrives.vehicle: mean range change %.4f m at rest before, %.4f m at rest after, %.3f m across "
      "the move\n",
      still, stillAfter, moved);
  CHECK(still < 0.03);
  CHECK(stillAfter < 0.03);
  CHECK(moved > 0.2);

  // The reflectors are where the truth puts them: the sweep's geometry survives the encoding, the
  // TCP and agvnav-vehicle's decoder (1 cm centre noise, rounding to mm and mdeg).
  REQUIRE(!before.back()->reflectors.empty());
  REQUIRE(!after.back()->reflectors.empty());
  const double errBefore = worstReflectorError(*before.back(), startLaser, world);
  const double errAfter = worstReflectorError(*after.back(), endLaser, world);
  const double errWrongPose = worstReflectorError(*after.back(), startLaser, world);
  std::printf(
      "simdrives.vehicle: worst reflector vs the world %.3f m before, %.3f m after (%.3f m placed from the "
      "start pose)\n",
      errBefore, errAfter, errWrongPose);
  CHECK(errBefore < 0.06);
  CHECK(errAfter < 0.06);
  CHECK(errWrongPose > 0.2);
}
