// The PLC link against real libmodbus peers on 127.0.0.1: the vehicle as server polled by a
// libmodbus client (the PLC), and as client writing to a libmodbus server (the PLC) that goes away
// and comes back. Loops are bounded by iteration counts.
#include <arpa/inet.h>
#include <modbus.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "agv/drivers/linux/modbus_plc_link.hpp"
#include "agv/drivers/linux/tcp_stream.hpp"
#include "agv_test.hpp"

using agv::Duration;
using agv::Status;
using namespace agv::drivers;
using namespace agv::drivers::plc;

namespace {
void sleepMs(int ms) {
  std::this_thread::sleep_for(std::chrono::milliseconds(ms));
}

PlcStatus sampleStatus(std::uint16_t heartbeat) {
  PlcStatus s;
  s.heartbeat = heartbeat;
  s.mode = agv::hal::NavMode::Localizing;
  s.health = static_cast<std::uint16_t>(PlcHealthBit::LaserOk) | static_cast<std::uint16_t>(PlcHealthBit::EncodersOk);
  s.pose = agv::Pose2d(10.25, -4.5, 0.75);
  s.covariance = {1e-4, 0, 0, 2e-4, 0, 3e-5};
  return s;
}

/// A PLC playing Modbus TCP server with libmodbus, on its own thread.
class PlcServer {
 public:
  explicit PlcServer(std::uint16_t port) {
    ctx_ = modbus_new_tcp("127.0.0.1", port);
    mapping_ = modbus_mapping_new_start_address(0, 0, 0, 0, 0, 300, 0, 0);
    listen_ = modbus_tcp_listen(ctx_, 1);
    sockaddr_in a{};
    socklen_t len = sizeof a;
    getsockname(listen_, reinterpret_cast<sockaddr*>(&a), &len);
    port_ = ntohs(a.sin_port);
    thread_ = std::thread([this] { run(); });
  }
  ~PlcServer() { stop(); }
  void stop() {
    stop_ = true;
    if (thread_.joinable())
      thread_.join();
    if (client_ >= 0)
      ::close(client_);
    client_ = -1;
    if (listen_ >= 0)
      ::close(listen_);
    listen_ = -1;
    if (ctx_)
      modbus_free(ctx_);
    ctx_ = nullptr;
    if (mapping_)
      modbus_mapping_free(mapping_);
    mapping_ = nullptr;
  }
  bool ok() const { return listen_ >= 0; }
  std::uint16_t port() const { return port_; }
  std::uint16_t reg(int a) {
    std::lock_guard<std::mutex> l(m_);
    return mapping_->tab_registers[a];
  }
  void setReg(int a, std::uint16_t v) {
    std::lock_guard<std::mutex> l(m_);
    mapping_->tab_registers[a] = v;
  }

 private:
  void run() {
    for (int guard = 0; guard < 100000 && !stop_; ++guard) {
      pollfd p[2] = {{listen_, POLLIN, 0}, {client_, POLLIN, 0}};
      if (::poll(p, client_ >= 0 ? 2 : 1, 10) <= 0)
        continue;
      if (p[0].revents) {
        const int fd = ::accept(listen_, nullptr, nullptr);
        if (client_ >= 0)
          ::close(client_);
        client_ = fd;
        continue;
      }
      if (client_ >= 0 && p[1].revents) {
        std::uint8_t q[MODBUS_TCP_MAX_ADU_LENGTH];
        modbus_set_socket(ctx_, client_);
        const int rc = modbus_receive(ctx_, q);
        if (rc > 0) {
          std::lock_guard<std::mutex> l(m_);
          modbus_reply(ctx_, q, rc, mapping_);
        } else if (rc < 0) {
          ::close(client_);
          client_ = -1;
        }
      }
    }
  }
  modbus_t* ctx_ = nullptr;
  modbus_mapping_t* mapping_ = nullptr;
  int listen_ = -1;
  int client_ = -1;
  std::uint16_t port_ = 0;
  std::atomic<bool> stop_{false};
  std::mutex m_;
  std::thread thread_;
};
}  // namespace

