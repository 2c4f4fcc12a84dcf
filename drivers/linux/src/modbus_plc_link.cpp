#include "agv/drivers/linux/modbus_plc_link.hpp"

#include "agv/drivers/linux/tcp_stream.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <modbus.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>

namespace agv::drivers {
namespace {
constexpr int kMaxRequestsPerCycle = 16;  // bound of the server loop in one cycle
constexpr int kMaxAcceptsPerCycle = 8;    // connections accepted per ready listening socket
constexpr int kMaxReadsPerVisit = 4;      // recv() calls per peer and round
constexpr int kPeerSendBuffer = 8192;     // SO_SNDBUF of a server connection
constexpr int kListenBacklog = 64;        // connections the kernel queues between two cycles

modbus_mapping_t* asMapping(void* p) noexcept {
  return static_cast<modbus_mapping_t*>(p);
}

int pollMs(Duration d) noexcept {
  if (d.ns <= 0) {
    return 0;
  }
  const std::int64_t ms = (d.ns + 999999) / 1000000;
  return ms > 10000 ? 10000 : static_cast<int>(ms);
}

std::uint16_t be16(const std::uint8_t* p) noexcept {
  return static_cast<std::uint16_t>((p[0] << 8U) | p[1]);
}
}  // namespace

ModbusPlcLink::ModbusPlcLink(const ModbusPlcLinkConfig& config) noexcept : config_(config), map_(config.map) {
  config_.address[sizeof(config_.address) - 1] = '\0';
  if (config_.maxConnections < 1) {
    config_.maxConnections = 1;
  }
  if (config_.maxConnections > kMaxClients) {
    config_.maxConnections = kMaxClients;
  }
}

ModbusPlcLink::~ModbusPlcLink() {
  for (const Peer& p : clients_) {
    if (p.fd >= 0) {
      ::close(p.fd);
    }
  }
  if (listenFd_ >= 0) {
    ::close(listenFd_);
  }
  if (clientFd_ >= 0) {
    ::close(clientFd_);
  }
  if (ctx_ != nullptr) {
    modbus_free(ctx_);
  }
  if (mapping_ != nullptr) {
    modbus_mapping_free(asMapping(mapping_));
  }
}

bool ModbusPlcLink::connected() const noexcept {
  if (config_.role == PlcLinkRole::Client) {
    return clientConnected_;
  }
  for (const Peer& p : clients_) {
    if (p.fd >= 0) {
      return true;
    }
  }
  return false;
}

Status ModbusPlcLink::open() noexcept {
  if (ctx_ != nullptr) {
    return Status::Ok;
  }
  const bool server = config_.role == PlcLinkRole::Server;
  ctx_ = modbus_new_tcp(config_.address, config_.port);
  if (ctx_ == nullptr) {
    return Status::InvalidArgument;
  }
  // libmodbus builds the server's replies (modbus_reply) only: the server reads and checks requests
  // itself (MbapRequestFramer, checkModbusRequest) and the client exchanges are the link's own
  // non-blocking state machine (exchange()), so no libmodbus timeout is ever waited on.
  sequenceSeen_ = server;  // the server's table starts at 0: the PLC's first sequence is new
  if (!server) {
    return Status::Ok;
  }
  mapping_ = modbus_mapping_new_start_address(0, 0, 0, 0, 0, plc::PlcRegisterMap::kRegisterCount, 0, 0);
  if (mapping_ == nullptr) {
    return Status::CapacityExceeded;
  }
  // Backlog: room for a burst of connections between two cycles (the policy sorts them out); a
  // full queue would drop the PLC's SYN, and its connect would wait for the retransmission (1 s).
  listenFd_ = modbus_tcp_listen(ctx_, kListenBacklog);
  if (listenFd_ < 0) {
    return Status::Lost;
  }
  const int flags = ::fcntl(listenFd_, F_GETFL, 0);
  (void)::fcntl(listenFd_, F_SETFL, flags | O_NONBLOCK);  // accept4 never waits
  (void)::fcntl(listenFd_, F_SETFD, FD_CLOEXEC);
  sockaddr_in a{};
  socklen_t len = sizeof a;
  // NOLINTNEXTLINE(cppcoreguidelines-pro-type-reinterpret-cast): the sockets API
  if (getsockname(listenFd_, reinterpret_cast<sockaddr*>(&a), &len) == 0) {
    boundPort_ = ntohs(a.sin_port);
  }
  return Status::Ok;
}

void ModbusPlcLink::acceptCommand(const plc::PlcCommand& c, Timestamp now) noexcept {
  if (!heartbeatSeen_ || c.plcHeartbeat != lastPlcHeartbeat_) {
    heartbeatSeen_ = true;
    lastPlcHeartbeat_ = c.plcHeartbeat;
    lastPlcHeartbeatChange_ = now;
    plcAlive_ = true;
  }
  if (!sequenceSeen_) {  // first view of the PLC's block: a baseline, not a command
    sequenceSeen_ = true;
    lastSequence_ = c.sequence;
    return;
  }
  if (c.sequence != lastSequence_) {
    lastSequence_ = c.sequence;
    command_ = c;
    commandStamp_ = now;
    newCommand_ = true;
    haveCommand_ = true;
    ++counters_.commands;
  }
}

Status ModbusPlcLink::publish(const hal::PoseReport& report) noexcept {
  plc::PlcStatus s;
  s.heartbeat = publishCount_++;
  s.mode = report.health.mode;
  s.health = report.health.bits;
  s.lastStatus = report.health.lastStatus;
  s.pose = report.pose;
  const Eigen::Matrix3d& c = report.covariance;
  s.covariance = {c(0, 0), c(0, 1), c(0, 2), c(1, 1), c(1, 2), c(2, 2)};
  s.stamp = report.stamp;
  s.matchedLandmarks = report.health.matchedLandmarks;
  s.visibleReflectors = report.health.visibleReflectors;
  s.reflectorsFused = report.health.reflectorsFused;
  s.reflectorsRejected = report.health.reflectorsRejected;
  s.cornersFused = report.health.cornersFused;
  s.cornersRejected = report.health.cornersRejected;
  s.routine = report.health.calibration;
  s.calibration = calibration_;
  const Status st = cycle(s, monotonicNow(), config_.publishBudget);
  return st == Status::Lost ? Status::Timeout : st;
}

Status ModbusPlcLink::readCommand(hal::PlcCommand& out) noexcept {
  plc::PlcCommand c;
  // A sequence change with code None carries no request.
  if (!takeCommand(c) || c.code == plc::PlcCommandCode::None) {
    return Status::NotFound;
  }
  out.stamp = commandStamp_;
  out.kind = static_cast<hal::PlcCommandKind>(static_cast<std::uint8_t>(c.code));  // same values
  out.initialPose = c.pose;
  return Status::Ok;
}

bool ModbusPlcLink::takeCommand(plc::PlcCommand& command) noexcept {
  if (!newCommand_) {
    return false;
  }
  command = command_;
  newCommand_ = false;
  return true;
}

Status ModbusPlcLink::cycle(const plc::PlcStatus& status, Timestamp now, Duration budget) noexcept {
  if (ctx_ == nullptr || (config_.role == PlcLinkRole::Server && listenFd_ < 0)) {
    return Status::NotInitialized;
  }
  if (heartbeatSeen_ && now - lastPlcHeartbeatChange_ > config_.plcHeartbeatTimeout) {
    plcAlive_ = false;
  }
  plc::PlcStatus published = status;
  if (!plcAlive_) {
    published.health =
        static_cast<std::uint16_t>(published.health | static_cast<std::uint16_t>(plc::PlcHealthBit::PlcHeartbeatLost));
  }
  if (lastRejected_) {
    published.health =
        static_cast<std::uint16_t>(published.health | static_cast<std::uint16_t>(plc::PlcHealthBit::CommandRejected));
  }
  if (config_.role == PlcLinkRole::Server) {
    modbus_mapping_t* m = asMapping(mapping_);
    (void)map_.encodeStatus(published,
                            Span<std::uint16_t>(m->tab_registers, static_cast<std::size_t>(m->nb_registers)));
    return serve(now, budget);
  }
  (void)map_.encodeStatus(published, Span<std::uint16_t>(table_.data(), table_.size()));
  return exchange(now, budget, true);
}

Status ModbusPlcLink::service(Timestamp now) noexcept {
  if (ctx_ == nullptr || (config_.role == PlcLinkRole::Server && listenFd_ < 0)) {
    return Status::NotInitialized;
  }
  if (config_.role == PlcLinkRole::Server) {
    return serve(now, Duration{});
  }
  return exchange(now, Duration{}, false);
}

void ModbusPlcLink::closeClient(int index) noexcept {
  Peer& p = clients_[static_cast<std::size_t>(index)];
  if (p.fd >= 0) {
    ::close(p.fd);
    p.fd = -1;
    p.framer.next();
    ++counters_.disconnects;
  }
}

int ModbusPlcLink::inputDescriptors(int* out, int capacity) const noexcept {
  int n = 0;
  if (config_.role == PlcLinkRole::Client) {
    if (clientFd_ >= 0 && capacity > 0 && (phase_ == ClientPhase::AwaitWrite || phase_ == ClientPhase::AwaitRead)) {
      out[n++] = clientFd_;  // a reply is awaited
    }
    return n;
  }
  if (listenFd_ < 0) {
    return 0;
  }
  if (n < capacity) {
    out[n++] = listenFd_;
  }
  for (const Peer& p : clients_) {
    if (p.fd >= 0 && n < capacity) {
      out[n++] = p.fd;
    }
  }
  return n;
}

bool ModbusPlcLink::peerAllowed(std::uint32_t address) const noexcept {
  if (config_.allowedPeerCount <= 0) {
    return true;
  }
  for (int i = 0; i < config_.allowedPeerCount && i < static_cast<int>(config_.allowedPeers.size()); ++i) {
    if (config_.allowedPeers[static_cast<std::size_t>(i)] == address) {
      return true;
    }
  }
  return false;
}

void ModbusPlcLink::acceptPeers(Timestamp now) noexcept {
  for (int k = 0; k < kMaxAcceptsPerCycle; ++k) {
    sockaddr_in from{};
    socklen_t len = sizeof from;
    // NOLINTNEXTLINE(cppcoreguidelines-pro-type-reinterpret-cast): the sockets API
    const int fd = ::accept4(listenFd_, reinterpret_cast<sockaddr*>(&from), &len, SOCK_CLOEXEC | SOCK_NONBLOCK);
    if (fd < 0) {
      if (errno == ECONNABORTED || errno == EINTR) {
        continue;  // that one went away before it was accepted; others may wait
      }
      return;  // EAGAIN: no more waiting connections (EMFILE ...: tried again next cycle)
    }
    if (from.sin_family != AF_INET || !peerAllowed(from.sin_addr.s_addr)) {
      ::close(fd);
      ++counters_.refusedPeers;
      continue;
    }
    int slot = -1;
    for (int i = 0; i < config_.maxConnections && slot < 0; ++i) {
      if (clients_[static_cast<std::size_t>(i)].fd < 0) {
        slot = i;
      }
    }
    if (slot < 0) {
      // Full. First choice: the oldest peer that never completed a request (a slot holder, or a
      // client that connected and said nothing). Else the longest-silent peer, if it has been
      // silent for evictSilentAfter. Else the newcomer is refused.
      int neverServed = -1;
      int silent = -1;
      for (int i = 0; i < config_.maxConnections; ++i) {
        const Peer& p = clients_[static_cast<std::size_t>(i)];
        if (!p.served) {
          if (neverServed < 0 || p.accepted < clients_[static_cast<std::size_t>(neverServed)].accepted) {
            neverServed = i;
          }
        } else if (now - p.lastRequest >= config_.evictSilentAfter &&
                   (silent < 0 || p.lastRequest < clients_[static_cast<std::size_t>(silent)].lastRequest)) {
          silent = i;
        }
      }
      slot = neverServed >= 0 ? neverServed : silent;
      if (slot >= 0) {
        closeClient(slot);
        ++counters_.evictions;
      }
    }
    if (slot < 0) {
      ::close(fd);
      ++counters_.connectFailures;
      continue;
    }
    // A small send buffer (the kernel doubles it: 16 KiB, about 60 of the longest replies): a PLC
    // has one reply outstanding, so only a peer that does not read fills it, and is then dropped
    // at once instead of after megabytes of autotuned buffer.
    (void)::setsockopt(fd, SOL_SOCKET, SO_SNDBUF, &kPeerSendBuffer, sizeof kPeerSendBuffer);
    Peer& p = clients_[static_cast<std::size_t>(slot)];
    p.fd = fd;
    p.framer.next();
    p.accepted = now;
    p.lastRequest = now;
    p.served = false;
    ++counters_.connects;
  }
}

Status ModbusPlcLink::serve(Timestamp now, Duration budget) noexcept {
  // Bounds first: a request not whole within responseTimeout of its first byte, or a connection
  // without a request for idleTimeout, is dropped.
  for (int i = 0; i < kMaxClients; ++i) {
    const Peer& p = clients_[static_cast<std::size_t>(i)];
    if (p.fd < 0) {
      continue;
    }
    if (p.framer.started() && now - p.firstByte > config_.responseTimeout) {
      ++counters_.requestTimeouts;
      ++counters_.requestErrors;
      closeClient(i);
    } else if (now - p.lastRequest > config_.idleTimeout) {
      ++counters_.idleTimeouts;
      closeClient(i);
    }
  }
  int handled = 0;
  bool first = true;
  // One poll waits up to the budget (0 from the vehicle loop, which waits on inputDescriptors()
  // itself); then rounds without waiting, each reading every ready peer once and answering at most
  // one complete request per peer, until nothing is ready or kMaxRequestsPerCycle were answered.
  for (int round = 0; round < kMaxRequestsPerCycle && handled < kMaxRequestsPerCycle; ++round) {
    pollfd fds[kMaxClients + 1];
    int idx[kMaxClients + 1];
    nfds_t n = 0;
    // Connections first, the listener last: a PLC whose first request is already in its socket is
    // served (and so no longer evictable) before this round's newcomers can evict it.
    for (int i = 0; i < kMaxClients; ++i) {
      const Peer& p = clients_[static_cast<std::size_t>(i)];
      if (p.fd >= 0) {
        fds[n] = pollfd{p.fd, POLLIN, 0};
        idx[n++] = i;
      }
    }
    fds[n] = pollfd{listenFd_, POLLIN, 0};
    idx[n++] = -1;
    const int rc = ::poll(fds, n, first ? pollMs(budget) : 0);
    first = false;
    if (rc <= 0) {
      break;
    }
    for (nfds_t k = 0; k < n && handled < kMaxRequestsPerCycle; ++k) {
      if (fds[k].revents == 0) {
        continue;
      }
      if (idx[k] < 0) {
        acceptPeers(now);
        continue;
      }
      Peer& p = clients_[static_cast<std::size_t>(idx[k])];
      if (p.fd != fds[k].fd) {
        continue;  // evicted by an accept of this round
      }
      if (!readPeer(p, now)) {
        closeClient(idx[k]);
        continue;
      }
      if (p.framer.complete()) {
        ++handled;
        const bool keep = handleRequest(p, now);
        p.framer.next();
        if (!keep) {
          closeClient(idx[k]);
        }
      }
    }
  }
  (void)modbus_set_socket(ctx_, -1);
  return Status::Ok;
}

bool ModbusPlcLink::readPeer(Peer& p, Timestamp now) noexcept {
  // Bounded: a request needs at most a header read and a body read; an oversized one is dropped in
  // pieces of up to 252 bytes, so a few reads per round (the rest waits for the next round/cycle).
  for (int reads = 0; reads < kMaxReadsPerVisit && !p.framer.complete(); ++reads) {
    const Span<std::uint8_t> space = p.framer.space();
    const ssize_t r = ::recv(p.fd, space.data(), space.size(), MSG_DONTWAIT);
    if (r == 0) {
      return false;  // the peer closed
    }
    if (r < 0) {
      return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR;
    }
    if (!p.framer.started()) {
      p.firstByte = now;
    }
    if (p.framer.commit(static_cast<std::size_t>(r)) != Status::Ok) {
      ++counters_.requestErrors;  // an MBAP length that frames nothing: the stream is lost
      return false;
    }
  }
  return true;
}

bool ModbusPlcLink::sendAll(int fd, const std::uint8_t* data, std::size_t n) noexcept {
  const ssize_t r = ::send(fd, data, n, MSG_DONTWAIT | MSG_NOSIGNAL);
  if (r == static_cast<ssize_t>(n)) {
    return true;
  }
  ++counters_.sendFailures;  // full send buffer (a peer that does not read) or a broken link
  return false;
}

bool ModbusPlcLink::handleRequest(Peer& p, Timestamp now) noexcept {
  const Span<const std::uint8_t> adu = p.framer.adu();
  const plc::RequestCheck c = plc::checkModbusRequest(adu, p.framer.oversized(), plc::PlcRegisterMap::kRegisterCount);
  std::uint8_t exceptionReply[9];
  auto refuse = [&](plc::ModbusException code) {
    const std::size_t n = plc::buildExceptionResponse(adu, code, exceptionReply);
    ++counters_.requests;
    return n == 0 || sendAll(p.fd, exceptionReply, n);
  };
  switch (c.verdict) {
    case plc::RequestVerdict::Discard:
      // Not Modbus (protocol id not 0), or an exception-flagged code (0x83 ...): unanswered.
      ++counters_.refusedRequests;
      return true;
    case plc::RequestVerdict::RefusedWrite:
      ++counters_.rejectedWrites;
      lastRejected_ = true;
      return refuse(c.exception);
    case plc::RequestVerdict::Exception:
      if (c.exception == plc::ModbusException::IllegalFunction) {
        ++counters_.refusedRequests;  // a function the map does not serve (00, 07, 17 ...)
      } else if (c.isWrite) {
        ++counters_.rejectedWrites;  // a malformed or oversized write
        lastRejected_ = true;
      }
      return refuse(c.exception);
    case plc::RequestVerdict::Serve:
      // A well-formed request of the map: the connection is a Modbus client doing its job (what
      // keeps it from the idle timeout and from eviction as a peer that never asked anything).
      p.served = true;
      p.lastRequest = now;
      break;
  }
  modbus_mapping_t* m = asMapping(mapping_);
  const Span<const std::uint16_t> table(m->tab_registers, static_cast<std::size_t>(m->nb_registers));
  if (c.isWrite) {
    std::uint16_t values[MODBUS_MAX_WRITE_REGISTERS];
    for (std::size_t i = 0; i < c.writeCount; ++i) {
      values[i] = be16(adu.data() + c.writeValuesOffset + 2 * i);
    }
    const Status s = map_.checkWrite(c.writeAddress, Span<const std::uint16_t>(values, c.writeCount), table);
    if (s != Status::Ok) {
      ++counters_.rejectedWrites;
      lastRejected_ = true;
      return refuse(s == Status::OutOfRange ? plc::ModbusException::IllegalDataAddress
                                            : plc::ModbusException::IllegalDataValue);
    }
  }
  // Checked above to be one libmodbus answers without an exception; it writes the reply with one
  // send() on the non-blocking socket (a short or refused send fails the call: the peer is dropped).
  (void)modbus_set_socket(ctx_, p.fd);
  if (modbus_reply(ctx_, adu.data(), static_cast<int>(adu.size()), m) < 0) {
    ++counters_.sendFailures;
    ++counters_.requestErrors;
    return false;
  }
  ++counters_.requests;
  if (c.isWrite) {
    lastRejected_ = false;  // cleared only by a write actually applied
    const Result<plc::PlcCommand> cmd = map_.decodeCommand(table);
    if (cmd.ok()) {
      acceptCommand(cmd.value(), now);
    }
  }
  return true;
}

Status ModbusPlcLink::failClient() noexcept {
  if (clientFd_ >= 0) {
    ::close(clientFd_);
    clientFd_ = -1;
  }
  if (clientConnected_) {
    ++counters_.disconnects;
  }
  clientConnected_ = false;
  phase_ = ClientPhase::Idle;
  return Status::Lost;
}

bool ModbusPlcLink::sendClientRequest(std::size_t length, Timestamp now) noexcept {
  clientFramer_.next();
  phaseDeadline_ = now + config_.responseTimeout;
  ++counters_.requests;
  return sendAll(clientFd_, clientRequest_.data(), length);
}

Status ModbusPlcLink::startConnect(Timestamp now) noexcept {
  nextAttempt_ = now + config_.reconnectInterval;
  Status s = Status::Ok;
  clientFd_ = startTcpConnect(config_.address, config_.port, s);
  if (clientFd_ < 0) {
    ++counters_.connectFailures;
    return s;
  }
  phase_ = ClientPhase::Connecting;  // also when connected at once: the next step sees POLLOUT
  phaseDeadline_ = now + config_.responseTimeout;
  return Status::Ok;
}

Status ModbusPlcLink::exchange(Timestamp now, Duration budget, bool startNew) noexcept {
  // A state machine over the cycles: connect, write the status block (FC 16), read the command
  // block (FC 03); every socket call is non-blocking, the only wait is the caller's `budget`
  // (0 from agvnav-vehicle: never waits). A step not done by its deadline (responseTimeout from
  // the connect or the request) drops the connection. One exchange per call; an exchange still in
  // flight from an earlier call is carried on (the status it writes is then one cycle old).
  if (clientFd_ < 0) {
    if (!startNew || now < nextAttempt_) {
      return Status::Lost;
    }
    const Status s = startConnect(now);
    if (s != Status::Ok) {
      return s == Status::InvalidArgument ? s : Status::Lost;
    }
  }
  const Timestamp waitUntil = monotonicNow() + budget;
  bool wrote = false;
  for (int step = 0; step < 16; ++step) {
    const Timestamp t = monotonicNow();
    const Duration toDeadline = phaseDeadline_ - t;
    const Duration toWaitEnd = waitUntil - t;
    const Duration wait = toWaitEnd < toDeadline ? toWaitEnd : toDeadline;
    if (phase_ == ClientPhase::Connecting) {
      pollfd p{clientFd_, POLLOUT, 0};
      if (::poll(&p, 1, pollMs(wait)) == 1) {
        int err = 0;
        socklen_t len = sizeof err;
        if (getsockopt(clientFd_, SOL_SOCKET, SO_ERROR, &err, &len) != 0 || err != 0) {
          ++counters_.connectFailures;
          return failClient();
        }
        clientConnected_ = true;
        ++counters_.connects;
        phase_ = ClientPhase::Idle;
        continue;
      }
      if (monotonicNow() >= phaseDeadline_) {
        ++counters_.connectFailures;
        return failClient();
      }
      return Status::Lost;  // still connecting: carried on by the next call
    }
    if (phase_ == ClientPhase::Idle) {
      if (wrote || !startNew) {
        return Status::Ok;
      }
      wrote = true;
      const std::size_t n =
          plc::buildWriteMultipleRequest(++transaction_, 0xFF, config_.remoteStatusBase,
                                         Span<const std::uint16_t>(table_.data() + plc::PlcRegisterMap::kStatusBase,
                                                                   plc::PlcRegisterMap::kStatusCount),
                                         clientRequest_);
      if (!sendClientRequest(n, t)) {
        ++counters_.requestErrors;
        return failClient();
      }
      phase_ = ClientPhase::AwaitWrite;
      continue;
    }
    // AwaitWrite / AwaitRead: take what the socket holds, never more than the reply.
    for (int reads = 0; reads < kMaxReadsPerVisit && !clientFramer_.complete(); ++reads) {
      const Span<std::uint8_t> space = clientFramer_.space();
      const ssize_t r = ::recv(clientFd_, space.data(), space.size(), MSG_DONTWAIT);
      if (r == 0 || (r < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) {
        ++counters_.requestErrors;  // the PLC closed or the link broke
        return failClient();
      }
      if (r < 0) {
        break;
      }
      if (clientFramer_.commit(static_cast<std::size_t>(r)) != Status::Ok) {
        ++counters_.requestErrors;
        return failClient();
      }
    }
    if (!clientFramer_.complete()) {
      if (monotonicNow() >= phaseDeadline_) {
        ++counters_.requestErrors;  // no whole reply within responseTimeout of the request
        return failClient();
      }
      pollfd p{clientFd_, POLLIN, 0};
      if (wait.ns <= 0 || ::poll(&p, 1, pollMs(wait)) <= 0) {
        return Status::Ok;  // connected, reply awaited by the next call
      }
      continue;
    }
    const bool isRead = phase_ == ClientPhase::AwaitRead;
    const std::size_t requestLength = isRead ? 12U : 13U + 2U * plc::PlcRegisterMap::kStatusCount;
    std::uint16_t block[plc::PlcRegisterMap::kCommandCount] = {};
    plc::ModbusException exception = plc::ModbusException::None;
    const Status s =
        plc::checkModbusResponse(clientFramer_.adu(), Span<const std::uint8_t>(clientRequest_.data(), requestLength),
                                 isRead ? Span<std::uint16_t>(block) : Span<std::uint16_t>{}, exception);
    clientFramer_.next();
    if (s == Status::Malformed) {
      ++counters_.requestErrors;
      return failClient();
    }
    if (s == Status::Rejected) {
      ++counters_.requestErrors;  // the PLC answered with an exception: its map is not ours
    }
    if (!isRead && config_.clientReadsCommands) {
      const std::size_t n = plc::buildReadHoldingRequest(++transaction_, 0xFF, config_.remoteCommandBase,
                                                         plc::PlcRegisterMap::kCommandCount, clientRequest_);
      if (!sendClientRequest(n, monotonicNow())) {
        ++counters_.requestErrors;
        return failClient();
      }
      phase_ = ClientPhase::AwaitRead;
      continue;
    }
    phase_ = ClientPhase::Idle;
    if (isRead && s == Status::Ok) {
      const Result<plc::PlcCommand> c = map_.decodeCommandBlock(block);
      if (!c.ok()) {
        ++counters_.rejectedWrites;
        lastRejected_ = true;
      } else {
        lastRejected_ = false;
        acceptCommand(c.value(), now);
      }
    }
  }
  return clientConnected_ ? Status::Ok : Status::Lost;
}

}  // namespace agv::drivers
