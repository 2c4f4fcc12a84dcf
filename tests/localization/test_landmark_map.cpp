// LandmarkMap lifecycle, capacity, spatial queries; map text format. Portable subset: also runs
// in the Cortex-M7 image (the map is static: ~280 KB).
#include <cstring>
#include <memory>
#include <new>
#include <vector>

#include "agv/localization/landmark_map.hpp"
#include "agv/localization/landmark_map_io.hpp"
#include "agv_test.hpp"

using namespace agv;

namespace {
LandmarkMap& sharedMap(const LandmarkMapParams& p = LandmarkMapParams{}) {
  static LandmarkMap map;
  map.~LandmarkMap();
  new (&map) LandmarkMap(p);
  return map;
}
// Deterministic pseudo-random numbers (no <random> on the MCU image).
struct Lcg {
  std::uint64_t s;
  double next() {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(s >> 11) * (1.0 / 9007199254740992.0);
  }
};
}  // namespace

TEST_CASE("landmark map: hit-count lifecycle and update rate", "[localization][map]") {
  LandmarkMapParams p;
  p.updateRate = 0.1;
  p.initialHits = 1;
  p.maxHits = 3;
  LandmarkMap& map = sharedMap(p);
  const auto r = map.insert(LandmarkKind::Reflector, 2.0, 3.0, 1e-4);
  REQUIRE(r.ok());
  const LandmarkIndex i = r.value();
  REQUIRE(map.at(i) != nullptr);
  CHECK(map.at(i)->hits == 1);
  CHECK(map.size() == 1U);
  // matched: +1 and 10 % of the way toward the observation; variance (1-a)^2 v + a^2 w
  CHECK(map.reinforce(i, 3.0, 3.0, 4e-4, 7U) == Status::Ok);
  AGV_CHECK_NEAR(map.at(i)->x, 2.1, 1e-12);
  AGV_CHECK_NEAR(map.at(i)->y, 3.0, 1e-12);
  AGV_CHECK_NEAR(map.at(i)->variance, 0.81e-4 + 0.01 * 4e-4, 1e-15);
  CHECK(map.at(i)->hits == 2);
  CHECK(map.at(i)->lastMatchedCycle == 7U);
  CHECK(map.reinforce(i, 3.0, 3.0, 4e-4, 8U) == Status::Ok);
  CHECK(map.reinforce(i, 3.0, 3.0, 4e-4, 9U) == Status::Ok);
  CHECK(map.at(i)->hits == 3);  // capped at maxHits
  // in view, not matched: -1 each, deleted at 0
  CHECK_FALSE(map.weaken(i));
  CHECK_FALSE(map.weaken(i));
  CHECK(map.weaken(i));
  CHECK(map.at(i) == nullptr);
  CHECK(map.size() == 0U);
  CHECK(map.counters().inserted == 1U);
  CHECK(map.counters().deleted == 1U);
  CHECK(map.reinforce(i, 1.0, 1.0, 0.0, 1U) == Status::NotFound);
  CHECK(map.remove(i) == Status::NotFound);
}

