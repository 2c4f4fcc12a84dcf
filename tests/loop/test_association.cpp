// Loop-closure point association: correspondence graph, affine Hough and RANSAC each recover a
// known rigid transform with 30 % outliers; refusals (fewer than 3 compatible pairs, empty,
// over-capacity, NaN, bad candidates); work bounds hit, reported and never exceeded; determinism;
// no allocation. Portable subset: also runs in the Cortex-M7 image.
#include <cmath>
#include <cstddef>

#include "agv/loop/affine_hough.hpp"
#include "agv/loop/correspondence_graph.hpp"
#include "agv/loop/ransac_association.hpp"
#include "agv_test.hpp"
#include "loop_test_util.hpp"

using namespace agv;
using agv::test::LoopRng;

namespace {

constexpr std::size_t kN = 16;        // 16 x 16 = 256 combinations: the CG vertex capacity
constexpr std::size_t kOutliers = 5;  // 31 %
constexpr double kSigma = 0.01;       // [m] noise of the second set, per coordinate

/// A first set, the second = truth^-1(first) + noise with kOutliers points replaced by random ones,
/// stored in a shuffled order; partner[j] = index in first of second[j] (kNoPartner for outliers).
struct Scene {
  static constexpr std::uint16_t kNoPartner = 0xFFFF;
  Eigen::Vector2f first[kN];
  Eigen::Vector2f second[kN];
  std::uint16_t partner[kN];
  Pose2d truth;
};

void makeScene(std::uint64_t seed, const Pose2d& truth, Scene& s) {
  LoopRng rng{seed};
  s.truth = truth;
  agv::test::randomPoints(rng, kN, -4.0, -4.0, 8.0, 8.0, 0.5, s.first);
  Eigen::Vector2f moved[kN];
  agv::test::transformPoints(truth.inverse(), s.first, kN, kSigma, rng, moved);
  for (std::size_t j = 0; j < kN; ++j) {
    const std::size_t i = (j * 7 + 3) % kN;  // a fixed shuffle (7 is coprime with 16)
    s.second[j] = moved[i];
    s.partner[j] = static_cast<std::uint16_t>(i);
  }
  Eigen::Vector2f junk[kOutliers];
  agv::test::randomPoints(rng, kOutliers, -5.0, -5.0, 10.0, 10.0, 0.5, junk);
  for (std::size_t k = 0; k < kOutliers; ++k) {
    s.second[k * 3] = junk[k];
    s.partner[k * 3] = Scene::kNoPartner;
  }
}

/// The tolerances the injected noise allows (5 standard deviations of the least-squares fit of
/// the inliers): rotation sigma / (sqrt(n) r_rms), translation at the centroid sigma / sqrt(n),
/// carried to the origin by the centroid's lever arm.
void checkRecovered(const Scene& s, const PointAssociation& a) {
  std::size_t correct = 0;
  std::size_t wrong = 0;
  for (const PointPair& p : a.pairs) {
    if (s.partner[p.second] == p.first) {
      ++correct;
    } else if (s.partner[p.second] != Scene::kNoPartner) {
      ++wrong;  // an inlier given the wrong partner
    }
  }
  const std::size_t inliers = kN - kOutliers;
  CHECK(correct >= inliers - 1);
  CHECK(wrong == 0U);
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (std::size_t j = 0; j < kN; ++j) {
    if (s.partner[j] != Scene::kNoPartner) {
      c += s.second[j].cast<double>();
    }
  }
  c /= static_cast<double>(inliers);
  double r2 = 0.0;
  for (std::size_t j = 0; j < kN; ++j) {
    if (s.partner[j] != Scene::kNoPartner) {
      r2 += (s.second[j].cast<double>() - c).squaredNorm();
    }
  }
  const double rRms = std::sqrt(r2 / static_cast<double>(inliers));
  const double sqrtN = std::sqrt(static_cast<double>(inliers));
  const double rotTol = 5.0 * kSigma / (sqrtN * rRms);
  const double transTol = 5.0 * kSigma * std::sqrt(2.0) / sqrtN + rotTol * c.norm();
  AGV_CHECK_NEAR(normalizeAngle(a.transform.theta - s.truth.theta), 0.0, rotTol);
  AGV_CHECK_NEAR(a.transform.x, s.truth.x, transTol);
  AGV_CHECK_NEAR(a.transform.y, s.truth.y, transTol);
  CHECK(a.rms < 4.0 * kSigma);
}

const Pose2d kTruths[] = {{1.2, -0.8, 0.6}, {-2.0, 1.5, -1.2}, {0.3, 0.2, 0.05}, {3.5, -3.0, 1.45}};

Span<const Eigen::Vector2f> span(const Eigen::Vector2f* p, std::size_t n) {
  return Span<const Eigen::Vector2f>(p, n);
}

}  // namespace

