#include "agv/drivers/protocol/sick/cola_a_scan.hpp"

#include <cmath>
#include <cstring>
#include <limits>

#include "agv/core/angle.hpp"
#include "protocol_detail.hpp"

namespace agv::drivers::sick {
namespace {

/// Space-separated token cursor over the telegram; never reads past its end.
class Tokens {
 public:
  explicit Tokens(Span<const std::uint8_t> t) noexcept : p_(t.data()), end_(t.data() + t.size()) {}

  /// Next token; false at the end of the telegram.
  bool next(const std::uint8_t*& tok, std::size_t& len) noexcept {
    while (p_ < end_ && *p_ == ' ') {
      ++p_;
    }
    if (p_ == end_) {
      return false;
    }
    tok = p_;
    while (p_ < end_ && *p_ != ' ') {
      ++p_;
    }
    len = static_cast<std::size_t>(p_ - tok);
    return true;
  }

  /// Next token as an unsigned hexadecimal number of at most 8 digits (an optional leading '+'
  /// is accepted). Truncated at the end, Malformed otherwise.
  Status hex(std::uint32_t& v) noexcept {
    const std::uint8_t* tok = nullptr;
    std::size_t len = 0;
    if (!next(tok, len)) {
      return Status::Truncated;
    }
    if (len > 0 && tok[0] == '+') {
      ++tok;
      --len;
    }
    if (len == 0 || len > 8) {
      return Status::Malformed;
    }
    std::uint32_t r = 0;
    for (std::size_t i = 0; i < len; ++i) {
      const std::uint8_t c = tok[i];
      std::uint32_t d = 0;
      if (c >= '0' && c <= '9') {
        d = static_cast<std::uint32_t>(c - '0');
      } else if (c >= 'A' && c <= 'F') {
        d = static_cast<std::uint32_t>(c - 'A' + 10);
      } else if (c >= 'a' && c <= 'f') {
        d = static_cast<std::uint32_t>(c - 'a' + 10);
      } else {
        return Status::Malformed;
      }
      r = (r << 4U) | d;
    }
    v = r;
    return Status::Ok;
  }

  /// Skips `n` tokens (bounded by the telegram length).
  Status skip(std::uint32_t n) noexcept {
    const std::uint8_t* tok = nullptr;
    std::size_t len = 0;
    for (std::uint32_t i = 0; i < n; ++i) {
      if (!next(tok, len)) {
        return Status::Truncated;
      }
    }
    return Status::Ok;
  }

