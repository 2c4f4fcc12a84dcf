#pragma once
/// @file landmark_map.hpp
/// The localizer's external point-landmark map: fixed capacity, two kinds (reflectors and FALKO
/// corners), the hit-count lifecycle (+1 matched, -1 in view and not matched, deleted at 0),
/// matched landmarks moving toward their observation by an update rate, surveyed landmarks that
/// never move or die, a static mode, and a hashed uniform grid so that a neighbourhood query
/// costs O(cells in the query + landmarks in them), independent of the map size.
///
/// Precision: double for coordinates (a warehouse spans hundreds of metres and landmarks move by
/// sub-millimetre steps under the update rate; float would quantise them to ~15 um at 200 m and
/// stall the averaging).
///
/// Storage: kMaxLandmarks slots (60 bytes each) and kLandmarkGridBuckets bucket heads, inline;
/// a map object is ~280 KB at the default capacities: give it static storage or allocate it once.

#include <cstddef>
#include <cstdint>

#include "agv/core/capacities.hpp"
#include "agv/core/result.hpp"
#include "agv/core/status.hpp"

namespace agv {

/// What a landmark is; the detector that sees it reports the same kind.
enum class LandmarkKind : std::uint8_t {
  Reflector = 0,  ///< artificial reflector pole (laser intensity), point = pole centre
  Corner = 1,     ///< FALKO keypoint, point = corner apex
};
/// Number of kinds.
inline constexpr std::size_t kLandmarkKindCount = 2;
/// Bit of `kind` in a kind mask.
constexpr std::uint8_t landmarkKindBit(LandmarkKind kind) noexcept {
  return static_cast<std::uint8_t>(1U << static_cast<unsigned>(kind));
}
/// Mask of every kind.
inline constexpr std::uint8_t kAllLandmarkKinds = 0x03;

/// How the map may change.
enum class MapMode : std::uint8_t {
  Dynamic = 0,  ///< landmarks are inserted, moved and deleted by the lifecycle
  Static = 1,   ///< the map is frozen: the lifecycle calls leave it untouched
};

/// Index of a slot in the map; stable while the landmark lives.
using LandmarkIndex = std::uint32_t;
/// "No landmark".
inline constexpr LandmarkIndex kNoLandmark = 0xFFFFFFFFU;
/// Largest |coordinate| accepted [m].
inline constexpr double kMaxMapCoordinate = 1.0e6;

/// One point landmark.
struct Landmark {
  double x = 0.0;                      ///< world [m]
  double y = 0.0;                      ///< world [m]
  double variance = 0.0;               ///< isotropic position variance [m^2]
  std::uint32_t id = 0;                ///< unique id (surveyed: from the map file)
  std::uint32_t lastMatchedCycle = 0;  ///< cycle number of the last match (0 = never)
  std::int16_t hits = 0;               ///< lifecycle counter (surveyed: unused)
  LandmarkKind kind = LandmarkKind::Reflector;
  bool surveyed = false;  ///< never moves, never dies
};

/// Parameters of the map (documented defaults from the reference localizer).
struct LandmarkMapParams {
  double cellSize = 2.0;         ///< grid cell edge [m], in [0.05, 1000]
  double updateRate = 0.1;       ///< a matched landmark moves this fraction toward the observation
  std::int16_t initialHits = 1;  ///< hit count of a newly inserted landmark
  std::int16_t maxHits = 20;     ///< cap, so a vanished landmark dies within maxHits cycles in view
  MapMode mode = MapMode::Dynamic;
};

/// Counters since construction or `clear()`.
struct LandmarkMapCounters {
  std::uint32_t inserted = 0;        ///< dynamic landmarks inserted
  std::uint32_t deleted = 0;         ///< landmarks that died (hits reached 0) or were removed
  std::uint32_t refusedFull = 0;     ///< inserts refused because the map was full
  std::uint32_t refusedInvalid = 0;  ///< inserts refused for non-finite / out-of-range input
};

class LandmarkMap {
 public:
  /// Invalid parameters are replaced by the defaults (`paramsValid()` says whether that happened).
  explicit LandmarkMap(const LandmarkMapParams& params = LandmarkMapParams{}) noexcept;
  LandmarkMap(const LandmarkMap&) = delete;
  LandmarkMap& operator=(const LandmarkMap&) = delete;

  /// Makes this map an exact copy of `other`: parameters, mode, landmarks in the same slots,
  /// grid, free slots and counters (O(capacity), no allocation). Copies are explicit because a
  /// map is large (see Storage above); one use is giving each of several concurrent localizers
  /// its own copy of a frozen map.
  void copyFrom(const LandmarkMap& other) noexcept;

  /// Removes every landmark and resets the counters (O(capacity)).
  void clear() noexcept;

  /// Adds a surveyed landmark (allowed in both modes). `id` must be unique among live landmarks
  /// (`InvalidArgument` otherwise); `sigma` >= 0 [m]. `CapacityExceeded` (counted) when full;
  /// `NonFiniteInput`/`OutOfRange` (counted) for bad coordinates.
  Result<LandmarkIndex> addSurveyed(LandmarkKind kind, double x, double y, double sigma, std::uint32_t id) noexcept;

  /// Inserts a dynamic landmark with `initialHits` (Dynamic mode only, `Unsupported` otherwise).
  /// `CapacityExceeded` (counted) when full.
  Result<LandmarkIndex> insert(LandmarkKind kind, double x, double y, double variance) noexcept;