TEST_CASE("Vehicle as Modbus server: a libmodbus PLC reads the map, writes commands, gets exceptions",
          "[drivers][modbus]") {
  ModbusPlcLinkConfig cfg;
  cfg.role = PlcLinkRole::Server;
  std::strcpy(cfg.address, "127.0.0.1");
  cfg.port = 0;
  cfg.map.wordOrder = WordOrder::CDAB;
  ModbusPlcLink link(cfg);
  REQUIRE(link.open() == Status::Ok);
  REQUIRE(link.boundPort() != 0);

  struct Seen {
    int connect = -1;
    std::uint16_t regs[40] = {};
    float x = 0, y = 0, theta = 0;
    int setPose = -1;
    int errStatusWrite = 0, errBadCode = 0, errHalfFloat = 0, errReadPast = 0, errMask = 0, errCoil = 0;
    std::uint16_t healthAfterReject = 0;
    std::uint16_t hb1 = 0, hb2 = 0;
  } seen;
  std::atomic<bool> done{false};
  std::thread plcThread([&] {
    modbus_t* plc = modbus_new_tcp("127.0.0.1", link.boundPort());
    modbus_set_response_timeout(plc, 2, 0);
    seen.connect = modbus_connect(plc);
    if (seen.connect == 0) {
      modbus_read_registers(plc, 0, 40, seen.regs);
      seen.x = modbus_get_float_cdab(&seen.regs[4]);
      seen.y = modbus_get_float_cdab(&seen.regs[6]);
      seen.theta = modbus_get_float_cdab(&seen.regs[8]);
      std::uint16_t cmd[9] = {1, 1, 0, 0, 0, 0, 0, 0, 17};
      modbus_set_float_cdab(0.0F, &cmd[2]);  // (0 is the same in every order)
      // Set-pose (3.5, -1.25, -0.5) in CDAB packed by hand: low word first.
      const float pose[3] = {3.5F, -1.25F, -0.5F};
      for (int i = 0; i < 3; ++i) {
        std::uint32_t b;
        std::memcpy(&b, &pose[i], 4);
        cmd[2 + 2 * i] = static_cast<std::uint16_t>(b & 0xFFFF);
        cmd[3 + 2 * i] = static_cast<std::uint16_t>(b >> 16);
      }
      seen.setPose = modbus_write_registers(plc, 100, 9, cmd);
      if (modbus_write_register(plc, 4, 1) == -1)
        seen.errStatusWrite = errno;
      if (modbus_write_register(plc, 100, 9) == -1)
        seen.errBadCode = errno;
      if (modbus_write_register(plc, 102, 0) == -1)
        seen.errHalfFloat = errno;
      std::uint16_t dummy[4];
      if (modbus_read_registers(plc, 108, 4, dummy) == -1)
        seen.errReadPast = errno;
      if (modbus_mask_write_register(plc, 100, 0xFFFF, 0) == -1)
        seen.errMask = errno;
      if (modbus_write_bit(plc, 0, 1) == -1)
        seen.errCoil = errno;
      sleepMs(50);
      modbus_read_registers(plc, 2, 1, &seen.healthAfterReject);
      modbus_read_registers(plc, 0, 1, &seen.hb1);
      sleepMs(50);
      modbus_read_registers(plc, 0, 1, &seen.hb2);
      modbus_close(plc);
    }
    modbus_free(plc);
    done = true;
  });
  std::uint16_t heartbeat = 0;
  for (int i = 0; i < 1000 && !done; ++i) {
    REQUIRE(link.cycle(sampleStatus(heartbeat++), monotonicNow(), Duration::fromMilliseconds(10)) == Status::Ok);
  }
  plcThread.join();
  REQUIRE(seen.connect == 0);
  AGV_CHECK_NEAR(seen.x, 10.25, 1e-6);
  AGV_CHECK_NEAR(seen.y, -4.5, 1e-6);
  AGV_CHECK_NEAR(seen.theta, 0.75, 1e-6);
  CHECK(seen.regs[1] == static_cast<std::uint16_t>(agv::hal::NavMode::Localizing));
  CHECK(seen.setPose == 9);
  CHECK(seen.errStatusWrite == EMBXILADD);
  CHECK(seen.errBadCode == EMBXILVAL);
  CHECK(seen.errHalfFloat == EMBXILVAL);
  CHECK(seen.errReadPast == EMBXILADD);
  CHECK(seen.errMask == EMBXILFUN);
  CHECK(seen.errCoil == EMBXILFUN);
  CHECK((seen.healthAfterReject & static_cast<std::uint16_t>(PlcHealthBit::CommandRejected)) != 0);
  CHECK(seen.hb2 != seen.hb1);  // the vehicle's heartbeat moves between polls
  PlcCommand c;
  REQUIRE(link.takeCommand(c));
  CHECK(c.code == PlcCommandCode::Localize);
  AGV_CHECK_NEAR(c.pose.x, 3.5, 1e-9);
  AGV_CHECK_NEAR(c.pose.y, -1.25, 1e-9);
  AGV_CHECK_NEAR(c.pose.theta, -0.5, 1e-9);
  CHECK(c.plcHeartbeat == 17);
  CHECK_FALSE(link.takeCommand(c));  // delivered once
  CHECK(link.counters().rejectedWrites == 5U);
  CHECK(link.counters().commands == 1U);
  CHECK(link.plcAlive());
}

