#include "agv/drivers/linux/socketcan_bus.hpp"

#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <ctime>

#include "receive_control.hpp"

namespace agv::drivers {

const char* toString(CanLinkState state) noexcept {
  switch (state) {
    case CanLinkState::Closed:
      return "closed";
    case CanLinkState::Up:
      return "up";
    case CanLinkState::Down:
      return "down";
  }
  return "unknown";
}

namespace {

// Reads handled by one receive() call before it reports a timeout: a flood of malformed reads or
// link flaps cannot keep the caller's cycle inside the driver.
constexpr int kMaxPassesPerReceive = 64;

std::int64_t toNs(const timespec& t) noexcept {
  return static_cast<std::int64_t>(t.tv_sec) * 1000000000LL + static_cast<std::int64_t>(t.tv_nsec);
}

Timestamp clockNow(clockid_t clock) noexcept {
  timespec t{};
  (void)clock_gettime(clock, &t);
  return Timestamp::fromNanoseconds(toNs(t));
}

timespec toTimespec(Duration d) noexcept {
  const std::int64_t ns = d.ns < 0 ? 0 : d.ns;
  timespec t{};
  t.tv_sec = static_cast<time_t>(ns / 1000000000LL);
  t.tv_nsec = static_cast<long>(ns % 1000000000LL);
  return t;
}

// errno values meaning the interface is down or gone: the socket must be reopened.
bool isLinkLoss(int err) noexcept {
  return err == ENETDOWN || err == ENODEV || err == ENXIO || err == ENETUNREACH;
}

bool validFilter(const CanFilter& f) noexcept {
  const std::uint32_t range = f.extended ? CAN_EFF_MASK : CAN_SFF_MASK;
  return (f.id & ~range) == 0U && (f.mask & ~range) == 0U;
}

Status fromErrno(int err) noexcept {
  if (err == EAFNOSUPPORT || err == EPROTONOSUPPORT) {
    return Status::Unsupported;
  }
  if (err == ENODEV || err == ENXIO) {
    return Status::NotFound;
  }
  return Status::DeviceFault;
}

}  // namespace

SocketCanBus::~SocketCanBus() {
  closeSocket();
}

Status SocketCanBus::open(const SocketCanConfig& config) noexcept {
  close();
  const char* name = config.interfaceName;
  if (name == nullptr || name[0] == '\0') {
    return Status::InvalidArgument;
  }
  std::size_t len = 0;
  while (len < sizeof(name_) && name[len] != '\0') {
    ++len;
  }
  if (len >= sizeof(name_)) {  // IFNAMSIZ includes the terminator
    return Status::InvalidArgument;
  }
  for (std::size_t i = 0; i < config.filters.size(); ++i) {
    if (!validFilter(config.filters[i])) {
      return Status::InvalidArgument;
    }
  }
  if (config.reopenBackoffInitial.ns <= 0 || config.reopenBackoffMax < config.reopenBackoffInitial ||
      config.busOffReopenAfter.ns <= 0 || config.receiveBufferBytes < 0) {
    return Status::InvalidArgument;
  }
  std::memcpy(name_, name, len);
  name_[len] = '\0';
  config_ = config;
  config_.interfaceName = name_;

  const Status s = openSocket();
  if (s != Status::Ok) {
    closeSocket();
    health_.link = CanLinkState::Closed;
    return s;
  }
  configured_ = true;
  backoff_ = config_.reopenBackoffInitial;
  return Status::Ok;
}

void SocketCanBus::close() noexcept {
  closeSocket();
  configured_ = false;
  health_.link = CanLinkState::Closed;
}

void SocketCanBus::closeSocket() noexcept {
  if (fd_ >= 0) {
    (void)::close(fd_);
    fd_ = -1;
  }
}

Status SocketCanBus::openSocket() noexcept {
  closeSocket();
  const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) {
    const int err = errno;
    health_.lastErrno = err;
    health_.lastFailure = fromErrno(err);
    return health_.lastFailure;
  }
  fd_ = fd;
  auto fail = [this](int err) noexcept {
    health_.lastErrno = err;
    health_.lastFailure = fromErrno(err);
    closeSocket();
    return health_.lastFailure;
  };

  ifreq ifr{};
  std::memcpy(ifr.ifr_name, name_, sizeof(name_) <= IFNAMSIZ ? sizeof(name_) : IFNAMSIZ);
  if (::ioctl(fd_, SIOCGIFINDEX, &ifr) < 0) {
    return fail(errno == ENODEV ? ENODEV : errno);
  }
  const int ifindex = ifr.ifr_ifindex;
  if (::ioctl(fd_, SIOCGIFFLAGS, &ifr) < 0) {
    return fail(errno);
  }
  if ((static_cast<unsigned>(ifr.ifr_flags) & static_cast<unsigned>(IFF_UP)) == 0U) {
    return fail(ENETDOWN);
  }

