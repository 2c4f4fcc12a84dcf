// Reliability of agvnav-vehicle's I/O against hostile Modbus peers, as a process on loopback (label
// `reliability`): a PLC polling the status block at 50 Hz must be answered every time and see the
// heartbeat register move at its rate while, in turn, peers trickle requests one byte per 40 ms,
// pipeline requests and never read the replies, hold every connection slot before the PLC
// connects, or storm the port with 50 connecting clients. Afterwards the program's descriptors
// and RSS are back to what they were; then the peers start again and SIGTERM ends the program at once.
//
// Bounds, and why they are what they are: the design answers a request within one loop period
// (1 ms here) plus the longest cycle (docs/plc-link.md, "Timing"); on this shared 2-core machine a
// process can be descheduled for tens of milliseconds, so the assertions allow 250 ms for a reply,
// 250 ms between two heartbeat changes (nominal 20 ms) and a heartbeat rate of at least 70 % of the
// nominal 50 Hz; SIGTERM, sent while the hostile peers are active, must end the program within
// 250 ms. Each is far below what the faults cost before: a trickled request held the cycle
// 10.4 s per frame (6 heartbeats in 12.8 s), a peer that did not read blocked it in send() while
// connected, four idle connections locked the PLC out (0 of 533 polls answered), SIGTERM took 9.7 s.
// The figures measured are printed on stdout (ctest -V).
#include <arpa/inet.h>
#include <dirent.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>

#include "vehicle_process.hpp"

using agv::test::PlcHealthBit;
using agv::test::RunningVehicle;
using Clock = std::chrono::steady_clock;

namespace {

void sleepMs(int ms) {
  std::this_thread::sleep_for(std::chrono::milliseconds(ms));
}

int countFds(pid_t pid) {
  const std::string path = "/proc/" + std::to_string(pid) + "/fd";
  DIR* d = ::opendir(path.c_str());
  if (d == nullptr)
    return -1;
  int n = 0;
  while (const dirent* e = ::readdir(d)) {
    if (e->d_name[0] != '.')
      ++n;
  }
  ::closedir(d);
  return n;
}

long rssKiB(pid_t pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(f, line)) {
    if (line.rfind("VmRSS:", 0) == 0)
      return std::strtol(line.c_str() + 6, nullptr, 10);
  }
  return -1;
}

/// Waits up to 3 s for the program's descriptor count to come back to `want`; the last count.
int settleFds(pid_t pid, int want) {
  int n = countFds(pid);
  for (int i = 0; i < 60 && n != want; ++i) {
    sleepMs(50);
    n = countFds(pid);
  }
  return n;
}

/// A raw TCP connection to 127.0.0.1:`port` (-1 on failure); `rcvbuf` > 0 shrinks its receive buffer.
/// `wait` false: a non-blocking connect, left in progress.
int rawConnect(std::uint16_t port, int rcvbuf = 0, bool wait = true) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC | (wait ? 0 : SOCK_NONBLOCK), 0);
  if (rcvbuf > 0)
    (void)::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(port);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 && (wait || errno != EINPROGRESS)) {
    ::close(fd);
    return -1;
  }
  return fd;
}

/// The PLC: a libmodbus client on its own thread reading registers 0..39 every 20 ms (absolute
/// schedule), recording each reply's latency and the heartbeat register with its time.
class Plc50Hz {
 public:
  explicit Plc50Hz(std::uint16_t port) : port_(port) {
    thread_ = std::thread([this] { run(); });
  }
  ~Plc50Hz() { stop(); }
  void stop() {
    stop_ = true;
    if (thread_.joinable())
      thread_.join();
  }
  bool connected() const { return connected_.load(); }
  int polls() const { return static_cast<int>(samples_.size()) + failures_; }
  int failures() const { return failures_; }
  double worstLatencyMs() const { return worstUs_ * 1e-3; }
  /// Longest time between two heartbeat changes seen [ms].
  double longestHeartbeatGapMs() const {
    double worst = 0.0;
    for (std::size_t i = 1, since = 0; i < samples_.size(); ++i) {
      if (samples_[i].beat != samples_[since].beat) {
        worst = std::max(worst, ms(samples_[i].t - samples_[since].t));
        since = i;
      }
    }
    return worst;
  }
  /// One answered poll: when, the heartbeat register (0) and the health bits (register 2).
  struct Sample {
    Clock::time_point t;
    std::uint16_t beat;
    std::uint16_t health;
  };
  const std::vector<Sample>& samples() const { return samples_; }
  /// Heartbeat increments per second over the run.
  double heartbeatRate() const {
    if (samples_.size() < 2)
      return 0.0;
    long advance = 0;
    for (std::size_t i = 1; i < samples_.size(); ++i)
      advance += static_cast<std::uint16_t>(samples_[i].beat - samples_[i - 1].beat);
    return static_cast<double>(advance) / (ms(samples_.back().t - samples_.front().t) * 1e-3);
  }

