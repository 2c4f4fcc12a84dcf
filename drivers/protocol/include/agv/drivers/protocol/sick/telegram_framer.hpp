#pragma once
/// @file telegram_framer.hpp
/// Cuts a SICK TCP byte stream into telegrams (CoLa A: STX ... ETX; CoLa B: 0x02020202, length,
/// payload, XOR checksum), heap-free, whatever the read boundaries.
///
/// TCP delivers bytes, not telegrams: one read may hold half a telegram, three telegrams, or noise
/// left by a reconnect. The framer keeps the bytes between reads in a fixed buffer and hands out
/// each complete telegram once. Every anomaly is counted, never silent:
/// - garbage: bytes outside any telegram (before a start marker), dropped;
/// - truncated: a telegram that ended early (CoLa A: a new STX before the ETX; any mode: a partial
///   telegram pending when the connection is reset);
/// - oversized: a telegram longer than the buffer (CoLa A: no ETX within the capacity, skipped up
///   to its ETX or the next STX; CoLa B: declared length over the capacity, the header is dropped and the framer
///   resynchronises on the next start marker);
/// - checksum errors (CoLa B): the telegram is dropped and the framer resynchronises one byte on.
///
/// Worst-case work per call is linear in the buffered bytes (each byte is scanned a bounded number
/// of times: the scan position is kept between calls).

#include <array>
#include <cstddef>
#include <cstdint>

#include "agv/core/span.hpp"
#include "agv/drivers/protocol/capacities.hpp"

namespace agv::drivers::sick {

/// Telegram framing of a SICK TCP port.
enum class Framing : std::uint8_t {
  ColaA,  ///< ASCII: 0x02 text 0x03 (LMS1xx/5xx/TiM default port 2111)
  ColaB,  ///< binary: 02 02 02 02, uint32 big-endian payload length, payload, XOR of the payload (NAV350 port 2112)
};

/// What the framer has seen since construction (never reset by `reset()`).
struct FramerCounters {
  std::uint32_t telegrams = 0;       ///< complete telegrams delivered
  std::uint32_t garbageBytes = 0;    ///< bytes dropped outside any telegram
  std::uint32_t truncated = 0;       ///< telegrams cut short (new start before the end, or reset)
  std::uint32_t oversized = 0;       ///< telegrams longer than the capacity, dropped
  std::uint32_t checksumErrors = 0;  ///< CoLa B telegrams whose XOR checksum did not match
};

/// Stream-to-telegram cutter with a fixed buffer of `kMaxLaserTelegramBytes` (agv/drivers/protocol/capacities.hpp).
class TelegramFramer {
 public:
  static constexpr std::size_t kCapacity = kMaxLaserTelegramBytes;

  explicit TelegramFramer(Framing framing) noexcept : framing_(framing) {}

  Framing framing() const noexcept { return framing_; }

  /// Free space the caller may fill (e.g. with `recv`) before `commit()`. Never empty after
  /// `next()` has returned false.
  Span<std::uint8_t> writable() noexcept;
  /// Declares that the first `n` bytes of `writable()` hold new data (n is clamped to its size).
  void commit(std::size_t n) noexcept;
  /// Copies as much of `data` as fits and returns how many bytes were taken; call `next()` until
  /// it returns false, then feed the rest.
  std::size_t feed(Span<const std::uint8_t> data) noexcept;

  /// Next complete telegram without its framing (CoLa A: the text between STX and ETX; CoLa B:
  /// the payload without header and checksum). The view stays valid until the next call of any
  /// non-const member. False when no complete telegram is buffered.
  bool next(Span<const std::uint8_t>& telegram) noexcept;

  /// Forgets buffered bytes (call on reconnect); a partial telegram is counted as truncated and
  /// other leftovers as garbage.
  void reset() noexcept;

  /// Bytes buffered and not yet delivered.
  std::size_t buffered() const noexcept { return end_ - begin_; }
  const FramerCounters& counters() const noexcept { return counters_; }

 private:
  void compact() noexcept;
  bool nextColaA(Span<const std::uint8_t>& telegram) noexcept;
  bool nextColaB(Span<const std::uint8_t>& telegram) noexcept;

  Framing framing_;
  std::array<std::uint8_t, kCapacity> buf_{};
  std::size_t begin_ = 0;    ///< first undelivered byte
  std::size_t end_ = 0;      ///< one past the last buffered byte
  std::size_t scan_ = 0;     ///< CoLa A: bytes after begin_ already searched for STX/ETX
  bool inTelegram_ = false;  ///< CoLa A: begin_ is an STX
  bool skipping_ = false;    ///< CoLa A: dropping an oversized telegram up to its ETX
  FramerCounters counters_{};
};

}  // namespace agv::drivers::sick
