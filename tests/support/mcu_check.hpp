#pragma once
/// @file mcu_check.hpp
/// Minimal test registry and checks for the bare-metal MCU test image (no heap, no exceptions,
/// no stdio). Spelled like the Catch2 subset listed in agv_test.hpp. Output goes through ARM
/// semihosting; the image's exit code is the verdict.

namespace agv::mcutest {

using TestFn = void (*)();

/// Registers a test case at static-initialisation time. Capacity: kMaxTests.
struct Registrar {
  Registrar(const char* name, TestFn fn) noexcept;
};

/// Records a failed check (prints file:line and the expression).
void fail(const char* file, int line, const char* expr) noexcept;

/// Runs every registered test; returns the number of failed test cases plus runner errors (no test
/// ran, fewer run than registered, stack guard overwritten, registry overflow): 0 = pass.
int runAll() noexcept;

}  // namespace agv::mcutest

#define AGV_MCU_CAT2(a, b) a##b
#define AGV_MCU_CAT(a, b) AGV_MCU_CAT2(a, b)
#define AGV_MCU_TEST_IMPL(fn, name)                                        \
  static void fn();                                                        \
  static const ::agv::mcutest::Registrar AGV_MCU_CAT(fn, _reg)(name, &fn); \
  static void fn()
#define TEST_CASE(name, ...) AGV_MCU_TEST_IMPL(AGV_MCU_CAT(agv_mcu_test_, __LINE__), name)

#define CHECK(...)                                            \
  do {                                                        \
    if (!(__VA_ARGS__)) {                                     \
      ::agv::mcutest::fail(__FILE__, __LINE__, #__VA_ARGS__); \
    }                                                         \
  } while (0)
#define CHECK_FALSE(...) CHECK(!(__VA_ARGS__))
#define REQUIRE(...)                                          \
  do {                                                        \
    if (!(__VA_ARGS__)) {                                     \
      ::agv::mcutest::fail(__FILE__, __LINE__, #__VA_ARGS__); \
      return;                                                 \
    }                                                         \
  } while (0)
#define REQUIRE_FALSE(...) REQUIRE(!(__VA_ARGS__))
// Context messages need a string stream: not on the MCU. The message is not evaluated.
#define INFO(...) \
  do {            \
  } while (0)
