// SICK drivers over real TCP against a loopback peer speaking CoLa A / binary CoLa: subscription,
// split telegrams, garbage, a connection dropped mid-telegram, reconnection, unreachable device.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "agv/core/angle.hpp"
#include "agv/drivers/linux/sick_laser_client.hpp"
#include "agv_test.hpp"
#include "loopback_server.hpp"
#include "sick_telegrams.hpp"

using agv::Duration;
using agv::LaserScan;
using agv::Status;
using namespace agv::drivers;

namespace {
std::vector<std::uint8_t> bytes(const std::string& s) {
  return std::vector<std::uint8_t>(s.begin(), s.end());
}

void setLoopback(TcpStreamConfig& tcp, std::uint16_t port) {
  std::strcpy(tcp.host, "127.0.0.1");
  tcp.port = port;
  tcp.connectTimeout = Duration::fromMilliseconds(500);
  tcp.reconnectInterval = Duration::fromMilliseconds(50);
}
}  // namespace

TEST_CASE("CoLa A client: subscription, split and noisy stream, reconnection after a drop", "[drivers][laser]") {
  agv::test::LoopbackServer server;
  REQUIRE(server.ok());
  const auto subscribe = agv::test::stxEtx("sEN LMDscandata 1");
  std::atomic<int> subscriptions{0};
  server.start([&](agv::test::LoopbackServer& s) {
    int fd = s.accept();
    if (fd < 0)
      return;
    if (s.read(fd, subscribe.size()) == subscribe)
      ++subscriptions;
    std::vector<std::uint8_t> first = bytes("garbage");
    const auto a = agv::test::colaScanTelegram(1, 1000);
    first.insert(first.end(), a.begin(), a.end());
    s.send(fd, first, 37);                               // telegram A in 37-byte pieces after noise
    s.send(fd, agv::test::stxEtx("sEA LMDscandata 1"));  // acknowledgement: ignored
    s.send(fd, agv::test::colaScanTelegram(2, 2000));    // B in one piece
    const auto c = agv::test::colaScanTelegram(3, 3000);
    s.send(fd, std::vector<std::uint8_t>(c.begin(), c.begin() + static_cast<std::ptrdiff_t>(c.size() / 2)));
    ::usleep(20000);
    ::close(fd);  // dropped in the middle of C
    fd = s.accept();
    if (fd < 0)
      return;
    if (s.read(fd, subscribe.size()) == subscribe)
      ++subscriptions;
    s.send(fd, agv::test::colaScanTelegram(4, 4000));
    agv::test::LoopbackServer::drainAndClose(fd, 3000);
  });

  ColaAScanClientConfig cfg;
  setLoopback(cfg.tcp, server.port());
  {
    ColaAScanClient client(cfg);
    static LaserScan scan;
    const Duration timeout = Duration::fromMilliseconds(3000);
    for (std::uint32_t expected : {1000U, 2000U, 4000U}) {
      const Status st = client.receive(scan, timeout);
      REQUIRE(st == Status::Ok);
      REQUIRE(scan.size() == 10U);
      AGV_CHECK_NEAR(scan.ranges[0], expected * 1e-3, 1e-6);
      AGV_CHECK_NEAR(scan.ranges[9], (expected + 9) * 1e-3, 1e-6);
      AGV_CHECK_NEAR(scan.angleMin, agv::deg2rad(-135.0), 1e-6);
    }
    CHECK(client.lastInfo().scanCounter == 4U);
    CHECK(client.counters().decoded == 3U);
    CHECK(client.counters().otherTelegrams == 1U);
    CHECK(client.framerCounters().garbageBytes == 7U);
    CHECK(client.framerCounters().truncated == 1U);  // C, cut by the drop
    CHECK(client.tcpCounters().connects == 2U);
    CHECK(client.tcpCounters().disconnects >= 1U);
  }  // the client closes: the peer's script ends
  server.join();
  CHECK(subscriptions.load() == 2);
}

