#pragma once
/// @file socketcan_bus.hpp
/// A classic CAN bus reached through a Linux SocketCAN raw socket (Linux only).
///
/// `SocketCanBus` opens a CAN_RAW socket on a named interface (can0, vcan0 ...), applies receive
/// filters, subscribes to the controller's error frames, receives with a bounded wait and the
/// kernel's receive timestamp, transmits without blocking, and keeps a health record: controller
/// state decoded from error frames, link state, and counters of everything dropped or refused.
///
/// Recovery. When the interface goes down or disappears, the socket reports it; the bus closes the
/// socket and reopens it with exponential back-off on later calls, re-applying the configuration.
/// After a bus-off the bus refuses to transmit (the frames could only pile up in the queue) until
/// the controller reports its restart (set `restart-ms` on the interface: `ip link set can0 type
/// can restart-ms 100`), a frame arrives, or the bus-off has lasted `busOffReopenAfter`: then the
/// socket is reopened and transmission is tried again.
///
/// No heap: every call works on the object's own storage. Not thread-safe: one thread owns a bus.

#include <cstddef>
#include <cstdint>

#include "agv/core/fixed_vector.hpp"
#include "agv/core/status.hpp"
#include "agv/core/timestamp.hpp"
#include "agv/drivers/linux/can_error.hpp"
#include "agv/drivers/linux/monotonic_clock.hpp"
#include "agv/drivers/protocol/can_frame.hpp"
#include "agv/drivers/protocol/capacities.hpp"

namespace agv::drivers {

/// An acceptance filter: a frame passes when (frame id & mask) == (id & mask) and its format
/// (standard or extended) is `extended`. Remote requests pass like data frames.
struct CanFilter {
  std::uint32_t id = 0;
  std::uint32_t mask = 0x7FFU;  ///< 0x7FF: exactly `id` among standard ids; 0x1FFFFFFF for extended
  bool extended = false;
};

/// Error classes subscribed by default: every class the controller reports except individual bus
/// errors (`CAN_ERR_BUSERROR`, one frame per disturbed bit: they can flood a noisy bus).
inline constexpr std::uint32_t kCanDefaultErrorClasses = 0x0000037FU;

/// Which clock the receive timestamps are put on.
enum class CanStampClock : std::uint8_t {
  Monotonic,  ///< CLOCK_MONOTONIC (the vehicle's steady clock, the default)
  Realtime,   ///< CLOCK_REALTIME as the kernel stamps it (wall time; jumps with NTP)
};

/// Configuration of a `SocketCanBus`. Defaults suit a vehicle bus with encoders and drives.
struct SocketCanConfig {
  /// Interface name (at most 15 characters), copied by `open()`.
  const char* interfaceName = "can0";
  /// Receive filters; empty = receive every frame.
  FixedVector<CanFilter, kMaxCanFilters> filters;
  /// Subscribe to the controller's error frames (returned by `receive()` with `error` set).
  bool receiveErrorFrames = true;
  /// Error classes subscribed when `receiveErrorFrames` (CAN_ERR_* bits).
  std::uint32_t errorClasses = kCanDefaultErrorClasses;
  /// Let other sockets of this host (candump, other processes) see the frames sent (kernel default).
  bool loopback = true;
  /// Receive the frames this socket sent itself (only with `loopback`).
  bool receiveOwnFrames = false;
  /// Socket receive buffer in bytes; 0 keeps the kernel default. The kernel doubles the value and
  /// enforces a minimum of a few frames. Frames that arrive while it is full are dropped and
  /// counted in `SocketCanCounters::rxDroppedByKernel`.
  int receiveBufferBytes = 0;
  /// Clock of `CanFrame::stamp` for received frames.
  CanStampClock stampClock = CanStampClock::Monotonic;
  /// First wait before reopening a lost socket; doubled after every failed try up to the maximum.
  Duration reopenBackoffInitial = Duration::fromMilliseconds(100);
  Duration reopenBackoffMax = Duration::fromSeconds(5.0);
  /// A bus-off with no restart report for this long makes the bus reopen its socket.
  Duration busOffReopenAfter = Duration::fromSeconds(2.0);
};

/// Whether the bus has a usable socket.
enum class CanLinkState : std::uint8_t {
  Closed = 0,  ///< never opened, or closed by the caller
  Up = 1,      ///< socket open and bound
  Down = 2,    ///< the socket was lost (interface down or gone); reopening with back-off
};

/// Short stable name of a link state ("closed", "up", "down"). Never null.
const char* toString(CanLinkState state) noexcept;

/// Running totals since construction (they survive reopens).
struct SocketCanCounters {
  std::uint64_t framesReceived = 0;       ///< data and remote frames returned by `receive()`
  std::uint64_t errorFramesReceived = 0;  ///< error frames returned by `receive()`
  std::uint64_t framesSent = 0;           ///< frames the kernel accepted for transmission
  std::uint64_t rxDroppedByKernel = 0;    ///< frames dropped because the socket queue was full
  std::uint64_t rxMalformed = 0;          ///< reads that were not one classic CAN frame (discarded)
  std::uint64_t txRefused = 0;            ///< `send()` calls refused (queue full, bus-off, link down)
  std::uint64_t txQueueFull = 0;          ///< of those, refused because the transmit queue was full
  std::uint64_t busOffEvents = 0;         ///< error frames reporting bus-off
  std::uint64_t noAckEvents = 0;          ///< error frames reporting a missing acknowledge
  std::uint64_t controllerProblems = 0;   ///< error frames reporting a controller problem
  std::uint64_t controllerOverflows = 0;  ///< of those, controller receive/transmit buffer overflows
  std::uint64_t protocolViolations = 0;   ///< error frames reporting a protocol violation
  std::uint64_t linkLosses = 0;           ///< times the socket was lost (interface down or gone)
  std::uint64_t reopenAttempts = 0;       ///< tries to reopen a lost socket
  std::uint64_t reopens = 0;              ///< successful reopens
};

/// The state of the bus as the last calls saw it.
struct SocketCanHealth {
  CanLinkState link = CanLinkState::Closed;
  CanControllerState controller = CanControllerState::ErrorActive;
  /// Why the link is down or the last failure to open (`Ok` when none).
  Status lastFailure = Status::Ok;
  /// `errno` of the last failed system call (0 when none), for the logs.
  int lastErrno = 0;
  /// The last error frame received and when (zero stamp when none yet).
  CanErrorReport lastError{};
  Timestamp lastErrorStamp{};
  SocketCanCounters counters{};
};

/// A SocketCAN raw socket with filters, error-frame decoding, timestamps and recovery.
class SocketCanBus {
 public:
  SocketCanBus() noexcept = default;
  ~SocketCanBus();
  SocketCanBus(const SocketCanBus&) = delete;
  SocketCanBus& operator=(const SocketCanBus&) = delete;

