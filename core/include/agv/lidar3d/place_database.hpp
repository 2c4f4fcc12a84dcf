#pragma once
/// @file place_database.hpp
/// Key-signatures and loop detection on normal-histogram signatures (Muhammad 2012, ch. 5).
///
/// Every revolution's signature goes through `add()`:
/// 1. Loop query: among the stored key-signatures except the newest `skipRecentKeys` (m = 15: the
///    places just driven through always look alike and are no loop), the key with the smallest
///    chi-square distance among those with chi-square < T_chi2 *and* Sorensen < T_Sor is the loop
///    candidate; with its orientation signature the relative yaw is estimated too. With the
///    orientation check on (PlaceParams::maxOrientationCost > 0), the candidates are checked
///    nearest first and the first whose orientation signatures agree is the loop.
/// 2. Key decision: the first revolution is a key; afterwards a revolution becomes a new key when
///    its chi-square distance to the last key exceeds T_key (the place has changed enough).
///
/// `PlaceDatabase<N>` holds N keys inline (capacity in the type, ~1.9 KiB per key);
/// `PlaceDatabaseBase` is its capacity-independent interface. A key into a full database is
/// refused with CapacityExceeded and counted (the loop query of that revolution still ran and its
/// result is in the update). An empty signature (no normals) is refused (EmptyInput, counted).
///
/// Work per add(): O(N) chi-square + Sorensen distances (101 terms each) + one relativeYaw, or up to
/// kPlaceVerifyCandidates relativeYaw calls with the orientation check, and as many alignProfiles
/// calls with the geometric verification (PlaceParams::maxLoopTranslation).

#include <array>
#include <cstddef>
#include <cstdint>

#include "agv/core/status.hpp"
#include "agv/lidar3d/normal_signature.hpp"
#include "agv/lidar3d/orientation_signature.hpp"
#include "agv/lidar3d/profile_alignment.hpp"

namespace agv {

/// Thresholds of key-signatures and loops. The defaults sit between the distances measured on the
/// four shared KITTI 00 HDL-64E scans (docs/lidar-places.md): consecutive scans ~1 m apart
/// (94/95, 198/199) at chi-square 5.0e-5 / 1.4e-4 and Sorensen 0.019 / 0.025, scans of the two
/// places 58 m apart at chi-square >= 4.8e-4 and Sorensen >= 0.049. Four scans are a smoke test,
/// not a tuning set: set them per site and sensor from a recorded route (agvnav-lidar-places).
struct PlaceParams {
  float keyThreshold = 1.0e-4F;        ///< T_key: chi-square to the last key above which a new key is made
  std::size_t skipRecentKeys = 15;     ///< m: the newest m keys take no part in the loop query (thesis: 15)
  float chiSquareThreshold = 3.0e-4F;  ///< T_chi2: a loop needs chi-square below this
  float sorensenThreshold = 0.035F;    ///< T_Sor: and Sorensen below this
  std::size_t minYawOverlap = 36;      ///< bins valid in both orientation signatures for a yaw
  /// Orientation check (an addition to the thesis; 0 = off): a candidate is accepted only when both
  /// it and the query have orientation signatures and their relative cost at the best shift
  /// (YawEstimate::relativeCost) is at most this. Structurally similar places have similar normal
  /// histograms but not the same ranges around them. Up to kPlaceVerifyCandidates candidates, the
  /// nearest by chi-square first, are checked; the first that passes is the loop.
  float maxOrientationCost = 0.0F;
  /// Geometric verification (an addition to the thesis; 0 = off): every candidate that passed the
  /// thresholds (and the orientation check when on), up to kPlaceVerifyCandidates nearest by
  /// chi-square, is aligned to the query by `alignProfiles` (from the signatures' relative yaw); a
  /// candidate is kept when the alignment succeeds, at least `minAlignedFraction` of the query's
  /// profile bins are inliers (ProfileAlignment::inlierFraction: paired within align.inlierResidual
  /// of the key's profile), and the translation is at most this [m] (the radius within which a loop
  /// is wanted). Of the kept ones the nearest by translation is the loop.
  float maxLoopTranslation = 0.0F;
  float minAlignedFraction = 0.5F;  ///< see maxLoopTranslation (0..1)
  ProfileAlignParams align{};       ///< see maxLoopTranslation
};

/// Candidates (nearest by chi-square) an orientation check examines per query at most.
inline constexpr std::size_t kPlaceVerifyCandidates = 8;

/// True when the thresholds are finite and positive (maxOrientationCost finite and >= 0).
bool isValid(const PlaceParams& p) noexcept;

/// One stored key.
struct PlaceKey {
  NormalSignature normal{};
  OrientationSignature orientation{};  ///< may be empty (no yaw for loops with this key)
  std::uint32_t scan = 0;              ///< caller's id of the revolution (e.g. its index in the sequence)
};

/// What one add() found.
struct PlaceUpdate {
  bool isKey = false;               ///< the revolution became a key (stored unless refused)
  std::uint32_t keyIndex = 0;       ///< its index among the keys when isKey and stored
  float chiSquareToLastKey = 0.0F;  ///< chi-square to the last key before this one (0 for the first)
  bool loop = false;                ///< a loop candidate was found
  std::uint32_t loopKey = 0;        ///< index of the matched key
  std::uint32_t loopScan = 0;       ///< scan id of the matched key
  float chiSquare = 0.0F;           ///< distances to it
  float sorensen = 0.0F;
  std::uint32_t candidates = 0;             ///< keys that passed both thresholds (the best is reported)
  std::uint32_t rejectedByOrientation = 0;  ///< of those, checked and refused by the orientation check
  bool hasYaw = false;                      ///< relative yaw of this revolution w.r.t. the matched key estimated
  YawEstimate yaw{};                        ///< the orientation signature's (coarse) yaw
  std::uint32_t rejectedByAlignment = 0;    ///< candidates refused by the geometric verification
  /// The geometric verification's alignment of this revolution to the matched key (maxLoopTranslation
  /// > 0): its yaw accounts for the translation (prefer it to yaw.yaw), x / y = this revolution's
  /// position in the key's frame.
  bool hasAlignment = false;
  ProfileAlignment alignment{};
  /// The other start's alignment of the matched key (the opposite heading of the kept one, when it
  /// succeeded and ended more than 90 deg away from it; else 0): its inlier share.
  float alternativeInlierFraction = 0.0F;
};

/// Capacity-independent interface of a `PlaceDatabase`. Not constructible on its own.
class PlaceDatabaseBase {
 public:
  PlaceDatabaseBase(const PlaceDatabaseBase&) = delete;
  PlaceDatabaseBase& operator=(const PlaceDatabaseBase&) = delete;