TEST_CASE("CoLa A client in polling mode sends sRN and decodes the sRA reply", "[drivers][laser]") {
  agv::test::LoopbackServer server;
  REQUIRE(server.ok());
  const auto poll = agv::test::stxEtx("sRN LMDscandata");
  server.start([&](agv::test::LoopbackServer& s) {
    const int fd = s.accept();
    if (fd < 0)
      return;
    for (int i = 0; i < 2; ++i) {
      if (s.read(fd, poll.size()) != poll)
        break;
      agv::test::ColaScanFields f;
      f.type = "sRA";
      agv::test::ColaChannel c;
      c.values.assign(5, 1500U + static_cast<std::uint32_t>(i));
      f.channels16.push_back(c);
      s.send(fd, agv::test::stxEtx(agv::test::buildColaScan(f)), 11);
    }
    agv::test::LoopbackServer::drainAndClose(fd, 3000);
  });
  ColaAScanClientConfig cfg;
  setLoopback(cfg.tcp, server.port());
  cfg.subscribe = false;
  {
    ColaAScanClient client(cfg);
    static LaserScan scan;
    for (int i = 0; i < 2; ++i) {
      REQUIRE(client.receive(scan, Duration::fromMilliseconds(3000)) == Status::Ok);
      AGV_CHECK_NEAR(scan.ranges[0], 1.5 + i * 1e-3, 1e-6);
    }
  }
  server.join();
}

TEST_CASE("Laser client: an unreachable device gives Lost within the timeout and is retried", "[drivers][laser]") {
  ColaAScanClientConfig cfg;
  setLoopback(cfg.tcp, agv::test::closedPort());
  ColaAScanClient client(cfg);
  static LaserScan scan;
  CHECK(client.receive(scan, Duration::fromMilliseconds(200)) == Status::Lost);
  CHECK(client.receive(scan, Duration::fromMilliseconds(200)) == Status::Lost);
  CHECK(client.tcpCounters().connectFailures >= 2U);
  CHECK(client.tcpCounters().connects == 0U);
}

TEST_CASE("NAV350 client: request, event in between, split reply, peer drop and re-request", "[drivers][laser]") {
  agv::test::LoopbackServer server;
  REQUIRE(server.ok());
  std::uint8_t payload[32];
  const std::size_t n = agv::drivers::sick::encodeNav350PoseRequest(
      true, agv::drivers::sick::Nav350Mask::PoseReflectors, agv::Span<std::uint8_t>(payload));
  const auto request = agv::test::colaB(std::vector<std::uint8_t>(payload, payload + n));
  agv::test::NavReplyFields f;
  f.xMm = -2500;
  f.yMm = 7250;
  f.phiMdeg = 90000;
  f.reflectors.resize(4);
  for (std::size_t i = 0; i < 4; ++i) {
    f.reflectors[i].distMm = static_cast<std::uint32_t>(3000 + 100 * i);
    f.reflectors[i].phiMdeg = static_cast<std::uint32_t>(45000 * i);
  }
  const auto reply = agv::test::colaB(agv::test::buildNavReply(f));
  std::atomic<int> requests{0};
  server.start([&](agv::test::LoopbackServer& s) {
    int fd = s.accept();
    if (fd < 0)
      return;
    if (s.read(fd, request.size()) == request)
      ++requests;
    s.send(fd, agv::test::colaB(bytes("sSN mNEVAChangeState \x01")));
    s.send(fd, reply, 50);
    if (s.read(fd, request.size()) == request)
      ++requests;
    ::close(fd);  // second request: dropped without an answer
    fd = s.accept();
    if (fd < 0)
      return;
    if (s.read(fd, request.size()) == request)
      ++requests;
    s.send(fd, reply, 7, 1);
    agv::test::LoopbackServer::drainAndClose(fd, 3000);
  });
  Nav350ClientConfig cfg;
  setLoopback(cfg.tcp, server.port());
  {
    Nav350Client client(cfg);
    static agv::drivers::sick::Nav350PoseReply r;
    for (int i = 0; i < 2; ++i) {
      REQUIRE(client.requestPose(true, agv::drivers::sick::Nav350Mask::PoseReflectors, r,
                                 Duration::fromMilliseconds(3000)) == Status::Ok);
      REQUIRE(r.poseValid);
      AGV_CHECK_NEAR(r.pose.x, -2.5, 1e-9);
      AGV_CHECK_NEAR(r.pose.y, 7.25, 1e-9);
      AGV_CHECK_NEAR(r.pose.theta, agv::kPi<double> / 2, 1e-9);
      REQUIRE(r.reflectors.size() == 4U);
      AGV_CHECK_NEAR(r.reflectors[3].range, 3.3, 1e-9);
      AGV_CHECK_NEAR(r.reflectors[3].bearing, agv::deg2rad(135.0), 1e-9);
    }
    CHECK(client.counters().decoded == 2U);
    CHECK(client.counters().otherTelegrams == 1U);
    CHECK(client.tcpCounters().connects == 2U);
  }
  server.join();
  CHECK(requests.load() == 3);
}