TEST_CASE("landmark map: surveyed landmarks never move or die; static mode freezes the map", "[localization][map]") {
  LandmarkMap& map = sharedMap();
  const auto s = map.addSurveyed(LandmarkKind::Corner, -4.0, 1.0, 0.002, 42U);
  REQUIRE(s.ok());
  CHECK(map.at(s.value())->surveyed);
  AGV_CHECK_NEAR(map.at(s.value())->variance, 4e-6, 1e-18);
  CHECK(map.addSurveyed(LandmarkKind::Corner, 0.0, 0.0, 0.0, 42U).status() == Status::InvalidArgument);  // duplicate id
  CHECK(map.addSurveyed(LandmarkKind::Corner, 0.0, 0.0, -1.0, 43U).status() == Status::InvalidArgument);
  for (int k = 0; k < 100; ++k) {
    CHECK_FALSE(map.weaken(s.value()));
    CHECK(map.reinforce(s.value(), 0.0, 0.0, 0.0, 5U) == Status::Ok);
  }
  CHECK(map.at(s.value()) != nullptr);
  CHECK(map.at(s.value())->x == -4.0);
  CHECK(map.at(s.value())->lastMatchedCycle == 5U);
  CHECK(map.findById(42U) == s.value());

  const auto d = map.insert(LandmarkKind::Reflector, 1.0, 1.0, 1e-4);
  REQUIRE(d.ok());
  CHECK(map.at(d.value())->id != 42U);
  map.setMode(MapMode::Static);
  CHECK(map.insert(LandmarkKind::Reflector, 5.0, 5.0, 1e-4).status() == Status::Unsupported);
  CHECK(map.reinforce(d.value(), 2.0, 2.0, 0.0, 9U) == Status::Ok);
  CHECK(map.at(d.value())->x == 1.0);
  CHECK(map.at(d.value())->hits == 1);
  CHECK_FALSE(map.weaken(d.value()));
  CHECK(map.at(d.value()) != nullptr);
  // surveyed landmarks can still be loaded into a static map
  CHECK(map.addSurveyed(LandmarkKind::Reflector, 9.0, 9.0, 0.001, 50U).ok());
  CHECK(map.size() == 3U);
}

TEST_CASE("landmark map: a full map refuses inserts and counts them; bad coordinates are refused",
          "[localization][map]") {
  LandmarkMap& map = sharedMap();
  for (std::size_t i = 0; i < kMaxLandmarks; ++i) {
    const double x = static_cast<double>(i % 64U);
    const double y = static_cast<double>(i / 64U);
    REQUIRE(map.insert(LandmarkKind::Reflector, x, y, 1e-4).ok());
  }
  CHECK(map.full());
  CHECK(map.insert(LandmarkKind::Reflector, 0.5, 0.5, 1e-4).status() == Status::CapacityExceeded);
  CHECK(map.addSurveyed(LandmarkKind::Reflector, 0.5, 0.5, 0.0, 999999U).status() == Status::CapacityExceeded);
  CHECK(map.counters().refusedFull == 2U);
  // freeing one slot makes room again
  REQUIRE(map.remove(17U) == Status::Ok);
  CHECK(map.insert(LandmarkKind::Corner, 0.5, 0.5, 1e-4).ok());

  LandmarkMap& m2 = sharedMap();
  const double nan = std::nan("");
  CHECK(m2.insert(LandmarkKind::Reflector, nan, 0.0, 1e-4).status() == Status::NonFiniteInput);
  CHECK(m2.insert(LandmarkKind::Reflector, 2e6, 0.0, 1e-4).status() == Status::OutOfRange);
  CHECK(m2.insert(LandmarkKind::Reflector, 0.0, 0.0, -1.0).status() == Status::InvalidArgument);
  CHECK(m2.counters().refusedInvalid == 3U);
  CHECK(m2.size() == 0U);
  // invalid parameters fall back to the defaults
  LandmarkMapParams bad;
  bad.updateRate = 2.0;
  LandmarkMap& m3 = sharedMap(bad);
  CHECK_FALSE(m3.paramsValid());
  AGV_CHECK_NEAR(m3.params().updateRate, 0.1, 0.0);
}

