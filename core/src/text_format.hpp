#pragma once
/// @file text_format.hpp
/// Internal: the line/token reader and the number writer shared by the core's text formats
/// (landmark maps, calibration files). Parses caller-owned buffers; no heap, no locale, no libc
/// number conversion (strtod/snprintf are locale-dependent and not on every target).

#include <cstddef>
#include <cstdint>

namespace agv::text {

/// Reading position in a buffer.
struct Cursor {
  const char* p;
  const char* end;
};

/// The next line of `c` without its end-of-line and without a `#` comment; false at the end of the
/// text. CR before LF counts as blank (see `nextToken`).
bool nextLine(Cursor& c, const char** begin, const char** lineEnd) noexcept;

/// The next token of [p, end) separated by spaces, tabs or CR; false when none is left.
bool nextToken(const char*& p, const char* end, const char** tb, const char** te) noexcept;

/// True when [b, e) equals the NUL-terminated `word`.
bool tokenIs(const char* b, const char* e, const char* word) noexcept;

/// Decimal number [b, e): optional sign, digits, optional fraction, optional exponent; the whole
/// token must be consumed and the value finite.
bool parseNumber(const char* b, const char* e, double* out) noexcept;

/// Unsigned decimal integer [b, e) no larger than `max`.
bool parseUnsigned(const char* b, const char* e, std::uint64_t max, std::uint64_t* out) noexcept;

/// Appends text to a caller-owned buffer; remembers an overflow instead of writing past the end.
struct Writer {
  char* p;
  char* end;
  bool overflow = false;

  void put(char ch) noexcept;
  void put(const char* s) noexcept;
  /// Decimal, left-padded with zeros to `minDigits`.
  void putUnsigned(std::uint64_t v, int minDigits = 1) noexcept;
  /// Fixed point with `decimals` (0..12) decimals, rounded half away from zero.
  void putFixed(double v, int decimals) noexcept;
  /// Characters written so far from `begin`.
  std::size_t written(const char* begin) const noexcept { return static_cast<std::size_t>(p - begin); }
};

}  // namespace agv::text
