#pragma once
// Internal helpers of the FALKO module (not installed).

#include <cmath>

#include <cstddef>
#include <cstdint>

#if defined(__SSE2__)
#include <emmintrin.h>
#elif defined(__ARM_NEON) && defined(__aarch64__)
#include <arm_neon.h>
#endif

#include "agv/core/angle.hpp"
#include "agv/falko/scan_points.hpp"

namespace agv {
namespace falko_detail {

/// atan2 in float with a 7th..9th order minimax polynomial: |error| < 2e-5 rad, far below the
/// 22.5 deg sector width it is used for; several times cheaper than std::atan2. (0, 0) gives 0.
inline float fastAtan2(float y, float x) noexcept {
  const float ax = std::fabs(x);
  const float ay = std::fabs(y);
  const float mx = ax > ay ? ax : ay;
  const float mn = ax > ay ? ay : ax;
  if (mx <= 0.0F) {
    return 0.0F;
  }
  const float z = mn / mx;
  const float z2 = z * z;
  float r = z * (0.9998660F + z2 * (-0.3302995F + z2 * (0.1801410F + z2 * (-0.0851330F + z2 * 0.0208351F))));
  if (ay > ax) {
    r = 0.5F * kPi<float> - r;
  }
  if (x < 0.0F) {
    r = kPi<float> - r;
  }
  return y < 0.0F ? -r : r;
}

/// Index in [0, bins) of the angle atan2(v, u), bin 0 *centred* on -pi (bin k covers
/// -pi + (k -+ 1/2) * width). Centred bins put the walls of 90 and 135 deg corners (at +-45 and
/// +-67.5 deg from the corner orientation) in the middle of a bin instead of on a boundary,
/// where range noise would flip them from one bin to the next.
inline unsigned sectorOf(float v, float u, float binsPerRadian, unsigned bins) noexcept {
  const float a = fastAtan2(v, u) + kPi<float>;
  const float f = a * binsPerRadian + 0.5F;
  if (!(f > 0.0F)) {
    return 0U;
  }
  const auto k = static_cast<unsigned>(f);
  return k < bins ? k : 0U;  // the upper half of the last half-bin is bin 0 again
}

/// Fast path of sectorOf for 16 bins: the bin of (u, v) from three sign tests and four
/// comparisons against the tangents of the bin boundaries (11.25, 33.75, 56.25, 78.75 deg); no
/// division, no polynomial. Same result as sectorOf(v, u, 16 / (2 pi), 16) except exactly on a
/// boundary.
inline unsigned sector16(float u, float v) noexcept {
  const float ax = std::fabs(u);
  const float ay = std::fabs(v);
  // Steps of 22.5 deg within the quadrant, 0 (on the u axis) .. 4 (on the v axis).
  const unsigned q = static_cast<unsigned>(ay > 0.19891237F * ax) + static_cast<unsigned>(ay > 0.66817864F * ax) +
                     static_cast<unsigned>(ay > 1.49660576F * ax) + static_cast<unsigned>(ay > 5.02733949F * ax);
  // Bin of the angle counted from 0 deg, 0..15: quadrant I: q; II: 8 - q; III: 8 + q; IV: 16 - q.
  const unsigned fromZero = u >= 0.0F ? (v >= 0.0F ? q : 16U - q) : (v >= 0.0F ? 8U - q : 8U + q);
  // Bin 0 is centred on -pi (180 deg).
  return (fromZero + 8U) & 15U;
}

/// Index of the lowest set bit of v (v != 0), without a compiler builtin: de Bruijn multiply.
inline unsigned lowestBitIndex(std::uint32_t v) noexcept {
  constexpr unsigned char kTable[32] = {0,  1,  28, 2,  29, 14, 24, 3, 30, 22, 20, 15, 25, 17, 4,  8,
                                        31, 27, 13, 23, 21, 19, 16, 7, 26, 12, 18, 6,  11, 5,  10, 9};
  const std::uint32_t lowest = v & (~v + 1U);
  return kTable[(lowest * 0x077CB531U) >> 27U];
}

/// True where the compiler can keep four float tests in one vector register (x86 SSE2, ARM NEON):
/// the four-at-a-time loops below pay off there. Without a vector unit (Cortex-M7) they only
/// add work, so the plain one-beam loops are used.
#if defined(__SSE2__) || defined(__ARM_NEON)
constexpr bool kFourWide = true;
#else
constexpr bool kFourWide = false;
#endif

/// sector16 without branches (select arithmetic on the signs), for loops over several points.
/// Same result as sector16 for every input.
inline unsigned sector16Branchless(float u, float v) noexcept {
  const float ax = std::fabs(u);
  const float ay = std::fabs(v);
  const unsigned q = static_cast<unsigned>(ay > 0.19891237F * ax) + static_cast<unsigned>(ay > 0.66817864F * ax) +
                     static_cast<unsigned>(ay > 1.49660576F * ax) + static_cast<unsigned>(ay > 5.02733949F * ax);
  // (fromZero + 8) mod 16 of sector16: u >= 0: v >= 0 -> 8 + q, v < 0 -> 24 - q;
  // u < 0: v >= 0 -> 16 - q, v < 0 -> 16 + q.
  const unsigned uNeg = static_cast<unsigned>(u < 0.0F);
  const unsigned vNeg = static_cast<unsigned>(v < 0.0F);
  const unsigned base = 8U + 8U * uNeg + 16U * (vNeg & (1U - uNeg));
  const unsigned flip = uNeg ^ vNeg;                  // q is subtracted when exactly one sign is negative
  const unsigned signedQ = (q ^ (0U - flip)) + flip;  // q or -q (mod 2^32)
  return (base + signedQ) & 15U;
}

/// First index j in [begin, end), ascending, whose point (x[j], y[j]) lies within sqrt(r2) of
/// (cx, cy); end when none does. Beams are tested four at a time without a branch per beam (the
/// compiler can keep the four tests in vector registers); the block holding the hit is then
/// searched beam by beam.
inline std::size_t firstWithinAscending(const float* x, const float* y, std::size_t begin, std::size_t end, float cx,
                                        float cy, float r2) noexcept {
  std::size_t j = begin;
  for (; kFourWide && j + 4 <= end; j += 4) {
    unsigned hit = 0;
    for (std::size_t k = 0; k < 4; ++k) {
      const float dx = x[j + k] - cx;
      const float dy = y[j + k] - cy;
      hit |= dx * dx + dy * dy <= r2 ? 1U : 0U;
    }
    if (hit != 0U) {
      break;
    }
  }
  for (; j < end; ++j) {
    const float dx = x[j] - cx;
    const float dy = y[j] - cy;
    if (dx * dx + dy * dy <= r2) {
      return j;
    }
  }
  return end;
}

/// Last index j in [begin, end) (searched descending) whose point lies within sqrt(r2) of
/// (cx, cy); end when none does. Four beams per step as in firstWithinAscending.
inline std::size_t lastWithinDescending(const float* x, const float* y, std::size_t begin, std::size_t end, float cx,
                                        float cy, float r2) noexcept {
  std::size_t j = end;
  for (; kFourWide && j >= begin + 4; j -= 4) {
    unsigned hit = 0;
    for (std::size_t k = 1; k <= 4; ++k) {
      const float dx = x[j - k] - cx;
      const float dy = y[j - k] - cy;
      hit |= dx * dx + dy * dy <= r2 ? 1U : 0U;
    }
    if (hit != 0U) {
      break;
    }
  }
  while (j > begin) {
    --j;
    const float dx = x[j] - cx;
    const float dy = y[j] - cy;
    if (dx * dx + dy * dy <= r2) {
      return j;
    }
  }
  return end;
}

/// True where farthestWithin4 exists: x86 SSE2 and AArch64 NEON. Elsewhere the detector searches
/// one beam at a time.
#if defined(__SSE2__) || (defined(__ARM_NEON) && defined(__aarch64__))
constexpr bool kLockstep4 = true;
#else
constexpr bool kLockstep4 = false;
#endif

/// The farthest-neighbour search of four consecutive candidate beams c..c+3 at once, one lane per
/// candidate. Lane l gets in found[l] the largest offset k in 1..kmax[l] whose beam c + l + dir*k
/// holds a point within sqrt(r2[l]) of the candidate's point (0 when none does). The beams k steps
/// from the four candidates are four consecutive beams, so a step is one unaligned four-wide load
/// per coordinate. Steps run from kTop (the largest kmax) inwards until every lane has its hit:
/// one exit test per step for four candidates, instead of two data-dependent exits per candidate.
/// The caller guarantees that no beam c + l + dir*k (k <= kTop) lies outside [0, n).
inline void farthestWithin4(const float* x, const float* y, std::size_t c, int dir, std::size_t kTop,
                            const float (&kmax)[4], const float (&r2)[4], float (&found)[4]) noexcept {
#if defined(__SSE2__)
  const __m128 cx = _mm_loadu_ps(x + c);
  const __m128 cy = _mm_loadu_ps(y + c);
  const __m128 vk = _mm_loadu_ps(kmax);
  const __m128 vr2 = _mm_loadu_ps(r2);
  const __m128 zero = _mm_setzero_ps();
  const __m128 one = _mm_set1_ps(1.0F);
  __m128 hits = zero;
  __m128 fk = _mm_set1_ps(static_cast<float>(static_cast<int>(kTop)));
  for (std::size_t k = kTop; k >= 1; --k) {
    const std::size_t j = dir < 0 ? c - k : c + k;
    const __m128 dx = _mm_sub_ps(_mm_loadu_ps(x + j), cx);
    const __m128 dy = _mm_sub_ps(_mm_loadu_ps(y + j), cy);
    const __m128 d2 = _mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy));
    // A lane takes its first hit (the farthest offset) within its own window.
    const __m128 take = _mm_and_ps(_mm_and_ps(_mm_cmple_ps(d2, vr2), _mm_cmple_ps(fk, vk)), _mm_cmpeq_ps(hits, zero));
    hits = _mm_or_ps(hits, _mm_and_ps(take, fk));
    if (_mm_movemask_ps(_mm_cmpgt_ps(hits, zero)) == 0xF) {
      break;
    }
    fk = _mm_sub_ps(fk, one);
  }
  _mm_storeu_ps(found, hits);
#elif defined(__ARM_NEON) && defined(__aarch64__)
  const float32x4_t cx = vld1q_f32(x + c);
  const float32x4_t cy = vld1q_f32(y + c);
  const float32x4_t vk = vld1q_f32(kmax);
  const float32x4_t vr2 = vld1q_f32(r2);
  const float32x4_t zero = vdupq_n_f32(0.0F);
  float32x4_t hits = zero;
  float32x4_t fk = vdupq_n_f32(static_cast<float>(static_cast<int>(kTop)));
  for (std::size_t k = kTop; k >= 1; --k) {
    const std::size_t j = dir < 0 ? c - k : c + k;
    const float32x4_t dx = vsubq_f32(vld1q_f32(x + j), cx);
    const float32x4_t dy = vsubq_f32(vld1q_f32(y + j), cy);
    const float32x4_t d2 = vaddq_f32(vmulq_f32(dx, dx), vmulq_f32(dy, dy));
    const uint32x4_t take = vandq_u32(vandq_u32(vcleq_f32(d2, vr2), vcleq_f32(fk, vk)), vceqq_f32(hits, zero));
    hits = vbslq_f32(take, fk, hits);
    if (vminvq_u32(vcgtq_f32(hits, zero)) != 0U) {
      break;
    }
    fk = vsubq_f32(fk, vdupq_n_f32(1.0F));
  }
  vst1q_f32(found, hits);
#else
  (void)x;
  (void)y;
  (void)c;
  (void)dir;
  (void)kTop;
  (void)kmax;
  (void)r2;
  found[0] = found[1] = found[2] = found[3] = 0.0F;  // not used: kLockstep4 is false
#endif
}

