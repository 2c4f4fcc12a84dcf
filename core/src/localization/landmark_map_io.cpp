#include "agv/localization/landmark_map_io.hpp"

#include <cmath>

#include "../text_format.hpp"

namespace agv {

namespace {

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
  // sigma is bounded like the coordinates: larger is meaningless, and it could not be written back.
  if (r->id == 0 || std::fabs(r->x) > kMaxMapCoordinate || std::fabs(r->y) > kMaxMapCoordinate || r->sigma < 0.0 ||
      r->sigma > kMaxMapCoordinate) {
    return Status::OutOfRange;
  }
  return Status::Ok;
}

/// Where a walk over the records stopped, and what it read.
struct Walk {
  std::size_t errorLine = 0;
  const char* detail = nullptr;
  std::uint32_t version = 0;
  std::size_t records = 0;
};

/// Walks the records; calls f(record) for each. Returns the first error, with its line and detail
/// in `w`.
template <typename F>
Status forEachRecord(Span<const char> text, Walk& w, F&& f) noexcept {
  text::RecordReader reader(text.data(), text.size(), "agvnav-landmarks", kLandmarkMapFormatVersion,
                            "the first record is not 'agvnav-landmarks <version>'");
  const char* tb = nullptr;
  const char* te = nullptr;
  const char* p = nullptr;
  const char* e = nullptr;
  Status s = Status::Ok;
  // Bounded: the reader consumes the text.
  while (s == Status::Ok && reader.next(&tb, &te, &p, &e)) {
    Record r;
    s = parseRecord(tb, e, &r);
    if (s == Status::Ok) {
      s = f(r);
    }
    if (s != Status::Ok) {
      s = reader.fail(s, nullptr);
    }
  }
  if (s == Status::Ok) {
    s = reader.status();
  }
  w = Walk{reader.errorLine(), reader.detail(), reader.version(), reader.records()};
  return s;
}

}  // namespace

Status parseLandmarkMap(Span<const char> text, LandmarkMap& map, LandmarkMapParseReport* report) noexcept {
  LandmarkMapParseReport local;
  LandmarkMapParseReport& rep = report != nullptr ? *report : local;
  rep = LandmarkMapParseReport{};
  // Pass 1: validate everything and count.
  Walk w;
  Status s = forEachRecord(text, w, [](const Record&) { return Status::Ok; });
  rep.version = w.version;
  rep.records = w.records;
  rep.errorLine = w.errorLine;
  rep.detail = w.detail;
  if (s != Status::Ok) {
    return s;
  }
  const std::size_t count = w.records;
  if (count > map.capacity() - map.size()) {
    rep.errorLine = 0;
    map.countRefusedFull(static_cast<std::uint32_t>(count));
    return Status::CapacityExceeded;
  }
  // Pass 2: insert; on a duplicate id undo what this call added.
  std::size_t added = 0;
  s = forEachRecord(text, w, [&](const Record& r) {
    const Result<LandmarkIndex> res = map.addSurveyed(r.kind, r.x, r.y, r.sigma, r.id);
    if (!res.ok()) {
      return res.status();
    }
    ++added;
    return Status::Ok;
  });
  if (s != Status::Ok) {
    rep.errorLine = w.errorLine;
    rep.detail = w.detail;
    std::size_t undone = 0;
    Walk ignored;
    (void)forEachRecord(text, ignored, [&](const Record& r) {
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
  w.put("agvnav-landmarks 2\n# kind id x[m] y[m] sigma[m]\n");
  std::uint64_t count = 0;
  map.forEach([&](LandmarkIndex, const Landmark& l) {
    if (surveyedOnly && !l.surveyed) {
      return;
    }
    ++count;
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
  w.put("end ");
  w.putUnsigned(count, 1);
  w.put('\n');
  if (w.overflow) {
    return Status::Truncated;
  }
  return static_cast<std::size_t>(w.p - out.data());
}

}  // namespace agv
