// GLAROT database: the pruned k-nearest search equals the exhaustive one; a moved and turned copy
// of a stored set is found first; exclusions by index, by count and by travelled distance;
// capacity refusals counted; bad queries refused; no allocation. Portable subset: also runs in
// the Cortex-M7 image.
#include <cmath>
#include <cstddef>

#include "agv/loop/glarot_database.hpp"
#include "agv_test.hpp"
#include "loop_test_util.hpp"

using namespace agv;
using agv::test::LoopRng;

namespace {

constexpr std::size_t kEntries = 48;
constexpr std::size_t kMaxSet = 24;

struct Fixture {
  GlarotDatabase<kEntries> db;
  GlarotSignature sig[kEntries];
  Eigen::Vector2f pts[kEntries][kMaxSet];
  std::size_t n[kEntries];
};

/// kEntries random sets of 4..24 points, inserted at poses 1 m apart along x.
Fixture& fixture() {
  static Fixture f;
  f.db.clear();
  LoopRng rng{2024};
  for (std::size_t e = 0; e < kEntries; ++e) {
    f.n[e] = 4 + (e * 7) % (kMaxSet - 3);
    agv::test::randomPoints(rng, f.n[e], -6.0, -4.0, 12.0, 8.0, 0.3, f.pts[e]);
    CHECK(computeGlarot(Span<const Eigen::Vector2f>(f.pts[e], f.n[e]), GlarotParams{}, f.sig[e]) == Status::Ok);
    CHECK(f.db.insert(f.sig[e], Pose2d{static_cast<double>(e), 0.0, 0.0}) == Status::Ok);
  }
  return f;
}

/// Exhaustive reference: SL1 to every admitted entry, k smallest, ties by index.
std::size_t bruteForce(const Fixture& f, const GlarotSignature& q, std::size_t k, std::size_t end,
                       GlarotCandidate* out) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < end; ++i) {
    const GlarotMatch m = glarotDistance(f.db.at(i)->signature, q).value();
    std::size_t pos = n < k ? n : k;
    if (pos == k && !(m.distance < out[k - 1].distance)) {
      continue;
    }
    if (pos == k) {
      pos = k - 1;
    }
    while (pos > 0 && out[pos - 1].distance > m.distance) {
      out[pos] = out[pos - 1];
      --pos;
    }
    out[pos] = GlarotCandidate{static_cast<std::uint32_t>(i), m.distance, m.shift};
    n = n < k ? n + 1 : k;
  }
  return n;
}

}  // namespace

TEST_CASE("glarot database: pruned search equals the exhaustive one; a moved copy is found first", "[loop][glarot]") {
  Fixture& f = fixture();
  static GlarotCandidates got;
  static GlarotCandidate want[kGlarotMaxCandidates];
  static GlarotSignature q;
  static Eigen::Vector2f moved[kMaxSet];
  LoopRng rng{77};
  for (std::size_t e : {std::size_t{3}, std::size_t{17}, std::size_t{40}}) {
    // The same place seen from elsewhere: turned, moved, 1 cm of noise.
    agv::test::transformPoints(Pose2d{2.0, -1.0, 0.9}, f.pts[e], f.n[e], 0.01, rng, moved);
    REQUIRE(computeGlarot(Span<const Eigen::Vector2f>(moved, f.n[e]), GlarotParams{}, q) == Status::Ok);
    for (std::size_t k : {std::size_t{1}, std::size_t{10}, std::size_t{32}}) {
      GlarotQuery gq;
      gq.k = k;
      REQUIRE(f.db.query(q, gq, got) == Status::Ok);
      const std::size_t n = bruteForce(f, q, k, kEntries, want);
      REQUIRE(got.size() == n);
      for (std::size_t i = 0; i < n; ++i) {
        CHECK(got[i].index == want[i].index);
        AGV_CHECK_NEAR(got[i].distance, want[i].distance, 1e-6);
        CHECK(got[i].shift == want[i].shift);
      }
      CHECK(got[0].index == e);
      // 0.9 rad = 2.29 cells of pi/8: shift 2 or 3.
      CHECK((got[0].shift == 2U || got[0].shift == 3U));
    }
  }
}