  /// Sets the thresholds (InvalidArgument, nothing changed, when out of their domain).
  Status setParams(const PlaceParams& params) noexcept;
  const PlaceParams& params() const noexcept { return params_; }

  /// Runs the loop query, then the key decision, for one revolution (see the file comment); `out`
  /// is filled in every case. Ok; EmptyInput (refused, counted, out.isKey false) for an empty
  /// signature; CapacityExceeded (refused, counted) when a new key did not fit.
  Status add(const NormalSignature& normal, const OrientationSignature& orientation, std::uint32_t scan,
             PlaceUpdate& out) noexcept;

  std::size_t size() const noexcept { return size_; }
  std::size_t capacity() const noexcept { return capacity_; }
  /// Key `i`, or nullptr when i >= size().
  const PlaceKey* at(std::size_t i) const noexcept { return i < size_ ? keys_ + i : nullptr; }
  /// Keys refused because the database was full.
  std::uint32_t refusedFull() const noexcept { return refusedFull_; }
  /// Revolutions refused because their signature was empty.
  std::uint32_t refusedEmpty() const noexcept { return refusedEmpty_; }
  /// Removes every key (the refused counts stay).
  void clear() noexcept { size_ = 0; }

 protected:
  PlaceDatabaseBase(PlaceKey* storage, std::size_t capacity) noexcept : keys_(storage), capacity_(capacity) {}
  ~PlaceDatabaseBase() = default;

 private:
  PlaceKey* keys_;
  std::size_t capacity_;
  std::size_t size_ = 0;
  PlaceParams params_{};
  std::uint32_t refusedFull_ = 0;
  std::uint32_t refusedEmpty_ = 0;
};

namespace detail {
template <std::size_t N>
struct PlaceDatabaseStorage {
  std::array<PlaceKey, N> keys_{};
};
}  // namespace detail

/// A database of at most N key-signatures stored inline.
template <std::size_t N>
class PlaceDatabase : private detail::PlaceDatabaseStorage<N>, public PlaceDatabaseBase {
  static_assert(N > 0, "PlaceDatabase capacity must be positive");
  using Storage = detail::PlaceDatabaseStorage<N>;

 public:
  static constexpr std::size_t kCapacity = N;
  PlaceDatabase() noexcept : Storage(), PlaceDatabaseBase(Storage::keys_.data(), N) {}
  PlaceDatabase(const PlaceDatabase&) = delete;
  PlaceDatabase& operator=(const PlaceDatabase&) = delete;
  ~PlaceDatabase() = default;
};

}  // namespace agv
