// GLAROT signature and SL1 distance: rotation invariance with the rotation recovered within one
// cell, translation invariance, normalisation, refusals, no allocation. Portable subset: also runs
// in the Cortex-M7 image.
#include <cmath>
#include <cstddef>

#include "agv/core/angle.hpp"
#include "agv/loop/glarot.hpp"
#include "agv_test.hpp"
#include "loop_test_util.hpp"

using namespace agv;
using agv::test::LoopRng;

namespace {

constexpr std::size_t kN = 20;

/// Circular distance between a shift and a continuous cell position, modulo n.
double circularCells(double a, double b, double n) {
  double d = std::fmod(std::fabs(a - b), n);
  return d > n / 2 ? n - d : d;
}

float cellSum(const GlarotSignature& s) {
  float sum = 0.0F;
  for (std::size_t k = 0; k < s.size(); ++k) {
    sum += s.cells[k];
  }
  return sum;
}

}  // namespace

TEST_CASE("glarot: SL1 of a set and its rotation is at the minimum, shift within one cell", "[loop][glarot]") {
  static Eigen::Vector2f base[kN];
  static Eigen::Vector2f turned[kN];
  static Eigen::Vector2f other[kN];
  static GlarotSignature sa;
  static GlarotSignature sb;
  static GlarotSignature so;
  const GlarotParams params;
  LoopRng rng{42};
  agv::test::randomPoints(rng, kN, -5.0, -5.0, 10.0, 10.0, 0.3, base);
  REQUIRE(computeGlarot(Span<const Eigen::Vector2f>(base, kN), params, sa) == Status::Ok);
  const double cell = kPi<double> / static_cast<double>(params.thetaBins);

  // Exact multiples of the cell width: the signature is shifted exactly, SL1 is ~0.
  for (std::size_t k = 0; k < params.thetaBins * 2; ++k) {
    const double phi = static_cast<double>(k) * cell - kPi<double>;
    agv::test::transformPoints(Pose2d{1.5, -2.0, phi}, base, kN, 0.0, rng, turned);
    REQUIRE(computeGlarot(Span<const Eigen::Vector2f>(turned, kN), params, sb) == Status::Ok);
    const auto m = glarotDistance(sa, sb);
    REQUIRE(m.ok());
    CHECK(m.value().distance < 1e-3F);
    CHECK(circularCells(m.value().shift, phi / cell, 8.0) < 0.01);
  }

  // Arbitrary angles: the recovered shift is within one cell of phi / cell (mod n_theta), and the
  // rotated copy is nearer than any of 10 other random sets of the same size and extent.
  float nearestOther = 10.0F;
  for (int k = 0; k < 10; ++k) {
    agv::test::randomPoints(rng, kN, -5.0, -5.0, 10.0, 10.0, 0.3, other);
    REQUIRE(computeGlarot(Span<const Eigen::Vector2f>(other, kN), params, so) == Status::Ok);
    const auto m = glarotDistance(sa, so);
    REQUIRE(m.ok());
    nearestOther = m.value().distance < nearestOther ? m.value().distance : nearestOther;
  }
  const double angles[] = {0.1, 0.31, 0.5, 1.0, 1.234, 1.7, 2.5, 3.0, -0.7, -1.9, -2.2, 5.5, -3.1};
  for (double phi : angles) {
    agv::test::transformPoints(Pose2d{-3.0, 7.0, phi}, base, kN, 0.0, rng, turned);
    REQUIRE(computeGlarot(Span<const Eigen::Vector2f>(turned, kN), params, sb) == Status::Ok);
    const auto m = glarotDistance(sa, sb);
    REQUIRE(m.ok());
    CHECK(circularCells(m.value().shift, phi / cell, 8.0) <= 1.0);
    CHECK(m.value().distance < nearestOther);
    // SL1 is the minimum over the shifts, attained at the reported one.
    for (std::size_t s = 0; s < params.thetaBins; ++s) {
      CHECK(glarotShiftedL1(sa, sb, s) >= m.value().distance);
    }
    AGV_CHECK_NEAR(glarotShiftedL1(sa, sb, m.value().shift), m.value().distance, 1e-6);
    // The rotation estimate agrees modulo pi within one cell.
    const double err = std::fabs(normalizeAngle(2.0 * (glarotRotation(m.value().shift, 8) - phi))) / 2.0;
    CHECK(err <= cell + 1e-6);
  }
}

TEST_CASE("glarot: translation does not change the signature", "[loop][glarot]") {
  static Eigen::Vector2f base[kN];
  static Eigen::Vector2f moved[kN];
  static GlarotSignature sa;
  static GlarotSignature sb;
  LoopRng rng{7};
  agv::test::randomPoints(rng, kN, 0.0, 0.0, 12.0, 6.0, 0.3, base);
  agv::test::transformPoints(Pose2d{37.5, -12.25, 0.0}, base, kN, 0.0, rng, moved);
  REQUIRE(computeGlarot(Span<const Eigen::Vector2f>(base, kN), GlarotParams{}, sa) == Status::Ok);
  REQUIRE(computeGlarot(Span<const Eigen::Vector2f>(moved, kN), GlarotParams{}, sb) == Status::Ok);
  REQUIRE(sa.size() == 256U);
  float maxDiff = 0.0F;
  for (std::size_t k = 0; k < sa.size(); ++k) {
    const float d = std::fabs(sa.cells[k] - sb.cells[k]);
    maxDiff = d > maxDiff ? d : maxDiff;
  }
  CHECK(maxDiff < 1e-5F);
  CHECK(sa.pairs == sb.pairs);
  const auto m = glarotDistance(sa, sb);
  REQUIRE(m.ok());
  CHECK(m.value().shift == 0U);
  CHECK(m.value().distance < 1e-4F);
}

