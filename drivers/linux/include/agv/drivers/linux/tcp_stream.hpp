#pragma once
/// @file tcp_stream.hpp
/// Non-blocking TCP client with bounded waits and rate-limited reconnection (Linux sockets).
///
/// Every call returns within the time it is given: connect, read and write never block past their
/// timeout, and a lost connection is retried at most once per `reconnectInterval`, so a dead
/// device cannot stall the caller's cycle.

#include <cstddef>
#include <cstdint>

#include "agv/core/span.hpp"
#include "agv/core/status.hpp"
#include "agv/core/timestamp.hpp"
#include "agv/drivers/linux/monotonic_clock.hpp"

namespace agv::drivers {

/// Address and timing of a TCP peer.
struct TcpStreamConfig {
  char host[64] = "192.168.0.1";                                 ///< numeric IPv4 address of the device
  std::uint16_t port = 2111;                                     ///< SICK CoLa A 2111, CoLa B 2112
  Duration connectTimeout = Duration::fromMilliseconds(1000);    ///< bound of one connection attempt
  Duration reconnectInterval = Duration::fromMilliseconds(500);  ///< minimum time between attempts
};

/// Counters of the connection's life.
struct TcpStreamCounters {
  std::uint32_t connects = 0;         ///< successful connections
  std::uint32_t connectFailures = 0;  ///< attempts that failed or timed out
  std::uint32_t disconnects = 0;      ///< connections lost (peer closed, error) or closed by us
};

/// Starts a non-blocking TCP connection to `host` (numeric IPv4) : `port`, with TCP_NODELAY.
/// Returns the socket with `status` Ok (connected at once) or Timeout (in progress: wait for
/// POLLOUT, then read SO_ERROR); or -1 with InvalidArgument (bad address) or Lost (refused,
/// unreachable, no socket).
int startTcpConnect(const char* host, std::uint16_t port, Status& status) noexcept;

class TcpStream {
 public:
  explicit TcpStream(const TcpStreamConfig& config) noexcept;
  ~TcpStream();
  TcpStream(const TcpStream&) = delete;
  TcpStream& operator=(const TcpStream&) = delete;

  bool connected() const noexcept { return fd_ >= 0; }
  /// Connects when not connected and the reconnect interval has passed since the last attempt;
  /// waits at most `budget` in this call. An attempt not finished within the budget stays pending
  /// (non-blocking connect) and is completed by later calls, until `connectTimeout` from its start:
  /// a caller that must not wait passes 0 and calls again. Ok when connected; Timeout (attempt not
  /// due yet, still pending, or given up after connectTimeout), Lost (refused/unreachable),
  /// InvalidArgument (bad host).
  Status ensureConnected(Duration budget) noexcept;
  /// A connection attempt is pending (started, neither connected nor failed yet).
  bool connecting() const noexcept { return pending_ >= 0; }
  /// Receives what is available into `buf`, waiting at most `timeout` for the first byte.
  /// Ok with n > 0; Timeout with n = 0; Lost when the peer closed or failed (the socket is closed).
  Status read(Span<std::uint8_t> buf, Duration timeout, std::size_t& n) noexcept;
  /// Sends all of `data` within `timeout`; Lost on error (closed), Timeout if not all sent.
  Status writeAll(Span<const std::uint8_t> data, Duration timeout) noexcept;
  /// Closes the connection (counted as a disconnect when it was open).
  void close() noexcept;
  /// The earliest time the next connection attempt is allowed.
  Timestamp nextAttempt() const noexcept { return nextAttempt_; }

  const TcpStreamCounters& counters() const noexcept { return counters_; }
  /// The socket while connected (-1 otherwise), for a caller that waits on it; valid until the next call.
  int fileDescriptor() const noexcept { return fd_; }
  const TcpStreamConfig& config() const noexcept { return config_; }

 private:
  /// Waits at most `budget` (and not past the attempt's deadline) for the pending connect.
  Status finishConnect(Timestamp now, Duration budget) noexcept;

  TcpStreamConfig config_;
  int fd_ = -1;
  int pending_ = -1;             ///< socket of the attempt in progress
  Timestamp pendingDeadline_{};  ///< the attempt's start + connectTimeout
  Timestamp nextAttempt_{};
  TcpStreamCounters counters_{};
};

}  // namespace agv::drivers