TEST_CASE("landmark map: grid queries find exactly the landmarks a brute-force search finds", "[localization][map]") {
  LandmarkMapParams p;
  p.cellSize = 1.5;
  LandmarkMap& map = sharedMap(p);
  Lcg rng{12345U};
  const int n = 1500;
  for (int i = 0; i < n; ++i) {
    REQUIRE(map.insert(LandmarkKind::Reflector, -40.0 + 80.0 * rng.next(), -40.0 + 80.0 * rng.next(), 1e-4).ok());
  }
  // move some across cells, delete some, so the index must have followed
  for (LandmarkIndex i = 0; i < 300; ++i) {
    for (int k = 0; k < 30; ++k)
      (void)map.reinforce(i, 35.0, -35.0, 0.0, 1U);
  }
  for (LandmarkIndex i = 300; i < 600; i += 2)
    REQUIRE(map.remove(i) == Status::Ok);
  for (int q = 0; q < 60; ++q) {
    const double cx = -45.0 + 90.0 * rng.next();
    const double cy = -45.0 + 90.0 * rng.next();
    const double r = 0.2 + 6.0 * rng.next();
    int viaGrid = 0;
    int visits = 0;
    map.forEachNear(cx, cy, r, [&](LandmarkIndex, const Landmark& l) {
      ++visits;
      if ((l.x - cx) * (l.x - cx) + (l.y - cy) * (l.y - cy) <= r * r)
        ++viaGrid;
    });
    int brute = 0;
    int total = 0;
    map.forEach([&](LandmarkIndex, const Landmark& l) {
      ++total;
      if ((l.x - cx) * (l.x - cx) + (l.y - cy) * (l.y - cy) <= r * r)
        ++brute;
    });
    CHECK(viaGrid == brute);
    CHECK(total == n - 150);
    // the grid visits only the cells around the query, not the whole map
    CHECK(visits < total / 4);
  }
}

#ifndef AGV_TEST_MCU  // two maps do not fit the Cortex-M7 image's RAM
TEST_CASE("landmark map: copyFrom gives an independent copy that behaves exactly like the original",
          "[localization][map]") {
  LandmarkMapParams p;
  p.cellSize = 1.5;
  p.updateRate = 0.25;
  LandmarkMap& original = sharedMap(p);
  Lcg rng{777U};
  for (int i = 0; i < 400; ++i) {
    REQUIRE(original.insert(LandmarkKind::Corner, -30.0 + 60.0 * rng.next(), -30.0 + 60.0 * rng.next(), 1e-4).ok());
  }
  REQUIRE(original.addSurveyed(LandmarkKind::Reflector, 3.0, 4.0, 0.002, 9001U).ok());
  for (LandmarkIndex i = 0; i < 100; ++i) {
    REQUIRE(original.reinforce(i, 10.0, -10.0, 4e-4, 7U) == Status::Ok);  // moves across cells
  }
  for (LandmarkIndex i = 100; i < 200; i += 3) {
    REQUIRE(original.remove(i) == Status::Ok);  // free slots in the middle
  }
  const std::size_t size = original.size();

  auto copy = std::make_unique<LandmarkMap>();  // other parameters: copyFrom replaces them
  REQUIRE(copy->insert(LandmarkKind::Reflector, 0.5, 0.5, 1e-4).ok());
  copy->copyFrom(original);
  CHECK(copy->size() == size);
  CHECK(copy->params().cellSize == p.cellSize);
  CHECK(copy->params().updateRate == p.updateRate);
  CHECK(copy->counters().inserted == original.counters().inserted);
  CHECK(copy->counters().deleted == original.counters().deleted);
  CHECK(copy->findById(9001U) == original.findById(9001U));
  // the same landmarks in the same slots
  for (LandmarkIndex i = 0; i < LandmarkMap::capacity(); ++i) {
    const Landmark* a = original.at(i);
    const Landmark* b = copy->at(i);
    REQUIRE((a == nullptr) == (b == nullptr));
    if (a != nullptr) {
      CHECK(std::memcmp(a, b, sizeof(Landmark)) == 0);
    }
  }
  // the grid: the same visits in the same order
  for (int q = 0; q < 30; ++q) {
    const double cx = -32.0 + 64.0 * rng.next();
    const double cy = -32.0 + 64.0 * rng.next();
    const double r = 0.5 + 5.0 * rng.next();
    std::vector<LandmarkIndex> va;
    std::vector<LandmarkIndex> vb;
    original.forEachNear(cx, cy, r, [&](LandmarkIndex i, const Landmark&) { va.push_back(i); });
    copy->forEachNear(cx, cy, r, [&](LandmarkIndex i, const Landmark&) { vb.push_back(i); });
    CHECK(va == vb);
  }
  // the free slots: the next inserts land in the same slots
  for (int k = 0; k < 40; ++k) {
    const double x = -20.0 + 40.0 * rng.next();
    const auto a = original.insert(LandmarkKind::Corner, x, 1.0, 1e-4);
    const auto b = copy->insert(LandmarkKind::Corner, x, 1.0, 1e-4);
    REQUIRE(a.ok());
    REQUIRE(b.ok());
    CHECK(a.value() == b.value());
    CHECK(original.at(a.value())->id == copy->at(b.value())->id);
  }
  // independent: changing one leaves the other
  REQUIRE(copy->remove(0) == Status::Ok);
  CHECK(original.at(0) != nullptr);
  original.clear();
  CHECK(copy->size() == size + 40 - 1);
  copy->copyFrom(*copy);  // self-copy is a no-op
  CHECK(copy->size() == size + 40 - 1);
}
#endif

