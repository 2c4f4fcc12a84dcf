// Test runner of the bare-metal MCU image: see mcu_check.hpp.
#include "mcu_check.hpp"

#include "semihosting.h"

namespace agv::mcutest {
namespace {
constexpr int kMaxTests = 256;
struct Entry {
  const char* name;
  TestFn fn;
};
Entry g_tests[kMaxTests];
int g_testCount = 0;
int g_overflow = 0;
int g_failures = 0;

}  // namespace

Registrar::Registrar(const char* name, TestFn fn) noexcept {
  if (g_testCount < kMaxTests) {
    g_tests[g_testCount++] = Entry{name, fn};
  } else {
    ++g_overflow;
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
  int failedCases = 0;
  for (int i = 0; i < g_testCount; ++i) {
    const int before = g_failures;
    g_tests[i].fn();
    const bool ok = g_failures == before;
    semihosting_write0(ok ? "[pass] " : "[FAIL] ");
    semihosting_write0(g_tests[i].name);
    semihosting_write0("\n");
    failedCases += ok ? 0 : 1;
  }
  if (g_overflow != 0) {
    semihosting_write0("too many test cases for the MCU runner (kMaxTests)\n");
    ++failedCases;
  }
  semihosting_write_int(g_testCount - failedCases);
  semihosting_write0(" passed, ");
  semihosting_write_int(failedCases);
  semihosting_write0(" failed\n");
  return failedCases;
}

}  // namespace agv::mcutest

int main() {
  return agv::mcutest::runAll() == 0 ? 0 : 1;
}
