#include "agv/localization/landmark_map_io.hpp"

#include <cmath>

#include "../text_format.hpp"

namespace agv {

namespace {

using text::Cursor;
using text::nextLine;
using text::nextToken;
using text::parseNumber;
using text::tokenIs;

bool parseId(const char* b, const char* e, std::uint32_t* out) noexcept {
  std::uint64_t v = 0;
  if (!text::parseUnsigned(b, e, 0xFFFFFFFFULL, &v)) {
    return false;
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
  text::Writer w{out.data(), out.data() + out.size()};
  w.put("agvnav-landmarks 1\n# kind id x[m] y[m] sigma[m]\n");
  map.forEach([&](LandmarkIndex, const Landmark& l) {
    if (surveyedOnly && !l.surveyed) {
      return;
    }
    w.put(l.kind == LandmarkKind::Corner ? "corner " : "reflector ");
    w.putUnsigned(l.id, 1);
    w.put(' ');
    w.putFixed(l.x, 6);
    w.put(' ');
    w.putFixed(l.y, 6);
    w.put(' ');
    w.putFixed(std::sqrt(l.variance), 6);
    w.put('\n');
  });
  if (w.overflow) {
    return Status::Truncated;
  }
  return static_cast<std::size_t>(w.p - out.data());
}

}  // namespace agv
