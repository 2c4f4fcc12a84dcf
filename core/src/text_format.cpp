#include "text_format.hpp"

#include <cmath>

namespace agv::text {

namespace {

bool isBlank(char c) noexcept {
  return c == ' ' || c == '\t' || c == '\r';
}
bool isDigit(char c) noexcept {
  return c >= '0' && c <= '9';
}

}  // namespace

bool nextLine(Cursor& c, const char** begin, const char** lineEnd) noexcept {
  if (c.p >= c.end) {
    return false;
  }
  const char* b = c.p;
  const char* e = b;
  while (e < c.end && *e != '\n') {
    ++e;
  }
  c.p = e < c.end ? e + 1 : e;
  const char* stop = b;
  while (stop < e && *stop != '#') {
    ++stop;
  }
  *begin = b;
  *lineEnd = stop;
  return true;
}

namespace {

/// True when the line `nextLine` just returned is the last of the text and has no LF: a file cut
/// inside its last line (or written without a final line end).
bool atUnterminatedEnd(const Cursor& c) noexcept {
  // After a line was read the text is not empty, so c.end[-1] exists.
  return c.p >= c.end && c.end[-1] != '\n';
}

/// The header record `<magic> <version>`: `Ok` with `*version` in 1..`maxVersion`; `Unsupported`
/// for a larger version number (a file of a newer format); `Malformed` for anything else.
Status parseHeader(const char* tb, const char* te, const char* p, const char* e, const char* magic,
                   std::uint64_t maxVersion, std::uint64_t* version) noexcept {
  const char* vb = nullptr;
  const char* ve = nullptr;
  const char* xb = nullptr;
  const char* xe = nullptr;
  std::uint64_t v = 0;
  if (!tokenIs(tb, te, magic) || !nextToken(p, e, &vb, &ve) || nextToken(p, e, &xb, &xe) ||
      !parseUnsigned(vb, ve, 0xFFFFFFFFULL, &v) || v == 0U) {
    return Status::Malformed;
  }
  if (v > maxVersion) {
    return Status::Unsupported;
  }
  *version = v;
  return Status::Ok;
}

/// The count of an `end <count>` record from the rest of its line [p, e): false when it is missing,
/// not a decimal integer or followed by another field.
bool parseEndCount(const char* p, const char* e, std::uint64_t* count) noexcept {
  const char* cb = nullptr;
  const char* ce = nullptr;
  const char* xb = nullptr;
  const char* xe = nullptr;
  return nextToken(p, e, &cb, &ce) && !nextToken(p, e, &xb, &xe) && parseUnsigned(cb, ce, 0xFFFFFFFFULL, count);
}

}  // namespace

RecordReader::RecordReader(const char* text, std::size_t size, const char* magic, std::uint32_t maxVersion,
                           const char* headerDetail) noexcept
    : c_{text, text + size}, magic_(magic), maxVersion_(maxVersion), headerDetail_(headerDetail) {}

Status RecordReader::stop(Status s, const char* detail) noexcept {
  status_ = s;
  errorLine_ = line_;
  detail_ = detail;
  return s;
}

Status RecordReader::fail(Status s, const char* detail) noexcept {
  if (version_ >= 2U && atUnterminatedEnd(c_) && s != Status::InvalidArgument) {
    return stop(Status::Truncated, "the file ends inside this line (cut short?)");
  }
  return stop(s, detail);
}

bool RecordReader::next(const char** tb, const char** te, const char** p, const char** e) noexcept {
  const char* b = nullptr;
  const char* le = nullptr;
  // Bounded: each iteration consumes at least one character of the text.
  while (nextLine(c_, &b, &le)) {
    ++line_;
    const char* q = b;
    if (!nextToken(q, le, tb, te)) {
      continue;  // blank or comment
    }
    if (version_ == 0U) {
      std::uint64_t v = 0;
      const Status hs = parseHeader(*tb, *te, q, le, magic_, maxVersion_, &v);
      if (hs != Status::Ok) {
        (void)stop(hs, hs == Status::Unsupported ? "a newer format version than this program reads" : headerDetail_);
        return false;
      }
      version_ = static_cast<std::uint32_t>(v);
      continue;
    }
    if (ended_) {
      (void)stop(Status::Malformed, "a record after the 'end' line");
      return false;
    }
    if (version_ >= 2U && tokenIs(*tb, *te, "end")) {
      std::uint64_t count = 0;
      if (!parseEndCount(q, le, &count)) {
        (void)fail(Status::Malformed, "'end' takes one count");
        return false;
      }
      if (count != records_) {
        (void)fail(Status::Malformed, "the count of 'end' is not the number of records before it");
        return false;
      }
      ended_ = true;
      continue;
    }
    ++records_;
    *p = q;
    *e = le;
    return true;
  }
  if (version_ == 0U) {
    (void)stop(Status::EmptyInput, nullptr);
  } else if (version_ >= 2U && !ended_) {
    (void)stop(Status::Truncated, "the file ends without its 'end <count>' line (cut short?)");
  } else {
    status_ = Status::Ok;
  }
  return false;
}

bool nextToken(const char*& p, const char* end, const char** tb, const char** te) noexcept {
  while (p < end && isBlank(*p)) {
    ++p;
  }
  if (p >= end) {
    return false;
  }
  *tb = p;
  while (p < end && !isBlank(*p)) {
    ++p;
  }
  *te = p;
  return true;
}

bool tokenIs(const char* b, const char* e, const char* word) noexcept {
  for (; b < e; ++b, ++word) {
    if (*word == '\0' || *word != *b) {
      return false;
    }
  }
  return *word == '\0';
}

bool parseNumber(const char* b, const char* e, double* out) noexcept {
  bool negative = false;
  if (b < e && (*b == '+' || *b == '-')) {
    negative = *b == '-';
    ++b;
  }
  std::uint64_t mantissa = 0;
  int digits = 0;
  int exponent = 0;
  bool any = false;
  for (; b < e && isDigit(*b); ++b) {
    any = true;
    if (digits < 18) {
      mantissa = mantissa * 10U + static_cast<std::uint64_t>(*b - '0');
      if (mantissa != 0U) {
        ++digits;
      }
    } else {
      ++exponent;
    }
  }
  if (b < e && *b == '.') {
    ++b;
    for (; b < e && isDigit(*b); ++b) {
      any = true;
      if (digits < 18) {
        mantissa = mantissa * 10U + static_cast<std::uint64_t>(*b - '0');
        if (mantissa != 0U) {
          ++digits;
        }
        --exponent;
      }
    }
  }
  if (!any) {
    return false;
  }
  if (b < e && (*b == 'e' || *b == 'E')) {
    ++b;
    bool expNegative = false;
    if (b < e && (*b == '+' || *b == '-')) {
      expNegative = *b == '-';
      ++b;
    }
    int ev = 0;
    bool expAny = false;
    for (; b < e && isDigit(*b); ++b) {
      expAny = true;
      if (ev < 1000) {
        ev = ev * 10 + (*b - '0');
      }
    }
    if (!expAny) {
      return false;
    }
    exponent += expNegative ? -ev : ev;
  }
  if (b != e) {
    return false;
  }
  double v = static_cast<double>(mantissa);
  if (mantissa != 0U) {
    if (exponent > 300 || exponent < -300) {
      return false;
    }
    double scale = 1.0;
    const int n = exponent < 0 ? -exponent : exponent;
    for (int i = 0; i < n; ++i) {
      scale *= 10.0;
    }
    v = exponent < 0 ? v / scale : v * scale;
  }
  *out = negative ? -v : v;
  return std::isfinite(v);
}

bool parseUnsigned(const char* b, const char* e, std::uint64_t max, std::uint64_t* out) noexcept {
  if (b >= e) {
    return false;
  }
  std::uint64_t v = 0;
  for (; b < e; ++b) {
    if (!isDigit(*b)) {
      return false;
    }
    v = v * 10U + static_cast<std::uint64_t>(*b - '0');
    if (v > max) {
      return false;
    }
  }
  *out = v;
  return true;
}

void Writer::put(char ch) noexcept {
  if (p < end) {
    *p++ = ch;
  } else {
    overflow = true;
  }
}

void Writer::put(const char* s) noexcept {
  while (*s != '\0') {
    put(*s++);
  }
}

void Writer::putUnsigned(std::uint64_t v, int minDigits) noexcept {
  char buf[24];
  int n = 0;
  do {
    buf[n++] = static_cast<char>('0' + static_cast<int>(v % 10U));
    v /= 10U;
  } while (v != 0U && n < 24);
  while (n < minDigits && n < 24) {
    buf[n++] = '0';
  }
  while (n > 0) {
    put(buf[--n]);
  }
}

void Writer::putFixed(double v, int decimals) noexcept {
  if (decimals < 0) {
    decimals = 0;
  } else if (decimals > 12) {
    decimals = 12;
  }
  std::uint64_t unit = 1;
  for (int i = 0; i < decimals; ++i) {
    unit *= 10U;
  }
  const double scaled = std::round(v * static_cast<double>(unit));
  if (!std::isfinite(scaled) || std::fabs(scaled) >= 9.0e18) {
    overflow = true;  // not representable in this fixed-point form
    return;
  }
  if (scaled < 0.0) {
    put('-');
  }
  const auto m = static_cast<std::uint64_t>(std::fabs(scaled));
  putUnsigned(m / unit, 1);
  if (decimals > 0) {
    put('.');
    putUnsigned(m % unit, decimals);
  }
}

}  // namespace agv::text
