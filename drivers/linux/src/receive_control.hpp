#pragma once
// Internal helper of the Linux drivers (not installed): the control messages of a received socket
// message (SocketCAN frames, UDP datagrams) — the kernel's receive stamp (SO_TIMESTAMPNS) and the
// kernel's drop counter (SO_RXQ_OVFL).

#include <sys/socket.h>

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

}  // namespace agv::drivers::detail