TEST_CASE("glarot database: exclusions by index, by count and by travelled distance", "[loop][glarot]") {
  Fixture& f = fixture();
  static GlarotCandidates got;
  const GlarotSignature& q = f.sig[30];
  GlarotQuery gq;
  gq.k = kGlarotMaxCandidates;
  REQUIRE(f.db.query(q, gq, got) == Status::Ok);
  CHECK(got[0].index == 30U);
  CHECK(got[0].distance == 0.0F);

  gq.excludeIndex = 30;  // offline: the query's own entry
  REQUIRE(f.db.query(q, gq, got) == Status::Ok);
  for (const GlarotCandidate& c : got) {
    CHECK(c.index != 30U);
  }
  gq = GlarotQuery{};
  gq.k = kGlarotMaxCandidates;
  gq.end = 30;  // earlier scans only
  REQUIRE(f.db.query(q, gq, got) == Status::Ok);
  CHECK(got.size() == 30U);
  for (const GlarotCandidate& c : got) {
    CHECK(c.index < 30U);
  }
  gq.excludeRecent = 5;  // and not the 5 before it
  REQUIRE(f.db.query(q, gq, got) == Status::Ok);
  CHECK(got.size() == 25U);
  for (const GlarotCandidate& c : got) {
    CHECK(c.index < 25U);
  }
  gq = GlarotQuery{};
  gq.k = kGlarotMaxCandidates;
  gq.excludeRecentTravel = 10.5;  // poses 1 m apart: the last 11 entries (47..37) are within 10.5 m
  REQUIRE(f.db.query(q, gq, got) == Status::Ok);
  CHECK(got.size() == kGlarotMaxCandidates);  // 37 admitted, k = 32
  for (const GlarotCandidate& c : got) {
    CHECK(c.index < kEntries - 11);
  }
  AGV_CHECK_NEAR(f.db.at(47)->travel, 47.0, 1e-9);
  gq.excludeRecentTravel = 1000.0;  // nothing left
  CHECK(f.db.query(q, gq, got) == Status::EmptyInput);
  CHECK(got.empty());
}

TEST_CASE("glarot database: capacity, shapes, poses and bad queries", "[loop][glarot]") {
  static GlarotDatabase<4> small;
  static GlarotSignature s;
  static GlarotSignature other;
  static GlarotCandidates got;
  static FixedVector<GlarotCandidate, 2> tiny;
  const Eigen::Vector2f pts[] = {{0.0F, 0.0F}, {1.0F, 0.0F}, {0.0F, 2.0F}};
  REQUIRE(computeGlarot(Span<const Eigen::Vector2f>(pts, 3), GlarotParams{}, s) == Status::Ok);
  GlarotQuery gq;
  CHECK(small.query(s, gq, got) == Status::EmptyInput);
  for (int i = 0; i < 4; ++i) {
    REQUIRE(small.insert(s) == Status::Ok);
  }
  CHECK(small.insert(s) == Status::CapacityExceeded);
  CHECK(small.insert(s) == Status::CapacityExceeded);
  CHECK(small.size() == 4U);
  CHECK(small.refusedCount() == 2U);
  CHECK(small.at(4) == nullptr);
  small.clear();
  GlarotParams p;
  p.thetaBins = 16;
  p.rhoBins = 16;
  REQUIRE(computeGlarot(Span<const Eigen::Vector2f>(pts, 3), p, other) == Status::Ok);
  REQUIRE(small.insert(s) == Status::Ok);
  CHECK(small.insert(other) == Status::InvalidArgument);
  CHECK(small.insert(GlarotSignature{}) == Status::InvalidArgument);
  CHECK(small.insert(s, Pose2d{std::nan(""), 0.0, 0.0}) == Status::NonFiniteInput);
  CHECK(small.size() == 1U);
  CHECK(small.query(other, gq, got) == Status::InvalidArgument);
  gq.k = 0;
  CHECK(small.query(s, gq, got) == Status::InvalidArgument);
  gq.k = kGlarotMaxCandidates + 1;
  CHECK(small.query(s, gq, got) == Status::InvalidArgument);
  gq.k = 3;
  CHECK(small.query(s, gq, tiny) == Status::InvalidArgument);  // out cannot hold k
  gq.k = 2;
  CHECK(small.query(s, gq, tiny) == Status::Ok);
  CHECK(tiny.size() == 1U);
}

TEST_CASE("glarot database: insert and query allocate nothing", "[loop][glarot]") {
  Fixture& f = fixture();
  static GlarotCandidates got;
  f.db.clear();
  Status st = Status::NotFound;
  AGV_CHECK_NO_ALLOCATIONS({
    for (std::size_t e = 0; e < kEntries; ++e) {
      (void)f.db.insert(f.sig[e]);
    }
    st = f.db.query(f.sig[5], GlarotQuery{}, got);
  });
  CHECK(st == Status::Ok);
  CHECK(got.size() == 10U);
}