TEST_CASE("landmark map text: round trip, comments, CRLF", "[localization][map][io]") {
  LandmarkMap& map = sharedMap();
  static const char text[] =
      "# surveyed hall 3\r\n"
      "\r\n"
      "agvnav-landmarks 2   # version\r\n"
      "reflector 1 12.345 -3.21 0.002\r\n"
      "corner\t2\t-0.5\t1e1\t1.5e-2\n"
      "   # indented comment\n"
      "reflector 7 +0.000001 -1000000 0\r\n"
      "end 3 # no final line end";
  LandmarkMapParseReport rep;
  REQUIRE(parseLandmarkMap(Span<const char>(text, sizeof(text) - 1U), map, &rep) == Status::Ok);
  CHECK(rep.landmarks == 3U);
  CHECK(rep.version == 2U);
  CHECK(map.size() == 3U);
  const Landmark* a = map.at(map.findById(1U));
  const Landmark* b = map.at(map.findById(2U));
  const Landmark* c = map.at(map.findById(7U));
  REQUIRE(a != nullptr);
  REQUIRE(b != nullptr);
  REQUIRE(c != nullptr);
  AGV_CHECK_NEAR(a->x, 12.345, 1e-12);
  AGV_CHECK_NEAR(a->y, -3.21, 1e-12);
  AGV_CHECK_NEAR(a->variance, 4e-6, 1e-15);
  CHECK(a->kind == LandmarkKind::Reflector);
  CHECK(b->kind == LandmarkKind::Corner);
  AGV_CHECK_NEAR(b->y, 10.0, 1e-12);
  AGV_CHECK_NEAR(std::sqrt(b->variance), 0.015, 1e-12);
  AGV_CHECK_NEAR(c->x, 1e-6, 1e-18);
  AGV_CHECK_NEAR(c->y, -1e6, 1e-9);
  CHECK(a->surveyed);

  static char buffer[1024];
  const auto w = formatLandmarkMap(map, Span<char>(buffer, sizeof(buffer)));
  REQUIRE(w.ok());
  REQUIRE(w.value() > 25U);
  CHECK(std::strncmp(buffer, "agvnav-landmarks 2\n", 19) == 0);
  CHECK(std::strncmp(buffer + w.value() - 6U, "end 3\n", 6) == 0);
  LandmarkMap& copy = sharedMap();
  REQUIRE(parseLandmarkMap(Span<const char>(buffer, w.value()), copy, &rep) == Status::Ok);
  CHECK(copy.size() == 3U);
  const Landmark* a2 = copy.at(copy.findById(1U));
  REQUIRE(a2 != nullptr);
  AGV_CHECK_NEAR(a2->x, 12.345, 1e-9);
  AGV_CHECK_NEAR(std::sqrt(a2->variance), 0.002, 1e-9);
  // a too-small buffer says so
  CHECK(formatLandmarkMap(copy, Span<char>(buffer, 20)).status() == Status::Truncated);
}

