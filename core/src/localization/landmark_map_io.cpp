#include "agv/localization/landmark_map_io.hpp"

#include <cmath>

namespace agv {

namespace {

struct Cursor {
  const char* p;
  const char* end;
};

bool isBlank(char c) noexcept {
  return c == ' ' || c == '\t' || c == '\r';
}
bool isDigit(char c) noexcept {
  return c >= '0' && c <= '9';
}

/// The next line without its end-of-line and comment; false at end of text.
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

/// Next whitespace-separated token of [p, end); false when none.
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

/// Decimal number with optional sign, fraction and exponent; the whole token must be consumed.
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

bool parseId(const char* b, const char* e, std::uint32_t* out) noexcept {
  if (b >= e) {
    return false;
  }
  std::uint64_t v = 0;
  for (; b < e; ++b) {
    if (!isDigit(*b)) {
      return false;
    }
    v = v * 10U + static_cast<std::uint64_t>(*b - '0');
    if (v > 0xFFFFFFFFULL) {
      return false;
    }
  }
  *out = static_cast<std::uint32_t>(v);
  return true;
}

struct Record {
  LandmarkKind kind = LandmarkKind::Reflector;
  std::uint32_t id = 0;
  double x = 0.0;
  double y = 0.0;
  double sigma = 0.0;
};

/// Parses one non-empty record line. Ok, Malformed or OutOfRange.
Status parseRecord(const char* p, const char* end, Record* r) noexcept {
  const char* tb = nullptr;
  const char* te = nullptr;
  if (!nextToken(p, end, &tb, &te)) {
    return Status::Malformed;
  }
  if (tokenIs(tb, te, "reflector")) {
    r->kind = LandmarkKind::Reflector;
  } else if (tokenIs(tb, te, "corner")) {
    r->kind = LandmarkKind::Corner;
  } else {
    return Status::Malformed;
  }
  if (!nextToken(p, end, &tb, &te) || !parseId(tb, te, &r->id)) {
    return Status::Malformed;
  }
  double* fields[3] = {&r->x, &r->y, &r->sigma};
  for (double* f : fields) {
    if (!nextToken(p, end, &tb, &te) || !parseNumber(tb, te, f)) {
      return Status::Malformed;
    }
  }
  if (nextToken(p, end, &tb, &te)) {
    return Status::Malformed;  // trailing field
  }
  if (r->id == 0 || std::fabs(r->x) > kMaxMapCoordinate || std::fabs(r->y) > kMaxMapCoordinate || r->sigma < 0.0) {
    return Status::OutOfRange;
  }
  return Status::Ok;
}

/// Walks the records; calls f(record) for each. Returns the first error and its line.
template <typename F>
Status forEachRecord(Span<const char> text, std::size_t* errorLine, F&& f) noexcept {
  Cursor c{text.data(), text.data() + text.size()};
  const char* b = nullptr;
  const char* e = nullptr;
  std::size_t line = 0;
  bool header = false;
  // Bounded: each iteration consumes at least one character.
  while (nextLine(c, &b, &e)) {
    ++line;
    const char* p = b;
    const char* tb = nullptr;
    const char* te = nullptr;
    if (!nextToken(p, e, &tb, &te)) {
      continue;  // blank or comment
    }
    if (!header) {
      const char* vb = nullptr;
      const char* ve = nullptr;
      const char* xb = nullptr;
      const char* xe = nullptr;
      if (!tokenIs(tb, te, "agvnav-landmarks") || !nextToken(p, e, &vb, &ve) || !tokenIs(vb, ve, "1") ||
          nextToken(p, e, &xb, &xe)) {
        *errorLine = line;
        return Status::Malformed;
      }
      header = true;
      continue;
    }
    Record r;
    const Status s = parseRecord(b, e, &r);
    if (s != Status::Ok) {
      *errorLine = line;
      return s;
    }
    const Status fs = f(r);
    if (fs != Status::Ok) {
      *errorLine = line;
      return fs;
    }
  }
  if (!header) {
    *errorLine = line;
    return Status::EmptyInput;
  }
  return Status::Ok;
}

// ---- formatting ----

struct Writer {
  char* p;
  char* end;
  bool overflow = false;
  void put(char ch) noexcept {
    if (p < end) {
      *p++ = ch;
    } else {
      overflow = true;
    }
  }
  void put(const char* s) noexcept {
    while (*s != '\0') {
      put(*s++);
    }
  }
  void putUnsigned(std::uint64_t v, int minDigits) noexcept {
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
  /// Fixed point with 6 decimals.
  void putFixed6(double v) noexcept {
    const double scaled = std::round(v * 1e6);
    if (scaled < 0.0) {
      put('-');
    }
    const std::uint64_t m = static_cast<std::uint64_t>(std::fabs(scaled));
    putUnsigned(m / 1000000U, 1);
    put('.');
    putUnsigned(m % 1000000U, 6);
  }
};

}  // namespace

Status parseLandmarkMap(Span<const char> text, LandmarkMap& map, LandmarkMapParseReport* report) noexcept {
  LandmarkMapParseReport local;
  LandmarkMapParseReport& rep = report != nullptr ? *report : local;
  rep = LandmarkMapParseReport{};
  // Pass 1: validate everything and count.
  std::size_t count = 0;
  Status s = forEachRecord(text, &rep.errorLine, [&](const Record&) {
    ++count;
    return Status::Ok;
  });
  if (s != Status::Ok) {
    return s;
  }
  if (count > map.capacity() - map.size()) {
    rep.errorLine = 0;
    map.countRefusedFull(static_cast<std::uint32_t>(count));
    return Status::CapacityExceeded;
  }
  // Pass 2: insert; on a duplicate id undo what this call added.
  std::size_t added = 0;
  std::size_t failLine = 0;
  s = forEachRecord(text, &failLine, [&](const Record& r) {
    const Result<LandmarkIndex> res = map.addSurveyed(r.kind, r.x, r.y, r.sigma, r.id);
    if (!res.ok()) {
      return res.status();
    }
    ++added;
    return Status::Ok;
  });
  if (s != Status::Ok) {
    rep.errorLine = failLine;
    std::size_t undone = 0;
    std::size_t ignored = 0;
    (void)forEachRecord(text, &ignored, [&](const Record& r) {
      if (undone >= added) {
        return Status::Ok;
      }
      ++undone;
      (void)map.remove(map.findById(r.id));
      return Status::Ok;
    });
    return s;
  }
  rep.landmarks = added;
  return Status::Ok;
}

Result<std::size_t> formatLandmarkMap(const LandmarkMap& map, Span<char> out, bool surveyedOnly) noexcept {
  Writer w{out.data(), out.data() + out.size()};
  w.put("agvnav-landmarks 1\n# kind id x[m] y[m] sigma[m]\n");
  map.forEach([&](LandmarkIndex, const Landmark& l) {
    if (surveyedOnly && !l.surveyed) {
      return;
    }
    w.put(l.kind == LandmarkKind::Corner ? "corner " : "reflector ");
    w.putUnsigned(l.id, 1);
    w.put(' ');
    w.putFixed6(l.x);
    w.put(' ');
    w.putFixed6(l.y);
    w.put(' ');
    w.putFixed6(std::sqrt(l.variance));
    w.put('\n');
  });
  if (w.overflow) {
    return Status::Truncated;
  }
  return static_cast<std::size_t>(w.p - out.data());
}

}  // namespace agv