  // Receive filters: none given = the kernel default (every frame).
  if (!config_.filters.empty()) {
    can_filter filters[kMaxCanFilters];
    for (std::size_t i = 0; i < config_.filters.size(); ++i) {
      const CanFilter& f = config_.filters[i];
      // The format flag is always compared, so a standard filter never passes an extended frame.
      filters[i].can_id = f.id | (f.extended ? CAN_EFF_FLAG : 0U);
      filters[i].can_mask = f.mask | CAN_EFF_FLAG;
    }
    const auto bytes = static_cast<socklen_t>(config_.filters.size() * sizeof(can_filter));
    if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_FILTER, filters, bytes) < 0) {
      return fail(errno);
    }
  }
  const can_err_mask_t errMask = config_.receiveErrorFrames ? (config_.errorClasses & CAN_ERR_MASK) : 0U;
  if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &errMask, sizeof(errMask)) < 0) {
    return fail(errno);
  }
  const int loopback = config_.loopback ? 1 : 0;
  const int own = (config_.loopback && config_.receiveOwnFrames) ? 1 : 0;
  const int one = 1;
  if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_LOOPBACK, &loopback, sizeof(loopback)) < 0 ||
      ::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_RECV_OWN_MSGS, &own, sizeof(own)) < 0 ||
      ::setsockopt(fd_, SOL_SOCKET, SO_TIMESTAMPNS, &one, sizeof(one)) < 0 ||
      ::setsockopt(fd_, SOL_SOCKET, SO_RXQ_OVFL, &one, sizeof(one)) < 0) {
    return fail(errno);
  }
  if (config_.receiveBufferBytes > 0 &&
      ::setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &config_.receiveBufferBytes, sizeof(config_.receiveBufferBytes)) < 0) {
    return fail(errno);
  }

  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = ifindex;
  if (::bind(fd_, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) < 0) {
    return fail(errno);
  }
  lastKernelDrops_ = 0;
  health_.link = CanLinkState::Up;
  health_.controller = CanControllerState::ErrorActive;
  health_.lastFailure = Status::Ok;
  health_.lastErrno = 0;
  return Status::Ok;
}

void SocketCanBus::loseLink(Status reason, int err, Timestamp now) noexcept {
  closeSocket();
  health_.link = CanLinkState::Down;
  health_.lastFailure = reason;
  health_.lastErrno = err;
  ++health_.counters.linkLosses;
  nextReopen_ = now + backoff_;
}

void SocketCanBus::maintain() noexcept {
  if (!configured_) {
    return;
  }
  const Timestamp now = monotonicNow();
  if (health_.link == CanLinkState::Up && health_.controller == CanControllerState::BusOff &&
      now - busOffSince_ >= config_.busOffReopenAfter) {
    // No restart report: start afresh (the socket's queue and state are reset, filters re-applied).
    ++health_.counters.reopenAttempts;
    if (openSocket() == Status::Ok) {
      ++health_.counters.reopens;
    } else {
      loseLink(health_.lastFailure, health_.lastErrno, now);
    }
    return;
  }
  if (health_.link == CanLinkState::Down && now >= nextReopen_) {
    ++health_.counters.reopenAttempts;
    if (openSocket() == Status::Ok) {
      ++health_.counters.reopens;
      backoff_ = config_.reopenBackoffInitial;
    } else {
      health_.link = CanLinkState::Down;
      const Duration doubled = backoff_ + backoff_;
      backoff_ = doubled > config_.reopenBackoffMax ? config_.reopenBackoffMax : doubled;
      nextReopen_ = now + backoff_;
    }
  }
}

void SocketCanBus::noteErrorFrame(const CanFrame& frame) noexcept {
  CanErrorReport r{};
  if (decodeCanError(frame, r) != Status::Ok) {
    return;
  }
  SocketCanCounters& c = health_.counters;
  ++c.errorFramesReceived;
  c.busOffEvents += r.busOff ? 1U : 0U;
  c.noAckEvents += r.noAck ? 1U : 0U;
  c.controllerProblems += r.controllerProblem ? 1U : 0U;
  c.controllerOverflows += (r.rxOverflow || r.txOverflow) ? 1U : 0U;
  c.protocolViolations += r.protocolViolation ? 1U : 0U;
  health_.lastError = r;
  health_.lastErrorStamp = frame.stamp;
  if (r.stateKnown) {
    if (r.state == CanControllerState::BusOff && health_.controller != CanControllerState::BusOff) {
      busOffSince_ = monotonicNow();
    }
    health_.controller = r.state;
  }
}

