// AGV_ASSERT on the bare-metal Cortex-M7: this image is compiled without NDEBUG (see
// tests/CMakeLists.txt), reads a FixedVector past its size, and must end in the assertion handler
// with the expected condition. Exit 0 only from the handler; reaching the end of main fails.
#include <cstring>

#include "agv/core/assert.hpp"
#include "agv/core/fixed_vector.hpp"
#include "semihosting.h"

namespace {
struct Probe {
  int v = 0;
};

void report(const char* condition, const char* file, int line) noexcept {
  semihosting_write0("AGV_ASSERT failed: ");
  semihosting_write0(condition);
  semihosting_write0(" at ");
  semihosting_write0(file);
  semihosting_write0(":");
  semihosting_write_int(line);
  semihosting_write0("\n");
  semihosting_exit(std::strcmp(condition, "i < size_") == 0 ? 0 : 1);
}
}  // namespace

int main() {
#ifdef NDEBUG
  semihosting_write0("compiled with NDEBUG: AGV_ASSERT is off in this image\n");
  return 1;
#else
  (void)agv::setAssertionHandler(&report);
  static agv::FixedVector<Probe, 8> v;
  (void)v.push_back(Probe{1});
  volatile int x = v[0].v;  // in range: no assertion
  x = v[1].v;               // past size(): must not return
  (void)x;
  semihosting_write0("no assertion for an index past size()\n");
  return 1;
#endif
}
