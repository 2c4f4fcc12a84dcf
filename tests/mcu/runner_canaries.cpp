// Test cases of the MCU runner's canary images (tests/CMakeLists.txt): each image must FAIL, for
// the reason its test names.
//   AGV_CANARY_THREE_TESTS: three trivial passing tests, linked with a runner whose list holds two
//     (AGV_MCU_MAX_TESTS=2): the runner walks 2 of 3 registered tests and must report the mismatch.
//   AGV_CANARY_STACK_OVERFLOW: one test that runs the stack about 1 KiB past the bottom of its
//     region (into .bss), as a too-deep test would; the runner's stack guard must see it.
#include <cstdint>

#include "agv_test.hpp"

#if defined(AGV_CANARY_THREE_TESTS)
TEST_CASE("canary 1", "[mcu]") {
  CHECK(1 + 1 == 2);
}
TEST_CASE("canary 2", "[mcu]") {
  CHECK(2 + 2 == 4);
}
TEST_CASE("canary 3", "[mcu]") {
  CHECK(3 + 3 == 6);
}
#elif defined(AGV_CANARY_STACK_OVERFLOW)
extern "C" std::uint32_t _ebss;  // bottom of the stack region (mps2_an500.ld)

namespace {
// Each level fills a 512-byte frame and recurses until a frame lies below `limit`; the write after
// the call keeps the compiler from turning the recursion into a loop.
__attribute__((noinline)) int dig(std::uintptr_t limit) {
  volatile std::uint8_t frame[512];
  for (auto& b : frame) {
    b = 0xA5;
  }
  int depth = 1;
  if (reinterpret_cast<std::uintptr_t>(&frame[0]) > limit) {
    depth += dig(limit);
  }
  frame[0] = static_cast<std::uint8_t>(depth);
  return depth;
}
}  // namespace

TEST_CASE("runs the stack past its bottom", "[mcu]") {
  const auto bottom = reinterpret_cast<std::uintptr_t>(&_ebss);
  CHECK(dig(bottom - 1024U) > 0);
}
#else
#error "define AGV_CANARY_THREE_TESTS or AGV_CANARY_STACK_OVERFLOW"
#endif