  /// Lifecycle "matched": +1 hit (capped) and, unless surveyed or Static, moves the landmark toward
  /// (x, y) by the update rate, its variance becoming (1-a)^2 var + a^2 observationVariance.
  /// Records `cycle` as the last match. `NotFound` for a dead index; `NonFiniteInput` for bad input.
  Status reinforce(LandmarkIndex index, double x, double y, double observationVariance, std::uint32_t cycle) noexcept;

  /// Lifecycle "in view and not matched": -1 hit; at 0 the landmark is deleted. No effect on
  /// surveyed landmarks or in Static mode. Returns true when the landmark was deleted.
  bool weaken(LandmarkIndex index) noexcept;

  /// Deletes a landmark (any kind, any mode). `NotFound` for a dead index.
  Status remove(LandmarkIndex index) noexcept;

  /// The landmark in slot `index`, or nullptr when the slot is empty.
  const Landmark* at(LandmarkIndex index) const noexcept {
    return index < kMaxLandmarks && nodes_[index].live ? &slots_[index] : nullptr;
  }

  /// Calls `f(LandmarkIndex, const Landmark&)` for every landmark whose grid cell intersects the
  /// square of half-size `radius` around (x, y) (a superset of the disc: filter by distance).
  /// `radius` is clamped to `kMaxQueryCells / 2` cells, which bounds the work. `f` may weaken or
  /// remove the landmark it is given, but must not insert.
  template <typename F>
  void forEachNear(double x, double y, double radius, F&& f) const noexcept;

  /// Calls `f(LandmarkIndex, const Landmark&)` for every live landmark (O(capacity); for saving
  /// and tests, not for the cycle).
  template <typename F>
  void forEach(F&& f) const noexcept {
    for (std::size_t i = 0; i < kMaxLandmarks; ++i) {
      if (nodes_[i].live) {
        f(static_cast<LandmarkIndex>(i), slots_[i]);
      }
    }
  }

  std::size_t size() const noexcept { return size_; }
  static constexpr std::size_t capacity() noexcept { return kMaxLandmarks; }
  bool full() const noexcept { return size_ == kMaxLandmarks; }
  const LandmarkMapCounters& counters() const noexcept { return counters_; }
  const LandmarkMapParams& params() const noexcept { return params_; }
  bool paramsValid() const noexcept { return paramsValid_; }
  MapMode mode() const noexcept { return params_.mode; }
  void setMode(MapMode mode) noexcept { params_.mode = mode; }
  /// Counts `n` inserts refused for lack of space without attempting them (a loader that checks
  /// the free space up front refuses a whole file at once).
  void countRefusedFull(std::uint32_t n) noexcept { counters_.refusedFull += n; }
  /// Finds a live landmark by id (O(capacity)). kNoLandmark when absent.
  LandmarkIndex findById(std::uint32_t id) const noexcept;

  /// Query width bound, in cells per axis.
  static constexpr std::int32_t kMaxQueryCells = 64;

 private:
  struct Node {
    LandmarkIndex next = kNoLandmark;  // bucket chain
    std::int32_t cx = 0;
    std::int32_t cy = 0;
    bool live = false;
  };

  std::int32_t cellOf(double v) const noexcept;
  static std::size_t bucketOf(std::int32_t cx, std::int32_t cy) noexcept {
    const std::uint32_t h = (static_cast<std::uint32_t>(cx) * 73856093U) ^ (static_cast<std::uint32_t>(cy) * 19349663U);
    return static_cast<std::size_t>(h) & (kLandmarkGridBuckets - 1U);
  }
  Status checkPoint(double x, double y) const noexcept;
  Result<LandmarkIndex> allocate(LandmarkKind kind, double x, double y, double variance) noexcept;
  void link(LandmarkIndex index) noexcept;
  void unlink(LandmarkIndex index) noexcept;

  LandmarkMapParams params_{};
  bool paramsValid_ = true;
  Landmark slots_[kMaxLandmarks];
  Node nodes_[kMaxLandmarks];
  LandmarkIndex buckets_[kLandmarkGridBuckets];
  LandmarkIndex freeList_[kMaxLandmarks];
  std::size_t freeCount_ = 0;
  std::size_t size_ = 0;
  std::uint32_t nextId_ = 1;
  LandmarkMapCounters counters_{};
};

template <typename F>
void LandmarkMap::forEachNear(double x, double y, double radius, F&& f) const noexcept {
  if (!(radius >= 0.0) || checkPoint(x, y) != Status::Ok) {
    return;
  }
  const double maxRadius = 0.5 * static_cast<double>(kMaxQueryCells - 1) * params_.cellSize;
  if (radius > maxRadius) {
    radius = maxRadius;
  }
  const std::int32_t x0 = cellOf(x - radius);
  const std::int32_t x1 = cellOf(x + radius);
  const std::int32_t y0 = cellOf(y - radius);
  const std::int32_t y1 = cellOf(y + radius);
  for (std::int32_t cx = x0; cx <= x1; ++cx) {
    for (std::int32_t cy = y0; cy <= y1; ++cy) {
      // Chains are bounded by the capacity; cells sharing a bucket are told apart by (cx, cy).
      LandmarkIndex i = buckets_[bucketOf(cx, cy)];
      for (std::size_t guard = 0; i != kNoLandmark && guard < kMaxLandmarks; ++guard) {
        const Node& n = nodes_[i];
        if (n.cx == cx && n.cy == cy) {
          f(i, slots_[i]);
        }
        i = n.next;
      }
    }
  }
}

}  // namespace agv