 private:
  const std::uint8_t* p_;
  const std::uint8_t* end_;
};

bool tokenIs(const std::uint8_t* tok, std::size_t len, const char* word) noexcept {
  const std::size_t n = std::strlen(word);
  return len == n && std::memcmp(tok, word, n) == 0;
}

float floatFromBits(std::uint32_t bits) noexcept {
  float f = 0.0F;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}

/// The header up to and including the 16-bit channel count.
Status parseHeader(Tokens& tk, ColaAScanInfo& info) noexcept {
  const std::uint8_t* tok = nullptr;
  std::size_t len = 0;
  if (!tk.next(tok, len)) {
    return Status::Truncated;
  }
  if (!tokenIs(tok, len, "sRA") && !tokenIs(tok, len, "sSN")) {
    return Status::Malformed;
  }
  if (!tk.next(tok, len)) {
    return Status::Truncated;
  }
  if (!tokenIs(tok, len, "LMDscandata")) {
    return Status::Malformed;
  }
  std::uint32_t v = 0;
  AGV_TRY(tk.hex(v));  // version
  AGV_TRY(tk.hex(v));  // device number
  AGV_TRY(tk.hex(info.serialNumber));
  AGV_TRY(tk.hex(v));
  info.deviceStatus = static_cast<std::uint16_t>(v);
  AGV_TRY(tk.hex(v));  // second status word
  AGV_TRY(tk.hex(v));
  info.telegramCounter = static_cast<std::uint16_t>(v);
  AGV_TRY(tk.hex(v));
  info.scanCounter = static_cast<std::uint16_t>(v);
  AGV_TRY(tk.hex(info.timeSinceStartupUs));
  AGV_TRY(tk.hex(info.timeOfTransmissionUs));
  AGV_TRY(tk.skip(5));  // digital inputs (2), digital outputs (2), reserved
  AGV_TRY(tk.hex(v));
  info.scanFrequency = static_cast<double>(v) * 0.01;
  AGV_TRY(tk.hex(v));  // measurement frequency
  std::uint32_t encoders = 0;
  AGV_TRY(tk.hex(encoders));
  if (encoders > 16U) {
    return Status::Malformed;
  }
  AGV_TRY(tk.skip(2U * encoders));
  return Status::Ok;
}

struct ChannelHead {
  bool isDist1 = false;
  float scale = 0.0F;
  float offset = 0.0F;
  std::int32_t start = 0;
  std::uint32_t step = 0;
  std::uint32_t count = 0;
};

Status parseChannelHead(Tokens& tk, ChannelHead& ch) noexcept {
  const std::uint8_t* tok = nullptr;
  std::size_t len = 0;
  if (!tk.next(tok, len)) {
    return Status::Truncated;
  }
  ch.isDist1 = tokenIs(tok, len, "DIST1");
  std::uint32_t v = 0;
  AGV_TRY(tk.hex(v));
  ch.scale = floatFromBits(v);
  AGV_TRY(tk.hex(v));
  ch.offset = floatFromBits(v);
  AGV_TRY(tk.hex(v));
  ch.start = static_cast<std::int32_t>(v);
  AGV_TRY(tk.hex(ch.step));
  AGV_TRY(tk.hex(ch.count));
  if (ch.step > 0xFFFFU || ch.count > 0xFFFFU) {
    return Status::Malformed;
  }
  return Status::Ok;
}

Status decodeDist1(Tokens& tk, const ChannelHead& ch, const ColaAScanConfig& config, Timestamp receivedAt,
                   LaserScan& scan, ColaAScanInfo& info) noexcept {
  if (!std::isfinite(ch.scale) || !(ch.scale > 0.0F) || !std::isfinite(ch.offset) || ch.step == 0U) {
    return Status::Malformed;
  }
  if (!detail::plausibleScanChannel(static_cast<double>(ch.scale), static_cast<double>(ch.offset),
                                    static_cast<double>(ch.start) * 1e-4, static_cast<double>(ch.step) * 1e-4,
                                    ch.count)) {
    return Status::OutOfRange;
  }
  info.scaleFactor = static_cast<double>(ch.scale);
  info.scaleOffset = static_cast<double>(ch.offset);
  info.beamCount = static_cast<std::uint16_t>(ch.count);
  const double stepRad = deg2rad(static_cast<double>(ch.step) * 1e-4);
  scan.angleMin = static_cast<float>(deg2rad(static_cast<double>(ch.start) * 1e-4) + config.angleOffset);
  scan.angleIncrement = static_cast<float>(stepRad);
  scan.rangeMin = config.rangeMin;
  scan.rangeMax = config.rangeMax;
  Status result = Status::Ok;
  for (std::uint32_t i = 0; i < ch.count; ++i) {
    std::uint32_t raw = 0;
    AGV_TRY(tk.hex(raw));
    float r = std::numeric_limits<float>::infinity();
    if (raw == 0U) {
      ++info.noReturnBeams;
    } else {
      // mm -> m in double: raw values reach 2^16 * scale, beyond float's exact integers after scaling.
      r = static_cast<float>(
          (static_cast<double>(raw) * static_cast<double>(ch.scale) + static_cast<double>(ch.offset)) * 1e-3);
    }
    if (scan.ranges.push_back(r) != Status::Ok) {
      result = Status::CapacityExceeded;
    }
  }
  // Sweep time: the beams cover count*step of a revolution taking 1/f.
  if (info.scanFrequency > 0.0 && ch.count > 1U) {
    const double span = static_cast<double>(ch.count - 1U) * stepRad;
    scan.sweepDuration = Duration::fromSeconds(span / kTwoPi<double> / info.scanFrequency);
  }
  const std::int64_t latencyUs =
      static_cast<std::int64_t>(info.timeOfTransmissionUs) - static_cast<std::int64_t>(info.timeSinceStartupUs);
  scan.stamp = receivedAt;
  if (latencyUs >= 0 && latencyUs < 1000000) {
    scan.stamp = receivedAt - Duration::fromMicroseconds(latencyUs);
  }
  return result;
}

}  // namespace

Status parseColaAScan(Span<const std::uint8_t> telegram, const ColaAScanConfig& config, Timestamp receivedAt,
                      LaserScan& scan, ColaAScanInfo* infoOut) noexcept {
  scan.ranges.clear();
  scan.ranges.resetRefusedCount();
  scan.sweepDuration = Duration{};
  ColaAScanInfo info{};
  Tokens tk(telegram);
  Status s = parseHeader(tk, info);
  bool found = false;
  // 16-bit channels, then 8-bit channels: DIST1 may be in either list depending on the resolution.
  for (int list = 0; list < 2 && s == Status::Ok && !found; ++list) {
    std::uint32_t channels = 0;
    s = tk.hex(channels);
    if (s == Status::Ok && channels > 16U) {
      s = Status::Malformed;
    }
    for (std::uint32_t c = 0; c < channels && s == Status::Ok && !found; ++c) {
      ChannelHead ch;
      s = parseChannelHead(tk, ch);
      if (s != Status::Ok) {
        break;
      }
      if (ch.isDist1) {
        found = true;
        s = decodeDist1(tk, ch, config, receivedAt, scan, info);
      } else {
        s = tk.skip(ch.count);
      }
    }
  }
  if (s == Status::Ok && !found) {
    s = Status::Malformed;
  }
  if (s != Status::Ok && s != Status::CapacityExceeded) {
    scan.ranges.clear();
  }
  if (infoOut != nullptr) {
    *infoOut = info;
  }
  return s;
}

}  // namespace agv::drivers::sick

