// Allocation counting for tests: see alloc_counter.hpp.
#include "alloc_counter.hpp"

#include <atomic>
#include <cerrno>
#include <cstddef>
#include <cstdlib>
#include <new>

#if defined(__SANITIZE_ADDRESS__)
#define AGV_ALLOC_VIA_SANITIZER_HOOKS 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define AGV_ALLOC_VIA_SANITIZER_HOOKS 1
#endif
#endif

namespace {
std::atomic<std::uint64_t> g_allocations{0};
std::atomic<std::uint64_t> g_deallocations{0};
std::atomic<bool> g_active{false};
// Allocations made by the current thread. Constant-initialised and defined in the executable
// (this file is compiled into every test binary), so reading it never allocates.
thread_local std::uint64_t t_allocations = 0;

void countOneAllocation() noexcept {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  ++t_allocations;
}
void noteAllocation(const void* p) noexcept {
  if (p != nullptr) {
    countOneAllocation();
  }
}
void noteDeallocation(const void* p) noexcept {
  if (p != nullptr) {
    g_deallocations.fetch_add(1, std::memory_order_relaxed);
  }
}
}  // namespace

namespace agv::test {
AllocationStats allocationStats() noexcept {
  return {g_allocations.load(std::memory_order_relaxed), g_deallocations.load(std::memory_order_relaxed)};
}
std::uint64_t threadAllocations() noexcept {
  return t_allocations;
}
bool allocationCountingActive() noexcept {
  return g_active.load();
}
}  // namespace agv::test

#ifdef AGV_ALLOC_VIA_SANITIZER_HOOKS
// ---- AddressSanitizer build: the sanitizer's allocator calls these for every (de)allocation ----
// Declared by the sanitizer runtime (GCC ships no header for it).
extern "C" int __sanitizer_install_malloc_and_free_hooks(void (*malloc_hook)(const volatile void*, std::size_t),
                                                         void (*free_hook)(const volatile void*));

namespace {
void mallocHook(const volatile void* p, std::size_t /*size*/) {
  noteAllocation(const_cast<const void*>(p));
}
void freeHook(const volatile void* p) {
  noteDeallocation(const_cast<const void*>(p));
}
struct InstallHooks {
  InstallHooks() noexcept { g_active = __sanitizer_install_malloc_and_free_hooks(mallocHook, freeHook) != 0; }
} g_installHooks;
}  // namespace

#else
// ---- Normal build: replace the C allocator and every operator new/delete, forward to glibc ----
extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void* __libc_valloc(std::size_t);
void* __libc_pvalloc(std::size_t);
void __libc_free(void*);

void* malloc(std::size_t size) {
  void* p = __libc_malloc(size);
  noteAllocation(p);
  return p;
}
void* calloc(std::size_t n, std::size_t size) {
  void* p = __libc_calloc(n, size);
  noteAllocation(p);
  return p;
}
void* realloc(void* old, std::size_t size) {
  void* p = __libc_realloc(old, size);
  if (p != nullptr || size == 0) {
    countOneAllocation();  // any realloc call is heap activity
  }
  return p;
}
void* memalign(std::size_t alignment, std::size_t size) {
  void* p = __libc_memalign(alignment, size);
  noteAllocation(p);
  return p;
}
void* aligned_alloc(std::size_t alignment, std::size_t size) {
  return memalign(alignment, size);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t size) {
  if (alignment < sizeof(void*) || (alignment & (alignment - 1)) != 0) {
    return EINVAL;
  }
  void* p = memalign(alignment, size);
  if (p == nullptr) {
    return ENOMEM;
  }
  *out = p;
  return 0;
}
void* valloc(std::size_t size) {
  void* p = __libc_valloc(size);
  noteAllocation(p);
  return p;
}
void* pvalloc(std::size_t size) {
  void* p = __libc_pvalloc(size);
  noteAllocation(p);
  return p;
}
void free(void* p) {
  noteDeallocation(p);
  __libc_free(p);
}
}  // extern "C"

namespace {
struct MarkActive {
  MarkActive() noexcept { g_active = true; }
} g_markActive;

void* newOrThrow(std::size_t size) {
  void* p = malloc(size == 0 ? 1 : size);
  if (p == nullptr) {
    throw std::bad_alloc();
  }
  return p;
}
void* alignedNewOrThrow(std::size_t size, std::align_val_t al) {
  std::size_t alignment = static_cast<std::size_t>(al);
  if (alignment < sizeof(void*)) {
    alignment = sizeof(void*);
  }
  void* p = memalign(alignment, size == 0 ? 1 : size);
  if (p == nullptr) {
    throw std::bad_alloc();
  }
  return p;
}
}  // namespace

void* operator new(std::size_t size) {
  return newOrThrow(size);
}
void* operator new[](std::size_t size) {
  return newOrThrow(size);
}
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  return malloc(size == 0 ? 1 : size);
}
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept {
  return malloc(size == 0 ? 1 : size);
}
void* operator new(std::size_t size, std::align_val_t al) {
  return alignedNewOrThrow(size, al);
}
void* operator new[](std::size_t size, std::align_val_t al) {
  return alignedNewOrThrow(size, al);
}
void* operator new(std::size_t size, std::align_val_t al, const std::nothrow_t&) noexcept {
  return memalign(static_cast<std::size_t>(al) < sizeof(void*) ? sizeof(void*) : static_cast<std::size_t>(al),
                  size == 0 ? 1 : size);
}
void* operator new[](std::size_t size, std::align_val_t al, const std::nothrow_t& tag) noexcept {
  return operator new(size, al, tag);
}
void operator delete(void* p) noexcept {
  free(p);
}
void operator delete[](void* p) noexcept {
  free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  free(p);
}
void operator delete[](void* p, std::size_t) noexcept {
  free(p);
}
void operator delete(void* p, const std::nothrow_t&) noexcept {
  free(p);
}
void operator delete[](void* p, const std::nothrow_t&) noexcept {
  free(p);
}
void operator delete(void* p, std::align_val_t) noexcept {
  free(p);
}
void operator delete[](void* p, std::align_val_t) noexcept {
  free(p);
}
void operator delete(void* p, std::size_t, std::align_val_t) noexcept {
  free(p);
}
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept {
  free(p);
}
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept {
  free(p);
}
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept {
  free(p);
}
#endif