 private:
  static double ms(Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); }
  void run() {
    modbus_t* ctx = modbus_new_tcp("127.0.0.1", port_);
    modbus_set_response_timeout(ctx, 1, 0);
    for (int i = 0; i < 40 && !stop_ && modbus_connect(ctx) != 0; ++i)
      sleepMs(25);
    connected_ = true;
    Clock::time_point next = Clock::now();
    std::uint16_t regs[40];
    while (!stop_) {
      const Clock::time_point t0 = Clock::now();
      const bool ok = modbus_read_registers(ctx, 0, 40, regs) == 40;
      const Clock::time_point t1 = Clock::now();
      worstUs_ = std::max(worstUs_, std::chrono::duration<double, std::micro>(t1 - t0).count());
      if (ok) {
        samples_.push_back({t1, regs[0], regs[2]});
      } else {
        ++failures_;
        modbus_close(ctx);  // a PLC reconnects after a failed exchange
        (void)modbus_connect(ctx);
      }
      next += std::chrono::milliseconds(20);
      std::this_thread::sleep_until(next);
    }
    modbus_close(ctx);
    modbus_free(ctx);
  }
  std::uint16_t port_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> connected_{false};
  std::vector<Sample> samples_;
  int failures_ = 0;
  double worstUs_ = 0.0;
  std::thread thread_;
};

/// One hostile-peer scenario: the program up (set up by `setup`: a laser peer, configuration keys),
/// its own PLC connection closed; `hostileBeforePlc` starts before the PLC connects (slot holders)
/// and `hostile` while it polls for `windowMs` (~3 s); then every peer goes, and the figures are
/// checked and printed.
struct Figures {
  int polls = 0, failures = 0;
  double worstLatencyMs = 0, longestGapMs = 0, rate = 0, sigtermMs = 0;
  int fdsBefore = 0, fdsAfter = 0, newFds = 0;
  long rssBefore = 0, rssAfter = 0;
  int exitCode = -1;
  std::string log;
  std::vector<Plc50Hz::Sample> samples;  ///< the PLC's answered polls while the peers were at it
  /// The number printed before `what` in the program's "modbus:" exit line (-1 when absent).
  long counter(const std::string& what) const {
    const std::size_t line = log.find("modbus: ");
    const std::size_t at = log.find(" " + what, line);
    if (line == std::string::npos || at == std::string::npos)
      return -1;
    const std::size_t start = log.rfind(' ', at - 1);
    return std::strtol(log.c_str() + start + 1, nullptr, 10);
  }
};

