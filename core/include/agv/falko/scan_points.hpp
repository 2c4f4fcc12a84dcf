#pragma once
/// @file scan_points.hpp
/// Cartesian cache of one laser scan, shared by the FALKO detector and its descriptors.

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "agv/core/capacities.hpp"
#include "agv/core/status.hpp"
#include "agv/scan/laser_scan.hpp"

namespace agv {

/// The valid readings of a `LaserScan` as sensor-frame points, plus the beam-geometry tables the
/// neighbourhood searches use.
///
/// Precision: float. A laser's range noise (mm..cm) is orders of magnitude above float resolution
/// (4 um at 50 m), neighbourhoods are at most a few metres wide and every fit below is done in
/// coordinates centred on the candidate, so double would buy nothing; on the single-precision FPU
/// of an MCU it would cost an order of magnitude in time.
///
/// Speed: the cos/sin of every beam angle are computed only when the scan geometry (angle_min,
/// increment, beam count) changes, so a stream of scans from one sensor costs one multiply per
/// coordinate and no trigonometry.
class ScanPoints {
 public:
  /// Coordinate given to invalid readings: squared distances to it stay finite (< 1e37) and
  /// exceed any neighbourhood radius.
  static constexpr float kFarAway = 1.0e12F;

  ScanPoints() noexcept = default;

  /// Converts `scan`. `InvalidArgument` (and an empty cache) when the increment is not finite and
  /// positive or angle_min is not finite. Invalid readings (NaN, inf, below rangeMin, at or above
  /// rangeMax) are marked and never used as points.
  Status assign(const LaserScan& scan) noexcept;

  /// Beam count of the last assigned scan.
  std::size_t size() const noexcept { return size_; }
  /// True when the scan covers 360 deg: beam 0 then neighbours beam size()-1.
  bool wraps() const noexcept { return wraps_; }
  /// Angle step [rad].
  float angleIncrement() const noexcept { return increment_; }
  bool valid(std::size_t i) const noexcept { return valid_[i] != 0U; }
  /// Coordinates [m]; an invalid reading is at (kFarAway, kFarAway), beyond any radius test.
  float x(std::size_t i) const noexcept { return x_[i]; }
  float y(std::size_t i) const noexcept { return y_[i]; }
  float range(std::size_t i) const noexcept { return range_[i]; }
  /// The coordinate arrays (size() entries), for loops that test several beams at once.
  const float* xData() const noexcept { return x_.data(); }
  const float* yData() const noexcept { return y_.data(); }
  /// Number of valid points.
  std::size_t validCount() const noexcept { return validCount_; }

  /// Beam offset k (in increments, per side) beyond which no beam can hold a point within
  /// `radius` of a point at range `rangeAtCentre` (sin(k * increment) * range > radius; an upper
  /// bound, at most one or two beams generous), bounded by the half scan (wrapping scans) or the
  /// scan length. O(1).
  std::size_t maxOffset(float rangeAtCentre, float radius) const noexcept {
    if (!(radius < rangeAtCentre)) {
      return maxSideOffset_;
    }
    return offsetForRatio(radius / rangeAtCentre);
  }

  /// maxOffset(range(i), radius) for the point of beam i, from its stored inverse range (no
  /// division).
  std::size_t maxOffsetAt(std::size_t i, float radius) const noexcept { return offsetForRatio(radius * invRange_[i]); }

  /// Index `k` beams after `i` (k may be negative), wrapped on 360 deg scans; returns size() when
  /// the result lies outside a non-wrapping scan.
  std::size_t offsetIndex(std::size_t i, std::ptrdiff_t k) const noexcept {
    const auto n = static_cast<std::ptrdiff_t>(size_);
    std::ptrdiff_t j = static_cast<std::ptrdiff_t>(i) + k;
    if (wraps_) {
      j %= n;
      if (j < 0) {
        j += n;
      }
      return static_cast<std::size_t>(j);
    }
    return (j < 0 || j >= n) ? size_ : static_cast<std::size_t>(j);
  }

 private:
  /// Beam offset bound for q = radius / range: beam k holds no point within the radius once
  /// k * increment > asin(q). Upper bounds of asin without a division, at most 2.5 % above it:
  /// - q <= 3/4: q * (1 + q^2 * (1/6 + q^2 / 5)) (the Taylor series of asin has positive
  ///   coefficients, and its tail beyond q^3 stays below q^5 / 5 up to q = 0.94);
  /// - 3/4 < q < 1: pi/2 - sqrt(2 (1 - q)), since acos(q) = 2 asin(sqrt((1 - q) / 2)) >=
  ///   sqrt(2 (1 - q)) (tan(asin(q)), the bound used before, is 84 % above asin at q = 0.9);
  /// - q >= 1 (or NaN): the whole half scan.
  /// One beam of slack covers the float rounding; callers' distance tests drop the extra beams.
  std::size_t offsetForRatio(float q) const noexcept {
    float angle = 0.0F;
    if (q <= 0.75F) {
      const float q2 = q * q;
      angle = q * (1.0F + q2 * (0.16666667F + 0.2F * q2));
    } else if (q < 1.0F) {
      angle = 1.57079633F - std::sqrt(2.0F * (1.0F - q));
    } else {
      return maxSideOffset_;
    }
    const float bound = angle * invIncrement_ + 1.0F;
    if (!(bound < static_cast<float>(maxSideOffset_))) {
      return maxSideOffset_;
    }
    return static_cast<std::size_t>(static_cast<int>(bound));  // 0 < bound < maxSideOffset_: fits an int
  }

  void rebuildGeometry(float angleMin, float increment, std::size_t n) noexcept;

  std::array<float, kMaxScanBeams> cos_{};
  std::array<float, kMaxScanBeams> sin_{};
  std::array<float, kMaxScanBeams> x_{};
  std::array<float, kMaxScanBeams> y_{};
  std::array<float, kMaxScanBeams> range_{};
  std::array<float, kMaxScanBeams> invRange_{};  ///< 1 / range, 0 for invalid readings
  std::array<std::uint8_t, kMaxScanBeams> valid_{};
  std::size_t size_ = 0;
  std::size_t validCount_ = 0;
  std::size_t maxSideOffset_ = 0;  ///< per-side walk bound from the scan length / wrap
  bool wraps_ = false;
  // Geometry the trig tables were built for.
  float geomAngleMin_ = 0.0F;
  float geomIncrement_ = -1.0F;
  std::size_t geomSize_ = 0;
  float increment_ = 0.0F;
  float invIncrement_ = 0.0F;
};

}  // namespace agv
