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

/// Plausibility of a scan channel's header (SICK CoLa A and NAV350 alike): a scale factor in
/// [1e-3, 100] (devices send 1 or 2), a range offset within +-10 m (devices send 0), an angular
/// step in (0, 5] deg, a start angle within +-360 deg, and the beams spanning at most one turn.
/// Values outside are not a scan of any SICK device (a scale of 3.4e38, an offset of 1e30, a
/// 6.5535 deg step over 541 beams) and the telegram is refused (`OutOfRange`).
inline bool plausibleScanChannel(double scale, double offsetMm, double startDeg, double stepDeg,
                                 std::uint32_t count) noexcept {
  constexpr double kMaxSpanDeg = 360.0 + 1e-6;
  const bool scaleOk = scale >= 1e-3 && scale <= 100.0;
  const bool offsetOk = offsetMm >= -1e4 && offsetMm <= 1e4;
  const bool stepOk = stepDeg > 0.0 && stepDeg <= 5.0;
  const bool startOk = startDeg >= -360.0 && startDeg <= 360.0;
  const bool spanOk = count < 2U || static_cast<double>(count - 1U) * stepDeg <= kMaxSpanDeg;
  return scaleOk && offsetOk && stepOk && startOk && spanOk;
}

}  // namespace agv::drivers::detail
