// SickLaserSource (hal::LaserSource over the SICK TCP clients) against a loopback peer speaking
// CoLa A / binary CoLa: polled without waiting, sweeps in order, reconnection after a drop,
// a silent laser reported and reconnected, an unreachable one reported, NAV350 reflectors in the
// sensor frame, and no allocation in any read().
#include <atomic>
#include <cmath>
#include <cstring>
#include <ctime>
#include <string>
#include <vector>

#include "agv/core/angle.hpp"
#include "agv/drivers/linux/sick_laser_source.hpp"
#include "agv_test.hpp"
#include "loopback_server.hpp"
#include "sick_telegrams.hpp"

using agv::Duration;
using agv::Status;
using agv::drivers::SickLaserModel;
using agv::drivers::SickLaserSource;
using agv::drivers::SickLaserSourceConfig;
using agv::hal::LaserMeasurement;

namespace {

SickLaserSourceConfig loopbackConfig(SickLaserModel model, std::uint16_t port) {
  SickLaserSourceConfig c;
  c.model = model;
  std::strcpy(c.tcp.host, "127.0.0.1");
  c.tcp.port = port;
  c.tcp.connectTimeout = Duration::fromMilliseconds(500);
  c.tcp.reconnectInterval = Duration::fromMilliseconds(50);
  c.connectBudget = Duration::fromMilliseconds(100);
  c.scanTimeout = Duration::fromMilliseconds(300);
  agv::drivers::applyModelRanges(model, c.scan, c.nav);
  return c;
}

void sleepMs(int ms) {
  timespec t{0, static_cast<long>(ms) * 1000000L};
  (void)nanosleep(&t, nullptr);
}

/// Polls `read()` (1 ms apart, at most `ms` times) until it returns `want`; counts the
/// allocations inside the read() calls and the other results seen.
struct Poller {
  SickLaserSource& src;
  std::uint64_t allocs = 0;
  int notFound = 0;
  Status poll(LaserMeasurement& m, Status want, int ms) {
    Status s = Status::NotFound;
    const agv::Timestamp end = agv::drivers::monotonicNow() + Duration::fromMilliseconds(ms);
    for (int i = 0; i < ms && agv::drivers::monotonicNow() < end; ++i) {
      allocs += agv::test::countAllocations([&]() { s = src.read(m); });
      if (s == want) {
        return s;
      }
      notFound += s == Status::NotFound ? 1 : 0;
      sleepMs(1);
    }
    return s;
  }
};

const std::vector<std::uint8_t> kSubscribe = agv::test::stxEtx("sEN LMDscandata 1");

/// Receives exactly `want.size()` bytes (bounded wait) and compares them, without allocating: the
/// peer thread runs while the source's read() calls are counted for allocations (process-wide).
bool receiveExactly(int fd, const std::vector<std::uint8_t>& want, int ms = 5000) {
  std::uint8_t buf[256];
  if (want.size() > sizeof buf)
    return false;
  std::size_t got = 0;
  for (int i = 0; i < ms / 10 && got < want.size(); ++i) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 10) != 1)
      continue;
    const ssize_t n = ::recv(fd, buf + got, want.size() - got, 0);
    if (n <= 0)
      return false;
    got += static_cast<std::size_t>(n);
  }
  return got == want.size() && std::memcmp(buf, want.data(), got) == 0;
}

}  // namespace