/// `newFds`: descriptors the program is expected to open during the window (the connection to a
/// laser that came up).
template <typename Hostile>
Figures runScenario(const char* name, bool hostileBeforePlc, Hostile hostile, const agv::test::VehicleSetup& setup = {},
                    int windowMs = 3000, int newFds = 0) {
  Figures f;
  RunningVehicle v("modbus.idle_timeout = 2\n", setup);
  REQUIRE(v.ready());
  modbus_close(v.plc);  // the scenario's PLC connects by itself
  sleepMs(200);
  f.fdsBefore = countFds(v.pid());
  f.rssBefore = rssKiB(v.pid());
  std::atomic<bool> stop{false};
  std::thread peers;
  std::unique_ptr<Plc50Hz> plc;
  if (hostileBeforePlc) {
    peers = std::thread([&] { hostile(v.modbusPort(), stop); });
    sleepMs(300);
  }
  plc = std::make_unique<Plc50Hz>(v.modbusPort());
  if (!hostileBeforePlc) {
    sleepMs(300);
    peers = std::thread([&] { hostile(v.modbusPort(), stop); });
  }
  sleepMs(windowMs);
  stop = true;
  peers.join();
  plc->stop();
  f.samples = plc->samples();
  f.polls = plc->polls();
  f.failures = plc->failures();
  f.worstLatencyMs = plc->worstLatencyMs();
  f.longestGapMs = plc->longestHeartbeatGapMs();
  f.rate = plc->heartbeatRate();
  f.newFds = newFds;
  f.fdsAfter = settleFds(v.pid(), f.fdsBefore + newFds);
  f.rssAfter = rssKiB(v.pid());
  // SIGTERM while the hostile peers are at it again.
  stop = false;
  peers = std::thread([&] { hostile(v.modbusPort(), stop); });
  sleepMs(500);
  const Clock::time_point t0 = Clock::now();
  f.exitCode = v.terminate();
  f.sigtermMs = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  stop = true;
  peers.join();
  std::printf(
      "reliability %-14s polls %4d failed %d | worst PLC reply %6.2f ms | heartbeat %5.1f Hz, longest gap %6.1f ms | "
      "fds %d -> %d | RSS %ld -> %ld KiB | SIGTERM -> exit %d in %.1f ms\n",
      name, f.polls, f.failures, f.worstLatencyMs, f.rate, f.longestGapMs, f.fdsBefore, f.fdsAfter, f.rssBefore,
      f.rssAfter, f.exitCode, f.sigtermMs);
  std::fflush(stdout);
  f.log = v.log();
  const std::size_t counters = f.log.find("agvnav-vehicle: loop:");
  std::printf("%s", counters == std::string::npos ? f.log.c_str() : f.log.c_str() + counters);
  std::fflush(stdout);
  return f;
}

void checkFigures(const Figures& f, int windowMs = 3000) {
  INFO(f.log);
  CHECK(f.failures == 0);
  CHECK(f.polls >= 120 * (windowMs + 300) / 3300);  // ~165 at 50 Hz over 3.3 s
  CHECK(f.worstLatencyMs < 250.0);
  CHECK(f.longestGapMs < 250.0);
  CHECK(f.rate > 35.0);  // 70 % of 50 Hz
  CHECK(f.fdsAfter == f.fdsBefore + f.newFds);
  CHECK(f.rssAfter - f.rssBefore < 1024);
  CHECK(f.exitCode == 0);
  CHECK(f.sigtermMs < 250.0);
}

}  // namespace

TEST_CASE("reliability: peers trickling a request one byte per 40 ms", "[reliability][trickle]") {
  const Figures f = runScenario("trickle", false, [](std::uint16_t port, std::atomic<bool>& stop) {
    const std::uint8_t read[12] = {0x00, 0x01, 0x00, 0x00, 0x00, 0x06, 0xFF, 0x03, 0x00, 0x00, 0x00, 0x28};
    auto trickle = [&] {
      while (!stop) {
        const int fd = rawConnect(port);
        for (std::size_t i = 0; fd >= 0 && !stop; i = (i + 1) % sizeof read) {
          if (::send(fd, read + i, 1, MSG_NOSIGNAL) != 1)
            break;  // dropped by the vehicle: connect again
          sleepMs(40);
        }
        if (fd >= 0)
          ::close(fd);
      }
    };
    std::thread second(trickle);
    trickle();
    second.join();
  });
  checkFigures(f);
  CHECK(f.counter("request timeouts") >= 20);  // each trickled request was dropped at the 50 ms bound
}

TEST_CASE("reliability: a peer pipelining requests and never reading the replies", "[reliability][noread]") {
  const Figures f = runScenario("never-reading", false, [](std::uint16_t port, std::atomic<bool>& stop) {
    const std::uint8_t read[12] = {0x00, 0x01, 0x00, 0x00, 0x00, 0x06, 0xFF, 0x03, 0x00, 0x00, 0x00, 110};
    while (!stop) {
      const int fd = rawConnect(port, 4096);
      while (fd >= 0 && !stop) {
        pollfd p{fd, POLLOUT, 0};
        if (::poll(&p, 1, 10) == 1) {
          if ((p.revents & (POLLERR | POLLHUP)) != 0 ||
              ::send(fd, read, sizeof read, MSG_NOSIGNAL | MSG_DONTWAIT) != static_cast<ssize_t>(sizeof read))
            break;
        }
      }
      if (fd >= 0)
        ::close(fd);
    }
  });
  checkFigures(f);
  CHECK(f.counter("send failures") >= 1);  // the peer was dropped when its send buffer was full
}

