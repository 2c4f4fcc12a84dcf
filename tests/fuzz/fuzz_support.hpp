#pragma once
// Shared by the libFuzzer targets: an invariant check that crashes (so libFuzzer records the
// input) and the framer driver that feeds a byte stream in read-sized chunks.
#include <cstddef>
#include <cstdint>

#include "agv/core/span.hpp"
#include "agv/drivers/protocol/sick/telegram_framer.hpp"

namespace agv::fuzz {

/// Traps when an invariant does not hold.
inline void check(bool ok) {
  if (!ok) {
    __builtin_trap();
  }
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