TEST_CASE("loop association: correspondence graph recovers a rigid transform with 30% outliers", "[loop][cg]") {
  static CorrespondenceGraphMatcher cg;
  static Scene s;
  static PointAssociation a;
  for (std::size_t t = 0; t < 4; ++t) {
    makeScene(100 + t, kTruths[t], s);
    REQUIRE(cg.match(span(s.first, kN), span(s.second, kN), a) == Status::Ok);
    CHECK(cg.lastVertices() == kN * kN);
    CHECK_FALSE(a.budgetHit);
    CHECK(a.work >= 1U);
    CHECK(a.work <= cg.params().maxNodes);
    checkRecovered(s, a);
  }
}

TEST_CASE("loop association: affine Hough recovers a rigid transform with 30% outliers", "[loop][ah]") {
  static AffineHoughMatcher ah;
  static Scene s;
  static PointAssociation a;
  for (std::size_t t = 0; t < 4; ++t) {
    makeScene(200 + t, kTruths[t], s);
    REQUIRE(ah.match(span(s.first, kN), span(s.second, kN), a) == Status::Ok);
    CHECK_FALSE(a.budgetHit);
    CHECK(a.work == kN * kN * 79U);  // thesis grid: 79 slices of +-pi/2 at 0.04 rad
    CHECK(ah.lastPeak() >= 3U);
    checkRecovered(s, a);
  }
}

TEST_CASE("loop association: RANSAC recovers a rigid transform with 30% outliers, deterministically",
          "[loop][ransac]") {
  static RansacMatcher ransac;
  static Scene s;
  static PointAssociation a;
  static PointAssociation b;
  for (std::size_t t = 0; t < 4; ++t) {
    makeScene(300 + t, kTruths[t], s);
    REQUIRE(ransac.match(span(s.first, kN), span(s.second, kN), a) == Status::Ok);
    CHECK_FALSE(a.budgetHit);
    CHECK(a.work <= ransac.params().maxSamples);
    checkRecovered(s, a);
    REQUIRE(ransac.match(span(s.first, kN), span(s.second, kN), b) == Status::Ok);
    CHECK(a.work == b.work);
    CHECK(a.transform.x == b.transform.x);
    CHECK(a.transform.theta == b.transform.theta);
    CHECK(a.pairs.size() == b.pairs.size());
  }
}

