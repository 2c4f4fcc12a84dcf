#pragma once
/// @file agv_test.hpp
/// The one include of every core test. On Linux targets it is Catch2; on the bare-metal MCU image
/// (AGV_TEST_MCU) it is a tiny runner with the same spelling for the subset core tests may use on
/// both: TEST_CASE(name, tags), CHECK, REQUIRE, CHECK_FALSE, REQUIRE_FALSE, and AGV_CHECK_NEAR
/// (INFO compiles on both and is a no-op on the MCU).
/// Tests that need more of Catch2 (SECTION, generators, matchers) are host-only: register them
/// without the MCU flag in CMake.
///
/// Emulated targets: the cross Linux trees (aarch64, armhf under qemu-user) compile every test with
/// AGV_TEST_EMULATED, the MCU image with AGV_TEST_MCU. Both run 8-12x slower than the host, so a
/// Monte-Carlo case may run fewer trials there with the same checks: the target's arithmetic is
/// exercised on every code path, and the rates over many trials are the native tree's to show.

#ifdef AGV_TEST_MCU
#include "mcu_check.hpp"
#else
#include <catch.hpp>
#endif

#include <cmath>

/// |a - b| <= tol, printed with both values on failure (Catch2) or the expression (MCU).
#define AGV_CHECK_NEAR(a, b, tol) \
  CHECK(std::fabs(static_cast<double>(a) - static_cast<double>(b)) <= static_cast<double>(tol))
#define AGV_REQUIRE_NEAR(a, b, tol) \
  REQUIRE(std::fabs(static_cast<double>(a) - static_cast<double>(b)) <= static_cast<double>(tol))

#ifdef AGV_TEST_MCU
// On the MCU no allocator is linked at all (the image's symbol check proves it), so a block that
// allocates cannot even build there; the check just runs the block.
#define AGV_CHECK_NO_ALLOCATIONS(...) \
  do {                                \
    __VA_ARGS__;                      \
  } while (0)
#else
#include "alloc_counter.hpp"
/// Runs the statements and checks that they performed no heap allocation of any kind.
#define AGV_CHECK_NO_ALLOCATIONS(...) CHECK(::agv::test::countAllocations([&]() { __VA_ARGS__; }) == 0U)
#endif
