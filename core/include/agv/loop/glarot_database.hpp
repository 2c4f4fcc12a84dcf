#pragma once
/// @file glarot_database.hpp
/// A database of GLAROT signatures (one per scan, with the pose it was taken at) and the search
/// for the k nearest by SL1: the candidates of a loop closure.
///
/// `GlarotDatabase<N>` holds N entries inline (capacity in the type, ~1.3 kB per entry with the
/// default signature capacity); `GlarotDatabaseBase` is its capacity-independent interface, so one
/// non-template function serves every capacity (the FixedVector / IVector pattern). An insert into
/// a full database is refused with CapacityExceeded and counted.
///
/// Search: exact k nearest by SL1 over the admitted entries. Each entry's rho marginal (the sum
/// over theta, which no shift changes) gives a lower bound of SL1 (L1 of the marginals <= L1 at
/// any shift); entries whose bound is not below the current k-th distance are skipped, and a
/// shift stops as soon as its partial sum reaches the best so far. Both only drop entries that
/// cannot enter the result, so the answer equals the exhaustive search. Worst case O(N n_theta^2
/// n_rho) = 2048 absolute differences per entry with the defaults, plus O(N k) for the sorted list.

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>

#include "agv/core/capacities.hpp"
#include "agv/core/fixed_vector.hpp"
#include "agv/core/pose2.hpp"
#include "agv/core/status.hpp"
#include "agv/loop/glarot.hpp"

namespace agv {

/// One stored scan.
struct GlarotEntry {
  GlarotSignature signature;
  std::array<float, kGlarotMaxRhoBins> rhoMarginal{};  ///< sum over theta of each rho bin
  Pose2d pose{};                                       ///< pose the scan was taken at (as given to insert; any frame)
  double travel = 0.0;  ///< [m] path length from the first entry through every stored pose
};

/// One result of a search.
struct GlarotCandidate {
  std::uint32_t index = 0;  ///< entry index (insertion order)
  float distance = 0.0F;    ///< SL1 to the query
  std::uint16_t shift = 0;  ///< the shift attaining it (see GlarotMatch)
};

/// A result list of the largest size a search can return.
using GlarotCandidates = FixedVector<GlarotCandidate, kGlarotMaxCandidates>;

/// What to search and what to leave out.
struct GlarotQuery {
  /// Number of candidates wanted (1..kGlarotMaxCandidates; the thesis uses 10).
  std::size_t k = 10;
  /// Only entries with index < end take part ("earlier scans only" when replaying a log).
  std::size_t end = std::numeric_limits<std::size_t>::max();
  /// The newest `excludeRecent` entries (of those before `end`) are left out: online, the scans
  /// just before the current one always look alike and are no loop.
  std::size_t excludeRecent = 0;
  /// [m] also left out: entries reached from the newest admitted one by less than this path length
  /// (summed over the stored poses), i.e. the recent trajectory measured in metres, not scans.
  double excludeRecentTravel = 0.0;
  /// One entry left out (the query's own entry in an offline all-against-all run).
  std::size_t excludeIndex = std::numeric_limits<std::size_t>::max();
};

/// Capacity-independent interface of a `GlarotDatabase`. Not constructible on its own.
class GlarotDatabaseBase {
 public:
  GlarotDatabaseBase(const GlarotDatabaseBase&) = delete;
  GlarotDatabaseBase& operator=(const GlarotDatabaseBase&) = delete;

  /// Appends a signature taken at `pose`. Returns Ok; CapacityExceeded (refused and counted) when
  /// full; InvalidArgument when its shape is empty or differs from the stored entries';
  /// NonFiniteInput for a NaN or infinite pose. A refused entry changes nothing.
  Status insert(const GlarotSignature& signature, const Pose2d& pose = Pose2d{}) noexcept;

  /// The k nearest admitted entries by SL1, nearest first (ties: lower index first), in `out`
  /// (cleared first; fewer than k when fewer are admitted). Returns Ok; InvalidArgument when k is
  /// 0, above kGlarotMaxCandidates or above out.capacity(), or the query's shape differs from the
  /// entries'; EmptyInput when no entry is admitted (out empty).
  Status query(const GlarotSignature& signature, const GlarotQuery& query,
               IVector<GlarotCandidate>& out) const noexcept;

  /// Entries stored.
  std::size_t size() const noexcept { return size_; }
  /// Entries it can hold.
  std::size_t capacity() const noexcept { return capacity_; }
  /// Entry `i`, or nullptr when i >= size().
  const GlarotEntry* at(std::size_t i) const noexcept { return i < size_ ? entries_ + i : nullptr; }
  /// Inserts refused because the database was full (since construction or resetRefusedCount()).
  std::uint32_t refusedCount() const noexcept { return refused_; }
  void resetRefusedCount() noexcept { refused_ = 0; }
  /// Removes every entry (the refused count stays).
  void clear() noexcept { size_ = 0; }

 protected:
  GlarotDatabaseBase(GlarotEntry* storage, std::size_t capacity) noexcept : entries_(storage), capacity_(capacity) {}
  ~GlarotDatabaseBase() = default;

 private:
  GlarotEntry* entries_;
  std::size_t capacity_;
  std::size_t size_ = 0;
  std::uint32_t refused_ = 0;
};

namespace detail {
/// Inline entry storage; a base class so that it exists before GlarotDatabaseBase takes its address.
template <std::size_t N>
struct GlarotDatabaseStorage {
  std::array<GlarotEntry, N> entries_{};
};
}  // namespace detail

/// A database of at most N signatures stored inline (large: allocate it statically or as a member).
template <std::size_t N>
class GlarotDatabase : private detail::GlarotDatabaseStorage<N>, public GlarotDatabaseBase {
  static_assert(N > 0, "GlarotDatabase capacity must be positive");
  using Storage = detail::GlarotDatabaseStorage<N>;

 public:
  static constexpr std::size_t kCapacity = N;
  GlarotDatabase() noexcept : Storage(), GlarotDatabaseBase(Storage::entries_.data(), N) {}
  GlarotDatabase(const GlarotDatabase&) = delete;
  GlarotDatabase& operator=(const GlarotDatabase&) = delete;
  ~GlarotDatabase() = default;
};

}  // namespace agv