TEST_CASE("loop association: candidate pairs (a descriptor filter) are used as given", "[loop][cg]") {
  static CorrespondenceGraphMatcher cg;
  static AffineHoughMatcher ah;
  static RansacMatcher ransac;
  static Scene s;
  static PointAssociation a;
  static CandidatePairs cand;
  makeScene(400, kTruths[0], s);
  // The true pairs of the inliers plus, for every point of the second set, three wrong ones.
  cand.clear();
  for (std::size_t j = 0; j < kN; ++j) {
    if (s.partner[j] != Scene::kNoPartner) {
      REQUIRE(cand.push_back(PointPair{s.partner[j], static_cast<std::uint16_t>(j)}) == Status::Ok);
    }
    for (std::size_t k = 1; k <= 3; ++k) {
      const auto i = static_cast<std::uint16_t>((j * 5 + k * 3 + 1) % kN);
      if (i != s.partner[j]) {
        REQUIRE(cand.push_back(PointPair{i, static_cast<std::uint16_t>(j)}) == Status::Ok);
      }
    }
  }
  const Span<const PointPair> c(cand.data(), cand.size());
  REQUIRE(cg.match(span(s.first, kN), span(s.second, kN), c, a) == Status::Ok);
  CHECK(cg.lastVertices() == cand.size());
  checkRecovered(s, a);
  REQUIRE(ah.match(span(s.first, kN), span(s.second, kN), c, a) == Status::Ok);
  checkRecovered(s, a);
  REQUIRE(ransac.match(span(s.first, kN), span(s.second, kN), c, a) == Status::Ok);
  checkRecovered(s, a);

  // A candidate indexing outside its set is refused.
  cand[2].first = static_cast<std::uint16_t>(kN);
  const Span<const PointPair> bad(cand.data(), cand.size());
  CHECK(cg.match(span(s.first, kN), span(s.second, kN), bad, a) == Status::InvalidArgument);
  CHECK(ah.match(span(s.first, kN), span(s.second, kN), bad, a) == Status::InvalidArgument);
  CHECK(ransac.match(span(s.first, kN), span(s.second, kN), bad, a) == Status::InvalidArgument);
  CHECK(cg.match(span(s.first, kN), span(s.second, kN), Span<const PointPair>(), a) == Status::EmptyInput);
}

TEST_CASE("loop association: correspondence graph refuses fewer than 3 compatible pairs", "[loop][cg]") {
  static CorrespondenceGraphMatcher cg;
  static PointAssociation a;
  // Triangles with sides (3, 4, 5) and (1, 1.5, 2.2): no distance agrees, no edge, cliques of 1.
  const Eigen::Vector2f t1[] = {{0.0F, 0.0F}, {3.0F, 0.0F}, {0.0F, 4.0F}};
  const Eigen::Vector2f t2[] = {{0.0F, 0.0F}, {1.0F, 0.0F}, {-0.3F, 1.45F}};
  CHECK(cg.match(span(t1, 3), span(t2, 3), a) == Status::NotEnoughData);
  CHECK(cg.lastEdges() == 0U);
  CHECK(a.pairs.size() == 1U);
  CHECK(a.transform.x == 0.0);
  // One shared distance (3 m): a clique of 2 pairs, still refused.
  const Eigen::Vector2f t3[] = {{5.0F, 5.0F}, {8.0F, 5.0F}, {5.0F, 9.5F}};
  CHECK(cg.match(span(t1, 3), span(t3, 3), a) == Status::NotEnoughData);
  CHECK(a.pairs.size() == 2U);
  // Two points per set cannot give 3 pairs.
  CHECK(cg.match(span(t1, 2), span(t1, 2), a) == Status::NotEnoughData);
  // The same triangle moved: 3 pairs, accepted, exact.
  const Eigen::Vector2f t4[] = {{10.0F, 1.0F}, {10.0F, 4.0F}, {6.0F, 1.0F}};  // t1 turned by +90 deg, moved
  REQUIRE(cg.match(span(t4, 3), span(t1, 3), a) == Status::Ok);
  CHECK(a.pairs.size() == 3U);
  AGV_CHECK_NEAR(a.transform.theta, 1.5707963, 1e-5);
  AGV_CHECK_NEAR(a.transform.x, 10.0, 1e-4);
  AGV_CHECK_NEAR(a.transform.y, 1.0, 1e-4);
  // minPairs above 3 raises the bar.
  CorrespondenceGraphParams p;
  p.minPairs = 4;
  cg.setParams(p);
  CHECK(cg.match(span(t4, 3), span(t1, 3), a) == Status::NotEnoughData);
  cg.setParams(CorrespondenceGraphParams{});
}

