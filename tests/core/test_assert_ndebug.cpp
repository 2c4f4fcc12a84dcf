// Half of test_assert.cpp compiled with NDEBUG whatever the build type: AGV_ASSERT must not
// evaluate its condition.
#ifndef NDEBUG
#define NDEBUG
#endif
#include "agv/core/assert.hpp"

int evaluationsWithNdebug() noexcept {
  int evaluations = 0;
  AGV_ASSERT(++evaluations < 0);
  return evaluations;
}
