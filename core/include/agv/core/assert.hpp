#pragma once
/// @file assert.hpp
/// `AGV_ASSERT(condition)`: a debug check of a caller's precondition (an index below `size()`, a
/// non-empty container). Active when `NDEBUG` is not defined (Debug builds, the `asan` preset),
/// compiled out otherwise (Release, RelWithDebInfo, MinSizeRel): the condition is then not even
/// evaluated, so it must have no side effects.
///
/// Not for errors of data or of the environment: those are `Status` values (status.hpp). A failed
/// assertion is a programming error; it calls `assertionFailed()`, which runs the handler installed
/// with `setAssertionHandler()` (if any) and then `std::abort()`. The core neither prints nor
/// formats: a program that wants a message installs a handler that writes one (a log line, a
/// semihosting call on the MCU). Nothing here needs more than `abort()` from the C library, which
/// newlib provides on bare metal (the Cortex-M7 start-up code replaces it with a semihosting exit).

namespace agv {

/// Receives a failed assertion: the condition as written, the file and the line. It may stop the
/// program itself (log and reset, exit); if it returns, `std::abort()` follows.
using AssertionHandler = void (*)(const char* condition, const char* file, int line) noexcept;

/// Installs `handler` (nullptr: none, the default) and returns the previous one. Meant to be called
/// once at start-up, before any other thread runs: the handler is a plain global.
AssertionHandler setAssertionHandler(AssertionHandler handler) noexcept;

/// Called by a failed `AGV_ASSERT`: runs the installed handler, then `std::abort()`. Never returns.
[[noreturn]] void assertionFailed(const char* condition, const char* file, int line) noexcept;

}  // namespace agv

#ifdef NDEBUG
#define AGV_ASSERT(condition) static_cast<void>(0)
#else
#define AGV_ASSERT(condition) \
  (static_cast<bool>(condition) ? static_cast<void>(0) : ::agv::assertionFailed(#condition, __FILE__, __LINE__))
#endif