TEST_CASE("loop association: work bounds are hit, reported and never exceeded", "[loop]") {
  static Scene s;
  static PointAssociation a;
  makeScene(500, kTruths[1], s);

  // Correspondence graph: a lattice repeats every distance, so the graph is dense and the search
  // long; every budget is respected exactly.
  static Eigen::Vector2f grid[kN];
  for (std::size_t i = 0; i < kN; ++i) {
    grid[i] = Eigen::Vector2f(static_cast<float>(i % 4), static_cast<float>(i / 4));
  }
  static CorrespondenceGraphMatcher unbounded;
  REQUIRE(unbounded.match(span(grid, kN), span(grid, kN), a) == Status::Ok);
  CHECK(a.pairs.size() == kN);  // the identity (and its symmetries) take every point
  const std::uint32_t needed = a.work;
  CHECK(needed > 10U);
  const std::uint32_t budgets[] = {1U, 2U, 10U, needed - 1U};
  for (std::uint32_t budget : budgets) {
    CorrespondenceGraphParams p;
    p.maxNodes = budget;
    static CorrespondenceGraphMatcher cg;
    cg.setParams(p);
    CHECK(cg.match(span(grid, kN), span(grid, kN), a) == Status::NotConverged);
    CHECK(a.budgetHit);
    CHECK(a.work == budget);
  }
  {
    CorrespondenceGraphParams p;
    p.maxNodes = needed;
    static CorrespondenceGraphMatcher cg;
    cg.setParams(p);
    CHECK(cg.match(span(grid, kN), span(grid, kN), a) == Status::Ok);
    CHECK_FALSE(a.budgetHit);
    CHECK(a.work == needed);
  }

  // Affine Hough: a vote budget of 10 slices.
  {
    AffineHoughParams p;
    p.maxVotes = kN * kN * 10 + 5;
    static AffineHoughMatcher ah;
    ah.setParams(p);
    CHECK(ah.match(span(s.first, kN), span(s.second, kN), a) == Status::NotConverged);
    CHECK(a.budgetHit);
    CHECK(a.work == kN * kN * 10);
    CHECK(a.work <= p.maxVotes);
    p.maxVotes = 100;  // not even one slice
    ah.setParams(p);
    CHECK(ah.match(span(s.first, kN), span(s.second, kN), a) == Status::NotConverged);
    CHECK(a.work == 0U);
    CHECK(a.pairs.empty());
  }

  // RANSAC: sample and hypothesis budgets.
  {
    RansacParams p;
    p.maxSamples = 50;
    static RansacMatcher r;
    r.setParams(p);
    CHECK(r.match(span(s.first, kN), span(s.second, kN), a) == Status::NotConverged);
    CHECK(a.budgetHit);
    CHECK(a.work == 50U);
    p = RansacParams{};
    p.maxHypotheses = 3;
    r.setParams(p);
    CHECK(r.match(span(s.first, kN), span(s.second, kN), a) == Status::NotConverged);
    CHECK(a.budgetHit);
    CHECK(r.lastHypotheses() == 3U);
    CHECK(a.work <= p.maxSamples);
  }
}