TEST_CASE("Vehicle as Modbus client: writes status, reads commands, survives the PLC going away", "[drivers][modbus]") {
  auto plc = std::make_unique<PlcServer>(0);
  REQUIRE(plc->ok());
  const std::uint16_t port = plc->port();
  plc->setReg(100, 2);  // a stale command present before the vehicle starts: not executed
  plc->setReg(101, 5);

  ModbusPlcLinkConfig cfg;
  cfg.role = PlcLinkRole::Client;
  std::strcpy(cfg.address, "127.0.0.1");
  cfg.port = port;
  cfg.map.wordOrder = WordOrder::ABCD;
  cfg.remoteStatusBase = 0;
  cfg.remoteCommandBase = 100;
  cfg.responseTimeout = Duration::fromMilliseconds(100);
  cfg.reconnectInterval = Duration::fromMilliseconds(50);
  cfg.plcHeartbeatTimeout = Duration::fromMilliseconds(100);
  ModbusPlcLink link(cfg);
  REQUIRE(link.open() == Status::Ok);

  std::uint16_t hb = 0;
  auto cycle = [&] { return link.cycle(sampleStatus(hb++), monotonicNow(), Duration::fromMilliseconds(10)); };
  REQUIRE(cycle() == Status::Ok);
  CHECK(plc->reg(0) == 0);
  REQUIRE(cycle() == Status::Ok);
  CHECK(plc->reg(0) == 1);
  CHECK(modbus_get_float_abcd(std::vector<std::uint16_t>{plc->reg(4), plc->reg(5)}.data()) == 10.25F);
  PlcCommand c;
  CHECK_FALSE(link.takeCommand(c));  // the stale block is a baseline only

  plc->setReg(100, 3);
  plc->setReg(101, 6);
  plc->setReg(108, 1);
  REQUIRE(cycle() == Status::Ok);
  REQUIRE(link.takeCommand(c));
  CHECK(c.code == PlcCommandCode::Stop);
  CHECK(c.sequence == 6);

  // An out-of-bounds block in the PLC is refused and flagged.
  plc->setReg(100, 77);
  REQUIRE(cycle() == Status::Ok);
  CHECK(link.counters().rejectedWrites == 1U);
  REQUIRE(cycle() == Status::Ok);
  CHECK((plc->reg(2) & static_cast<std::uint16_t>(PlcHealthBit::CommandRejected)) != 0);
  plc->setReg(100, 0);

  // The PLC disappears: cycles report Lost and go on (rate-limited reconnection attempts).
  plc->stop();
  int lost = 0;
  for (int i = 0; i < 20; ++i) {
    if (cycle() == Status::Lost)
      ++lost;
    sleepMs(10);
  }
  CHECK(lost >= 19);  // the first may still succeed on the half-closed connection
  CHECK(link.counters().disconnects >= 1U);
  CHECK(link.counters().connectFailures >= 1U);
  CHECK_FALSE(link.plcAlive());  // heartbeat register unchanged for > 100 ms

  // It comes back on the same port: the link reconnects by itself.
  plc = std::make_unique<PlcServer>(port);
  REQUIRE(plc->ok());
  int ok = 0;
  for (int i = 0; i < 100 && ok < 3; ++i) {
    if (cycle() == Status::Ok)
      ++ok;
    sleepMs(10);
  }
  CHECK(ok == 3);
  CHECK(link.counters().connects >= 2U);
  CHECK(plc->reg(0) == static_cast<std::uint16_t>(hb - 1));
}

TEST_CASE("Vehicle as Modbus client: an unreachable PLC costs one bounded attempt per interval", "[drivers][modbus]") {
  ModbusPlcLinkConfig cfg;
  cfg.role = PlcLinkRole::Client;
  std::strcpy(cfg.address, "127.0.0.1");
  {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
    socklen_t len = sizeof a;
    ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
    ::close(fd);
    cfg.port = ntohs(a.sin_port);
  }
  cfg.reconnectInterval = Duration::fromMilliseconds(10000);
  ModbusPlcLink link(cfg);
  REQUIRE(link.open() == Status::Ok);
  for (int i = 0; i < 50; ++i) {
    CHECK(link.cycle(sampleStatus(0), monotonicNow(), Duration::fromMilliseconds(1)) == Status::Lost);
  }
  CHECK(link.counters().connectFailures == 1U);  // one attempt; the other 49 cycles did not wait
}