TEST_CASE("landmark map text: malformed input is refused and leaves the map unchanged", "[localization][map][io]") {
  LandmarkMap& map = sharedMap();
  REQUIRE(map.addSurveyed(LandmarkKind::Reflector, 0.0, 0.0, 0.0, 5U).ok());
  struct Case {
    const char* text;
    Status expect;
    std::size_t line;
  };
  static const Case cases[] = {
      {"", Status::EmptyInput, 0U},
      {"# only a comment\n", Status::EmptyInput, 1U},
      {"agvnav-landmarks 3\n", Status::Unsupported, 1U},
      {"agvnav-landmarks 0\n", Status::Malformed, 1U},
      {"agvnav-landmarks 1.0\n", Status::Malformed, 1U},
      {"agvnav-landmarks\n", Status::Malformed, 1U},
      {"agvnav-landmarks 2\n", Status::Truncated, 1U},
      {"agvnav-landmarks 2\nreflector 1 0 0 0\n", Status::Truncated, 2U},
      {"agvnav-landmarks 2\nreflector 1 0 0 0\n\n# x\n", Status::Truncated, 4U},
      {"agvnav-landmarks 2\nreflector 1 0 0 0\nend 2\n", Status::Malformed, 3U},
      {"agvnav-landmarks 2\nreflector 1 0 0 0\nend 0\n", Status::Malformed, 3U},
      {"agvnav-landmarks 2\nreflector 1 0 0 0\nend\n", Status::Malformed, 3U},
      {"agvnav-landmarks 2\nreflector 1 0 0 0\nend 1 1\n", Status::Malformed, 3U},
      {"agvnav-landmarks 2\nreflector 1 0 0 0\nend 1\nreflector 2 0 0 0\n", Status::Malformed, 4U},
      {"agvnav-landmarks 2\nreflector 1 0 0 0\nend 1\n# c\n\nx", Status::Malformed, 6U},
      {"agvnav-landmarks 2\nreflector 1 0 0 0\nend 1\nend 1\n", Status::Malformed, 4U},
      {"agvnav-landmarks 2\nreflector 1 0 0 0\nend 12", Status::Truncated, 3U},  // cut inside the end line
      {"agvnav-landmarks 2\nreflector 1 0 0", Status::Truncated, 2U},
      {"agvnav-landmarks 2\nreflector 1 0 0 -0.1", Status::Truncated, 2U},  // "-0.1e-3" cut
      {"agvnav-landmarks 2\nreflector 1 0 0 -0.1\nend 1\n", Status::OutOfRange, 2U},
      {"agvnav-landmarks 1\nreflector 1 0 0 0\nend 1\n", Status::Malformed, 3U},  // no end in version 1
      {"reflector 1 0 0 0\n", Status::Malformed, 1U},
      {"agvnav-landmarks 1\nreflector 1 0 0 0\npole 2 0 0 0\n", Status::Malformed, 3U},
      {"agvnav-landmarks 1\nreflector 1 0 0\n", Status::Malformed, 2U},
      {"agvnav-landmarks 1\nreflector 1 0 0 0 9\n", Status::Malformed, 2U},
      {"agvnav-landmarks 1\nreflector 1 0x3 0 0\n", Status::Malformed, 2U},
      {"agvnav-landmarks 1\nreflector 1 nan 0 0\n", Status::Malformed, 2U},
      {"agvnav-landmarks 1\nreflector 1 1e 0 0\n", Status::Malformed, 2U},
      {"agvnav-landmarks 1\nreflector -1 0 0 0\n", Status::Malformed, 2U},
      {"agvnav-landmarks 1\nreflector 0 0 0 0\n", Status::OutOfRange, 2U},
      {"agvnav-landmarks 1\nreflector 1 0 2000000 0\n", Status::OutOfRange, 2U},
      {"agvnav-landmarks 1\nreflector 1 0 0 -0.1\n", Status::OutOfRange, 2U},
      {"agvnav-landmarks 1\nreflector 1 0 0 1000000.5\n", Status::OutOfRange, 2U},
      {"agvnav-landmarks 1\nreflector 1 0 0 0\nreflector 2 0 0 0\nreflector 1 1 1 0\n", Status::InvalidArgument, 4U},
      {"agvnav-landmarks 1\nreflector 5 0 0 0\n", Status::InvalidArgument, 2U},  // id already in the map
  };
  for (const Case& c : cases) {
    LandmarkMapParseReport rep;
    const Status s = parseLandmarkMap(Span<const char>(c.text, std::strlen(c.text)), map, &rep);
    INFO(c.text);
    CHECK(s == c.expect);
    CHECK(rep.errorLine == c.line);
    CHECK(rep.landmarks == 0U);
    CHECK(map.size() == 1U);
  }
}

