#pragma once
/// @file vm_alloc_count.hpp
/// Heap allocation calls of the statically linked VM test (see vm_alloc_count.cpp).
#include <cstdint>

namespace agv::test {
/// malloc/calloc/realloc/posix_memalign/aligned_alloc calls since program start.
std::uint64_t vmAllocationCalls() noexcept;
}  // namespace agv::test