TEST_CASE("glarot: normalised to sum 1 for any set size; keypoints equal points", "[loop][glarot]") {
  static Eigen::Vector2f pts[40];
  static FalkoKeypoint kps[40];
  static GlarotSignature s;
  static GlarotSignature sk;
  LoopRng rng{99};
  agv::test::randomPoints(rng, 40, -6.0, -6.0, 12.0, 12.0, 0.2, pts);
  for (std::size_t n : {std::size_t{2}, std::size_t{3}, std::size_t{10}, std::size_t{40}}) {
    REQUIRE(computeGlarot(Span<const Eigen::Vector2f>(pts, n), GlarotParams{}, s) == Status::Ok);
    AGV_CHECK_NEAR(cellSum(s), 1.0, 1e-4);
    CHECK(s.pairs == n * (n - 1) / 2);
  }
  for (std::size_t i = 0; i < 40; ++i) {
    kps[i].x = pts[i].x();
    kps[i].y = pts[i].y();
  }
  REQUIRE(computeGlarot(Span<const FalkoKeypoint>(kps, 40), GlarotParams{}, sk) == Status::Ok);
  const auto m = glarotDistance(s, sk);
  REQUIRE(m.ok());
  CHECK(m.value().distance == 0.0F);

  // Pairs beyond maxDistance are not counted, and say so.
  GlarotParams p;
  p.maxDistance = 4.0F;
  REQUIRE(computeGlarot(Span<const Eigen::Vector2f>(pts, 40), p, s) == Status::Ok);
  CHECK(s.pairsBeyond > 0U);
  CHECK(s.pairs + s.pairsBeyond == 40U * 39U / 2U);
  AGV_CHECK_NEAR(cellSum(s), 1.0, 1e-4);
}

TEST_CASE("glarot: empty, single, NaN, over-capacity and bad parameters are refused", "[loop][glarot]") {
  static Eigen::Vector2f pts[kMaxKeypoints + 1];
  static GlarotSignature s;
  static GlarotSignature t;
  for (std::size_t i = 0; i < kMaxKeypoints + 1; ++i) {
    pts[i] = Eigen::Vector2f(static_cast<float>(i % 16), static_cast<float>(i / 16));
  }
  CHECK(computeGlarot(Span<const Eigen::Vector2f>(), GlarotParams{}, s) == Status::EmptyInput);
  CHECK(s.thetaBins == 8U);
  CHECK(s.rhoBins == 32U);
  CHECK(cellSum(s) == 0.0F);
  CHECK(computeGlarot(Span<const Eigen::Vector2f>(pts, 1), GlarotParams{}, s) == Status::NotEnoughData);
  CHECK(computeGlarot(Span<const Eigen::Vector2f>(pts, kMaxKeypoints + 1), GlarotParams{}, s) ==
        Status::CapacityExceeded);
  CHECK(cellSum(s) == 0.0F);
  CHECK(computeGlarot(Span<const Eigen::Vector2f>(pts, kMaxKeypoints), GlarotParams{}, s) == Status::Ok);
  pts[3].y() = std::nanf("");
  CHECK(computeGlarot(Span<const Eigen::Vector2f>(pts, 10), GlarotParams{}, s) == Status::NonFiniteInput);
  pts[3].y() = INFINITY;
  CHECK(computeGlarot(Span<const Eigen::Vector2f>(pts, 10), GlarotParams{}, s) == Status::NonFiniteInput);
  CHECK(cellSum(s) == 0.0F);
  pts[3].y() = 0.0F;

  GlarotParams bad;
  bad.thetaBins = 16;
  bad.rhoBins = 32;  // 512 cells > kGlarotMaxCells
  CHECK_FALSE(isValid(bad));
  CHECK(computeGlarot(Span<const Eigen::Vector2f>(pts, 10), bad, s) == Status::InvalidArgument);
  bad = GlarotParams{};
  bad.sigmaRho = 0.0F;
  CHECK(computeGlarot(Span<const Eigen::Vector2f>(pts, 10), bad, s) == Status::InvalidArgument);
  bad = GlarotParams{};
  bad.maxDistance = std::nanf("");
  CHECK_FALSE(isValid(bad));

  // Shapes must agree.
  GlarotParams other;
  other.thetaBins = 16;
  other.rhoBins = 16;
  REQUIRE(computeGlarot(Span<const Eigen::Vector2f>(pts, 10), GlarotParams{}, s) == Status::Ok);
  REQUIRE(computeGlarot(Span<const Eigen::Vector2f>(pts, 10), other, t) == Status::Ok);
  CHECK(glarotDistance(s, t).status() == Status::InvalidArgument);
  CHECK(glarotShiftedL1(s, t, 0) < 0.0F);
  CHECK(glarotShiftedL1(s, s, 8) < 0.0F);
  CHECK(glarotDistance(GlarotSignature{}, GlarotSignature{}).status() == Status::InvalidArgument);
}

TEST_CASE("glarot: computing and comparing allocate nothing", "[loop][glarot]") {
  static Eigen::Vector2f pts[30];
  static GlarotSignature s;
  static GlarotSignature t;
  LoopRng rng{5};
  agv::test::randomPoints(rng, 30, 0.0, 0.0, 8.0, 8.0, 0.2, pts);
  float d = 0.0F;
  AGV_CHECK_NO_ALLOCATIONS({
    (void)computeGlarot(Span<const Eigen::Vector2f>(pts, 30), GlarotParams{}, s);
    (void)computeGlarot(Span<const Eigen::Vector2f>(pts, 20), GlarotParams{}, t);
    d = glarotDistance(s, t).value().distance;
  });
  CHECK(d > 0.0F);
}
