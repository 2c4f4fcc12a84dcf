#pragma once
// Internal helper of the Linux drivers (not installed): the control messages of a received socket
// message (SocketCAN frames, UDP datagrams) — the kernel's receive stamp (SO_TIMESTAMPNS) and the
// kernel's drop counter (SO_RXQ_OVFL).

#include <sys/socket.h>
#include <sys/types.h>

#include <cstdint>
#include <cstring>
#include <ctime>

#include "agv/core/timestamp.hpp"

namespace agv::drivers::detail {

/// Room for both control messages (aligned like cmsghdr by the caller).
inline constexpr std::size_t kReceiveControlBytes = CMSG_SPACE(sizeof(timespec)) + CMSG_SPACE(sizeof(std::uint32_t));

struct ReceiveControl {
  Timestamp kernelStamp{};  ///< CLOCK_REALTIME of the kernel's receive, when `stamped`
  bool stamped = false;
  bool haveDrops = false;
  std::uint32_t drops = 0;  ///< the socket's cumulative drop counter (wraps), when `haveDrops`
};

/// Reads the SOL_SOCKET control messages of `msg` after recvmsg().
inline ReceiveControl readReceiveControl(msghdr& msg) noexcept {
  ReceiveControl rc;
  for (cmsghdr* cm = CMSG_FIRSTHDR(&msg); cm != nullptr; cm = CMSG_NXTHDR(&msg, cm)) {
    if (cm->cmsg_level != SOL_SOCKET) {
      continue;
    }
    if (cm->cmsg_type == SCM_TIMESTAMPNS && cm->cmsg_len >= CMSG_LEN(sizeof(timespec))) {
      timespec ts{};
      std::memcpy(&ts, CMSG_DATA(cm), sizeof(ts));
      rc.kernelStamp = Timestamp::fromNanoseconds(static_cast<std::int64_t>(ts.tv_sec) * 1000000000LL +
                                                  static_cast<std::int64_t>(ts.tv_nsec));
      rc.stamped = rc.kernelStamp.ns != 0;
    } else if (cm->cmsg_type == SO_RXQ_OVFL && cm->cmsg_len >= CMSG_LEN(sizeof(std::uint32_t))) {
      std::memcpy(&rc.drops, CMSG_DATA(cm), sizeof(rc.drops));
      rc.haveDrops = true;
    }
  }
  return rc;
}

/// One recvmsg(MSG_DONTWAIT) of a message into [data, data + len) with room for both control
/// messages, which are read into `rc`; `flags` = the message's msg_flags (MSG_TRUNC: cut). Returns
/// recvmsg's result (-1 with errno set: nothing read, `rc` untouched).
inline ssize_t receiveWithControl(int fd, void* data, std::size_t len, ReceiveControl& rc, int& flags) noexcept {
  iovec iov{};
  iov.iov_base = data;
  iov.iov_len = len;
  alignas(cmsghdr) unsigned char control[kReceiveControlBytes];
  msghdr msg{};
  msg.msg_iov = &iov;
  msg.msg_iovlen = 1;
  msg.msg_control = control;
  msg.msg_controllen = sizeof(control);
  const ssize_t n = ::recvmsg(fd, &msg, MSG_DONTWAIT);
  if (n >= 0) {
    rc = readReceiveControl(msg);
    flags = msg.msg_flags;
  }
  return n;
}

}  // namespace agv::drivers::detail
