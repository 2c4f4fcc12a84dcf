#include "agv/drivers/protocol/sick/telegram_framer.hpp"

#include <cstring>

namespace agv::drivers::sick {
namespace {
constexpr std::uint8_t kStx = 0x02;
constexpr std::uint8_t kEtx = 0x03;
constexpr std::size_t kColaBHeader = 8;  // 4 x STX + uint32 length
// A CoLa B length at or above this cannot be a real telegram of any SICK device: the header is
// then taken for noise (one byte dropped, counted as garbage) rather than an oversized telegram.
// Its first byte is 0x01 or more, so a run of 0x02 before a real header is never mistaken for one.
constexpr std::uint32_t kImplausibleLength = 1U << 24;

bool magicAt(const std::uint8_t* p) noexcept {
  return p[0] == kStx && p[1] == kStx && p[2] == kStx && p[3] == kStx;
}

std::uint32_t be32(const std::uint8_t* p) noexcept {
  return (static_cast<std::uint32_t>(p[0]) << 24U) | (static_cast<std::uint32_t>(p[1]) << 16U) |
         (static_cast<std::uint32_t>(p[2]) << 8U) | static_cast<std::uint32_t>(p[3]);
}

std::uint32_t clampCount(std::size_t n) noexcept {
  return n > 0xFFFFFFFFU ? 0xFFFFFFFFU : static_cast<std::uint32_t>(n);
}
}  // namespace

void TelegramFramer::compact() noexcept {
  if (begin_ == 0) {
    return;
  }
  const std::size_t n = end_ - begin_;
  if (n > 0) {
    std::memmove(buf_.data(), buf_.data() + begin_, n);
  }
  begin_ = 0;
  end_ = n;
}

Span<std::uint8_t> TelegramFramer::writable() noexcept {
  compact();
  return Span<std::uint8_t>(buf_.data() + end_, kCapacity - end_);
}

void TelegramFramer::commit(std::size_t n) noexcept {
  const std::size_t room = kCapacity - end_;
  end_ += n < room ? n : room;
}

std::size_t TelegramFramer::feed(Span<const std::uint8_t> data) noexcept {
  const Span<std::uint8_t> room = writable();
  const std::size_t n = data.size() < room.size() ? data.size() : room.size();
  if (n > 0) {
    std::memcpy(room.data(), data.data(), n);
  }
  end_ += n;
  return n;
}

bool TelegramFramer::next(Span<const std::uint8_t>& telegram) noexcept {
  compact();
  return framing_ == Framing::ColaA ? nextColaA(telegram) : nextColaB(telegram);
}

bool TelegramFramer::nextColaA(Span<const std::uint8_t>& telegram) noexcept {
  // Every pass either delivers, returns, or moves begin_ forward: at most buffered() passes.
  while (begin_ < end_) {
    if (skipping_) {  // drop up to the ETX, or up to a new STX (CoLa A text never holds one)
      std::size_t k = begin_;
      while (k < end_ && buf_[k] != kEtx && buf_[k] != kStx) {
        ++k;
      }
      if (k == end_) {
        begin_ = end_;
        return false;
      }
      begin_ = buf_[k] == kEtx ? k + 1 : k;
      skipping_ = false;
      continue;
    }
    if (!inTelegram_) {
      const void* stx = std::memchr(buf_.data() + begin_, kStx, end_ - begin_);
      if (stx == nullptr) {
        counters_.garbageBytes += clampCount(end_ - begin_);
        begin_ = end_;
        return false;
      }
      const std::size_t j = static_cast<std::size_t>(static_cast<const std::uint8_t*>(stx) - buf_.data());
      counters_.garbageBytes += clampCount(j - begin_);
      begin_ = j;
      inTelegram_ = true;
      scan_ = 1;
    }
    bool restarted = false;
    for (std::size_t k = begin_ + scan_; k < end_; ++k) {
      const std::uint8_t c = buf_[k];
      if (c == kEtx) {
        telegram = Span<const std::uint8_t>(buf_.data() + begin_ + 1, k - begin_ - 1);
        begin_ = k + 1;
        inTelegram_ = false;
        scan_ = 0;
        ++counters_.telegrams;
        return true;
      }
      if (c == kStx) {  // a new telegram starts before this one ended
        ++counters_.truncated;
        begin_ = k;
        scan_ = 1;
        restarted = true;
        break;
      }
    }
    if (restarted) {
      continue;
    }
    scan_ = end_ - begin_;
    if (end_ - begin_ >= kCapacity) {  // no ETX within the capacity: drop it up to its ETX
      ++counters_.oversized;
      skipping_ = true;
      inTelegram_ = false;
      scan_ = 0;
      begin_ = end_;
    }
    return false;
  }
  return false;
}

bool TelegramFramer::nextColaB(Span<const std::uint8_t>& telegram) noexcept {
  while (begin_ < end_) {
    // Find the start marker; keep a trailing partial marker (up to three 0x02) for the next read.
    std::size_t j = begin_;
    while (j + 4 <= end_ && !magicAt(buf_.data() + j)) {
      ++j;
    }
    if (j + 4 > end_) {
      std::size_t keep = end_;
      while (keep > begin_ && end_ - keep < 3 && buf_[keep - 1] == kStx) {
        --keep;
      }
      counters_.garbageBytes += clampCount(keep - begin_);
      begin_ = keep;
      return false;
    }
    counters_.garbageBytes += clampCount(j - begin_);
    begin_ = j;
    if (end_ - begin_ < kColaBHeader) {
      return false;
    }
    const std::uint32_t length = be32(buf_.data() + begin_ + 4);
    if (length == 0 || length >= kImplausibleLength) {  // noise that looks like a marker
      ++counters_.garbageBytes;
      ++begin_;
      continue;
    }
    if (static_cast<std::size_t>(length) > kCapacity - kColaBHeader - 1) {
      ++counters_.oversized;
      begin_ += 4;  // drop the marker; the payload that follows is skipped as garbage
      continue;
    }
    const std::size_t total = kColaBHeader + length + 1;
    if (end_ - begin_ < total) {
      return false;
    }
    const std::uint8_t* payload = buf_.data() + begin_ + kColaBHeader;
    std::uint8_t x = 0;
    for (std::size_t i = 0; i < length; ++i) {
      x = static_cast<std::uint8_t>(x ^ payload[i]);
    }
    if (x != payload[length]) {
      ++counters_.checksumErrors;
      ++counters_.garbageBytes;
      ++begin_;  // resynchronise: a real marker may start inside the damaged telegram
      continue;
    }
    telegram = Span<const std::uint8_t>(payload, length);
    begin_ += total;
    ++counters_.telegrams;
    return true;
  }
  return false;
}

void TelegramFramer::reset() noexcept {
  const std::size_t n = end_ - begin_;
  if (n > 0) {
    const bool partial = framing_ == Framing::ColaA ? inTelegram_ : (n >= 4 && magicAt(buf_.data() + begin_));
    if (partial) {
      ++counters_.truncated;
    } else if (!skipping_) {
      counters_.garbageBytes += clampCount(n);
    }
  }
  begin_ = 0;
  end_ = 0;
  scan_ = 0;
  inTelegram_ = false;
  skipping_ = false;
}

}  // namespace agv::drivers::sick
