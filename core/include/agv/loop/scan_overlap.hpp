#pragma once
/// @file scan_overlap.hpp
/// Verification of a loop closure by the scans themselves, once an association has given the
/// transform between them. Two kinds of evidence, each counted over the points of one scan placed
/// in the other's frame:
/// - **hits**: points that land next to the other scan's endpoints (the walls agree);
/// - **conflicts**: points that land in the other scan's free space, well short of what its beam
///   in that direction measured (that beam passed through the place where the point is).
/// A wrong loop between two places that share a few corners (the keypoints agree) leaves walls
/// apart and puts walls in the free space of the other scan; a true loop puts them on top of each
/// other.
///
/// Hits: the reference scan's endpoints mark the cells of a square grid (cell `cell`, dilated by
/// one cell each way, so a point within about one cell of a reference point counts). The grid is
/// not stored densely: the cell coordinates are hashed into a bit table of kOverlapTableBits bits
/// (32 KiB). A collision can only turn a miss into a hit; with a 360-point scan (3240 marked
/// cells) about 1.2 % of misses do, for any range of the scans.
///
/// Conflicts: a placed point at range r and bearing b in the reference sensor's frame, inside the
/// reference's field of view, conflicts when the reference's beams at b and its two neighbours all
/// returned (valid readings) and all measured more than r + max(conflictMargin, conflictRatio r).
/// Invalid readings (no return) say nothing. A point hidden from the reference (behind what its
/// beam hit) is no conflict; objects and people that moved between the scans can make some.
///
/// Heap-free (about 41 KiB per object: static or member). Work: setReference O(kOverlapTableBits /
/// 64 + 9 n), score O(m), n and m beams at most kMaxScanBeams.

#include <array>
#include <cstddef>
#include <cstdint>

#include "agv/core/capacities.hpp"
#include "agv/core/fixed_vector.hpp"
#include "agv/core/pose2.hpp"
#include "agv/core/status.hpp"
#include "agv/scan/laser_scan.hpp"

namespace agv {

/// Bits of the hashed cell table (a power of two).
inline constexpr std::size_t kOverlapTableBits = std::size_t{1} << 18;

/// Parameters of the scan agreement test.
struct ScanOverlapParams {
  /// [m] grid cell of the hit test; points within about one cell (up to 1.5 cells) count.
  float cell = 0.10F;
  /// [m] and [fraction of the range]: a point conflicts when the reference's beams measured more
  /// than its range plus the larger of the two.
  float conflictMargin = 0.30F;
  float conflictRatio = 0.05F;
};

/// True when every field is finite and > 0.
bool isValid(const ScanOverlapParams& p) noexcept;

/// Result of placing one scan in the reference's frame.
struct ScanOverlapScore {
  std::size_t points = 0;     ///< valid readings of the placed scan
  std::size_t hits = 0;       ///< of which landed next to a reference endpoint
  std::size_t inView = 0;     ///< of which landed in the reference's field of view, beams valid
  std::size_t conflicts = 0;  ///< of those, points in the reference's free space
  /// hits / points (0 when points is 0).
  double hitFraction() const noexcept {
    return points == 0 ? 0.0 : static_cast<double>(hits) / static_cast<double>(points);
  }
  /// inView / points (0 when points is 0).
  double inViewFraction() const noexcept {
    return points == 0 ? 0.0 : static_cast<double>(inView) / static_cast<double>(points);
  }
  /// conflicts / points (0 when points is 0).
  double conflictFraction() const noexcept {
    return points == 0 ? 0.0 : static_cast<double>(conflicts) / static_cast<double>(points);
  }
};

/// Takes a reference scan once, then scores any number of placed scans against it.
class ScanOverlap {
 public:
  /// Sets the parameters (InvalidArgument and nothing changes when !isValid). Clears the
  /// reference.
  Status setParams(const ScanOverlapParams& params) noexcept;
  const ScanOverlapParams& params() const noexcept { return params_; }

  /// Takes `reference` (its readings, copied) and marks the cells of its endpoints. EmptyInput
  /// when no reading is valid; InvalidArgument for a non-finite or non-positive angle increment.
  Status setReference(const LaserScan& reference) noexcept;

  /// Places `scan` by `transform` (its sensor pose in the reference's frame, as
  /// PointAssociation::transform) and counts hits and conflicts. NotInitialized without a
  /// reference; NonFiniteInput for a non-finite transform; InvalidArgument for a bad angle
  /// increment; EmptyInput when `scan` has no valid reading. `out` is zeroed on every refusal.
  Status score(const LaserScan& scan, const Pose2d& transform, ScanOverlapScore& out) const noexcept;

 private:
  std::size_t slot(std::int32_t cx, std::int32_t cy) const noexcept;
  bool cellOf(float x, float y, std::int32_t& cx, std::int32_t& cy) const noexcept;
  // Whether the reference's beams around `bearing` all returned beyond `range` plus the margin;
  // false when out of view or a beam is invalid. `inView` is set when the three beams are valid.
  bool seenThrough(float bearing, float range, bool& inView) const noexcept;

  std::array<std::uint64_t, kOverlapTableBits / 64> bits_{};
  FixedVector<float, kMaxScanBeams> ranges_;  ///< reference readings, invalid ones as -1
  float angleMin_ = 0.0F;
  float angleIncrement_ = 0.0F;
  ScanOverlapParams params_{};
  bool hasReference_ = false;
};

/// The agreement of two scans under `transform` (second scan's pose in the first's frame): the
/// smaller hit fraction and the larger conflict fraction of the two directions. `first` and
/// `second` are both used as reference in turn (their previous references are replaced).
struct MutualOverlap {
  double hitFraction = 0.0;
  double conflictFraction = 1.0;
  double inViewFraction = 0.0;  ///< the smaller of the two
};
Status mutualOverlap(ScanOverlap& first, const LaserScan& firstScan, ScanOverlap& second, const LaserScan& secondScan,
                     const Pose2d& transform, MutualOverlap& out) noexcept;

}  // namespace agv