TEST_CASE("reliability: six idle connections hold the slots before the PLC connects", "[reliability][holders]") {
  const Figures f = runScenario("idle-holders", true, [](std::uint16_t port, std::atomic<bool>& stop) {
    std::vector<int> fds;
    for (int i = 0; i < 6; ++i)
      fds.push_back(rawConnect(port));
    while (!stop)
      sleepMs(10);
    for (const int fd : fds)
      if (fd >= 0)
        ::close(fd);
  });
  checkFigures(f);
  CHECK(f.counter("evictions") >= 3);  // the late holders and the PLC took the slots of the early ones
}

TEST_CASE("reliability: a storm of 50 connecting clients, again and again", "[reliability][storm]") {
  const Figures f = runScenario("storm-50", false, [](std::uint16_t port, std::atomic<bool>& stop) {
    while (!stop) {
      std::vector<int> fds;
      for (int i = 0; i < 50 && !stop; ++i)
        fds.push_back(rawConnect(port, 0, false));  // 50 SYNs at once: no waiting for each accept
      sleepMs(100);
      for (const int fd : fds)
        if (fd >= 0)
          ::close(fd);
    }
  });
  checkFigures(f);
  CHECK(f.counter("connects") >= 500);   // the storms reached the program (50 every ~100 ms) ...
  CHECK(f.counter("evictions") >= 500);  // ... and evicted each other, never the polling PLC
}

TEST_CASE("reliability: the PLC connects in the middle of a storm", "[reliability][stormfirst]") {
  const Figures f = runScenario("storm-first", true, [](std::uint16_t port, std::atomic<bool>& stop) {
    while (!stop) {
      std::vector<int> fds;
      for (int i = 0; i < 50 && !stop; ++i)
        fds.push_back(rawConnect(port, 0, false));
      sleepMs(100);
      for (const int fd : fds)
        if (fd >= 0)
          ::close(fd);
    }
  });
  checkFigures(f);
}