TEST_CASE("landmark map text: every cut of a written map is refused, naming the line where it ends",
          "[localization][map][io]") {
  LandmarkMap& map = sharedMap();
  for (std::uint32_t id = 1; id <= 5U; ++id) {
    REQUIRE(map.addSurveyed(id % 2U != 0U ? LandmarkKind::Reflector : LandmarkKind::Corner, 1.25 * id, -3.5 * id,
                            0.002 * id, id)
                .ok());
  }
  static char full[1024];
  const auto w = formatLandmarkMap(map, Span<char>(full, sizeof(full)));
  REQUIRE(w.ok());
  const std::size_t n = w.value();
  const std::size_t header = 19U;  // "agvnav-landmarks 2\n"
  std::size_t refused = 0;
  for (std::size_t cut = 0; cut < n; ++cut) {
    LandmarkMap& copy = sharedMap();
    LandmarkMapParseReport rep;
    const Status s = parseLandmarkMap(Span<const char>(full, cut), copy, &rep);
    INFO("cut at " << cut);
    if (cut + 1U == n) {
      CHECK(s == Status::Ok);  // only the final LF missing: nothing lost
      CHECK(copy.size() == 5U);
      continue;
    }
    refused += s != Status::Ok ? 1U : 0U;
    CHECK(copy.size() == 0U);
    if (cut <= header) {
      continue;  // inside the header: EmptyInput or Malformed
    }
    CHECK(s == Status::Truncated);
    std::size_t lines = 0;
    for (std::size_t i = 0; i < cut; ++i) {
      lines += full[i] == '\n' ? 1U : 0U;
    }
    lines += full[cut - 1U] != '\n' ? 1U : 0U;
    CHECK(rep.errorLine == lines);
    CHECK(rep.detail != nullptr);
  }
  CHECK(refused == n - 1U);

  // Version 1 is still read (no end line), and a cut at a line end goes unnoticed: why version 2.
  static char v1[1024];
  std::memcpy(v1, full, n - 6U);  // without "end 5\n"
  v1[17] = '1';                   // "agvnav-landmarks 1"
  LandmarkMapParseReport rep;
  REQUIRE(parseLandmarkMap(Span<const char>(v1, n - 6U), sharedMap(), &rep) == Status::Ok);
  CHECK(rep.version == 1U);
  CHECK(rep.landmarks == 5U);
  std::size_t lastLine = n - 7U;
  while (v1[lastLine - 1U] != '\n') {
    --lastLine;
  }
  LandmarkMap& cutMap = sharedMap();
  CHECK(parseLandmarkMap(Span<const char>(v1, lastLine), cutMap, &rep) == Status::Ok);
  CHECK(cutMap.size() == 4U);
}