TEST_CASE("SICK laser source: polled stream, noise, drop and reconnection", "[drivers][laser]") {
  agv::test::LoopbackServer server;
  REQUIRE(server.ok());
  std::atomic<int> subscriptions{0};
  std::atomic<bool> done{false};
  std::vector<std::uint8_t> first = {'n', 'o', 'i', 's', 'e'};
  const auto a = agv::test::colaScanTelegram(1, 1000);
  first.insert(first.end(), a.begin(), a.end());
  const auto b = agv::test::colaScanTelegram(2, 2000);
  const auto c = agv::test::colaScanTelegram(3, 3000);
  const std::vector<std::uint8_t> halfC(c.begin(), c.begin() + static_cast<std::ptrdiff_t>(c.size() / 2));
  const auto d = agv::test::colaScanTelegram(4, 4000);
  server.start([&](agv::test::LoopbackServer& s) {
    int fd = s.accept();
    if (fd < 0)
      return;
    if (receiveExactly(fd, kSubscribe))
      ++subscriptions;
    sleepMs(50);  // the source is polled meanwhile and has nothing
    s.send(fd, first, 29);
    s.send(fd, b, 1000);
    s.send(fd, halfC);
    sleepMs(20);
    ::close(fd);  // dropped in the middle of C
    fd = s.accept();
    if (fd < 0)
      return;
    if (receiveExactly(fd, kSubscribe))
      ++subscriptions;
    s.send(fd, d);
    for (int i = 0; i < 300 && !done.load(); ++i)
      sleepMs(10);
    ::close(fd);
  });

  SickLaserSource src(loopbackConfig(SickLaserModel::Lms1xx, server.port()));
  static LaserMeasurement m;
  m.hasReflectors = true;
  Poller p{src};
  CHECK(src.health() == Status::NotInitialized);
  for (std::uint32_t expected : {1000U, 2000U, 4000U}) {
    REQUIRE(p.poll(m, Status::Ok, 3000) == Status::Ok);
    REQUIRE(m.scan.size() == 10U);
    AGV_CHECK_NEAR(m.scan.ranges[0], expected * 1e-3, 1e-6);
    AGV_CHECK_NEAR(m.scan.ranges[9], (expected + 9) * 1e-3, 1e-6);
    AGV_CHECK_NEAR(m.scan.angleMin, agv::deg2rad(-135.0), 1e-6);
    CHECK_FALSE(m.hasReflectors);
    CHECK(src.health() == Status::Ok);
  }
  done = true;
  server.join();
  CHECK(p.notFound > 0);  // read() came back empty-handed instead of waiting
  CHECK(p.allocs == 0U);
  CHECK(subscriptions.load() == 2);
  CHECK(src.counters().sweeps == 3U);
  CHECK(src.counters().malformed == 0U);
  CHECK(src.framerCounters().garbageBytes == 5U);
  CHECK(src.framerCounters().truncated == 1U);
  CHECK(src.tcpCounters().connects == 2U);
}

TEST_CASE("SICK laser source: a silent laser is a timeout and is reconnected", "[drivers][laser]") {
  agv::test::LoopbackServer server;
  REQUIRE(server.ok());
  std::atomic<int> subscriptions{0};
  const auto e = agv::test::colaScanTelegram(7, 1500);
  server.start([&](agv::test::LoopbackServer& s) {
    int fd = s.accept();
    if (fd < 0)
      return;
    if (receiveExactly(fd, kSubscribe))
      ++subscriptions;
    // Stays silent on this connection; the source gives up on it and connects again.
    const int fd2 = s.accept();
    ::close(fd);
    if (fd2 < 0)
      return;
    if (receiveExactly(fd2, kSubscribe))
      ++subscriptions;
    s.send(fd2, e);
    agv::test::LoopbackServer::drainAndClose(fd2, 300);
  });
  SickLaserSource src(loopbackConfig(SickLaserModel::Lms5xx, server.port()));
  static LaserMeasurement m;
  Poller p{src};
  CHECK(p.poll(m, Status::Timeout, 3000) == Status::Timeout);
  CHECK(src.health() == Status::Timeout);
  REQUIRE(p.poll(m, Status::Ok, 3000) == Status::Ok);
  AGV_CHECK_NEAR(m.scan.ranges[0], 1.5, 1e-6);
  CHECK(src.counters().silenceReconnects == 1U);
  CHECK(src.health() == Status::Ok);
  CHECK(p.allocs == 0U);
  server.join();
  CHECK(subscriptions.load() == 2);
}

TEST_CASE("SICK laser source: an unreachable laser is a timeout, retried at the interval", "[drivers][laser]") {
  SickLaserSource src(loopbackConfig(SickLaserModel::Tim, agv::test::closedPort()));
  static LaserMeasurement m;
  Poller p{src};
  CHECK(p.poll(m, Status::Timeout, 3000) == Status::Timeout);
  CHECK(p.notFound > 0);  // within the scan timeout: nothing yet, no fault
  CHECK(src.health() == Status::Timeout);
  CHECK_FALSE(src.connected());
  CHECK(src.tcpCounters().connectFailures >= 2U);
  CHECK(src.tcpCounters().connects == 0U);
  CHECK(p.allocs == 0U);
}