TEST_CASE("Vehicle as client: a PLC trickling its reply never holds a cycle; a budget of 0 never waits",
          "[drivers][modbus]") {
  // A PLC (raw socket server) that answers the status write with a correct FC 16 reply, one byte
  // per 30 ms: with libmodbus' blocking client and its byte timeout of 50 ms, the 12-byte reply held
  // the cycle ~360 ms. Now the link is cycled with a budget of 0 (as agvnav-vehicle does): no call
  // waits, and the reply not whole within responseTimeout (50 ms) of the request drops the link.
  const int listener = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  REQUIRE(::bind(listener, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0);
  REQUIRE(::listen(listener, 1) == 0);
  socklen_t len = sizeof a;
  ::getsockname(listener, reinterpret_cast<sockaddr*>(&a), &len);
  std::atomic<bool> stop{false};
  std::thread plc([&] {
    pollfd p{listener, POLLIN, 0};
    if (::poll(&p, 1, 5000) != 1)
      return;
    const int fd = ::accept(listener, nullptr, nullptr);
    std::uint8_t req[260];
    const ssize_t n = ::recv(fd, req, sizeof req, 0);
    if (n >= 12) {
      const std::uint8_t reply[12] = {req[0], req[1], 0, 0, 0, 6, req[6], req[7], req[8], req[9], req[10], req[11]};
      for (std::size_t i = 0; i < sizeof reply && !stop; ++i) {
        if (::send(fd, reply + i, 1, MSG_NOSIGNAL) != 1)
          break;
        sleepMs(30);
      }
    }
    ::close(fd);
  });
  ModbusPlcLinkConfig cfg;
  cfg.role = PlcLinkRole::Client;
  std::strcpy(cfg.address, "127.0.0.1");
  cfg.port = ntohs(a.sin_port);
  cfg.responseTimeout = Duration::fromMilliseconds(50);
  cfg.reconnectInterval = Duration::fromMilliseconds(10000);
  ModbusPlcLink link(cfg);
  REQUIRE(link.open() == Status::Ok);
  double worstMs = 0.0;
  for (int i = 0; i < 150; ++i) {  // ~300 ms of 2 ms cycles
    const auto t0 = std::chrono::steady_clock::now();
    (void)link.cycle(sampleStatus(1), monotonicNow(), Duration{});
    (void)link.service(monotonicNow());
    worstMs =
        std::max(worstMs, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    sleepMs(2);
  }
  stop = true;
  plc.join();
  ::close(listener);
  CHECK(link.counters().connects == 1U);
  CHECK(link.counters().requestErrors == 1U);  // the trickled reply, dropped at 50 ms
  CHECK_FALSE(link.connected());
  // A call does no waiting; 20 ms leaves room for a descheduled thread on this noisy machine and is
  // still far below the 50 ms a single wait for the reply would have taken.
  CHECK(worstMs < 20.0);
}

TEST_CASE("Vehicle as client with a budget of 0: the exchange runs over cycles and service() calls",
          "[drivers][modbus]") {
  auto plc = std::make_unique<PlcServer>(0);
  REQUIRE(plc->ok());
  plc->setReg(101, 5);  // baseline sequence
  ModbusPlcLinkConfig cfg;
  cfg.role = PlcLinkRole::Client;
  std::strcpy(cfg.address, "127.0.0.1");
  cfg.port = plc->port();
  cfg.responseTimeout = Duration::fromMilliseconds(500);
  ModbusPlcLink link(cfg);
  REQUIRE(link.open() == Status::Ok);
  int fds[4];
  bool sawReplyFd = false;
  PlcCommand c;
  bool gotCommand = false;
  std::uint16_t hb = 0;
  for (int i = 0; i < 500 && !gotCommand; ++i) {
    if (i % 10 == 0) {  // a publication every 10 cycles, as the pipeline's publish period
      (void)link.cycle(sampleStatus(hb++), monotonicNow(), Duration{});
    }
    sawReplyFd = sawReplyFd || link.inputDescriptors(fds, 4) == 1;
    (void)link.service(monotonicNow());
    if (hb == 3) {
      plc->setReg(100, 3);  // Stop, new sequence
      plc->setReg(101, 6);
    }
    gotCommand = link.takeCommand(c);
    sleepMs(2);
  }
  REQUIRE(gotCommand);
  CHECK(c.code == PlcCommandCode::Stop);
  CHECK(sawReplyFd);         // while a reply is awaited, the loop can wait on the connection
  CHECK(plc->reg(0) >= 1U);  // status blocks written
  CHECK(link.counters().requestErrors == 0U);
  CHECK(link.counters().connects == 1U);
}

TEST_CASE("Link used before open() says so", "[drivers][modbus]") {
  ModbusPlcLink link(ModbusPlcLinkConfig{});
  CHECK(link.cycle(sampleStatus(0), monotonicNow(), Duration::fromMilliseconds(1)) == Status::NotInitialized);
}

TEST_CASE("Vehicle as Modbus server: a stalled half request and surplus connections do not block other PLCs",
          "[drivers][modbus]") {
  ModbusPlcLinkConfig cfg;
  std::strcpy(cfg.address, "127.0.0.1");
  cfg.port = 0;
  cfg.maxConnections = 2;
  cfg.responseTimeout = Duration::fromMilliseconds(50);
  ModbusPlcLink link(cfg);
  REQUIRE(link.open() == Status::Ok);
  auto rawConnect = [&] {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons(link.boundPort());
    ::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
    return fd;
  };
  // A PLC that sends 5 bytes of a 12-byte read request and then nothing.
  const int stalled = rawConnect();
  const std::uint8_t half[5] = {0x00, 0x01, 0x00, 0x00, 0x00};
  REQUIRE(::send(stalled, half, sizeof half, MSG_NOSIGNAL) == 5);
  for (int i = 0; i < 10; ++i) {
    REQUIRE(link.cycle(sampleStatus(static_cast<std::uint16_t>(i)), monotonicNow(), Duration::fromMilliseconds(10)) ==
            Status::Ok);
  }
  CHECK(link.counters().requestErrors >= 1U);  // the half request timed out ...
  CHECK(link.counters().disconnects >= 1U);    // ... and its connection was dropped
  ::close(stalled);

  // Two well-behaved PLCs fill the connection slots; a third is refused; the two are served.
  std::atomic<int> reads{0};
  std::atomic<bool> done{false};
  std::thread plcs([&] {
    modbus_t* a = modbus_new_tcp("127.0.0.1", link.boundPort());
    modbus_t* b = modbus_new_tcp("127.0.0.1", link.boundPort());
    modbus_set_response_timeout(a, 2, 0);
    modbus_set_response_timeout(b, 2, 0);
    if (modbus_connect(a) == 0 && modbus_connect(b) == 0) {
      std::uint16_t r[4];
      // Both served once (a peer that never completed a request would be evicted for the
      // newcomer), so the surplus connection finds no peer to evict and is refused.
      if (modbus_read_registers(a, 0, 4, r) == 4)
        ++reads;
      if (modbus_read_registers(b, 4, 4, r) == 4)
        ++reads;
      const int extra = rawConnect();  // over maxConnections
      for (int i = 0; i < 4; ++i) {
        if (modbus_read_registers(a, 0, 4, r) == 4)
          ++reads;
        if (modbus_read_registers(b, 4, 4, r) == 4)
          ++reads;
      }
      ::close(extra);
      modbus_close(a);
      modbus_close(b);
    }
    modbus_free(a);
    modbus_free(b);
    done = true;
  });
  for (int i = 0; i < 1000 && !done; ++i) {
    REQUIRE(link.cycle(sampleStatus(static_cast<std::uint16_t>(i)), monotonicNow(), Duration::fromMilliseconds(10)) ==
            Status::Ok);
  }
  plcs.join();
  CHECK(reads.load() == 10);
  CHECK(link.counters().connectFailures >= 1U);  // the surplus connection was refused
}

TEST_CASE("The link as hal::PlcLink: PoseReport published, PLC command read as hal::PlcCommand", "[drivers][modbus]") {
  ModbusPlcLinkConfig cfg;
  std::strcpy(cfg.address, "127.0.0.1");
  cfg.port = 0;
  cfg.publishBudget = Duration::fromMilliseconds(5);
  ModbusPlcLink link(cfg);
  REQUIRE(link.open() == Status::Ok);
  agv::hal::PlcLink& hal = link;

  agv::hal::PoseReport report;
  report.pose = agv::Pose2d(5.5, -2.25, 1.0);
  report.covariance << 4e-4, 1e-5, 2e-6, 1e-5, 9e-4, 3e-6, 2e-6, 3e-6, 1e-5;
  report.health.mode = agv::hal::NavMode::Lost;
  report.health.matchedLandmarks = 6;
  report.health.visibleReflectors = 8;
  struct Seen {
    int connect = -1;
    std::uint16_t regs[26] = {};
    int wrote = -1;
  } seen;
  std::atomic<bool> done{false};
  std::thread plcThread([&] {
    modbus_t* plc = modbus_new_tcp("127.0.0.1", link.boundPort());
    modbus_set_response_timeout(plc, 2, 0);
    seen.connect = modbus_connect(plc);
    if (seen.connect == 0) {
      sleepMs(30);
      modbus_read_registers(plc, 0, 26, seen.regs);
      std::uint16_t cmd[9] = {2, 1, 0, 0, 0, 0, 0, 0, 1};  // Calibrate, sequence 1
      seen.wrote = modbus_write_registers(plc, 100, 9, cmd);
      modbus_close(plc);
    }
    modbus_free(plc);
    done = true;
  });
  agv::hal::PlcCommand cmd;
  Status got = Status::NotFound;
  for (int i = 0; i < 1000 && got != Status::Ok; ++i) {
    REQUIRE(hal.publish(report) == Status::Ok);
    got = hal.readCommand(cmd);
    if (done && got != Status::Ok) {
      got = hal.readCommand(cmd);
      break;
    }
  }
  plcThread.join();
  REQUIRE(seen.connect == 0);
  CHECK(seen.wrote == 9);
  CHECK(seen.regs[1] == static_cast<std::uint16_t>(agv::hal::NavMode::Lost));
  AGV_CHECK_NEAR(modbus_get_float_abcd(&seen.regs[4]), 5.5, 1e-6);
  AGV_CHECK_NEAR(modbus_get_float_abcd(&seen.regs[10]), 4e-4, 1e-10);  // xx
  AGV_CHECK_NEAR(modbus_get_float_abcd(&seen.regs[16]), 9e-4, 1e-10);  // yy
  AGV_CHECK_NEAR(modbus_get_float_abcd(&seen.regs[20]), 1e-5, 1e-11);  // theta-theta
  CHECK(seen.regs[24] == 6);
  CHECK(seen.regs[25] == 8);
  REQUIRE(got == Status::Ok);
  CHECK(cmd.kind == agv::hal::PlcCommandKind::Calibrate);
  CHECK(hal.readCommand(cmd) == Status::NotFound);
}

TEST_CASE("Vehicle as Modbus server: non-Modbus frames are discarded, unserved function codes get exception 01",
          "[drivers][modbus]") {
  ModbusPlcLinkConfig cfg;
  std::strcpy(cfg.address, "127.0.0.1");
  cfg.port = 0;
  ModbusPlcLink link(cfg);
  REQUIRE(link.open() == Status::Ok);
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(link.boundPort());
  REQUIRE(::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0);
  std::uint16_t heartbeat = 0;
  // Sends `adu`, serves a few cycles, returns what came back (empty: nothing within ~100 ms).
  auto exchange = [&](const std::vector<std::uint8_t>& adu) {
    REQUIRE(::send(fd, adu.data(), adu.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(adu.size()));
    std::vector<std::uint8_t> reply;
    for (int i = 0; i < 10 && reply.empty(); ++i) {
      REQUIRE(link.cycle(sampleStatus(heartbeat++), monotonicNow(), Duration::fromMilliseconds(10)) == Status::Ok);
      pollfd p{fd, POLLIN, 0};
      if (::poll(&p, 1, 0) == 1) {
        std::uint8_t buf[260];
        const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
        if (n > 0) {
          reply.assign(buf, buf + n);
        }
      }
    }
    return reply;
  };
  // FC 06 to the PLC heartbeat register (108) with MBAP protocol id 0xFFFF: not Modbus, discarded.
  const std::vector<std::uint8_t> notModbus = {0x00, 0x01, 0xFF, 0xFF, 0x00, 0x06, 0xFF, 0x06, 0x00, 108, 0x12, 0x34};
  CHECK(exchange(notModbus).empty());
  CHECK(link.counters().refusedRequests == 1U);
  // The register is untouched: a proper FC 03 read of 108 gives 0.
  const std::vector<std::uint8_t> read108 = {0x00, 0x02, 0x00, 0x00, 0x00, 0x06, 0xFF, 0x03, 0x00, 108, 0x00, 0x01};
  const std::vector<std::uint8_t> value = exchange(read108);
  REQUIRE(value.size() == 11U);
  CHECK(value[7] == 0x03);
  CHECK((value[9] == 0x00 && value[10] == 0x00));
  // Function codes the map does not serve, well-formed: exception 01 (function | 0x80); report
  // server id (17) no longer tells the library and its version; 00 and 07 (which libmodbus' own
  // receive refused by closing the connection) too.
  const std::vector<std::vector<std::uint8_t>> unserved = {
      {0x00, 0x06, 0x00, 0x00, 0x00, 0x02, 0xFF, 0x00},                          // 00
      {0x00, 0x07, 0x00, 0x00, 0x00, 0x02, 0xFF, 0x07},                          // read exception status
      {0x00, 0x03, 0x00, 0x00, 0x00, 0x06, 0xFF, 0x01, 0x00, 0x00, 0x00, 0x08},  // read coils
      {0x00, 0x04, 0x00, 0x00, 0x00, 0x06, 0xFF, 0x04, 0x00, 0x00, 0x00, 0x02},  // read input registers
      {0x00, 0x05, 0x00, 0x00, 0x00, 0x02, 0xFF, 0x11}};                         // report server id
  for (const std::vector<std::uint8_t>& request : unserved) {
    const std::uint8_t function = request[7];
    INFO("function " << static_cast<int>(function));
    const std::vector<std::uint8_t> reply = exchange(request);
    REQUIRE(reply.size() == 9U);
    CHECK(reply[7] == static_cast<std::uint8_t>(function | 0x80U));
    CHECK(reply[8] == 0x01);
  }
  CHECK(link.counters().refusedRequests == 6U);
  // An exception-flagged code (0x83) is not a request: libmodbus answered it as a normal FC 03
  // reply (0x83 | 0x80 truncated to 0x03); now it is discarded unanswered, and the stream stays in step.
  CHECK(exchange({0x00, 0x08, 0x00, 0x00, 0x00, 0x03, 0xFF, 0x83, 0x02}).empty());
  CHECK(link.counters().refusedRequests == 7U);
  // FC 16 of 124 registers (261 bytes, over the 260-byte frame; libmodbus reset the connection):
  // read to its end and answered with exception 03; the next request is served.
  std::vector<std::uint8_t> oversized = {0x00, 0x09, 0x00, 0x00, 0x00, 255, 0xFF, 0x10, 0x00, 100, 0x00, 124, 248};
  oversized.resize(261, 0x00);
  const std::vector<std::uint8_t> reply = exchange(oversized);
  REQUIRE(reply.size() == 9U);
  CHECK((reply[0] == 0x00 && reply[1] == 0x09));
  CHECK(reply[7] == 0x90);
  CHECK(reply[8] == 0x03);
  CHECK(exchange(read108).size() == 11U);
  CHECK(link.connected());  // refused, not dropped
  ::close(fd);
}

namespace {
/// A raw TCP connection to the link's port on 127.0.0.1 from `source` (an address of 127/8).
int rawConnectFrom(std::uint16_t port, const char* source = "127.0.0.1") {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in s{};
  s.sin_family = AF_INET;
  inet_pton(AF_INET, source, &s.sin_addr);
  (void)::bind(fd, reinterpret_cast<sockaddr*>(&s), sizeof s);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(port);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

/// A PLC on its own thread: a libmodbus client reading the status block as fast as it is answered
/// (pause `periodMs` between polls) until stopped; counts polls, failures and the slowest reply.
class PollingPlc {
 public:
  PollingPlc(std::uint16_t port, int periodMs) {
    thread_ = std::thread([this, port, periodMs] {
      modbus_t* plc = modbus_new_tcp("127.0.0.1", port);
      modbus_set_response_timeout(plc, 2, 0);
      if (modbus_connect(plc) == 0) {
        std::uint16_t r[40];
        while (!stop_) {
          const auto t0 = std::chrono::steady_clock::now();
          if (modbus_read_registers(plc, 0, 40, r) == 40) {
            ++ok;
          } else {
            ++failed;
          }
          const auto us =
              std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::steady_clock::now() - t0).count();
          if (us > worstUs)
            worstUs = us;
          sleepMs(periodMs);
        }
        modbus_close(plc);
      } else {
        failed = 1000;
      }
      modbus_free(plc);
    });
  }
  ~PollingPlc() { stop(); }
  /// Ends the polling after the poll in progress (keep cycling the link until then).
  void requestStop() { stop_ = true; }
  void stop() {
    stop_ = true;
    if (thread_.joinable())
      thread_.join();
  }
  std::atomic<int> ok{0};
  std::atomic<int> failed{0};
  std::atomic<long long> worstUs{0};

 private:
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

/// Cycles `link` with budget 0 every ~2 ms for `ms` milliseconds (as agvnav-vehicle does); returns
/// the longest cycle() call [us].
long long cycleFor(ModbusPlcLink& link, int ms) {
  long long worst = 0;
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(ms);
  std::uint16_t hb = 0;
  while (std::chrono::steady_clock::now() < end) {
    const auto t0 = std::chrono::steady_clock::now();
    REQUIRE(link.cycle(sampleStatus(hb++), monotonicNow(), Duration{}) == Status::Ok);
    const long long us =
        std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::steady_clock::now() - t0).count();
    worst = us > worst ? us : worst;
    sleepMs(2);
  }
  return worst;
}

ModbusPlcLinkConfig hostileConfig() {
  ModbusPlcLinkConfig cfg;
  std::strcpy(cfg.address, "127.0.0.1");
  cfg.port = 0;
  cfg.responseTimeout = Duration::fromMilliseconds(50);
  return cfg;
}
}  // namespace

// Bounds of these tests: a cycle() with budget 0 does no waiting, so on this noisy 2-core machine
// its longest call is a few ms; the assertions use 100 ms, far below what each fault cost before
// (a trickled request held one call for 12 x 40 ms = 480 ms, a full send buffer until the peer read)
// and far above scheduling noise. The PLC's polls must all be answered (none failed).
TEST_CASE("Vehicle as Modbus server: a trickling peer is dropped at the request bound, the PLC is served",
          "[drivers][modbus][hostile]") {
  ModbusPlcLink link(hostileConfig());
  REQUIRE(link.open() == Status::Ok);
  std::atomic<bool> stop{false};
  std::thread trickle([&] {
    const std::uint8_t read[12] = {0x00, 0x01, 0x00, 0x00, 0x00, 0x06, 0xFF, 0x03, 0x00, 0x00, 0x00, 0x28};
    for (int k = 0; k < 3 && !stop; ++k) {  // three connections, each trickling one byte per 40 ms
      const int fd = rawConnectFrom(link.boundPort());
      for (std::size_t i = 0; i < sizeof read && !stop; ++i) {
        if (::send(fd, read + i, 1, MSG_NOSIGNAL) != 1)
          break;  // dropped by the vehicle
        sleepMs(40);
      }
      ::close(fd);
    }
  });
  PollingPlc plc(link.boundPort(), 20);
  const long long worstCycle = cycleFor(link, 1500);
  stop = true;
  trickle.join();
  plc.requestStop();  // the PLC ends its last poll while the link still answers
  (void)cycleFor(link, 100);
  plc.stop();
  CHECK(worstCycle < 100000);
  CHECK(link.counters().requestTimeouts >= 2U);
  CHECK(plc.ok.load() >= 20);
  CHECK(plc.failed.load() == 0);
}

TEST_CASE("Vehicle as Modbus server: a peer that never reads its replies is dropped, never waited for",
          "[drivers][modbus][hostile]") {
  ModbusPlcLink link(hostileConfig());
  REQUIRE(link.open() == Status::Ok);
  std::atomic<bool> stop{false};
  std::atomic<int> sent{0};
  std::thread flood([&] {
    const int fd = rawConnectFrom(link.boundPort());
    int small = 4096;
    (void)::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
    // Pipelined reads of 110 registers (229-byte replies), never reading one.
    const std::uint8_t read[12] = {0x00, 0x01, 0x00, 0x00, 0x00, 0x06, 0xFF, 0x03, 0x00, 0x00, 0x00, 110};
    while (!stop) {
      pollfd p{fd, POLLOUT, 0};
      if (::poll(&p, 1, 10) == 1 && (p.revents & POLLOUT) != 0) {
        if (::send(fd, read, sizeof read, MSG_NOSIGNAL | MSG_DONTWAIT) != static_cast<ssize_t>(sizeof read))
          break;
        ++sent;
      }
      if ((p.revents & (POLLERR | POLLHUP)) != 0)
        break;
    }
    ::close(fd);
  });
  PollingPlc plc(link.boundPort(), 20);
  const long long worstCycle = cycleFor(link, 1500);
  stop = true;
  flood.join();
  plc.requestStop();  // the PLC ends its last poll while the link still answers
  (void)cycleFor(link, 100);
  plc.stop();
  CHECK(worstCycle < 100000);
  CHECK(sent.load() > 100);
  CHECK(link.counters().sendFailures >= 1U);
  CHECK(plc.ok.load() >= 20);
  CHECK(plc.failed.load() == 0);
}

TEST_CASE("Vehicle as Modbus server: idle slot holders make room for the PLC, then time out",
          "[drivers][modbus][hostile]") {
  ModbusPlcLinkConfig cfg = hostileConfig();
  cfg.idleTimeout = Duration::fromMilliseconds(600);
  ModbusPlcLink link(cfg);
  REQUIRE(link.open() == Status::Ok);
  int holders[6];
  for (int& h : holders) {
    h = rawConnectFrom(link.boundPort());
    REQUIRE(h >= 0);
  }
  (void)cycleFor(link, 100);  // 4 slots taken: the two late holders evicted the two first ones
  CHECK(link.counters().connects == 6U);
  CHECK(link.counters().evictions == 2U);
  PollingPlc plc(link.boundPort(), 20);
  (void)cycleFor(link, 300);
  CHECK(link.counters().evictions == 3U);  // the PLC took the oldest holder's slot
  CHECK(plc.ok.load() >= 5);
  (void)cycleFor(link, 900);  // past the idle timeout: the holders are closed, the PLC stays
  plc.requestStop();          // the PLC ends its last poll while the link still answers
  (void)cycleFor(link, 100);
  plc.stop();
  CHECK(link.counters().idleTimeouts == 3U);
  CHECK(plc.failed.load() == 0);
  for (const int h : holders)
    ::close(h);
}

TEST_CASE("Vehicle as Modbus server: a peer sending only refused requests holds no slot against the PLC",
          "[drivers][modbus][hostile]") {
  ModbusPlcLinkConfig cfg = hostileConfig();
  cfg.maxConnections = 1;
  ModbusPlcLink link(cfg);
  REQUIRE(link.open() == Status::Ok);
  const int junk = rawConnectFrom(link.boundPort());
  REQUIRE(junk >= 0);
  const std::uint8_t fc17[8] = {0x00, 0x01, 0x00, 0x00, 0x00, 0x02, 0xFF, 0x11};
  REQUIRE(::send(junk, fc17, sizeof fc17, MSG_NOSIGNAL) == 8);
  (void)cycleFor(link, 50);
  CHECK(link.counters().refusedRequests == 1U);  // answered with exception 01, still connected
  CHECK(link.connected());
  PollingPlc plc(link.boundPort(), 20);
  (void)cycleFor(link, 300);
  plc.requestStop();  // the PLC ends its last poll while the link still answers
  (void)cycleFor(link, 100);
  plc.stop();
  CHECK(link.counters().evictions == 1U);  // the junk peer made room for the PLC
  CHECK(plc.ok.load() >= 5);
  CHECK(plc.failed.load() == 0);
  ::close(junk);
}

TEST_CASE(
    "Vehicle as Modbus server: the allow-list refuses other addresses; a storm of clients cannot evict a "
    "polling PLC",
    "[drivers][modbus][hostile]") {
  ModbusPlcLinkConfig cfg = hostileConfig();
  cfg.allowedPeerCount = 1;
  inet_pton(AF_INET, "127.0.0.1", &cfg.allowedPeers[0]);
  ModbusPlcLink link(cfg);
  REQUIRE(link.open() == Status::Ok);
  const int stranger = rawConnectFrom(link.boundPort(), "127.0.0.2");
  REQUIRE(stranger >= 0);
  (void)cycleFor(link, 50);
  CHECK(link.counters().refusedPeers == 1U);
  CHECK(link.counters().connects == 0U);
  ::close(stranger);

  ModbusPlcLink open(hostileConfig());  // no allow-list
  REQUIRE(open.open() == Status::Ok);
  PollingPlc plc(open.boundPort(), 20);
  (void)cycleFor(open, 100);
  std::thread storm([&] {
    std::vector<int> fds;
    for (int i = 0; i < 50; ++i) {
      fds.push_back(rawConnectFrom(open.boundPort()));
      sleepMs(2);
    }
    sleepMs(200);
    for (const int fd : fds)
      ::close(fd);
  });
  (void)cycleFor(open, 600);
  storm.join();
  plc.requestStop();  // the PLC ends its last poll while the link still answers
  (void)cycleFor(open, 100);
  plc.stop();
  CHECK(open.counters().evictions >= 40U);  // storm connections evicted each other ...
  CHECK(plc.failed.load() == 0);            // ... never the PLC
  CHECK(plc.ok.load() >= 15);
}

TEST_CASE("Vehicle as Modbus server: health bit 8 is cleared only by a write actually applied", "[drivers][modbus]") {
  ModbusPlcLink link(hostileConfig());
  REQUIRE(link.open() == Status::Ok);
  std::atomic<bool> done{false};
  std::uint16_t afterReject = 0, afterReadPast = 0, afterGood = 0;
  int readPastErrno = 0;
  std::thread plcThread([&] {
    modbus_t* plc = modbus_new_tcp("127.0.0.1", link.boundPort());
    modbus_set_response_timeout(plc, 2, 0);
    if (modbus_connect(plc) == 0) {
      (void)modbus_write_register(plc, 100, 9);  // code 9: refused, bit 8
      sleepMs(30);
      modbus_read_registers(plc, 2, 1, &afterReject);
      // FC 23: a valid write of the PLC heartbeat, a read past the map: exception 02 (nothing written).
      std::uint16_t w = 5, r[4];
      if (modbus_write_and_read_registers(plc, 108, 1, &w, 200, 4, r) == -1)
        readPastErrno = errno;
      sleepMs(30);
      modbus_read_registers(plc, 2, 1, &afterReadPast);
      (void)modbus_write_register(plc, 108, 6);
      sleepMs(30);
      modbus_read_registers(plc, 2, 1, &afterGood);
      modbus_close(plc);
    }
    modbus_free(plc);
    done = true;
  });
  for (int i = 0; i < 1000 && !done; ++i) {
    REQUIRE(link.cycle(sampleStatus(0), monotonicNow(), Duration::fromMilliseconds(5)) == Status::Ok);
  }
  plcThread.join();
  const auto bit8 = static_cast<std::uint16_t>(PlcHealthBit::CommandRejected);
  CHECK((afterReject & bit8) != 0);
  CHECK(readPastErrno == EMBXILADD);
  CHECK((afterReadPast & bit8) != 0);  // libmodbus' refusal used to clear it
  CHECK((afterGood & bit8) == 0);
}