namespace {

/// The first answered poll at or after `from` whose health bits satisfy `holds`; nullptr when none.
template <typename Holds>
const Plc50Hz::Sample* firstSample(const Figures& f, Clock::time_point from, Holds holds) {
  for (const Plc50Hz::Sample& s : f.samples)
    if (s.t >= from && holds(s.health))
      return &s;
  return nullptr;
}

bool laserOk(std::uint16_t health) {
  return (health & static_cast<std::uint16_t>(PlcHealthBit::LaserOk)) != 0U;
}

double msBetween(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

/// A CoLa A laser that reboots when asked, as after a power cut: its connection goes silent
/// without being closed (no FIN: the vehicle has only its silence check to notice) and the port
/// refuses connections for `downMs` while the device boots; then it listens on the same port again
/// and streams to the next connection. Only the first request reboots it. `bootAtStart`: the laser
/// is still booting when the program starts (its port refuses connections, `VehicleSetup::laserUp`
/// false) and comes up when asked.
struct RebootingLaser {
  bool bootAtStart = false;
  int downMs = 1500;
  std::atomic<bool> reboot{false};
  std::atomic<int> subscriptions{0};
  std::atomic<int> connectionsAfter{0};  ///< connections accepted after coming back
  bool relistened = true;
  Clock::time_point rebootAt{}, backAt{};  ///< read once the laser thread is joined

  void run(agv::test::LoopbackServer& s, const std::atomic<bool>& stop) {
    bool back = false;
    if (bootAtStart) {
      while (!reboot && !stop)
        sleepMs(1);
      comeBack(s, back);
    }
    while (!stop) {
      const int fd = s.accept(50);
      if (fd < 0)
        continue;
      connectionsAfter += back ? 1 : 0;
      agv::test::streamColaScans(s, fd, subscriptions, [&] { return !stop && !(reboot && !back); });
      if (reboot && !back && !stop) {
        s.stopListening();
        rebootAt = Clock::now();
        for (int i = 0; i < downMs / 10 && !stop; ++i)
          sleepMs(10);
        comeBack(s, back);
      }
      ::close(fd);  // the device lost the old connection when it rebooted
    }
  }

 private:
  void comeBack(agv::test::LoopbackServer& s, bool& back) {
    relistened = s.listenAgain();
    backAt = Clock::now();
    back = true;
  }
};

/// The laser goes down for 1.5 s while the PLC polls (or, `bootAtStart`, comes up 0.3 s into the
/// PLC's polls, having refused connections since the program started), with `laser.scan_timeout`
/// and `laser.reconnect_interval` as given; the figures and the laser's recovery are checked.
void laserReboot(const char* name, const char* scanTimeout, const char* reconnectInterval, bool bootAtStart = false) {
  RebootingLaser laser;
  laser.bootAtStart = bootAtStart;
  agv::test::VehicleSetup setup;
  setup.settings = {{"laser.scan_timeout", scanTimeout}, {"laser.reconnect_interval", reconnectInterval}};
  setup.laser = [&laser](agv::test::LoopbackServer& s, const std::atomic<bool>& stop) { laser.run(s, stop); };
  setup.laserUp = !bootAtStart;
  bool first = true;
  const int windowMs = 4000;
  const Figures f = runScenario(
      name, false,
      [&](std::uint16_t, std::atomic<bool>& stop) {
        laser.reboot = first;  // the second run (SIGTERM while the peers are at it) leaves the laser up
        first = false;
        while (!stop)
          sleepMs(10);
      },
      setup, windowMs, bootAtStart ? 1 : 0);
  checkFigures(f, windowMs);
  INFO(f.log);
  REQUIRE(laser.relistened);
  REQUIRE(laser.backAt > laser.rebootAt);
  const double interval = std::strtod(reconnectInterval, nullptr) * 1e3;
  const double timeout = std::strtod(scanTimeout, nullptr) * 1e3;
  REQUIRE_FALSE(f.samples.empty());
  const Plc50Hz::Sample* okBefore = firstSample(f, Clock::time_point{}, laserOk);
  const Plc50Hz::Sample* lost = firstSample(f, laser.rebootAt, [](std::uint16_t h) { return !laserOk(h); });
  const Plc50Hz::Sample* back = firstSample(f, laser.backAt, laserOk);
  REQUIRE(okBefore != nullptr);
  if (bootAtStart) {
    CHECK_FALSE(laserOk(f.samples.front().health));  // not ok while it boots
  } else {
    // Laser ok before the reboot, cleared while it was down (after scan_timeout without a sweep).
    CHECK(okBefore->t < laser.rebootAt);
    REQUIRE(lost != nullptr);
    CHECK(lost->t < laser.backAt);
    CHECK(msBetween(laser.rebootAt, lost->t) < timeout + 250.0);
  }
  REQUIRE(back != nullptr);
  const double recoveryMs = msBetween(laser.backAt, back->t);
  // Stays ok to the end: the new connection is not closed by the silence check.
  const Plc50Hz::Sample* flap = firstSample(f, back->t, [](std::uint16_t h) { return !laserOk(h); });
  const std::string outage = bootAtStart ? std::string("laser booting since the program started")
                                         : "laser ok cleared " +
                                               std::to_string(std::lround(msBetween(laser.rebootAt, lost->t))) +
                                               " ms after the reboot";
  std::printf(
      "reliability %-14s scan_timeout %s s, reconnect_interval %s s: %s, back %.0f ms after the laser (bound "
      "%.0f ms); %d connection(s) after it\n",
      name, scanTimeout, reconnectInterval, outage.c_str(), recoveryMs, interval + 250.0,
      laser.connectionsAfter.load());
  std::fflush(stdout);
  // One reconnect interval to the next attempt, then a scan (sent at once), one publication (20 ms)
  // and one poll (20 ms): within the interval and the suite's 250 ms for a loaded machine.
  CHECK(recoveryMs < interval + 250.0);
  CHECK(flap == nullptr);
  CHECK(laser.connectionsAfter.load() == 1);  // starved connections were opened and closed again and again
}

/// A NAV350 answering each pose request at its 8 Hz: good replies (no reflector) until `errors`,
/// then only error replies (error code 4, no pose, no landmarks).
struct Nav350Peer {
  std::atomic<bool> errors{false};
  std::atomic<int> errorReplies{0};
  Clock::time_point lastGood{}, firstError{};  ///< read once the laser thread is joined

  void run(agv::test::LoopbackServer& s, const std::atomic<bool>& stop) {
    agv::test::NavReplyFields bad;
    bad.errorCode = 4;  // no position
    bad.pose = false;
    bad.poseDetails = false;
    bad.landmarks = false;
    const auto good = agv::test::colaB(agv::test::buildNavReply(agv::test::NavReplyFields{}));
    const auto failed = agv::test::colaB(agv::test::buildNavReply(bad));
    int fd = -1;
    while (fd < 0 && !stop)
      fd = s.accept(50);
    Clock::time_point next = Clock::now();
    while (fd >= 0 && !stop) {
      // A CoLa B request: 4 STX bytes, a 32-bit big-endian length, the payload, a checksum byte.
      const auto head = s.read(fd, 8, 1000);
      if (head.size() != 8)
        break;
      const std::size_t length = (std::size_t{head[4]} << 24) | (std::size_t{head[5]} << 16) |
                                 (std::size_t{head[6]} << 8) | std::size_t{head[7]};
      if (length > 1024 || s.read(fd, length + 1, 1000).size() != length + 1)
        break;
      next += std::chrono::milliseconds(125);
      std::this_thread::sleep_until(next);
      const bool error = errors.load();
      const Clock::time_point now = Clock::now();  // before the send: the vehicle receives it later
      if (error && errorReplies.load() == 0)
        firstError = now;
      if (!error)
        lastGood = now;
      errorReplies += error ? 1 : 0;
      s.send(fd, error ? failed : good);
    }
    if (fd >= 0)
      ::close(fd);
  }
};

}  // namespace

TEST_CASE("reliability: the laser reboots, scan_timeout equal to reconnect_interval (0.5 s / 0.5 s)",
          "[reliability][laserreboot]") {
  laserReboot("reboot-equal", "0.5", "0.5");
}

TEST_CASE("reliability: the laser reboots, scan_timeout below reconnect_interval (0.2 s / 1 s)",
          "[reliability][laserreboot_slowretry]") {
  laserReboot("reboot-slow", "0.2", "1.0");
}

TEST_CASE("reliability: the laser reboots, scan_timeout above reconnect_interval (1 s / 0.2 s)",
          "[reliability][laserreboot_fastretry]") {
  laserReboot("reboot-fast", "1.0", "0.2");
}

TEST_CASE("reliability: the laser boots after the program, scan_timeout equal to reconnect_interval (0.5 s / 0.5 s)",
          "[reliability][laserboot]") {
  laserReboot("boot-equal", "0.5", "0.5", true);
}

TEST_CASE("reliability: a NAV350 answering only with error replies", "[reliability][nav350errors]") {
  Nav350Peer nav;
  agv::test::VehicleSetup setup;
  setup.settings = {{"laser.model", "nav350"}, {"laser.scan_timeout", "0.5"}};
  setup.laser = [&nav](agv::test::LoopbackServer& s, const std::atomic<bool>& stop) { nav.run(s, stop); };
  const Figures f = runScenario(
      "nav350-errors", false,
      [&](std::uint16_t, std::atomic<bool>& stop) {
        nav.errors = true;
        while (!stop)
          sleepMs(10);
      },
      setup);
  checkFigures(f);
  INFO(f.log);
  REQUIRE(nav.errorReplies.load() >= 10);  // ~24 over 3 s at 8 Hz
  const Plc50Hz::Sample* okBefore = firstSample(f, Clock::time_point{}, laserOk);
  const Plc50Hz::Sample* cleared = firstSample(f, nav.firstError, [](std::uint16_t h) { return !laserOk(h); });
  REQUIRE(okBefore != nullptr);
  CHECK(okBefore->t < nav.firstError);
  REQUIRE(cleared != nullptr);
  const double afterGoodMs = msBetween(nav.lastGood, cleared->t);
  // Never ok again while the errors go on; never "laser timeout" either: the device answers.
  const Plc50Hz::Sample* again = firstSample(f, cleared->t, laserOk);
  const auto timeoutBit = static_cast<std::uint16_t>(PlcHealthBit::LaserTimeout);
  const Plc50Hz::Sample* timedOut =
      firstSample(f, Clock::time_point{}, [&](std::uint16_t h) { return (h & timeoutBit) != 0U; });
  std::printf(
      "reliability %-14s %d error replies; laser ok cleared %.0f ms after the last good reply (scan_timeout "
      "500 ms, bound 750 ms)\n",
      "nav350-errors", nav.errorReplies.load(), afterGoodMs);
  std::fflush(stdout);
  CHECK(afterGoodMs >= 500.0);  // not before scan_timeout since the last good sweep
  CHECK(afterGoodMs < 500.0 + 250.0);
  CHECK(again == nullptr);
  CHECK(timedOut == nullptr);
}

TEST_CASE("reliability: special files, a directory and cut files are refused at once", "[reliability][badfiles]") {
  agv::test::TempFolder dir;
  REQUIRE(dir.ok());
  const std::string fifo = dir.track("peer.fifo");
  REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
  const std::string calibration = agv::test::goodCalibration();
  const std::string map = agv::test::goodMap();
  const std::string cutMap = dir.write("cut-map.txt", map.substr(0, map.find("reflector 3")));
  const std::string cutCalibration =
      dir.write("cut-calibration.txt", calibration.substr(0, calibration.find("laser_theta 0.0") + 13U));
  const std::string config =
      agv::test::goodVehicleConfig("agvcan7", "127.0.0.1", agv::test::closedPort(), agv::test::closedPort());
  dir.write("calibration.txt", calibration);
  dir.write("landmarks.txt", map);
  struct Case {
    const char* key;  ///< the configuration key given `path`; nullptr: `path` is the configuration
    std::string path;
    std::string says;
  };
  const Case cases[] = {
      {nullptr, "/dev/zero", "/dev/zero: not a regular file"},
      {nullptr, fifo, fifo + ": not a regular file"},
      {nullptr, dir.path(), dir.path() + ": a directory"},
      {"calibration.file", "/dev/zero", "calibration.file: refused: cannot read /dev/zero: not a regular file"},
      {"calibration.file", fifo, "calibration.file: refused: cannot read " + fifo + ": not a regular file"},
      {"calibration.file", dir.path(), "calibration.file: refused: cannot read " + dir.path() + ": a directory"},
      {"calibration.file", cutCalibration, cutCalibration + ":8: calibration.file: refused: the file ends without"},
      {"map.file", "/dev/zero", "map.file: refused: cannot read /dev/zero: not a regular file"},
      {"map.file", fifo, "map.file: refused: cannot read " + fifo + ": not a regular file"},
      {"map.file", dir.path(), "map.file: refused: cannot read " + dir.path() + ": a directory"},
      {"map.file", cutMap, cutMap + ":3: map.file: refused: the file ends without its 'end <count>' line"},
  };
  double worstMs = 0.0;
  for (const Case& c : cases) {
    const std::string conf =
        c.key == nullptr ? c.path : dir.write("vehicle.conf", agv::test::withValue(config, c.key, c.path));
    std::string log;
    const Clock::time_point t0 = Clock::now();
    const int rc = agv::test::runVehicle({"--config", conf}, dir, log);
    const double ms = msBetween(t0, Clock::now());
    worstMs = std::max(worstMs, ms);
    INFO((c.key != nullptr ? c.key : "--config") << " = " << c.path << ": " << log);
    std::printf("reliability badfiles  %-16s %-40s exit %d in %6.1f ms: %s", c.key != nullptr ? c.key : "--config",
                c.path.c_str(), rc, ms, log.c_str());
    CHECK(rc == 2);
    CHECK(ms < 2000.0);  // used to be: /dev/zero std::bad_alloc after 16-19 s, a FIFO hung
    CHECK(log.find(c.says) != std::string::npos);
  }
  std::printf("reliability badfiles  worst %.1f ms\n", worstMs);
  std::fflush(stdout);
}
