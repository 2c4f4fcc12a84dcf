// Allocation counting for the statically linked VM test. The host tests replace glibc's malloc
// (tests/support/alloc_counter.cpp), which a static link cannot do; here the link wraps the C
// allocator instead (-Wl,--wrap=malloc,...): every call from this program and libstdc++
// (operator new calls malloc) goes through these counters.
#include "vm_alloc_count.hpp"

#include <atomic>
#include <cstddef>

namespace {
std::atomic<std::uint64_t> g_calls{0};
}

extern "C" {
void* __real_malloc(std::size_t n);
void* __real_calloc(std::size_t n, std::size_t size);
void* __real_realloc(void* p, std::size_t n);
int __real_posix_memalign(void** p, std::size_t alignment, std::size_t n);
void* __real_aligned_alloc(std::size_t alignment, std::size_t n);

void* __wrap_malloc(std::size_t n) {
  g_calls.fetch_add(1, std::memory_order_relaxed);
  return __real_malloc(n);
}
void* __wrap_calloc(std::size_t n, std::size_t size) {
  g_calls.fetch_add(1, std::memory_order_relaxed);
  return __real_calloc(n, size);
}
void* __wrap_realloc(void* p, std::size_t n) {
  g_calls.fetch_add(1, std::memory_order_relaxed);
  return __real_realloc(p, n);
}
int __wrap_posix_memalign(void** p, std::size_t alignment, std::size_t n) {
  g_calls.fetch_add(1, std::memory_order_relaxed);
  return __real_posix_memalign(p, alignment, n);
}
void* __wrap_aligned_alloc(std::size_t alignment, std::size_t n) {
  g_calls.fetch_add(1, std::memory_order_relaxed);
  return __real_aligned_alloc(alignment, n);
}
}

namespace agv::test {
std::uint64_t vmAllocationCalls() noexcept {
  return g_calls.load(std::memory_order_relaxed);
}
}  // namespace agv::test