namespace {
/// A CoLa A laser on `server`: accepts one connection, waits for the subscription, then sends
/// `telegrams` 100 ms apart (each read on its own by the source), and closes after 300 ms.
void serveOneByOne(agv::test::LoopbackServer& server, std::vector<std::vector<std::uint8_t>> telegrams) {
  server.start([telegrams](agv::test::LoopbackServer& s) {
    const int fd = s.accept();
    if (fd < 0)
      return;
    (void)receiveExactly(fd, kSubscribe);
    for (std::size_t i = 0; i < telegrams.size(); ++i) {
      if (i > 0)
        sleepMs(100);
      s.send(fd, telegrams[i]);
    }
    agv::test::LoopbackServer::drainAndClose(fd, 300);
  });
}
}  // namespace

TEST_CASE("SICK laser source: a malformed scan telegram is reported", "[drivers][laser]") {
  agv::test::LoopbackServer server;
  REQUIRE(server.ok());
  const auto bad = agv::test::stxEtx("sSN LMDscandata 1 zz");
  const auto good = agv::test::colaScanTelegram(1, 900);
  serveOneByOne(server, {bad, good});
  SickLaserSource src(loopbackConfig(SickLaserModel::Lms1xx, server.port()));
  static LaserMeasurement m;
  Poller p{src};
  CHECK(p.poll(m, Status::Malformed, 3000) == Status::Malformed);
  REQUIRE(p.poll(m, Status::Ok, 3000) == Status::Ok);
  CHECK(m.scan.size() == 10U);
  CHECK(src.counters().malformed == 1U);
  CHECK(p.allocs == 0U);
}

TEST_CASE("SICK laser source: implausible scan telegrams are refused and counted, not taken as sweeps",
          "[drivers][laser]") {
  agv::test::LoopbackServer server;
  REQUIRE(server.ok());
  // Well-formed telegrams with a scale factor of 3.4e38 and an offset of 1e30 mm.
  agv::test::ColaScanFields hugeScale;
  agv::test::ColaChannel c;
  c.values.assign(10, 900);
  c.scale = 3.4e38F;
  hugeScale.channels16.push_back(c);
  agv::test::ColaScanFields hugeOffset;
  c.scale = 1.0F;
  c.offset = 1e30F;
  hugeOffset.channels16.push_back(c);
  const auto bad1 = agv::test::stxEtx(agv::test::buildColaScan(hugeScale));
  const auto bad2 = agv::test::stxEtx(agv::test::buildColaScan(hugeOffset));
  const auto good = agv::test::colaScanTelegram(1, 900);
  serveOneByOne(server, {bad1, bad2, good});
  SickLaserSource src(loopbackConfig(SickLaserModel::Lms1xx, server.port()));
  static LaserMeasurement m;
  Poller p{src};
  REQUIRE(p.poll(m, Status::Ok, 3000) == Status::Ok);
  CHECK(m.scan.size() == 10U);
  AGV_CHECK_NEAR(m.scan.ranges[0], 0.9, 1e-6);
  CHECK(src.counters().sweeps == 1U);
  CHECK(src.counters().implausible == 2U);
  CHECK(src.counters().malformed == 2U);
  CHECK(p.allocs == 0U);
}