TEST_CASE("TCP stream: with budget 0 a slow connection attempt never waits and completes in later calls",
          "[drivers][laser]") {
  // A listener whose accept queue is full (backlog 0, one connection queued and not accepted): the
  // kernel drops our SYN, so the connection stays in progress until the SYN is retransmitted (~1 s).
  const int listener = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  REQUIRE(::bind(listener, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0);
  REQUIRE(::listen(listener, 0) == 0);
  socklen_t len = sizeof a;
  ::getsockname(listener, reinterpret_cast<sockaddr*>(&a), &len);
  std::vector<int> fillers;
  for (int i = 0; i < 2; ++i) {
    const int f = ::socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK, 0);
    (void)::connect(f, reinterpret_cast<sockaddr*>(&a), sizeof a);
    fillers.push_back(f);
  }
  ::usleep(50000);
  auto worstCallMs = [](TcpStream& s, int calls, Status& last) {
    double worst = 0.0;
    for (int i = 0; i < calls && last != Status::Ok; ++i) {
      const auto t0 = std::chrono::steady_clock::now();
      last = s.ensureConnected(Duration{});
      worst = std::max(worst, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      ::usleep(10000);
    }
    return worst;
  };

  // Given up after connectTimeout (200 ms), counted once; no call waited.
  TcpStreamConfig cfg;
  setLoopback(cfg, ntohs(a.sin_port));
  cfg.connectTimeout = Duration::fromMilliseconds(200);
  cfg.reconnectInterval = Duration::fromSeconds(10.0);
  {
    TcpStream s(cfg);
    Status last = Status::Timeout;
    const double worst = worstCallMs(s, 40, last);
    CHECK(last == Status::Timeout);
    CHECK_FALSE(s.connecting());
    CHECK(s.counters().connectFailures == 1U);
    CHECK(s.counters().connects == 0U);
    CHECK(worst < 50.0);  // each call: a poll of 0 ms (the old stream waited the whole budget)
  }
  // With a 3 s timeout: pending while the queue is full; once the queue is drained the
  // retransmitted SYN gets through and a later call completes the connection.
  cfg.connectTimeout = Duration::fromMilliseconds(3000);
  TcpStream s(cfg);
  Status last = Status::Timeout;
  (void)worstCallMs(s, 5, last);
  CHECK(s.connecting());
  CHECK(last == Status::Timeout);
  for (int i = 0; i < 2; ++i) {
    const int c = ::accept(listener, nullptr, nullptr);
    if (c >= 0)
      ::close(c);
  }
  const double worst = worstCallMs(s, 300, last);
  CHECK(last == Status::Ok);
  CHECK(s.connected());
  CHECK(s.counters().connects == 1U);
  CHECK(s.counters().connectFailures == 0U);
  CHECK(worst < 50.0);
  for (const int f : fillers)
    ::close(f);
  ::close(listener);
}