Status SocketCanBus::readOne(CanFrame& out) noexcept {
  can_frame raw{};
  detail::ReceiveControl rc;  // the kernel's receive stamp and drop counter
  int flags = 0;
  const ssize_t n = detail::receiveWithControl(fd_, &raw, sizeof(raw), rc, flags);
  if (n < 0) {
    const int err = errno;
    if (err == EAGAIN || err == EWOULDBLOCK || err == EINTR) {
      return Status::Timeout;
    }
    loseLink(isLinkLoss(err) ? Status::DeviceFault : fromErrno(err), err, monotonicNow());
    return Status::DeviceFault;
  }

  // Both clocks read right after the read: their difference maps the kernel's wall-clock stamp
  // onto the monotonic clock without the read latency entering the stamp.
  const Timestamp monoNow = monotonicNow();
  const Timestamp realNow = clockNow(CLOCK_REALTIME);
  const bool stamped = rc.stamped;
  Timestamp kernelStamp = rc.kernelStamp;
  if (rc.haveDrops) {
    health_.counters.rxDroppedByKernel += static_cast<std::uint32_t>(rc.drops - lastKernelDrops_);  // wraps
    lastKernelDrops_ = rc.drops;
  }

  if (static_cast<std::size_t>(n) != sizeof(can_frame) || (flags & MSG_TRUNC) != 0 || raw.can_dlc > CAN_MAX_DLEN) {
    ++health_.counters.rxMalformed;
    return Status::Malformed;
  }

  CanFrame f{};
  f.error = (raw.can_id & CAN_ERR_FLAG) != 0U;
  f.extended = !f.error && (raw.can_id & CAN_EFF_FLAG) != 0U;
  f.rtr = !f.error && (raw.can_id & CAN_RTR_FLAG) != 0U;
  f.id =
      f.error ? (raw.can_id & CAN_ERR_MASK) : (f.extended ? (raw.can_id & CAN_EFF_MASK) : (raw.can_id & CAN_SFF_MASK));
  f.dlc = raw.can_dlc;
  std::memcpy(f.data, raw.data, sizeof(f.data));
  if (!stamped) {
    kernelStamp = realNow;  // no kernel stamp (never seen on Linux >= 2.6.22): the read time
  }
  f.stamp = config_.stampClock == CanStampClock::Realtime ? kernelStamp : kernelStamp - (realNow - monoNow);

  if (f.error) {
    noteErrorFrame(f);
  } else {
    ++health_.counters.framesReceived;
    if (health_.controller == CanControllerState::BusOff) {
      health_.controller = CanControllerState::ErrorActive;  // frames flow again: the controller is back
    }
  }
  out = f;
  return Status::Ok;
}

Status SocketCanBus::receive(CanFrame& out, Duration maxWait) noexcept {
  if (!configured_) {
    return Status::NotInitialized;
  }
  const Timestamp deadline = monotonicNow() + (maxWait.ns > 0 ? maxWait : Duration{});
  for (int pass = 0; pass < kMaxPassesPerReceive; ++pass) {
    maintain();
    if (health_.link == CanLinkState::Up) {
      const Status s = readOne(out);
      if (s == Status::Ok) {
        return Status::Ok;
      }
      if (s == Status::Malformed) {
        continue;
      }
    }
    const Timestamp now = monotonicNow();
    if (now >= deadline) {
      break;
    }
    if (health_.link == CanLinkState::Up) {
      pollfd p{};
      p.fd = fd_;
      p.events = POLLIN;
      const timespec wait = toTimespec(deadline - now);
      (void)::ppoll(&p, 1, &wait, nullptr);  // readiness, error or timeout: the next pass reads
    } else {
      const Timestamp until = nextReopen_ < deadline ? nextReopen_ : deadline;
      const timespec wait = toTimespec(until - now);
      (void)::ppoll(nullptr, 0, &wait, nullptr);
    }
  }
  return health_.link == CanLinkState::Up ? Status::Timeout : Status::DeviceFault;
}

Status SocketCanBus::send(const CanFrame& frame) noexcept {
  if (!configured_) {
    ++health_.counters.txRefused;
    return Status::NotInitialized;
  }
  const std::uint32_t range = frame.extended ? CAN_EFF_MASK : CAN_SFF_MASK;
  if (frame.dlc > CAN_MAX_DLEN || frame.error || (frame.id & ~range) != 0U) {
    ++health_.counters.txRefused;
    return Status::InvalidArgument;
  }
  maintain();
  if (health_.link != CanLinkState::Up || health_.controller == CanControllerState::BusOff) {
    ++health_.counters.txRefused;
    return Status::DeviceFault;
  }
  can_frame raw{};
  raw.can_id = frame.id | (frame.extended ? CAN_EFF_FLAG : 0U) | (frame.rtr ? CAN_RTR_FLAG : 0U);
  raw.can_dlc = frame.dlc;
  std::memcpy(raw.data, frame.data, sizeof(raw.data));
  const ssize_t n = ::send(fd_, &raw, sizeof(raw), MSG_DONTWAIT);
  if (n == static_cast<ssize_t>(sizeof(raw))) {
    ++health_.counters.framesSent;
    return Status::Ok;
  }
  const int err = n < 0 ? errno : EIO;
  ++health_.counters.txRefused;
  if (err == EAGAIN || err == EWOULDBLOCK || err == ENOBUFS) {
    ++health_.counters.txQueueFull;
    return Status::CapacityExceeded;
  }
  health_.lastErrno = err;
  if (isLinkLoss(err)) {
    loseLink(Status::DeviceFault, err, monotonicNow());
  }
  return Status::DeviceFault;
}

}  // namespace agv::drivers
