#pragma once
/// @file loopback_server.hpp
/// A scripted TCP peer on 127.0.0.1 (ephemeral or given port): the laser of the transport and
/// vehicle tests, and the simulated NAV350 of `agvnav-sim-drives --vehicle` (docs/drives.md).
/// Every wait is bounded. Header-only and allocating (threads, vectors): for tests and simulators,
/// not for the vehicle's own loop.

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <string>
#include <thread>
#include <vector>

namespace agv::drivers {

class LoopbackServer {
 public:
  /// Listens on 127.0.0.1:`port` (0: an ephemeral port).
  explicit LoopbackServer(std::uint16_t port = 0) { ok_ = listenOn(port); }
  ~LoopbackServer() {
    if (thread_.joinable()) {
      thread_.join();
    }
    stopListening();
  }
  bool ok() const { return ok_; }
  std::uint16_t port() const { return port_; }

  /// Stops listening, as a rebooting device: connection attempts are refused until `listenAgain`.
  void stopListening() {
    if (listenFd_ >= 0) {
      ::close(listenFd_);
    }
    listenFd_ = -1;
  }
  /// Listens again on the same port; false when it cannot be bound.
  bool listenAgain() { return listenOn(port_); }

  /// Runs `script` on a thread (joined by the destructor or `join()`).
  void start(std::function<void(LoopbackServer&)> script) {
    thread_ = std::thread([this, script]() { script(*this); });
  }
  void join() {
    if (thread_.joinable()) {
      thread_.join();
    }
  }

  /// Accepts one connection within `ms`; -1 on timeout.
  int accept(int ms = 5000) {
    pollfd p{listenFd_, POLLIN, 0};
    if (::poll(&p, 1, ms) != 1) {
      return -1;
    }
    return ::accept4(listenFd_, nullptr, nullptr, SOCK_CLOEXEC);
  }
  /// Reads until `want` bytes arrived, the peer closed, or `ms` passed.
  static std::vector<std::uint8_t> read(int fd, std::size_t want, int ms = 5000) {
    std::vector<std::uint8_t> got;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(ms);
    while (got.size() < want && std::chrono::steady_clock::now() < deadline) {
      pollfd p{fd, POLLIN, 0};
      if (::poll(&p, 1, 50) != 1) {
        continue;
      }
      std::uint8_t b[4096];
      const ssize_t n = ::recv(fd, b, std::min(sizeof b, want - got.size()), 0);
      if (n <= 0) {
        break;
      }
      got.insert(got.end(), b, b + n);
    }
    return got;
  }
  /// Sends `data` in pieces of `chunk` bytes with a short pause between them (forces split reads).
  static void send(int fd, const std::vector<std::uint8_t>& data, std::size_t chunk = 1 << 20, int pauseMs = 5) {
    for (std::size_t pos = 0; pos < data.size(); pos += chunk) {
      const std::size_t n = std::min(chunk, data.size() - pos);
      std::size_t sent = 0;
      while (sent < n) {
        const ssize_t w = ::send(fd, data.data() + pos + sent, n - sent, MSG_NOSIGNAL);
        if (w <= 0) {
          return;
        }
        sent += static_cast<std::size_t>(w);
      }
      if (pos + n < data.size()) {
        std::this_thread::sleep_for(std::chrono::milliseconds(pauseMs));
      }
    }
  }
  /// Waits (bounded) until the peer closes, then closes.
  static void drainAndClose(int fd, int ms = 5000) {
    (void)read(fd, static_cast<std::size_t>(-1) / 2, ms);
    ::close(fd);
  }

 private:
  bool listenOn(std::uint16_t port) {
    // Close-on-exec: a program the test spawns (agvnav-vehicle) must not inherit the listener and
    // keep the port listening after `stopListening`.
    listenFd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    const int one = 1;
    ::setsockopt(listenFd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons(port);
    const bool ok = ::bind(listenFd_, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0 && ::listen(listenFd_, 4) == 0;
    socklen_t len = sizeof a;
    ::getsockname(listenFd_, reinterpret_cast<sockaddr*>(&a), &len);
    port_ = ntohs(a.sin_port);
    return ok;
  }

  int listenFd_ = -1;
  bool ok_ = false;
  std::uint16_t port_ = 0;
  std::thread thread_;
};

/// A port on 127.0.0.1 with nobody listening (bound, then released).
inline std::uint16_t closedPort() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  socklen_t len = sizeof a;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
  ::close(fd);
  return ntohs(a.sin_port);
}

}  // namespace agv::drivers
