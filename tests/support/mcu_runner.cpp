// Test runner of the bare-metal MCU image: see mcu_check.hpp.
//
// The verdict must not be "pass" when the image did not really run its tests: a stack overflow
// (the stack sits right above .bss and grows down into it) or any other stray write can clobber
// the test list, and a list walked as empty used to print "0 passed, 0 failed" and exit 0. So the
// runner fails when
// - no test ran at all,
// - the number of tests run differs from the number registered (counted at registration, apart
//   from the list, and kept with its complement so that a clobbered count is seen),
// - the guard words at the bottom of the stack region are overwritten (stack overflow),
// - the registry overflowed (more than kMaxTests test cases).
#include <cstdint>

#include "mcu_check.hpp"
#include "semihosting.h"

extern "C" std::uint32_t _ebss;  // end of .bss = bottom of the stack region (mps2_an500.ld)

namespace agv::mcutest {
namespace {
#ifndef AGV_MCU_MAX_TESTS
#define AGV_MCU_MAX_TESTS 256
#endif
constexpr int kMaxTests = AGV_MCU_MAX_TESTS;
struct Entry {
  const char* name;
  TestFn fn;
};
Entry g_tests[kMaxTests];
int g_testCount = 0;
int g_failures = 0;
// Registrations counted apart from the list; the complement is only ever written together with
// the count, so a stray write to either shows up as a mismatch.
volatile std::uint32_t g_registered = 0;
volatile std::uint32_t g_registeredComplement = ~std::uint32_t{0};

// Stack guard: the lowest words of the stack region (the stack grows down from _estack to here).
constexpr int kGuardWords = 16;
constexpr std::uint32_t kGuardPattern = 0xDEADC0DEU;
volatile std::uint32_t* stackGuard() noexcept {
  // The .stack section starts at the next 8-byte boundary after _ebss.
  const auto bottom = (reinterpret_cast<std::uintptr_t>(&_ebss) + 7U) & ~std::uintptr_t{7};
  return reinterpret_cast<volatile std::uint32_t*>(bottom);
}
void paintStackGuard() noexcept {
  volatile std::uint32_t* g = stackGuard();
  for (int i = 0; i < kGuardWords; ++i) {
    g[i] = kGuardPattern;
  }
}
bool stackGuardIntact() noexcept {
  const volatile std::uint32_t* g = stackGuard();
  for (int i = 0; i < kGuardWords; ++i) {
    if (g[i] != kGuardPattern) {
      return false;
    }
  }
  return true;
}

}  // namespace

Registrar::Registrar(const char* name, TestFn fn) noexcept {
  const std::uint32_t n = g_registered + 1U;
  g_registered = n;
  g_registeredComplement = ~n;
  if (g_testCount < kMaxTests) {
    g_tests[g_testCount++] = Entry{name, fn};
  }
}

void fail(const char* file, int line, const char* expr) noexcept {
  ++g_failures;
  semihosting_write0("  FAILED ");
  semihosting_write0(file);
  semihosting_write0(":");
  semihosting_write_int(line);
  semihosting_write0(": ");
  semihosting_write0(expr);
  semihosting_write0("\n");
}

int runAll() noexcept {
  paintStackGuard();
  int failedCases = 0;
  int ran = 0;
  bool stackOk = true;
  const int listed = g_testCount;
  for (int i = 0; i < listed && i < kMaxTests; ++i) {
    const int before = g_failures;
    g_tests[i].fn();
    ++ran;
    if (!stackGuardIntact()) {  // before touching the list again: it may be what was overwritten
      semihosting_write0("stack overflow: the guard below the 64 KiB stack was overwritten by test ");
      semihosting_write_int(i + 1);
      semihosting_write0("\n");
      stackOk = false;
      break;
    }
    const bool ok = g_failures == before;
    semihosting_write0(ok ? "[pass] " : "[FAIL] ");
    semihosting_write0(g_tests[i].name);
    semihosting_write0("\n");
    failedCases += ok ? 0 : 1;
  }
  const std::uint32_t registered = g_registered;
  const bool countIntact = registered == ~g_registeredComplement;
  int errors = 0;
  if (!stackOk) {
    ++errors;
  }
  if (!countIntact) {
    semihosting_write0("the registration count was overwritten (stray write or stack overflow)\n");
    ++errors;
  }
  if (registered > static_cast<std::uint32_t>(kMaxTests)) {
    semihosting_write0("too many test cases for the MCU runner (kMaxTests)\n");
    ++errors;
  }
  if (ran == 0) {
    semihosting_write0("no test ran: an image without tests (or with a clobbered test list) fails\n");
    ++errors;
  } else if (countIntact && stackOk && static_cast<std::uint32_t>(ran) != registered) {
    semihosting_write0("ran ");
    semihosting_write_int(ran);
    semihosting_write0(" tests but ");
    semihosting_write_int(static_cast<long long>(registered));
    semihosting_write0(" were registered\n");
    ++errors;
  }
  semihosting_write_int(ran - failedCases);
  semihosting_write0(" passed, ");
  semihosting_write_int(failedCases);
  semihosting_write0(" failed of ");
  semihosting_write_int(static_cast<long long>(registered));
  semihosting_write0(" registered\n");
  return failedCases + errors;
}

}  // namespace agv::mcutest

int main() {
  return agv::mcutest::runAll() == 0 ? 0 : 1;
}
