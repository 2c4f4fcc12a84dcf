// Laser egomotion from two reflector observations: simulated reflector field with known motion,
// range noise, missed reflectors and spurious returns.
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

#include "agv/calib/reflector_alignment.hpp"
#include "agv/core/capacities.hpp"
#include "agv_test.hpp"
#include "calib_sim.hpp"

using agv::deg2rad;
using agv::Pose2d;
using agv::ReflectorAlignment;
using agv::ReflectorAlignmentOptions;
using agv::Status;
using Points = std::vector<Eigen::Vector2d>;

namespace {

agv::Span<const Eigen::Vector2d> span(const Points& v) {
  return {v.data(), v.size()};
}

/// Reflectors spread over a hall, at least `spacing` apart.
Points reflectorField(std::mt19937_64& rng, int count, double half, double spacing) {
  std::uniform_real_distribution<double> u(-half, half);
  Points field;
  for (int attempt = 0; attempt < 10000 && static_cast<int>(field.size()) < count; ++attempt) {
    const Eigen::Vector2d p(u(rng), u(rng));
    bool ok = true;
    for (const auto& q : field) {
      ok = ok && (p - q).norm() >= spacing;
    }
    if (ok) {
      field.push_back(p);
    }
  }
  return field;
}

struct Observation {
  Points points;
  std::vector<int> ids;  // index in the field, -1 for a spurious return
};

/// What a laser at `pose` reports: reflectors within `range`, each missed with probability
/// `miss`, with N(0, sigma) noise per axis, plus `spurious` random returns.
Observation observe(const Points& field, const Pose2d& pose, double range, double sigma, double miss, int spurious,
                    std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Observation obs;
  for (std::size_t i = 0; i < field.size(); ++i) {
    Eigen::Vector2d q = pose.inverseTransformPoint(field[i]);
    if (q.norm() > range || u(rng) < miss) {
      continue;
    }
    if (sigma > 0.0) {
      q += sigma * Eigen::Vector2d(n(rng), n(rng));
    }
    obs.points.push_back(q);
    obs.ids.push_back(static_cast<int>(i));
  }
  for (int k = 0; k < spurious; ++k) {
    const double r = 1.0 + (range - 1.0) * u(rng);
    const double a = agv::kTwoPi<double> * u(rng);
    obs.points.emplace_back(r * std::cos(a), r * std::sin(a));
    obs.ids.push_back(-1);
  }
  return obs;
}

int commonCount(const Observation& a, const Observation& b) {
  int c = 0;
  for (int i : a.ids) {
    for (int j : b.ids) {
      c += (i >= 0 && i == j) ? 1 : 0;
    }
  }
  return c;
}

// A half-circle of the vehicle seen by a front-mounted laser: 180 deg and several metres.
const Pose2d kStart{2.0, -1.0, deg2rad(20.0)};
const Pose2d kMotion = Pose2d{1.6, 0.4, deg2rad(5.0)}
                           .inverse()
                           .compose(agv::tricycleArc(8.0, deg2rad(36.0), 1.5))
                           .compose(Pose2d{1.6, 0.4, deg2rad(5.0)});
const Pose2d kGuessError{0.15, -0.10, deg2rad(1.5)};

}  // namespace

TEST_CASE("reflector alignment: noise-free sets give the exact motion from a rough guess", "[calib][egomotion]") {
  std::mt19937_64 rng(11);
  const Points field = reflectorField(rng, 20, 15.0, 2.5);
  const Observation a = observe(field, kStart, 40.0, 0.0, 0.0, 0, rng);
  const Observation b = observe(field, kStart.compose(kMotion), 40.0, 0.0, 0.0, 0, rng);
  ReflectorAlignment out;
  REQUIRE(agv::alignReflectors(span(a.points), span(b.points), kMotion.compose(kGuessError), {}, out) == Status::Ok);
  AGV_CHECK_NEAR(out.motion.x, kMotion.x, 1e-12);
  AGV_CHECK_NEAR(out.motion.y, kMotion.y, 1e-12);
  AGV_CHECK_NEAR(agv::angleDiff(out.motion.theta, kMotion.theta), 0.0, 1e-13);
  CHECK(out.matches == field.size());
  CHECK(out.rms < 1e-12);
}

