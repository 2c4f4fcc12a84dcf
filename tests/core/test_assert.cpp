// AGV_ASSERT: active without NDEBUG (this file undefines it whatever the build type), compiled out
// with it (test_assert_ndebug.cpp); the containers' checked accessors stop a program on an index
// past size() or on an empty container. Each failing access runs in a child process, whose
// assertion handler reports the condition through its exit status. Host only (fork).
#undef NDEBUG
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstring>

#include "agv/core/assert.hpp"
#include "agv/core/fixed_ring.hpp"
#include "agv/core/fixed_vector.hpp"
#include "agv_test.hpp"

// Defined in test_assert_ndebug.cpp, compiled with NDEBUG: how often AGV_ASSERT there evaluated
// its condition (0 when compiled out).
int evaluationsWithNdebug() noexcept;

namespace {

// Local element types: their container instantiations exist only in this file, so compiling them
// with assertions on here cannot clash with other files compiled with NDEBUG.
struct Probe {
  int v = 0;
};

// The child's handler: exit status 3 when the failed condition is `g_expected`, 4 otherwise.
const char* g_expected = "";
void exitWithVerdict(const char* condition, const char* /*file*/, int /*line*/) noexcept {
  _exit(std::strcmp(condition, g_expected) == 0 ? 3 : 4);
}

/// Runs `body` in a child process; its exit status: 3 = the expected assertion failed, 4 = another
/// one, 0 = none (body returned), -1 = killed by a signal (e.g. abort without the handler).
template <typename F>
int childStatus(const char* expected, F body) {
  const pid_t pid = fork();
  if (pid == 0) {
    g_expected = expected;
    (void)agv::setAssertionHandler(&exitWithVerdict);
    body();
    _exit(0);
  }
  int status = 0;
  if (pid < 0 || waitpid(pid, &status, 0) != pid) {
    return -2;
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace

TEST_CASE("AGV_ASSERT stops on a false condition, runs the handler, and is compiled out with NDEBUG",
          "[core][assert]") {
  CHECK(childStatus("1 + 1 == 3", [] { AGV_ASSERT(1 + 1 == 3); }) == 3);
  CHECK(childStatus("1 + 1 == 3", [] { AGV_ASSERT(1 + 1 == 2); }) == 0);
  // Without a handler the program aborts (a signal, not an exit).
  const pid_t pid = fork();
  if (pid == 0) {
    AGV_ASSERT(sizeof(int) == 0);
    _exit(0);
  }
  int status = 0;
  REQUIRE(waitpid(pid, &status, 0) == pid);
  CHECK(WIFSIGNALED(status));
  // Compiled out: the condition is not even evaluated.
  CHECK(evaluationsWithNdebug() == 0);
  // setAssertionHandler returns the previous handler.
  CHECK(agv::setAssertionHandler(&exitWithVerdict) == nullptr);
  CHECK(agv::setAssertionHandler(nullptr) == &exitWithVerdict);
}

TEST_CASE("FixedVector element access is checked in debug builds", "[core][assert][fixed_vector]") {
  CHECK(childStatus("i < size_", [] {
          agv::FixedVector<Probe, 4> v;
          (void)v.push_back(Probe{1});
          (void)v.push_back(Probe{2});
          volatile int x = v[1].v;  // in range: fine
          (void)x;
          v.pop_back();
          x = v[1].v;  // past size(): the slot holds no element any more
        }) == 3);
  CHECK(childStatus("i < size_", [] {
          const agv::FixedVector<Probe, 4> v;
          volatile int x = v[0].v;
          (void)x;
        }) == 3);
  CHECK(childStatus("size_ > 0", [] {
          agv::FixedVector<Probe, 4> v;
          v.front().v = 1;
        }) == 3);
  CHECK(childStatus("size_ > 0", [] {
          agv::FixedVector<Probe, 4> v;
          (void)v.push_back(Probe{1});
          v.clear();
          v.back().v = 1;
        }) == 3);
  CHECK(childStatus("i < size_", [] {
          agv::FixedVector<Probe, 4> v;
          (void)v.push_back(Probe{1});
          v[0].v = 2;
          v.front().v = 3;
          v.back().v = 4;
        }) == 0);
}

TEST_CASE("FixedRing element access is checked in debug builds", "[core][assert][fixed_ring]") {
  CHECK(childStatus("k < size_", [] {
          agv::FixedRing<Probe, 3> r;
          for (int i = 0; i < 5; ++i) {
            (void)r.push(Probe{i});
          }
          volatile int x = r[2].v;  // in range: fine
          r.pop_front();
          x = r[2].v;  // past size()
          (void)x;
        }) == 3);
  CHECK(childStatus("size_ > 0", [] {
          const agv::FixedRing<Probe, 3> r;
          volatile int x = r.front().v;
          (void)x;
        }) == 3);
  CHECK(childStatus("size_ > 0", [] {
          agv::FixedRing<Probe, 3> r;
          (void)r.push(Probe{1});
          r.clear();
          r.back().v = 1;
        }) == 3);
}