TEST_CASE("loop association: empty, over-capacity and NaN inputs, bad parameters", "[loop]") {
  static CorrespondenceGraphMatcher cg;
  static AffineHoughMatcher ah;
  static RansacMatcher ransac;
  static PointAssociation a;
  static Eigen::Vector2f many[kMaxLoopPoints + 1];
  for (std::size_t i = 0; i < kMaxLoopPoints + 1; ++i) {
    many[i] = Eigen::Vector2f(static_cast<float>(i % 8), static_cast<float>(i / 8));
  }
  const Span<const Eigen::Vector2f> none;
  const Span<const Eigen::Vector2f> three = span(many, 3);
  const Span<const Eigen::Vector2f> tooMany = span(many, kMaxLoopPoints + 1);
  CHECK(cg.match(none, three, a) == Status::EmptyInput);
  CHECK(cg.match(three, none, a) == Status::EmptyInput);
  CHECK(ah.match(none, three, a) == Status::EmptyInput);
  CHECK(ransac.match(three, none, a) == Status::EmptyInput);
  CHECK(a.pairs.empty());
  CHECK(cg.match(tooMany, three, a) == Status::CapacityExceeded);
  CHECK(ah.match(three, tooMany, a) == Status::CapacityExceeded);
  CHECK(ransac.match(tooMany, tooMany, a) == Status::CapacityExceeded);
  // 17 x 16 combinations exceed the correspondence graph's 256 vertices: refused, not truncated.
  CHECK(cg.match(span(many, 17), span(many, 16), a) == Status::CapacityExceeded);
  CHECK(cg.match(span(many, 16), span(many, 16), a) == Status::Ok);
  // The other two take every combination of full sets.
  CHECK(ah.match(span(many, kMaxLoopPoints), span(many, kMaxLoopPoints), a) != Status::CapacityExceeded);
  CHECK(ransac.match(span(many, kMaxLoopPoints), span(many, kMaxLoopPoints), a) != Status::CapacityExceeded);

  static Eigen::Vector2f bad[4] = {{0.0F, 0.0F}, {1.0F, 0.0F}, {0.0F, 1.0F}, {1.0F, 1.0F}};
  bad[2].x() = std::nanf("");
  CHECK(cg.match(span(bad, 4), three, a) == Status::NonFiniteInput);
  CHECK(ah.match(three, span(bad, 4), a) == Status::NonFiniteInput);
  CHECK(ransac.match(span(bad, 4), three, a) == Status::NonFiniteInput);
  bad[2].x() = -INFINITY;
  CHECK(cg.match(three, span(bad, 4), a) == Status::NonFiniteInput);

  CorrespondenceGraphParams pc;
  pc.epsilon = 0.0F;
  CHECK_FALSE(isValid(pc));
  cg.setParams(pc);
  CHECK(cg.match(three, three, a) == Status::InvalidArgument);
  cg.setParams(CorrespondenceGraphParams{});
  CHECK(cg.match(three, three, a) != Status::InvalidArgument);
  AffineHoughParams ph;
  ph.translationStep = 0.01F;  // 1000 x 1000 cells per slice > kMaxHoughCells
  CHECK_FALSE(isValid(ph));
  ph = AffineHoughParams{};
  ph.rotationStep = std::nanf("");
  CHECK_FALSE(isValid(ph));
  CHECK(isValid(AffineHoughParams{}));
  RansacParams pr;
  pr.confidence = 1.0F;
  CHECK_FALSE(isValid(pr));
  CHECK(isValid(RansacParams{}));
  CHECK(isValid(CorrespondenceGraphParams{}));
}

TEST_CASE("loop association: steady-state calls allocate nothing", "[loop]") {
  static CorrespondenceGraphMatcher cg;
  static AffineHoughMatcher ah;
  static RansacMatcher ransac;
  static Scene s;
  static PointAssociation a;
  makeScene(600, kTruths[2], s);
  Status st1 = Status::NotFound;
  Status st2 = Status::NotFound;
  Status st3 = Status::NotFound;
  AGV_CHECK_NO_ALLOCATIONS({
    st1 = cg.match(span(s.first, kN), span(s.second, kN), a);
    st2 = ah.match(span(s.first, kN), span(s.second, kN), a);
    st3 = ransac.match(span(s.first, kN), span(s.second, kN), a);
  });
  CHECK(st1 == Status::Ok);
  CHECK(st2 == Status::Ok);
  CHECK(st3 == Status::Ok);
}
