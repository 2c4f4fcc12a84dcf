#include "agv/core/assert.hpp"

#include <cstdlib>

namespace agv {

namespace {
// Set once at start-up (see setAssertionHandler); read only when an assertion fails.
AssertionHandler g_assertionHandler = nullptr;  // NOLINT(cppcoreguidelines-avoid-non-const-global-variables)
}  // namespace

AssertionHandler setAssertionHandler(AssertionHandler handler) noexcept {
  const AssertionHandler previous = g_assertionHandler;
  g_assertionHandler = handler;
  return previous;
}

void assertionFailed(const char* condition, const char* file, int line) noexcept {
  if (g_assertionHandler != nullptr) {
    g_assertionHandler(condition, file, line);
  }
  std::abort();
}

}  // namespace agv
