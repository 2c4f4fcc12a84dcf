#pragma once
/// @file glarot_l1.hpp
/// Private: the shifted L1 kernel shared by glarotDistance and the database search.

#include <cmath>
#include <cstddef>

namespace agv::detail {

/// sum_{t,r} |a[(t - s) mod nT][r] - b[t][r]| over theta-major accumulators, stopping (and
/// returning the partial sum, >= abortAt) once a whole theta row has taken it to abortAt or more.
inline float glarotShiftedL1Kernel(const float* a, const float* b, std::size_t nT, std::size_t nR, std::size_t s,
                                   float abortAt) noexcept {
  float sum = 0.0F;
  std::size_t ta = nT - s;  // row of a matched with row 0 of b: (0 - s) mod nT
  if (ta == nT) {
    ta = 0;
  }
  for (std::size_t t = 0; t < nT; ++t) {
    const float* ar = a + ta * nR;
    const float* br = b + t * nR;
    float row = 0.0F;
    for (std::size_t r = 0; r < nR; ++r) {
      row += std::fabs(ar[r] - br[r]);
    }
    sum += row;
    if (sum >= abortAt) {
      return sum;
    }
    ta = ta + 1 == nT ? 0 : ta + 1;
  }
  return sum;
}

}  // namespace agv::detail
