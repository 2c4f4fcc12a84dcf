#pragma once
/// @file alloc_counter.hpp
/// Counts every heap allocation of the test binary that links `agv_alloc_counter`.
///
/// In a normal build the library replaces malloc, calloc, realloc, aligned_alloc, memalign,
/// posix_memalign, valloc, pvalloc, free and every form of operator new / new[] / delete /
/// delete[] (plain, nothrow, sized, aligned), counting each call and forwarding to glibc.
/// Under AddressSanitizer, which owns the allocator, it counts through the sanitizer's
/// malloc/free hooks instead (they see malloc, new and every aligned form alike).

#include <cstdint>
#include <utility>

namespace agv::test {

/// Totals since program start. Counters are process-wide and atomic.
struct AllocationStats {
  std::uint64_t allocations = 0;    ///< successful allocating calls (realloc counts as one)
  std::uint64_t deallocations = 0;  ///< calls that freed a non-null pointer
};

/// Current totals.
AllocationStats allocationStats() noexcept;

/// Successful allocating calls made so far by the calling thread alone.
std::uint64_t threadAllocations() noexcept;

/// True when this binary's allocations are really being counted (the self-test checks it).
bool allocationCountingActive() noexcept;

/// Runs `f` and returns how many allocations it performed on the calling thread. Allocations
/// that other threads make meanwhile (a test's scripted TCP peer, say) are not counted; the code
/// under test never starts threads, so nothing it does escapes the count.
template <typename F>
std::uint64_t countAllocations(F&& f) {
  const std::uint64_t before = threadAllocations();
  std::forward<F>(f)();
  return threadAllocations() - before;
}

}  // namespace agv::test