  /// Opens the socket on `config.interfaceName` and applies the configuration (closing any socket
  /// this bus had). Returns `InvalidArgument` for a bad configuration (name empty or too long,
  /// filter id/mask out of range, back-off not positive), `NotFound` when no such interface
  /// exists, `Unsupported` when the kernel has no SocketCAN, `DeviceFault` for other failures
  /// (details in `health().lastErrno`). On any failure the bus stays closed.
  Status open(const SocketCanConfig& config) noexcept;

  /// Closes the socket; the bus stays closed until `open()`.
  void close() noexcept;

  /// Waits at most `maxWait` (zero: do not wait) for one frame and stores it in `out`.
  ///
  /// Returns `Ok` with a data, remote or error frame (`out.error`; error frames have already
  /// updated `health()`), `Timeout` when none came in time, `DeviceFault` when the link is down
  /// for the whole wait (a reopen is tried whenever the back-off allows, also during the wait),
  /// `NotInitialized` when the bus is closed. `out` is changed only on `Ok`.
  Status receive(CanFrame& out, Duration maxWait) noexcept;

  /// Queues `frame` for transmission without blocking.
  ///
  /// Returns `Ok` when the kernel took it, `InvalidArgument` for an impossible frame (dlc > 8,
  /// id out of range, error flag set), `CapacityExceeded` when the transmit queue is full,
  /// `DeviceFault` while the controller is bus-off or the link is down, `NotInitialized` when
  /// closed. Every refusal is counted.
  Status send(const CanFrame& frame) noexcept;

  /// Reopens a lost socket if the back-off allows and reopens after a lasting bus-off. `receive()`
  /// and `send()` call it; a caller that only transmits may call it once per cycle.
  void maintain() noexcept;

  /// Health record (link, controller state, last error frame, counters).
  const SocketCanHealth& health() const noexcept { return health_; }

  /// True when the socket is open and bound.
  bool isUp() const noexcept { return health_.link == CanLinkState::Up; }

  /// The socket descriptor (-1 when none), e.g. to wait on several devices with one poll().
  int fileDescriptor() const noexcept { return fd_; }

 private:
  Status openSocket() noexcept;
  void closeSocket() noexcept;
  void loseLink(Status reason, int err, Timestamp now) noexcept;
  void noteErrorFrame(const CanFrame& frame) noexcept;
  Status readOne(CanFrame& out) noexcept;

  SocketCanConfig config_{};
  char name_[16] = {};
  int fd_ = -1;
  bool configured_ = false;
  std::uint32_t lastKernelDrops_ = 0;
  Duration backoff_{};
  Timestamp nextReopen_{};
  Timestamp busOffSince_{};
  SocketCanHealth health_{};
};

}  // namespace agv::drivers
