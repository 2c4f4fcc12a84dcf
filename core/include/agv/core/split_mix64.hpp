#pragma once
/// @file split_mix64.hpp
/// A deterministic pseudo-random generator for the algorithms that draw samples (RANSAC,
/// hypothesis search): the same draws on every platform, a 64-bit state, nothing that allocates.

#include <cstdint>

namespace agv {

/// Deterministic generator (splitmix64): reproducible draws on every platform, no state that
/// allocates.
struct SplitMix64 {
  std::uint64_t state;
  std::uint64_t next() noexcept {
    state += 0x9E3779B97F4A7C15ULL;
    std::uint64_t z = state;
    z = (z ^ (z >> 30U)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27U)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31U);
  }
  /// Uniform in [0, n) for 0 < n < 2^32 (multiply-shift, bias below 2^-32 n).
  std::uint32_t below(std::uint32_t n) noexcept {
    return static_cast<std::uint32_t>(((next() >> 32U) * static_cast<std::uint64_t>(n)) >> 32U);
  }
};

}  // namespace agv
