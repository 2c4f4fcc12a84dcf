#pragma once
/// @file loop_test_util.hpp
/// Point sets for the loop-closure tests: deterministic random points, rigid transforms, noise and
/// outliers. Portable (also compiled into the Cortex-M7 image): no <random>, no heap.

#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "agv/core/pose2.hpp"

namespace agv::test {

/// Deterministic generator (64-bit LCG, top bits): same sequence on every platform.
struct LoopRng {
  std::uint64_t s;
  double uniform() noexcept {
    s = s * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(s >> 11U) * (1.0 / 9007199254740992.0);
  }
  double uniform(double lo, double hi) noexcept { return lo + (hi - lo) * uniform(); }
  /// Standard normal (Box-Muller).
  double normal() noexcept {
    double u = uniform();
    if (u < 1e-300) {
      u = 1e-300;
    }
    return std::sqrt(-2.0 * std::log(u)) * std::cos(6.283185307179586 * uniform());
  }
};

/// n points uniformly in [x0, x0 + w] x [y0, y0 + h], at least minSep apart (bounded tries).
inline void randomPoints(LoopRng& rng, std::size_t n, double x0, double y0, double w, double h, double minSep,
                         Eigen::Vector2f* out) noexcept {
  for (std::size_t i = 0; i < n; ++i) {
    Eigen::Vector2f p;
    for (int attempt = 0; attempt < 1000; ++attempt) {
      p = Eigen::Vector2f(static_cast<float>(rng.uniform(x0, x0 + w)), static_cast<float>(rng.uniform(y0, y0 + h)));
      bool ok = true;
      for (std::size_t j = 0; j < i; ++j) {
        if ((out[j] - p).norm() < static_cast<float>(minSep)) {
          ok = false;
          break;
        }
      }
      if (ok) {
        break;
      }
    }
    out[i] = p;
  }
}

/// out[i] = T(in[i]) + N(0, sigma^2) per coordinate.
inline void transformPoints(const Pose2d& t, const Eigen::Vector2f* in, std::size_t n, double sigma, LoopRng& rng,
                            Eigen::Vector2f* out) noexcept {
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d p = t.transformPoint(in[i].cast<double>());
    out[i] = Eigen::Vector2f(static_cast<float>(p.x() + sigma * rng.normal()),
                             static_cast<float>(p.y() + sigma * rng.normal()));
  }
}

}  // namespace agv::test
