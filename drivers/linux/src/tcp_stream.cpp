#include "agv/drivers/linux/tcp_stream.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>
#include <cerrno>

namespace agv::drivers {
namespace {
int toPollMs(Duration d) noexcept {
  if (d.ns <= 0) {
    return 0;
  }
  const std::int64_t ms = (d.ns + 999999) / 1000000;
  return ms > 60000 ? 60000 : static_cast<int>(ms);
}
}  // namespace

int startTcpConnect(const char* host, std::uint16_t port, Status& status) noexcept {
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  if (inet_pton(AF_INET, host, &addr.sin_addr) != 1) {
    status = Status::InvalidArgument;
    return -1;
  }
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd < 0) {
    status = Status::Lost;
    return -1;
  }
  const int one = 1;
  (void)setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  // NOLINTNEXTLINE(cppcoreguidelines-pro-type-reinterpret-cast): the sockets API
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) == 0) {
    status = Status::Ok;
    return fd;
  }
  if (errno != EINPROGRESS) {
    ::close(fd);
    status = Status::Lost;
    return -1;
  }
  status = Status::Timeout;
  return fd;
}

TcpStream::TcpStream(const TcpStreamConfig& config) noexcept : config_(config) {
  config_.host[sizeof(config_.host) - 1] = '\0';
}

TcpStream::~TcpStream() {
  if (fd_ >= 0) {
    ::close(fd_);
  }
  if (pending_ >= 0) {
    ::close(pending_);
  }
}

void TcpStream::close() noexcept {
  if (pending_ >= 0) {  // an attempt in progress is abandoned, not counted
    ::close(pending_);
    pending_ = -1;
  }
  if (fd_ >= 0) {
    ::close(fd_);
    fd_ = -1;
    ++counters_.disconnects;
  }
}

Status TcpStream::ensureConnected(Duration budget) noexcept {
  if (fd_ >= 0) {
    return Status::Ok;
  }
  const Timestamp now = monotonicNow();
  if (pending_ >= 0) {
    return finishConnect(now, budget);
  }
  if (now < nextAttempt_) {
    return Status::Timeout;
  }
  nextAttempt_ = now + config_.reconnectInterval;
  Status s = Status::Ok;
  const int fd = startTcpConnect(config_.host, config_.port, s);
  if (fd < 0) {
    ++counters_.connectFailures;
    return s;
  }
  if (s == Status::Ok) {
    fd_ = fd;
    ++counters_.connects;
    return Status::Ok;
  }
  pending_ = fd;
  pendingDeadline_ = now + config_.connectTimeout;
  return finishConnect(now, budget);
}

Status TcpStream::finishConnect(Timestamp now, Duration budget) noexcept {
  const Duration left = pendingDeadline_ - now;
  const Duration wait = budget < left ? budget : left;
  pollfd p{pending_, POLLOUT, 0};
  const int rc = ::poll(&p, 1, toPollMs(wait));
  if (rc == 1) {
    int err = 0;
    socklen_t len = sizeof err;
    const bool ok = getsockopt(pending_, SOL_SOCKET, SO_ERROR, &err, &len) == 0 && err == 0;
    if (ok) {
      fd_ = pending_;
      pending_ = -1;
      ++counters_.connects;
      return Status::Ok;
    }
    ::close(pending_);
    pending_ = -1;
    ++counters_.connectFailures;
    return Status::Lost;
  }
  if (monotonicNow() >= pendingDeadline_) {  // given up after connectTimeout
    ::close(pending_);
    pending_ = -1;
    ++counters_.connectFailures;
  }
  return Status::Timeout;
}

Status TcpStream::read(Span<std::uint8_t> buf, Duration timeout, std::size_t& n) noexcept {
  n = 0;
  if (fd_ < 0) {
    return Status::Lost;
  }
  if (buf.empty()) {
    return Status::InvalidArgument;
  }
  pollfd p{fd_, POLLIN, 0};
  const int rc = ::poll(&p, 1, toPollMs(timeout));
  if (rc == 0 || (rc < 0 && errno == EINTR)) {
    return Status::Timeout;
  }
  if (rc < 0) {
    close();
    return Status::Lost;
  }
  const ssize_t got = ::recv(fd_, buf.data(), buf.size(), MSG_DONTWAIT);
  if (got > 0) {
    n = static_cast<std::size_t>(got);
    return Status::Ok;
  }
  if (got < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) {
    return Status::Timeout;
  }
  close();  // 0 = orderly shutdown by the peer, < 0 = error
  return Status::Lost;
}

Status TcpStream::writeAll(Span<const std::uint8_t> data, Duration timeout) noexcept {
  if (fd_ < 0) {
    return Status::Lost;
  }
  const Timestamp deadline = monotonicNow() + timeout;
  std::size_t sent = 0;
  // Each pass sends some bytes or waits (poll) for room until the deadline.
  while (sent < data.size()) {
    const ssize_t w = ::send(fd_, data.data() + sent, data.size() - sent, MSG_NOSIGNAL | MSG_DONTWAIT);
    if (w > 0) {
      sent += static_cast<std::size_t>(w);
      continue;
    }
    if (w < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) {
      close();
      return Status::Lost;
    }
    const Duration left = deadline - monotonicNow();
    if (left.ns <= 0) {
      return Status::Timeout;
    }
    pollfd p{fd_, POLLOUT, 0};
    (void)::poll(&p, 1, toPollMs(left));
  }
  return Status::Ok;
}

}  // namespace agv::drivers