namespace agv::drivers::sick {
namespace {
/// Appends text to a bounded buffer; remembers an overflow.
class TextOut {
 public:
  explicit TextOut(Span<std::uint8_t> out) noexcept : out_(out) {}
  void byte(std::uint8_t c) noexcept {
    if (n_ < out_.size()) {
      out_[n_++] = c;
    } else {
      overflow_ = true;
    }
  }
  void text(const char* s) noexcept {
    for (; *s != '\0'; ++s) {
      byte(static_cast<std::uint8_t>(*s));
    }
  }
  /// " " + uppercase hexadecimal without leading zeros.
  void hex(std::uint32_t v) noexcept {
    byte(' ');
    char digits[8];
    int k = 0;
    do {
      const std::uint32_t d = v & 0xFU;
      digits[k++] = static_cast<char>(d < 10U ? '0' + static_cast<int>(d) : 'A' + static_cast<int>(d - 10U));
      v >>= 4U;
    } while (v != 0U && k < 8);
    while (k > 0) {
      byte(static_cast<std::uint8_t>(digits[--k]));
    }
  }
  std::size_t size() const noexcept { return overflow_ ? 0U : n_; }

 private:
  Span<std::uint8_t> out_;
  std::size_t n_ = 0;
  bool overflow_ = false;
};

std::uint32_t floatBits(float f) noexcept {
  std::uint32_t u = 0;
  std::memcpy(&u, &f, sizeof u);
  return u;
}
}  // namespace

std::size_t encodeColaAScan(const LaserScan& scan, const ColaAScanEncodeParams& p, Span<std::uint8_t> out) noexcept {
  if (!(p.scaleFactor > 0.0F) || !std::isfinite(p.scaleFactor) || scan.size() > 0xFFFFU) {
    return 0;
  }
  TextOut t(out);
  t.byte(0x02);
  t.text("sSN LMDscandata");
  t.hex(1);  // version
  t.hex(1);  // device number
  t.hex(p.serialNumber);
  t.hex(0);  // device status
  t.hex(0);
  t.hex(p.telegramCounter);
  t.hex(p.scanCounter);
  t.hex(p.timeSinceStartupUs);
  t.hex(p.timeOfTransmissionUs);
  for (int i = 0; i < 5; ++i) {
    t.hex(0);  // inputs (2), outputs (2), reserved
  }
  t.hex(static_cast<std::uint32_t>(std::lround(p.scanFrequency * 100.0)));
  t.hex(static_cast<std::uint32_t>(std::lround(p.scanFrequency * static_cast<double>(scan.size()) / 100.0)));
  t.hex(0);  // encoders
  t.hex(1);  // one 16-bit channel
  t.text(" DIST1");
  t.hex(floatBits(p.scaleFactor));
  t.hex(floatBits(0.0F));
  const double startDeg = rad2deg(static_cast<double>(scan.angleMin) - p.angleOffset);
  const double stepDeg = rad2deg(static_cast<double>(scan.angleIncrement));
  t.hex(static_cast<std::uint32_t>(static_cast<std::int32_t>(std::lround(startDeg * 1e4))));
  t.hex(static_cast<std::uint32_t>(std::lround(stepDeg * 1e4)) & 0xFFFFU);
  t.hex(static_cast<std::uint32_t>(scan.size()));
  for (std::size_t i = 0; i < scan.size(); ++i) {
    std::uint32_t raw = 0;
    if (scan.isValid(i)) {
      const double counts = static_cast<double>(scan.ranges[i]) * 1000.0 / static_cast<double>(p.scaleFactor);
      raw = counts >= 65535.0 ? 0xFFFFU : static_cast<std::uint32_t>(std::lround(counts));
      if (raw == 0U) {
        raw = 1U;  // a valid reading never reads as "no echo"
      }
    }
    t.hex(raw);
  }
  t.hex(0);  // 8-bit channels
  for (int i = 0; i < 5; ++i) {
    t.hex(0);  // position, name, comment, time, event
  }
  t.byte(0x03);
  return t.size();
}

}  // namespace agv::drivers::sick
