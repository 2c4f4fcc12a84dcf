#include "agv/report/number.hpp"

#include <charconv>
#include <cmath>
#include <limits>
#include <system_error>

namespace agv::report {
namespace {

/// Splits an optional sign off `text`; false when a second sign follows (from_chars would take
/// "-" after "+").
bool takeSign(std::string_view& text, bool& negative) noexcept {
  negative = false;
  if (!text.empty() && (text.front() == '+' || text.front() == '-')) {
    negative = text.front() == '-';
    text.remove_prefix(1);
    if (!text.empty() && (text.front() == '+' || text.front() == '-')) {
      return false;
    }
  }
  return true;
}

bool isDigit(char c) noexcept {
  return c >= '0' && c <= '9';
}

bool equalsNoCase(std::string_view a, std::string_view lowerB) noexcept {
  if (a.size() != lowerB.size()) {
    return false;
  }
  for (std::size_t i = 0; i < a.size(); ++i) {
    const char c = (a[i] >= 'A' && a[i] <= 'Z') ? static_cast<char>(a[i] - 'A' + 'a') : a[i];
    if (c != lowerB[i]) {
      return false;
    }
  }
  return true;
}

/// Magnitude digits in `base` (10 or 16) into [0, limit]; `limit` is INT64_MAX or its magnitude + 1.
NumberError unsignedMagnitude(std::string_view digits, int base, std::uint64_t limit, std::uint64_t& out) noexcept {
  if (digits.empty()) {
    return NumberError::Malformed;
  }
  std::uint64_t v = 0;
  const char* end = digits.data() + digits.size();
  const std::from_chars_result r = std::from_chars(digits.data(), end, v, base);
  if (r.ec == std::errc::result_out_of_range) {
    return NumberError::OutOfRange;
  }
  if (r.ec != std::errc() || r.ptr != end) {
    return NumberError::Malformed;
  }
  if (v > limit) {
    return NumberError::OutOfRange;
  }
  out = v;
  return NumberError::None;
}

NumberError integerInBase(std::string_view text, bool allowHex, std::int64_t& out) noexcept {
  if (text.empty()) {
    return NumberError::Empty;
  }
  bool negative = false;
  if (!takeSign(text, negative)) {
    return NumberError::Malformed;
  }
  int base = 10;
  if (allowHex && text.size() > 2 && text[0] == '0' && (text[1] == 'x' || text[1] == 'X')) {
    base = 16;
    text.remove_prefix(2);
    if (!text.empty() && (text.front() == '+' || text.front() == '-')) {
      return NumberError::Malformed;
    }
  }
  constexpr auto kMax = static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max());
  std::uint64_t magnitude = 0;
  const NumberError e = unsignedMagnitude(text, base, negative ? kMax + 1U : kMax, magnitude);
  if (e != NumberError::None) {
    return e;
  }
  out = negative ? static_cast<std::int64_t>(0U - magnitude) : static_cast<std::int64_t>(magnitude);
  return NumberError::None;
}

}  // namespace

const char* describe(NumberError e) noexcept {
  switch (e) {
    case NumberError::None:
      return "ok";
    case NumberError::Empty:
      return "empty";
    case NumberError::Malformed:
      return "not a decimal number";
    case NumberError::OutOfRange:
      return "out of range";
    case NumberError::NotFinite:
      return "not finite";
  }
  return "?";
}

NumberError parseReal(std::string_view text, double& out, NonFinite nonFinite) noexcept {
  if (text.empty()) {
    return NumberError::Empty;
  }
  bool negative = false;
  if (!takeSign(text, negative)) {
    return NumberError::Malformed;
  }
  if (text.empty()) {
    return NumberError::Malformed;
  }
  if (!isDigit(text.front()) && text.front() != '.') {
    // Only inf / infinity / nan are words that read as reals.
    if (!equalsNoCase(text, "inf") && !equalsNoCase(text, "infinity") && !equalsNoCase(text, "nan")) {
      return NumberError::Malformed;
    }
    if (nonFinite == NonFinite::Refuse) {
      return NumberError::NotFinite;
    }
    const double v =
        equalsNoCase(text, "nan") ? std::numeric_limits<double>::quiet_NaN() : std::numeric_limits<double>::infinity();
    out = negative ? -v : v;
    return NumberError::None;
  }
  // std::chars_format::general reads decimal only: "0x10" stops at the 'x' and is refused below.
  double v = 0.0;
  const char* end = text.data() + text.size();
  const std::from_chars_result r = std::from_chars(text.data(), end, v, std::chars_format::general);
  if (r.ec == std::errc::result_out_of_range) {
    return NumberError::OutOfRange;
  }
  if (r.ec != std::errc() || r.ptr != end) {
    return NumberError::Malformed;
  }
  out = negative ? -v : v;
  return NumberError::None;
}

NumberError parseInteger(std::string_view text, std::int64_t& out) noexcept {
  return integerInBase(text, false, out);
}

NumberError parseIntegerOrHex(std::string_view text, std::int64_t& out) noexcept {
  return integerInBase(text, true, out);
}

}  // namespace agv::report
