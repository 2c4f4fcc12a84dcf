#include "agv/drivers/linux/modbus_plc_link.hpp"

#include "agv/drivers/linux/tcp_stream.hpp"

#include <modbus.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>

namespace agv::drivers {
namespace {
constexpr int kMaxRequestsPerCycle = 16;  // bound of the server loop in one cycle

modbus_mapping_t* asMapping(void* p) noexcept {
  return static_cast<modbus_mapping_t*>(p);
}

void setTimeout(modbus_t* ctx, Duration d, int (*setter)(modbus_t*, std::uint32_t, std::uint32_t)) noexcept {
  const std::int64_t us = d.ns > 0 ? d.ns / 1000 : 1000;
  (void)setter(ctx, static_cast<std::uint32_t>(us / 1000000), static_cast<std::uint32_t>(us % 1000000));
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
  clients_.fill(-1);
  if (config_.maxConnections < 1) {
    config_.maxConnections = 1;
  }
  if (config_.maxConnections > kMaxClients) {
    config_.maxConnections = kMaxClients;
  }
}

ModbusPlcLink::~ModbusPlcLink() {
  for (int i = 0; i < kMaxClients; ++i) {
    if (clients_[static_cast<std::size_t>(i)] >= 0) {
      ::close(clients_[static_cast<std::size_t>(i)]);
    }
  }
  if (listenFd_ >= 0) {
    ::close(listenFd_);
  }
  if (ctx_ != nullptr) {
    if (config_.role == PlcLinkRole::Client) {
      modbus_close(ctx_);
    }
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
  for (const int fd : clients_) {
    if (fd >= 0) {
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
  setTimeout(ctx_, config_.responseTimeout, modbus_set_response_timeout);
  setTimeout(ctx_, config_.responseTimeout, modbus_set_byte_timeout);
  setTimeout(ctx_, config_.responseTimeout, modbus_set_indication_timeout);
  sequenceSeen_ = server;  // the server's table starts at 0: the PLC's first sequence is new
  if (!server) {
    return Status::Ok;
  }
  mapping_ = modbus_mapping_new_start_address(0, 0, 0, 0, 0, plc::PlcRegisterMap::kRegisterCount, 0, 0);
  if (mapping_ == nullptr) {
    return Status::CapacityExceeded;
  }
  listenFd_ = modbus_tcp_listen(ctx_, config_.maxConnections);
  if (listenFd_ < 0) {
    return Status::Lost;
  }
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
  return exchange(now);
}

void ModbusPlcLink::closeClient(int index) noexcept {
  int& fd = clients_[static_cast<std::size_t>(index)];
  if (fd >= 0) {
    ::close(fd);
    fd = -1;
    ++counters_.disconnects;
  }
}

Status ModbusPlcLink::serve(Timestamp now, Duration budget) noexcept {
  int handled = 0;
  bool first = true;
  // One poll waits up to the budget; then pending requests are drained without waiting, at most
  // kMaxRequestsPerCycle of them.
  while (handled < kMaxRequestsPerCycle) {
    pollfd fds[kMaxClients + 1];
    int idx[kMaxClients + 1];
    nfds_t n = 0;
    fds[n] = pollfd{listenFd_, POLLIN, 0};
    idx[n++] = -1;
    for (int i = 0; i < kMaxClients; ++i) {
      if (clients_[static_cast<std::size_t>(i)] >= 0) {
        fds[n] = pollfd{clients_[static_cast<std::size_t>(i)], POLLIN, 0};
        idx[n++] = i;
      }
    }
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
        const int fd = ::accept4(listenFd_, nullptr, nullptr, SOCK_CLOEXEC);
        if (fd < 0) {
          continue;
        }
        int slot = -1;
        for (int i = 0; i < config_.maxConnections; ++i) {
          if (clients_[static_cast<std::size_t>(i)] < 0) {
            slot = i;
            break;
          }
        }
        if (slot < 0) {
          ::close(fd);
          ++counters_.connectFailures;
        } else {
          clients_[static_cast<std::size_t>(slot)] = fd;
          ++counters_.connects;
        }
        continue;
      }
      if ((fds[k].revents & (POLLIN | POLLHUP | POLLERR)) != 0) {
        const int fd = clients_[static_cast<std::size_t>(idx[k])];
        handleRequest(fd, now);
        if (modbus_get_socket(ctx_) < 0) {  // the exchange failed: drop this connection
          clients_[static_cast<std::size_t>(idx[k])] = -1;
          ::close(fd);
          ++counters_.disconnects;
        }
        ++handled;
      }
    }
  }
  (void)modbus_set_socket(ctx_, -1);
  return Status::Ok;
}

void ModbusPlcLink::handleRequest(int fd, Timestamp now) noexcept {
  std::uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
  (void)modbus_set_socket(ctx_, fd);
  const int rc = modbus_receive(ctx_, query);
  if (rc < 0) {
    ++counters_.requestErrors;
    (void)modbus_set_socket(ctx_, -1);  // tells serve() to drop the connection
    return;
  }
  if (rc == 0) {
    return;  // not for us
  }
  const int hl = modbus_get_header_length(ctx_);
  const auto len = static_cast<std::size_t>(rc);
  const auto h = static_cast<std::size_t>(hl);
  const std::uint8_t function = query[h];
  // MBAP protocol identifier 0 (Modbus): anything else is not a Modbus request and is discarded
  // unanswered, as the Modbus TCP specification says (a write with protocol id 0xFFFF used to be
  // applied).
  if (h >= 7 && (query[2] != 0U || query[3] != 0U)) {
    ++counters_.refusedRequests;
    return;
  }
  // Only the functions of the register map are served: read holding registers (03), write single
  // register (06), write multiple registers (16), read/write registers (23); the coil and mask
  // writes below are refused as writes. Every other code (00, diagnostics 07/08, report server id
  // 17, which would tell the library and its version, an exception-flagged 0x80+ code ...) gets
  // exception 01, without touching the command state.
  const bool served = function == MODBUS_FC_READ_HOLDING_REGISTERS || function == MODBUS_FC_WRITE_SINGLE_REGISTER ||
                      function == MODBUS_FC_WRITE_MULTIPLE_REGISTERS || function == MODBUS_FC_WRITE_AND_READ_REGISTERS;
  const bool refusedWrite = function == MODBUS_FC_MASK_WRITE_REGISTER || function == MODBUS_FC_WRITE_SINGLE_COIL ||
                            function == MODBUS_FC_WRITE_MULTIPLE_COILS;
  if (!served && !refusedWrite) {
    ++counters_.refusedRequests;
    (void)modbus_reply_exception(ctx_, query, MODBUS_EXCEPTION_ILLEGAL_FUNCTION);
    ++counters_.requests;
    return;
  }
  modbus_mapping_t* m = asMapping(mapping_);
  const Span<const std::uint16_t> table(m->tab_registers, static_cast<std::size_t>(m->nb_registers));
  std::uint16_t values[MODBUS_MAX_WRITE_REGISTERS];
  std::size_t count = 0;
  std::uint16_t address = 0;
  bool isWrite = false;
  bool malformed = false;
  if (function == MODBUS_FC_WRITE_SINGLE_REGISTER) {
    isWrite = true;
    malformed = len < h + 5;
    if (!malformed) {
      address = be16(query + h + 1);
      values[0] = be16(query + h + 3);
      count = 1;
    }
  } else if (function == MODBUS_FC_WRITE_MULTIPLE_REGISTERS || function == MODBUS_FC_WRITE_AND_READ_REGISTERS) {
    isWrite = true;
    const std::size_t at = function == MODBUS_FC_WRITE_MULTIPLE_REGISTERS ? h + 1 : h + 5;
    malformed = len < at + 5;
    if (!malformed) {
      address = be16(query + at);
      count = be16(query + at + 2);
      malformed = count == 0 || count > MODBUS_MAX_WRITE_REGISTERS || len < at + 5 + 2 * count;
      for (std::size_t i = 0; !malformed && i < count; ++i) {
        values[i] = be16(query + at + 5 + 2 * i);
      }
    }
  } else if (function == MODBUS_FC_MASK_WRITE_REGISTER || function == MODBUS_FC_WRITE_SINGLE_COIL ||
             function == MODBUS_FC_WRITE_MULTIPLE_COILS) {
    ++counters_.rejectedWrites;
    lastRejected_ = true;
    (void)modbus_reply_exception(ctx_, query, MODBUS_EXCEPTION_ILLEGAL_FUNCTION);
    ++counters_.requests;
    return;
  }
  if (isWrite) {
    const Status s =
        malformed ? Status::Malformed : map_.checkWrite(address, Span<const std::uint16_t>(values, count), table);
    if (s != Status::Ok) {
      ++counters_.rejectedWrites;
      lastRejected_ = true;
      const unsigned code =
          s == Status::OutOfRange ? MODBUS_EXCEPTION_ILLEGAL_DATA_ADDRESS : MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE;
      (void)modbus_reply_exception(ctx_, query, code);
      ++counters_.requests;
      return;
    }
  }
  if (modbus_reply(ctx_, query, rc, m) < 0) {
    ++counters_.requestErrors;
    (void)modbus_set_socket(ctx_, -1);
    return;
  }
  ++counters_.requests;
  if (isWrite) {
    lastRejected_ = false;
    const Result<plc::PlcCommand> c = map_.decodeCommand(table);
    if (c.ok()) {
      acceptCommand(c.value(), now);
    }
  }
}

Status ModbusPlcLink::exchange(Timestamp now) noexcept {
  if (!clientConnected_) {
    if (now < nextAttempt_) {
      return Status::Lost;
    }
    nextAttempt_ = now + config_.reconnectInterval;
    if (modbus_connect(ctx_) != 0) {  // bounded by the response timeout
      ++counters_.connectFailures;
      return Status::Lost;
    }
    clientConnected_ = true;
    ++counters_.connects;
  }
  ++counters_.requests;
  if (modbus_write_registers(ctx_, config_.remoteStatusBase, plc::PlcRegisterMap::kStatusCount,
                             table_.data() + plc::PlcRegisterMap::kStatusBase) != plc::PlcRegisterMap::kStatusCount) {
    ++counters_.requestErrors;
    modbus_close(ctx_);
    clientConnected_ = false;
    ++counters_.disconnects;
    return Status::Lost;
  }
  if (!config_.clientReadsCommands) {
    return Status::Ok;
  }
  ++counters_.requests;
  std::uint16_t block[plc::PlcRegisterMap::kCommandCount];
  if (modbus_read_registers(ctx_, config_.remoteCommandBase, plc::PlcRegisterMap::kCommandCount, block) !=
      plc::PlcRegisterMap::kCommandCount) {
    ++counters_.requestErrors;
    modbus_close(ctx_);
    clientConnected_ = false;
    ++counters_.disconnects;
    return Status::Lost;
  }
  const Result<plc::PlcCommand> c = map_.decodeCommandBlock(block);
  if (!c.ok()) {
    ++counters_.rejectedWrites;
    lastRejected_ = true;
    return Status::Ok;
  }
  lastRejected_ = false;
  acceptCommand(c.value(), now);
  return Status::Ok;
}

}  // namespace agv::drivers