/// Calls f(j) for the beams 1..k steps from beam i in direction dir (-1 or +1), nearest first,
/// wrapping on 360 deg scans and stopping at the scan ends otherwise. Plain index loops (no modulo
/// per step); k must not exceed pts.maxOffset(...) so that the two directions never overlap.
template <typename F>
inline void walkBeams(const ScanPoints& pts, std::size_t i, int dir, std::size_t k, F&& f) {
  const std::size_t n = pts.size();
  if (dir < 0) {
    const std::size_t direct = k <= i ? k : i;
    for (std::size_t s = 1; s <= direct; ++s) {
      f(i - s);
    }
    if (pts.wraps() && k > direct) {
      for (std::size_t s = 0; s < k - direct; ++s) {
        f(n - 1 - s);
      }
    }
  } else {
    const std::size_t direct = i + k < n ? k : n - 1 - i;
    for (std::size_t s = 1; s <= direct; ++s) {
      f(i + s);
    }
    if (pts.wraps() && k > direct) {
      for (std::size_t s = 0; s < k - direct; ++s) {
        f(s);
      }
    }
  }
}

/// Calls f(j) for the beams kNear..kFar steps (1 <= kNear; nothing when kNear > kFar) from beam i
/// in direction dir (-1 or +1), in increasing beam order: farthest first before the candidate,
/// nearest first after it. Wraps on 360 deg scans and stops at the scan ends otherwise; kFar must
/// not exceed pts.maxOffset(...) so that the two directions never overlap. Two plain index runs.
template <typename F>
inline void walkBeamsInOrder(const ScanPoints& pts, std::size_t i, int dir, std::size_t kNear, std::size_t kFar,
                             F&& f) {
  if (kNear > kFar || kNear == 0) {
    return;
  }
  const std::size_t n = pts.size();
  if (dir < 0) {
    // Offsets beyond i wrap to the end of the scan: indices n + i - kFar .. n + i - max(kNear, i + 1).
    if (kFar > i && pts.wraps()) {
      const std::size_t sNear = kNear > i ? kNear : i + 1;
      for (std::size_t j = n + i - kFar; j <= n + i - sNear; ++j) {
        f(j);
      }
    }
    if (kNear <= i) {
      const std::size_t sFar = kFar <= i ? kFar : i;
      for (std::size_t j = i - sFar; j <= i - kNear; ++j) {
        f(j);
      }
    }
  } else {
    // Offsets up to n - 1 - i stay direct, the rest wrap to the start of the scan.
    const std::size_t lastDirect = n - 1 - i;
    if (kNear <= lastDirect) {
      const std::size_t sFar = kFar <= lastDirect ? kFar : lastDirect;
      for (std::size_t j = i + kNear; j <= i + sFar; ++j) {
        f(j);
      }
    }
    if (kFar > lastDirect && pts.wraps()) {
      const std::size_t sNear = kNear > lastDirect ? kNear : lastDirect + 1;
      for (std::size_t j = i + sNear - n; j <= i + kFar - n; ++j) {
        f(j);
      }
    }
  }
}

/// The beams at most k steps from beam i (i included) as at most two index runs [begin, end)
/// (two when a 360 deg scan wraps), for loops where the visiting order does not matter. k must
/// not exceed pts.maxOffset(...). Returns the number of runs.
inline std::size_t beamRuns(const ScanPoints& pts, std::size_t i, std::size_t k, std::size_t (&begin)[2],
                            std::size_t (&end)[2]) noexcept {
  const std::size_t n = pts.size();
  const std::size_t lo = k <= i ? i - k : 0;
  const std::size_t hi = i + k < n ? i + k + 1 : n;
  begin[0] = lo;
  end[0] = hi;
  if (!pts.wraps()) {
    return 1;
  }
  // Wrapped parts: before beam 0 (from the end of the scan) or after beam n - 1 (from its start).
  // maxOffset keeps 2k + 1 <= n, so the two parts never overlap the direct run.
  if (k > i) {
    begin[1] = n + i - k;
    end[1] = n;
    return 2;
  }
  if (i + k >= n) {
    begin[1] = 0;
    end[1] = i + k + 1 - n;
    return 2;
  }
  return 1;
}

}  // namespace falko_detail
}  // namespace agv
