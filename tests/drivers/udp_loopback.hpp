#pragma once
/// @file udp_loopback.hpp
/// Loopback helpers of the UDP receiver's tests: a plain sender socket and a receiver configuration
/// bound to 127.0.0.1 on a free port.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstring>

#include "agv/drivers/linux/udp_receiver.hpp"

namespace agv::test {

/// A plain UDP sender to 127.0.0.1:port.
struct UdpSender {
  int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in to{};
  explicit UdpSender(std::uint16_t port) {
    to.sin_family = AF_INET;
    to.sin_port = htons(port);
    to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  }
  ~UdpSender() { ::close(fd); }
  UdpSender(const UdpSender&) = delete;
  UdpSender& operator=(const UdpSender&) = delete;
  /// True when the whole datagram was sent.
  bool send(const std::uint8_t* p, std::size_t n) const {
    return ::sendto(fd, p, n, 0, reinterpret_cast<const sockaddr*>(&to), sizeof(to)) == static_cast<ssize_t>(n);
  }
};

/// A receiver on 127.0.0.1, any free port, with SO_RCVBUF `rcvbuf` (<= 0: the kernel's default).
inline drivers::UdpReceiverConfig loopbackReceiver(int rcvbuf) {
  drivers::UdpReceiverConfig c;
  std::strcpy(c.bindAddress, "127.0.0.1");
  c.port = 0;
  c.receiveBufferBytes = rcvbuf;
  return c;
}

}  // namespace agv::test
