#include "agv/drivers/linux/sick_laser_client.hpp"

#include <cstring>
#include <ctime>

namespace agv::drivers {
namespace {

bool startsWith(Span<const std::uint8_t> t, const char* prefix) noexcept {
  const std::size_t n = std::strlen(prefix);
  return t.size() >= n && std::memcmp(t.data(), prefix, n) == 0;
}

void sleepFor(Duration d) noexcept {
  if (d.ns <= 0) {
    return;
  }
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(d.ns / 1000000000);
  ts.tv_nsec = static_cast<long>(d.ns % 1000000000);
  (void)nanosleep(&ts, nullptr);
}

/// Makes sure `tcp` is connected before `deadline`: waits for the next allowed attempt if it falls
/// before the deadline. Ok when connected (and `fresh` tells whether the connection is new; a new
/// connection restarts `framer`, as in connectForPoll).
Status connectBy(TcpStream& tcp, sick::TelegramFramer& framer, Timestamp deadline, bool& fresh) noexcept {
  fresh = false;
  if (tcp.connected()) {
    return Status::Ok;
  }
  const Timestamp now = monotonicNow();
  if (!tcp.connecting() && tcp.nextAttempt() > now) {
    if (tcp.nextAttempt() >= deadline) {
      sleepFor(deadline - now);
      return Status::Lost;
    }
    sleepFor(tcp.nextAttempt() - now);
  }
  const Status s = tcp.ensureConnected(deadline - monotonicNow());
  if (s != Status::Ok) {
    return Status::Lost;
  }
  framer.reset();
  fresh = true;
  return Status::Ok;
}

/// Reads once into the framer; false when the connection was lost (the framer is reset).
bool pump(TcpStream& tcp, sick::TelegramFramer& framer, Duration wait) noexcept {
  std::size_t n = 0;
  const Status s = tcp.read(framer.writable(), wait, n);
  if (s == Status::Ok) {
    framer.commit(n);
  } else if (s == Status::Lost) {
    framer.reset();
    return false;
  }
  return true;
}

/// Takes the telegrams the framer holds: those `wanted` accepts are decoded by `decode` until one
/// succeeds (true, its status Ok or CapacityExceeded in `result`); failures and other telegrams
/// are counted.
template <typename Wanted, typename Decode>
bool decodeFirst(sick::TelegramFramer& framer, LaserClientCounters& counters, Wanted wanted, Decode decode,
                 Status& result) noexcept {
  Span<const std::uint8_t> t;
  while (framer.next(t)) {
    if (!wanted(t)) {
      ++counters.otherTelegrams;
      continue;
    }
    const Status s = decode(t);
    if (s == Status::Ok || s == Status::CapacityExceeded) {
      ++counters.decoded;
      result = s;
      return true;
    }
    ++counters.decodeErrors;
    counters.implausible += s == Status::OutOfRange ? 1U : 0U;
  }
  return false;
}

/// poll(): connected, or connects when an attempt is due (at most `budget`; a new connection
/// resets the framer and sets `fresh`). Lost when not connected after this.
Status connectForPoll(TcpStream& tcp, sick::TelegramFramer& framer, Duration budget, bool& fresh) noexcept {
  fresh = false;
  if (tcp.connected()) {
    return Status::Ok;
  }
  if ((!tcp.connecting() && monotonicNow() < tcp.nextAttempt()) || tcp.ensureConnected(budget) != Status::Ok) {
    return Status::Lost;  // not due, still connecting (completed by a later call) or failed
  }
  framer.reset();
  fresh = true;
  return Status::Ok;
}

// Reads one poll() call makes from a socket that keeps having data.
constexpr int kMaxPollReads = 16;

/// Reads what the socket already holds into the framer, at most kMaxPollReads times, until `done`
/// says a telegram of interest was decoded. Timeout when nothing (more) is there, Lost when the
/// connection was lost (the framer is reset), Ok when `done` returned true.
template <typename Done>
Status drainSocket(TcpStream& tcp, sick::TelegramFramer& framer, Done done) noexcept {
  for (int i = 0; i < kMaxPollReads; ++i) {
    std::size_t n = 0;
    const Status r = tcp.read(framer.writable(), Duration{}, n);
    if (r == Status::Lost) {
      framer.reset();
      return Status::Lost;
    }
    if (r != Status::Ok) {
      break;
    }
    framer.commit(n);
    if (done()) {
      return Status::Ok;
    }
  }
  return Status::Timeout;
}

}  // namespace

ColaAScanClient::ColaAScanClient(const ColaAScanClientConfig& config) noexcept : config_(config), tcp_(config.tcp) {}

Status ColaAScanClient::sendCommand(const char* command, Duration timeout) noexcept {
  std::uint8_t buf[64];
  const std::size_t n = std::strlen(command);
  if (n + 2 > sizeof buf) {
    return Status::InvalidArgument;
  }
  buf[0] = 0x02;
  // A telegram, not a C string: framed by STX/ETX, no terminating NUL.
  std::memcpy(buf + 1, command, n);  // NOLINT(bugprone-not-null-terminated-result)
  buf[n + 1] = 0x03;
  return tcp_.writeAll(Span<const std::uint8_t>(buf, n + 2), timeout);
}

bool ColaAScanClient::decodeBuffered(LaserScan& scan, Status& result) noexcept {
  return decodeFirst(
      framer_, counters_,
      [](Span<const std::uint8_t> t) noexcept {
        return startsWith(t, "sSN LMDscandata ") || startsWith(t, "sRA LMDscandata ");
      },
      [&](Span<const std::uint8_t> t) noexcept {
        return sick::parseColaAScan(t, config_.scan, monotonicNow(), scan, &info_);
      },
      result);
}

void ColaAScanClient::disconnect() noexcept {
  tcp_.close();
  framer_.reset();
  pollRequested_ = false;
}

Status ColaAScanClient::poll(LaserScan& scan, Duration connectBudget) noexcept {
  Status decoded = Status::Ok;
  if (decodeBuffered(scan, decoded)) {
    pollRequested_ = false;
    return decoded;
  }
  bool fresh = false;
  if (connectForPoll(tcp_, framer_, connectBudget, fresh) != Status::Ok) {
    return Status::Lost;
  }
  if (fresh) {
    pollRequested_ = false;
    if (config_.subscribe && sendCommand("sEN LMDscandata 1", connectBudget) != Status::Ok) {
      disconnect();
      return Status::Lost;
    }
  }
  if (!config_.subscribe && !pollRequested_) {
    if (sendCommand("sRN LMDscandata", connectBudget) != Status::Ok) {
      disconnect();
      return Status::Lost;
    }
    pollRequested_ = true;
  }
  // A bounded number of reads of what is already there: a fast stream cannot hold the caller.
  const Status r = drainSocket(tcp_, framer_, [&]() noexcept { return decodeBuffered(scan, decoded); });
  if (r == Status::Timeout) {
    return Status::Timeout;
  }
  pollRequested_ = false;
  return r == Status::Ok ? decoded : Status::Lost;
}

Status ColaAScanClient::receive(LaserScan& scan, Duration timeout) noexcept {
  const Timestamp deadline = monotonicNow() + timeout;
  bool requested = false;
  // Each pass reads once or (re)connects; the deadline bounds the loop.
  for (;;) {
    Status decoded = Status::Ok;
    if (decodeBuffered(scan, decoded)) {
      return decoded;
    }
    const Timestamp now = monotonicNow();
    if (now >= deadline) {
      return Status::Timeout;
    }
    bool fresh = false;
    if (connectBy(tcp_, framer_, deadline, fresh) != Status::Ok) {
      return Status::Lost;
    }
    if (fresh) {
      requested = false;
      if (config_.subscribe && sendCommand("sEN LMDscandata 1", deadline - monotonicNow()) != Status::Ok) {
        tcp_.close();
        continue;
      }
    }
    if (!config_.subscribe && !requested) {
      if (sendCommand("sRN LMDscandata", deadline - monotonicNow()) != Status::Ok) {
        tcp_.close();
        continue;
      }
      requested = true;
    }
    (void)pump(tcp_, framer_, deadline - monotonicNow());
  }
}

Nav350Client::Nav350Client(const Nav350ClientConfig& config) noexcept : config_(config), tcp_(config.tcp) {}

bool Nav350Client::decodeBuffered(sick::Nav350PoseReply& reply, Status& result) noexcept {
  return decodeFirst(
      framer_, counters_,
      [&](Span<const std::uint8_t> t) noexcept { return pollRequested_ && startsWith(t, "sAN mNPOSGetData "); },
      [&](Span<const std::uint8_t> t) noexcept {
        pollRequested_ = false;  // answered, well-formed or not
        return sick::parseNav350PoseReply(t, config_.nav, monotonicNow(), reply);
      },
      result);
}

void Nav350Client::disconnect() noexcept {
  tcp_.close();
  framer_.reset();
  pollRequested_ = false;
}

Status Nav350Client::poll(bool waitForNextScan, sick::Nav350Mask mask, sick::Nav350PoseReply& reply,
                          Duration connectBudget) noexcept {
  Status decoded = Status::Ok;
  if (decodeBuffered(reply, decoded)) {
    return decoded;
  }
  bool fresh = false;
  if (connectForPoll(tcp_, framer_, connectBudget, fresh) != Status::Ok) {
    return Status::Lost;
  }
  if (fresh) {
    pollRequested_ = false;
  }
  if (!pollRequested_) {
    std::uint8_t payload[32];
    std::uint8_t telegram[48];
    const std::size_t n = sick::encodeNav350PoseRequest(waitForNextScan, mask, Span<std::uint8_t>(payload));
    const std::size_t m = sick::encodeColaB(Span<const std::uint8_t>(payload, n), Span<std::uint8_t>(telegram));
    if (tcp_.writeAll(Span<const std::uint8_t>(telegram, m), connectBudget) != Status::Ok) {
      disconnect();
      return Status::Lost;
    }
    pollRequested_ = true;
  }
  const Status r = drainSocket(tcp_, framer_, [&]() noexcept { return decodeBuffered(reply, decoded); });
  if (r == Status::Lost) {
    pollRequested_ = false;
  }
  return r == Status::Ok ? decoded : r;
}

Status Nav350Client::requestPose(bool waitForNextScan, sick::Nav350Mask mask, sick::Nav350PoseReply& reply,
                                 Duration timeout) noexcept {
  const Timestamp deadline = monotonicNow() + timeout;
  bool requested = false;
  for (;;) {
    Span<const std::uint8_t> t;
    while (framer_.next(t)) {
      if (requested && startsWith(t, "sAN mNPOSGetData ")) {
        const Status s = sick::parseNav350PoseReply(t, config_.nav, monotonicNow(), reply);
        if (s == Status::Ok || s == Status::CapacityExceeded) {
          ++counters_.decoded;
          return s;
        }
        ++counters_.decodeErrors;
        counters_.implausible += s == Status::OutOfRange ? 1U : 0U;
      } else {
        ++counters_.otherTelegrams;  // stale replies from before the request, events
      }
    }
    if (monotonicNow() >= deadline) {
      return Status::Timeout;
    }
    bool fresh = false;
    if (connectBy(tcp_, framer_, deadline, fresh) != Status::Ok) {
      return Status::Lost;
    }
    if (fresh) {
      requested = false;
    }
    if (!requested) {
      std::uint8_t payload[32];
      std::uint8_t telegram[48];
      const std::size_t n = sick::encodeNav350PoseRequest(waitForNextScan, mask, Span<std::uint8_t>(payload));
      const std::size_t m = sick::encodeColaB(Span<const std::uint8_t>(payload, n), Span<std::uint8_t>(telegram));
      if (tcp_.writeAll(Span<const std::uint8_t>(telegram, m), deadline - monotonicNow()) != Status::Ok) {
        tcp_.close();
        continue;
      }
      requested = true;
    }
    (void)pump(tcp_, framer_, deadline - monotonicNow());
  }
}

}  // namespace agv::drivers
