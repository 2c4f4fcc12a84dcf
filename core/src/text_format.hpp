#pragma once
/// @file text_format.hpp
/// Internal: the line/token reader and the number writer shared by the core's text formats
/// (landmark maps, calibration files). Parses caller-owned buffers; no heap, no locale, no libc
/// number conversion (strtod/snprintf are locale-dependent and not on every target).

#include <cstddef>
#include <cstdint>

#include "agv/core/status.hpp"

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

/// The records of a versioned text file: first the header `<magic> <version>` (1..maxVersion),
/// then the data records; from version 2 on the last record is `end <count>` (count = the data
/// records), after which only blank lines and comments may come. A version-2 file that ends before
/// its `end` line, or whose last line is unterminated and fails (`fail`), is `Truncated`: cut short.
class RecordReader {
 public:
  /// `headerDetail`: the detail of a bad header (static text naming the expected header).
  RecordReader(const char* text, std::size_t size, const char* magic, std::uint32_t maxVersion,
               const char* headerDetail) noexcept;

  /// The next data record: true with its first token [*tb, *te) and the rest of its line [*p, *e).
  /// False at the end of the records or at an error of the framing; `status()` then says which.
  bool next(const char** tb, const char** te, const char** p, const char** e) noexcept;
  /// The record just returned is refused with `s` (`detail` may be null): returns the status to
  /// report (`Truncated` when it is a cut last line of a version-2 file, except for a duplicate,
  /// `InvalidArgument`), and remembers the line.
  Status fail(Status s, const char* detail) noexcept;

  /// After `next` returned false: `Ok`, or why the framing is refused.
  Status status() const noexcept { return status_; }
  std::size_t errorLine() const noexcept { return errorLine_; }
  const char* detail() const noexcept { return detail_; }
  /// Header version (0 until the header was read).
  std::uint32_t version() const noexcept { return version_; }
  /// Data records returned by `next` so far.
  std::size_t records() const noexcept { return records_; }

 private:
  Status stop(Status s, const char* detail) noexcept;

  Cursor c_;
  const char* magic_;
  std::uint32_t maxVersion_;
  const char* headerDetail_;
  std::size_t line_ = 0;
  std::uint32_t version_ = 0;
  std::size_t records_ = 0;
  bool ended_ = false;
  Status status_ = Status::Ok;
  std::size_t errorLine_ = 0;
  const char* detail_ = nullptr;
};

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