TEST_CASE("reflector alignment with noise, misses and spurious returns matches its error model", "[calib][egomotion]") {
  constexpr int kTrials = 300;
  constexpr double kSigma = 0.005;
  std::mt19937_64 rng(12);
  agv::test::Stats rotNorm;  // rotation error / predicted std
  agv::test::Stats tx;
  agv::test::Stats ty;
  int exactInliers = 0;
  int failures = 0;
  for (int t = 0; t < kTrials; ++t) {
    const Points field = reflectorField(rng, 20, 15.0, 2.5);
    const Observation a = observe(field, kStart, 40.0, kSigma, 0.1, 3, rng);
    const Observation b = observe(field, kStart.compose(kMotion), 40.0, kSigma, 0.1, 3, rng);
    ReflectorAlignment out;
    if (agv::alignReflectors(span(a.points), span(b.points), kMotion.compose(kGuessError), {}, out) != Status::Ok) {
      ++failures;
      continue;
    }
    const int common = commonCount(a, b);
    exactInliers += static_cast<int>(out.matches) == common ? 1 : 0;
    // Predicted rotation std from the noise of both sets: sqrt(2) sigma / sqrt(sum |q - mean|^2).
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    int n = 0;
    for (std::size_t j = 0; j < b.points.size(); ++j) {
      if (b.ids[j] >= 0) {
        for (int i : a.ids) {
          if (i == b.ids[j]) {
            mean += b.points[j];
            ++n;
          }
        }
      }
    }
    mean /= n;
    double spread = 0.0;
    for (std::size_t j = 0; j < b.points.size(); ++j) {
      for (int i : a.ids) {
        if (b.ids[j] >= 0 && i == b.ids[j]) {
          spread += (b.points[j] - mean).squaredNorm();
        }
      }
    }
    const double rotStd = std::sqrt(2.0) * kSigma / std::sqrt(spread);
    rotNorm.add(agv::angleDiff(out.motion.theta, kMotion.theta) / rotStd);
    tx.add(out.motion.x - kMotion.x);
    ty.add(out.motion.y - kMotion.y);
    // out.rms estimates sqrt(2) sigma (times sqrt((n-3)/n) for the fitted dof)
    CHECK(out.rms < 3.0 * std::sqrt(2.0) * kSigma);
  }
  std::printf(
      "reflector alignment (N = %d): rotation error / predicted std: mean %+.3f std %.3f; "
      "t_x mean %+.3f mm std %.3f mm; t_y mean %+.3f mm std %.3f mm; exact inlier sets %d\n",
      kTrials, rotNorm.mean, rotNorm.stddev(), tx.mean * 1e3, tx.stddev() * 1e3, ty.mean * 1e3, ty.stddev() * 1e3,
      exactInliers);
  CHECK(failures == 0);
  CHECK(exactInliers >= kTrials * 99 / 100);
  CHECK(rotNorm.unbiased());
  CHECK(rotNorm.stddev() > 0.8);
  CHECK(rotNorm.stddev() < 1.2);
  CHECK(tx.unbiased());
  CHECK(ty.unbiased());
  // translation of the origin: centroid error ~ sigma sqrt(2/n) plus the rotation error times the
  // centroid's lever arm: about 2 mm here
  CHECK(tx.stddev() < 0.003);
  CHECK(ty.stddev() < 0.003);
}

TEST_CASE("reflector alignment refuses bad input and does not allocate", "[calib][egomotion]") {
  std::mt19937_64 rng(13);
  const Points field = reflectorField(rng, 12, 15.0, 2.5);
  const Observation a = observe(field, kStart, 40.0, 0.002, 0.0, 0, rng);
  const Observation b = observe(field, kStart.compose(kMotion), 40.0, 0.002, 0.0, 0, rng);
  const Pose2d guess = kMotion.compose(kGuessError);
  ReflectorAlignment out;
  Status s = Status::NotInitialized;
  AGV_CHECK_NO_ALLOCATIONS(s = agv::alignReflectors(span(a.points), span(b.points), guess, {}, out));
  CHECK(s == Status::Ok);

  CHECK(agv::alignReflectors(span(a.points), agv::Span<const Eigen::Vector2d>(), guess, {}, out) == Status::EmptyInput);
  Points bad = b.points;
  bad[2].y() = std::numeric_limits<double>::quiet_NaN();
  CHECK(agv::alignReflectors(span(a.points), span(bad), guess, {}, out) == Status::NonFiniteInput);
  CHECK(agv::alignReflectors(span(a.points), span(b.points), Pose2d{0.0, std::numeric_limits<double>::infinity(), 0.0},
                             {}, out) == Status::NonFiniteInput);
  Points many(agv::kMaxReflectors + 1, Eigen::Vector2d(1.0, 2.0));
  CHECK(agv::alignReflectors(span(many), span(b.points), guess, {}, out) == Status::CapacityExceeded);
  // two reflectors cannot give the three pairs asked for
  Points two(b.points.begin(), b.points.begin() + 2);
  CHECK(agv::alignReflectors(span(a.points), span(two), guess, {}, out) == Status::NotEnoughData);
  // a guess 3 m off associates nothing: refused, not a wrong answer
  CHECK(agv::alignReflectors(span(a.points), span(b.points), kMotion.compose(Pose2d{3.0, 0.0, 0.0}), {}, out) ==
        Status::NotEnoughData);
  ReflectorAlignmentOptions badOpt;
  badOpt.minMatches = 1;
  CHECK(agv::alignReflectors(span(a.points), span(b.points), guess, badOpt, out) == Status::InvalidArgument);
}
