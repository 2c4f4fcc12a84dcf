#include "agv/drivers/linux/udp_receiver.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <ctime>

#include "agv/drivers/linux/monotonic_clock.hpp"
#include "receive_control.hpp"

namespace agv::drivers {

namespace {
std::int64_t toNs(const timespec& t) noexcept {
  return static_cast<std::int64_t>(t.tv_sec) * 1000000000LL + static_cast<std::int64_t>(t.tv_nsec);
}
Timestamp realtimeNow() noexcept {
  timespec t{};
  (void)clock_gettime(CLOCK_REALTIME, &t);
  return Timestamp::fromNanoseconds(toNs(t));
}
}  // namespace

UdpReceiver::~UdpReceiver() {
  close();
}

void UdpReceiver::close() noexcept {
  if (fd_ >= 0) {
    (void)::close(fd_);
  }
  fd_ = -1;
  localPort_ = 0;
}

Status UdpReceiver::open() noexcept {
  close();
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(config_.port);
  if (::inet_pton(AF_INET, config_.bindAddress, &addr.sin_addr) != 1) {
    return Status::InvalidArgument;
  }
  fd_ = ::socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd_ < 0) {
    return Status::DeviceFault;
  }
  const int one = 1;
  bool ok = ::setsockopt(fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one)) == 0 &&
            ::setsockopt(fd_, SOL_SOCKET, SO_TIMESTAMPNS, &one, sizeof(one)) == 0 &&
            ::setsockopt(fd_, SOL_SOCKET, SO_RXQ_OVFL, &one, sizeof(one)) == 0;
  if (ok && config_.receiveBufferBytes > 0) {
    ok = ::setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &config_.receiveBufferBytes, sizeof(config_.receiveBufferBytes)) == 0;
  }
  if (ok) {
    ok = ::bind(fd_, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) == 0;
  }
  sockaddr_in bound{};
  socklen_t len = sizeof(bound);
  if (ok) {
    ok = ::getsockname(fd_, reinterpret_cast<sockaddr*>(&bound), &len) == 0;
  }
  if (!ok) {
    close();
    return Status::DeviceFault;
  }
  localPort_ = ntohs(bound.sin_port);
  lastKernelDrops_ = 0;
  haveStamp_ = false;
  return Status::Ok;
}

Status UdpReceiver::receive(Span<std::uint8_t> buf, Duration timeout, std::size_t& n, Timestamp& stamp) noexcept {
  n = 0;
  if (fd_ < 0) {
    return Status::NotInitialized;
  }
  pollfd p{};
  p.fd = fd_;
  p.events = POLLIN;
  const std::int64_t ms = timeout.ns <= 0 ? 0 : (timeout.ns + 999999) / 1000000;
  const int ready = ::poll(&p, 1, static_cast<int>(ms > 60000 ? 60000 : ms));
  if (ready <= 0) {
    return Status::Timeout;  // nothing (or EINTR: the caller calls again)
  }
  detail::ReceiveControl rc;
  int flags = 0;
  const ssize_t got = detail::receiveWithControl(fd_, buf.data(), buf.size(), rc, flags);
  if (got < 0) {
    const int err = errno;
    if (err == EAGAIN || err == EWOULDBLOCK || err == EINTR) {
      return Status::Timeout;
    }
    ++counters_.receiveErrors;
    return Status::DeviceFault;
  }
  // Both clocks right after the read map the kernel's wall-clock stamp onto the monotonic clock;
  // the wall clock is read between two monotonic reads and paired with their midpoint.
  const Timestamp monoBefore = monotonicNow();
  const Timestamp realNow = realtimeNow();
  const Timestamp monoAfter = monotonicNow();
  const Timestamp monoNow = monoBefore + Duration{(monoAfter - monoBefore).ns / 2};
  const Timestamp kernel = rc.stamped ? rc.kernelStamp : realNow;  // no kernel stamp: the read time
  if (rc.haveDrops) {
    counters_.kernelDrops += static_cast<std::uint32_t>(rc.drops - lastKernelDrops_);  // wraps
    lastKernelDrops_ = rc.drops;
  }
  if ((flags & MSG_TRUNC) != 0) {
    ++counters_.oversized;
    return Status::Malformed;
  }
  n = static_cast<std::size_t>(got);
  stamp = kernel - (realNow - monoNow);
  if (haveStamp_ && stamp < lastStamp_) {
    stamp = lastStamp_;  // mapping jitter, not a reordering: datagrams are stamped in arrival order
  }
  lastStamp_ = stamp;
  haveStamp_ = true;
  ++counters_.datagrams;
  return Status::Ok;
}

}  // namespace agv::drivers
