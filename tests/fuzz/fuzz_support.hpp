#pragma once
// Shared by the libFuzzer targets: an invariant check that crashes (so libFuzzer records the
// input) and the framer driver that feeds a byte stream in read-sized chunks.
#include <cstddef>
#include <cstdint>

#include "agv/core/span.hpp"
#include "agv/drivers/protocol/can_frame.hpp"
#include "agv/drivers/protocol/sick/telegram_framer.hpp"

namespace agv::fuzz {

/// Traps when an invariant does not hold.
inline void check(bool ok) {
  if (!ok) {
    __builtin_trap();
  }
}

/// Little-endian u16 at `p`.
inline std::uint16_t u16le(const std::uint8_t* p) {
  return static_cast<std::uint16_t>(p[0] | (p[1] << 8));
}

/// The CAN frame of the 14 input bytes at `p` (the layout of the CAN fuzz targets): identifier (2,
/// 11 bits kept), dlc (1, modulo 9), flags (1: bit 0 extended, 1 remote, 2 error; the others are
/// the target's), data (8; bytes past dlc zeroed), then 2 bytes the target uses as its time step.
inline drivers::CanFrame canFrameFromBytes(const std::uint8_t* p) {
  drivers::CanFrame f;
  f.id = u16le(p) & 0x7FFU;
  f.dlc = static_cast<std::uint8_t>(p[2] % 9);
  f.extended = (p[3] & 1) != 0;
  f.rtr = (p[3] & 2) != 0;
  f.error = (p[3] & 4) != 0;
  for (int i = 0; i < 8; ++i) {
    f.data[i] = i < f.dlc ? p[4 + i] : 0;
  }
  return f;
}

/// Feeds `data` to `framer` (after a reset) in reads of `chunk` bytes, as a socket would deliver
/// them, and calls `onTelegram(span)` for every telegram the framer completes. Checks that each
/// telegram fits the framer and that the framer always makes room once its telegrams are taken.
template <typename OnTelegram>
void feedInChunks(drivers::sick::TelegramFramer& framer, const std::uint8_t* data, std::size_t size, std::size_t chunk,
                  OnTelegram&& onTelegram) {
  framer.reset();
  std::size_t pos = 0;
  while (pos < size) {
    const std::size_t n = size - pos < chunk ? size - pos : chunk;
    std::size_t fed = 0;
    while (fed < n) {
      const std::size_t k = framer.feed(Span<const std::uint8_t>(data + pos + fed, n - fed));
      fed += k;
      Span<const std::uint8_t> t;
      while (framer.next(t)) {
        check(t.data() != nullptr && t.size() < drivers::sick::TelegramFramer::kCapacity);
        onTelegram(t);
      }
      check(k > 0 || fed == n);
    }
    pos += n;
  }
}

}  // namespace agv::fuzz
