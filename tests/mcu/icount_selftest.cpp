// Self-test of the Cortex-M7 instruction counter: a loop of known length must measure right.
#include <cstdint>
#include <initializer_list>

#include "instruction_counter.h"
#include "semihosting.h"

namespace {

__attribute__((noinline)) void loop(std::uint32_t n) {
  __asm__ volatile(
      "1:\n\t"
      "subs %0, %0, #1\n\t"
      "bne 1b\n\t"
      : "+r"(n)
      :
      : "cc");
}
}  // namespace

int main() {
  const std::uint32_t per1024 = agv_icount_init();
  if (per1024 == 0U) {
    semihosting_write0("SysTick does not advance: run QEMU with -icount shift=0\n");
    return 1;
  }
  int failures = 0;
  for (std::uint32_t n : {50000U, 3000000U, 20000000U}) {  // the last spans several SysTick wraps
    const std::uint64_t t0 = agv_icount_ticks();
    loop(n);
    const std::uint64_t t1 = agv_icount_ticks();
    const std::uint64_t measured = agv_icount_instructions(t1 - t0);
    const std::uint64_t expected = 2ULL * n;
    const std::uint64_t diff = measured > expected ? measured - expected : expected - measured;
    semihosting_write0("loop of ");
    semihosting_write_int(static_cast<long long>(expected));
    semihosting_write0(" instructions measured as ");
    semihosting_write_int(static_cast<long long>(measured));
    semihosting_write0("\n");
    if (diff * 100U > expected) {  // within 1 %
      ++failures;
    }
  }
  return failures == 0 ? 0 : 1;
}