TEST_CASE("SICK laser source: NAV350 replies give scan and reflectors in the sensor frame", "[drivers][laser]") {
  agv::test::LoopbackServer server;
  REQUIRE(server.ok());
  std::uint8_t payload[32];
  const std::size_t n = agv::drivers::sick::encodeNav350PoseRequest(
      true, agv::drivers::sick::Nav350Mask::PoseReflectorsScan, agv::Span<std::uint8_t>(payload));
  const auto request = agv::test::colaB(std::vector<std::uint8_t>(payload, payload + n));
  agv::test::NavReplyFields f;
  f.reflectors.resize(3);
  for (std::size_t i = 0; i < 3; ++i) {
    f.reflectors[i].distMm = static_cast<std::uint32_t>(4000 + 500 * i);
    f.reflectors[i].phiMdeg = static_cast<std::uint32_t>(30000 + 60000 * i);  // 30, 90, 150 deg
    // Seen a sixth of a turn (125 ms / 6) apart; the pose follows 20 ms after the last one.
    f.reflectors[i].timestampMs = static_cast<std::uint32_t>(50000 + 21 * i);
  }
  f.poseTimestampMs = 50000 + 42 + 20;
  f.scanTimestampMs = 50000;
  f.scan = true;
  f.startMdeg = 0;
  f.stepMdeg = 250;
  f.distMm.assign(1440, 5000U);
  const auto reply = agv::test::colaB(agv::test::buildNavReply(f));
  agv::test::NavReplyFields bad;
  bad.errorCode = 4;  // no position
  bad.pose = false;
  bad.poseDetails = false;
  bad.landmarks = false;
  const auto failed = agv::test::colaB(agv::test::buildNavReply(bad));
  std::atomic<int> requests{0};
  server.start([&](agv::test::LoopbackServer& s) {
    const int fd = s.accept();
    if (fd < 0)
      return;
    for (int i = 0; i < 3; ++i) {
      if (!receiveExactly(fd, request))
        break;
      ++requests;
      s.send(fd, i == 1 ? failed : reply, 300);
    }
    agv::test::LoopbackServer::drainAndClose(fd, 300);
  });
  SickLaserSourceConfig cfg = loopbackConfig(SickLaserModel::Nav350, server.port());
  SickLaserSource src(cfg);
  static LaserMeasurement m;
  Poller p{src};
  REQUIRE(p.poll(m, Status::Ok, 3000) == Status::Ok);
  CHECK(m.hasReflectors);
  REQUIRE(m.reflectors.size() == 3U);
  for (std::size_t i = 0; i < 3; ++i) {
    const double range = 4.0 + 0.5 * static_cast<double>(i);
    const double bearing = agv::deg2rad(30.0 + 60.0 * static_cast<double>(i));
    AGV_CHECK_NEAR(m.reflectors[i].x, range * std::cos(bearing), 1e-5);
    AGV_CHECK_NEAR(m.reflectors[i].y, range * std::sin(bearing), 1e-5);
    // Stamped on the vehicle clock: the reply's newest device instant (the pose) at its
    // reception, which stamps the sweep.
    REQUIRE(m.reflectors[i].stamped);
    CHECK(m.scan.stamp - m.reflectors[i].stamp == agv::Duration::fromMilliseconds(62 - 21 * static_cast<int>(i)));
  }
  REQUIRE(m.scan.size() == 1440U);
  AGV_CHECK_NEAR(m.scan.ranges[100], 5.0, 1e-6);
  // The second reply says "no position": a device fault; the third is fine again.
  CHECK(p.poll(m, Status::DeviceFault, 3000) == Status::DeviceFault);
  REQUIRE(p.poll(m, Status::Ok, 3000) == Status::Ok);
  CHECK(m.reflectors.size() == 3U);
  CHECK(src.counters().deviceErrors == 1U);
  CHECK(src.counters().sweeps == 2U);
  CHECK(p.allocs == 0U);
  server.join();
  CHECK(requests.load() == 3);
}

TEST_CASE("SICK laser model names", "[drivers][laser]") {
  SickLaserModel model = SickLaserModel::Lms1xx;
  for (SickLaserModel m :
       {SickLaserModel::Lms1xx, SickLaserModel::Lms5xx, SickLaserModel::Tim, SickLaserModel::Nav350}) {
    REQUIRE(agv::drivers::parseSickLaserModel(agv::drivers::toString(m), model));
    CHECK(model == m);
  }
  CHECK_FALSE(agv::drivers::parseSickLaserModel("lms200", model));
  CHECK_FALSE(agv::drivers::parseSickLaserModel(nullptr, model));
  CHECK(agv::drivers::defaultPort(SickLaserModel::Nav350) == 2112U);
  CHECK(agv::drivers::defaultPort(SickLaserModel::Tim) == 2111U);
}

