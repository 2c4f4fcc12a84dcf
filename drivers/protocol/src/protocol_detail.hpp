#pragma once
// Internal helpers of the protocol decoders (not installed).

#include <cstddef>
#include <cstdint>
#include <cstring>

#include "agv/core/span.hpp"
#include "agv/core/status.hpp"

/// Returns the status of `expr` from the enclosing function unless it is Ok.
#define AGV_TRY(expr)                \
  do {                               \
    const ::agv::Status s_ = (expr); \
    if (s_ != ::agv::Status::Ok) {   \
      return s_;                     \
    }                                \
  } while (0)

namespace agv::drivers::detail {

/// Big-endian reader over a byte span; every read is bounds-checked (Truncated past the end).
class BeReader {
 public:
  explicit BeReader(Span<const std::uint8_t> b) noexcept : p_(b.data()), n_(b.size()) {}

  std::size_t remaining() const noexcept { return n_ - pos_; }
  std::size_t position() const noexcept { return pos_; }

  Status u8(std::uint8_t& v) noexcept {
    if (remaining() < 1) {
      return Status::Truncated;
    }
    v = p_[pos_++];
    return Status::Ok;
  }
  Status u16(std::uint16_t& v) noexcept {
    if (remaining() < 2) {
      return Status::Truncated;
    }
    v = static_cast<std::uint16_t>((static_cast<unsigned>(p_[pos_]) << 8U) | p_[pos_ + 1]);
    pos_ += 2;
    return Status::Ok;
  }
  Status u32(std::uint32_t& v) noexcept {
    if (remaining() < 4) {
      return Status::Truncated;
    }
    v = (static_cast<std::uint32_t>(p_[pos_]) << 24U) | (static_cast<std::uint32_t>(p_[pos_ + 1]) << 16U) |
        (static_cast<std::uint32_t>(p_[pos_ + 2]) << 8U) | static_cast<std::uint32_t>(p_[pos_ + 3]);
    pos_ += 4;
    return Status::Ok;
  }
  Status i32(std::int32_t& v) noexcept {
    std::uint32_t u = 0;
    AGV_TRY(u32(u));
    v = static_cast<std::int32_t>(u);
    return Status::Ok;
  }
  Status f32(float& v) noexcept {
    std::uint32_t u = 0;
    AGV_TRY(u32(u));
    std::memcpy(&v, &u, sizeof v);
    return Status::Ok;
  }
  /// Consumes `text` exactly, else Malformed (Truncated if the buffer ends first).
  Status literal(const char* text) noexcept {
    const std::size_t n = std::strlen(text);
    if (remaining() < n) {
      return Status::Truncated;
    }
    if (std::memcmp(p_ + pos_, text, n) != 0) {
      return Status::Malformed;
    }
    pos_ += n;
    return Status::Ok;
  }
  /// Next `n` raw bytes (Truncated if fewer remain).
  Status bytes(std::size_t n, const std::uint8_t*& out) noexcept {
    if (remaining() < n) {
      return Status::Truncated;
    }
    out = p_ + pos_;
    pos_ += n;
    return Status::Ok;
  }

 private:
  const std::uint8_t* p_;
  std::size_t n_;
  std::size_t pos_ = 0;
};

}  // namespace agv::drivers::detail
