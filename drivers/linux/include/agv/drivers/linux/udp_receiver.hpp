#pragma once
/// @file udp_receiver.hpp
/// Non-blocking UDP receiver of a lidar's data packets (Velodyne: port 2368, 1206 bytes; Ouster:
/// port 7502, up to 24 832 bytes: size the buffer to the unit's packet), Linux sockets.
///
/// Each datagram is stamped with the kernel's receive time (SO_TIMESTAMPNS) mapped onto
/// CLOCK_MONOTONIC (the drivers' clock, see monotonic_clock.hpp), as the SocketCAN bus does.
/// Datagrams the kernel dropped because the socket buffer was full are counted (SO_RXQ_OVFL), and so
/// are datagrams larger than the caller's buffer (cut by the kernel: refused, not delivered).
/// No heap; every call returns within the timeout it is given.

#include <cstddef>
#include <cstdint>

#include "agv/core/span.hpp"
#include "agv/core/status.hpp"
#include "agv/core/timestamp.hpp"

namespace agv::drivers {

struct UdpReceiverConfig {
  char bindAddress[64] = "0.0.0.0";  ///< numeric IPv4 address to listen on (0.0.0.0: every interface)
  std::uint16_t port = 2368;         ///< Velodyne data port; 0 = any free port (tests)
  int receiveBufferBytes = 4 << 20;  ///< SO_RCVBUF (a VLP-16 sends ~0.9 MB/s); <= 0 keeps the default
};

struct UdpReceiverCounters {
  std::uint32_t datagrams = 0;      ///< delivered to the caller
  std::uint32_t kernelDrops = 0;    ///< dropped by the kernel (socket buffer full)
  std::uint32_t oversized = 0;      ///< refused: larger than the caller's buffer
  std::uint32_t receiveErrors = 0;  ///< recvmsg failures other than "nothing to read"
};

class UdpReceiver {
 public:
  explicit UdpReceiver(const UdpReceiverConfig& config) noexcept : config_(config) {}
  ~UdpReceiver();
  UdpReceiver(const UdpReceiver&) = delete;
  UdpReceiver& operator=(const UdpReceiver&) = delete;

  /// Opens and binds the socket (non-blocking). Ok; InvalidArgument (bad address); DeviceFault
  /// (socket, option or bind failed, e.g. the port is taken). Reopens when already open.
  Status open() noexcept;
  void close() noexcept;
  bool isOpen() const noexcept { return fd_ >= 0; }
  /// The bound port (the chosen one when configured with 0); 0 when closed.
  std::uint16_t localPort() const noexcept { return localPort_; }

  /// Receives one datagram into `buf`, waiting at most `timeout` for it. Ok with `n` bytes and its
  /// receive `stamp` (monotonic; the kernel's wall-clock arrival stamp mapped onto the monotonic
  /// clock, never earlier than the previous datagram's: the kernel stamps in arrival order, and the
  /// microsecond jitter of the mapping must not reorder a burst); Timeout (nothing arrived); Malformed (a datagram
  /// larger than `buf`: refused and counted); NotInitialized (not open); DeviceFault (socket error, counted).
  Status receive(Span<std::uint8_t> buf, Duration timeout, std::size_t& n, Timestamp& stamp) noexcept;

  const UdpReceiverCounters& counters() const noexcept { return counters_; }
  /// The socket while open (-1 otherwise), for a caller that polls several devices.
  int fileDescriptor() const noexcept { return fd_; }

 private:
  UdpReceiverConfig config_;
  int fd_ = -1;
  std::uint16_t localPort_ = 0;
  std::uint32_t lastKernelDrops_ = 0;
  Timestamp lastStamp_{};
  bool haveStamp_ = false;
  UdpReceiverCounters counters_{};
};

}  // namespace agv::drivers