TEST_CASE("SICK laser source: with scanTimeout equal to reconnectInterval a rebooted laser is back within one interval",
          "[drivers][laser]") {
  // The laser is down (connections refused) while the source polls: the connect attempts and the
  // silence check both run every 300 ms, in step. When the laser is back, the connection that an
  // attempt opens must get a whole scanTimeout to deliver: the silence check used to close it in
  // the cycle that opened it, at every attempt, forever.
  const std::uint16_t port = agv::test::closedPort();
  SickLaserSourceConfig config = loopbackConfig(SickLaserModel::Lms1xx, port);
  config.scanTimeout = Duration::fromMilliseconds(300);
  config.tcp.reconnectInterval = Duration::fromMilliseconds(300);
  SickLaserSource src(config);
  static LaserMeasurement m;
  Poller p{src};
  CHECK(p.poll(m, Status::Ok, 1000) == Status::Timeout);  // down: 3 attempts, 3 silences
  agv::test::LoopbackServer server(port);
  REQUIRE(server.ok());
  const auto scan = agv::test::colaScanTelegram(2, 2000);
  std::atomic<bool> done{false};
  std::atomic<int> connections{0};
  server.start([&](agv::test::LoopbackServer& s) {
    for (int c = 0; c < 10 && !done.load(); ++c) {  // every connection the source opens is served
      const int fd = s.accept(1000);
      if (fd < 0)
        continue;
      ++connections;
      if (receiveExactly(fd, kSubscribe, 1000)) {
        for (int i = 0; i < 100 && !done.load(); ++i) {  // a scan every 20 ms until the source leaves
          if (::send(fd, scan.data(), scan.size(), MSG_NOSIGNAL) < 0)
            break;
          sleepMs(20);
        }
      }
      ::close(fd);
    }
  });
  const agv::Timestamp up = agv::drivers::monotonicNow();
  const Status s = p.poll(m, Status::Ok, 3000);
  const double recovery = (agv::drivers::monotonicNow() - up).seconds();
  done = true;
  server.join();
  INFO("recovered after " << recovery << " s; " << src.counters().silenceReconnects << " silence reconnects, "
                          << src.tcpCounters().connects << " connects");
  REQUIRE(s == Status::Ok);
  AGV_CHECK_NEAR(m.scan.ranges[0], 2.0, 1e-6);
  CHECK(recovery < 0.3 + 0.3 + 0.3);  // one interval to connect, one timeout to deliver, a margin
  CHECK(src.tcpCounters().connects == 1U);
  CHECK(connections.load() == 1);
  CHECK(src.health() == Status::Ok);
}

TEST_CASE("SICK laser source: a NAV350 answering only with error replies is a device fault after scanTimeout",
          "[drivers][laser]") {
  agv::test::LoopbackServer server;
  REQUIRE(server.ok());
  std::uint8_t payload[32];
  const std::size_t n = agv::drivers::sick::encodeNav350PoseRequest(
      true, agv::drivers::sick::Nav350Mask::PoseReflectorsScan, agv::Span<std::uint8_t>(payload));
  const auto request = agv::test::colaB(std::vector<std::uint8_t>(payload, payload + n));
  agv::test::NavReplyFields good;
  good.reflectors.resize(1);
  good.reflectors[0].distMm = 4000;
  good.reflectors[0].phiMdeg = 30000;
  const auto reply = agv::test::colaB(agv::test::buildNavReply(good));
  agv::test::NavReplyFields bad;
  bad.errorCode = 4;  // no position
  bad.pose = false;
  bad.poseDetails = false;
  bad.landmarks = false;
  const auto failed = agv::test::colaB(agv::test::buildNavReply(bad));
  std::atomic<bool> done{false};
  server.start([&](agv::test::LoopbackServer& s) {
    const int fd = s.accept();
    if (fd < 0)
      return;
    for (int i = 0; i < 400 && !done.load(); ++i) {  // one good reply, then errors only
      if (!receiveExactly(fd, request, 1000))
        break;
      s.send(fd, i == 0 ? reply : failed);
    }
    ::close(fd);
  });
  SickLaserSource src(loopbackConfig(SickLaserModel::Nav350, server.port()));
  static LaserMeasurement m;
  Poller p{src};
  REQUIRE(p.poll(m, Status::Ok, 3000) == Status::Ok);
  CHECK(src.health() == Status::Ok);
  REQUIRE(p.poll(m, Status::DeviceFault, 3000) == Status::DeviceFault);
  // Error replies keep coming: the device is heard, so not a timeout, but no sweep for longer than
  // scanTimeout (300 ms) is no longer "laser ok".
  for (int i = 0; i < 600 && src.health() == Status::Ok; ++i) {
    (void)src.read(m);
    sleepMs(1);
  }
  CHECK(src.health() == Status::DeviceFault);
  CHECK(src.counters().deviceErrors > 1U);
  done = true;
  server.join();
}
