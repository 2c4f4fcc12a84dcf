// FixedRing: order from the oldest to the newest, wrap-around, overwrite (push) versus refusal
// (tryPush), clear, capacity 1, element lifetime; no allocation. Portable subset (MCU image too).
#include <cstdint>
#include <new>

#include "agv/core/fixed_ring.hpp"
#include "agv_test.hpp"
#include "counted.hpp"

using agv::FixedRing;
using agv::Status;
using agv::test::Counted;
using agv::test::NoDefault;

namespace {

/// True when `r` holds exactly first, first + 1, ..., first + n - 1 from the oldest to the newest,
/// seen through operator[], front() and back().
template <std::size_t N>
bool holdsRun(const FixedRing<int, N>& r, int first, std::size_t n) {
  if (r.size() != n || r.empty() != (n == 0) || r.full() != (n == N)) {
    return false;
  }
  for (std::size_t k = 0; k < n; ++k) {
    if (r[k] != first + static_cast<int>(k)) {
      return false;
    }
  }
  return n == 0 || (r.front() == first && r.back() == first + static_cast<int>(n) - 1);
}

}  // namespace

TEST_CASE("FixedRing keeps the order from the oldest to the newest across wrap-arounds", "[core][fixed_ring]") {
  FixedRing<int, 4> r;
  CHECK(r.capacity() == 4U);
  CHECK(FixedRing<int, 4>::kCapacity == 4U);
  CHECK(holdsRun(r, 0, 0));
  for (int v = 1; v <= 4; ++v) {
    CHECK_FALSE(r.push(v));  // room left: nothing dropped
  }
  CHECK(holdsRun(r, 1, 4));
  CHECK(r.push(5));  // full: 1 dropped
  CHECK(holdsRun(r, 2, 4));
  for (int v = 6; v <= 11; ++v) {
    CHECK(r.push(v));
  }
  CHECK(holdsRun(r, 8, 4));  // the storage wrapped more than once
  r.pop_front();
  CHECK(holdsRun(r, 9, 3));
  CHECK_FALSE(r.push(12));  // room again after the pop
  CHECK(holdsRun(r, 9, 4));
  r[1] = 100;  // write access through operator[] reaches the same element
  CHECK(r[1] == 100);
  r.front() = 90;
  r.back() = 120;
  CHECK(r[0] == 90);
  CHECK(r[3] == 120);
  CHECK(r.refusedCount() == 0U);  // push never refuses
}

TEST_CASE("FixedRing matches a reference FIFO over random pushes and pops", "[core][fixed_ring]") {
  // Reference: an unbounded run of values [lo, hi) of which the ring must hold the newest N.
  FixedRing<int, 7> r;
  std::uint32_t state = 12345U;
  int lo = 0;
  int hi = 0;
  int next = 0;
  bool ok = true;
  for (int step = 0; step < 2000 && ok; ++step) {
    state = state * 1664525U + 1013904223U;
    const std::uint32_t op = (state >> 16) % 8U;
    if (op < 5U) {
      const bool dropped = r.push(next++);
      ++hi;
      ok = ok && dropped == (hi - lo > 7);
      if (hi - lo > 7) {
        ++lo;
      }
    } else if (op < 7U) {
      r.pop_front();
      if (hi > lo) {
        ++lo;
      }
    } else {
      const Status s = r.tryPush(next);
      if (hi - lo < 7) {
        ok = ok && s == Status::Ok;
        ++next;
        ++hi;
      } else {
        ok = ok && s == Status::CapacityExceeded;
      }
    }
    ok = ok && holdsRun(r, lo, static_cast<std::size_t>(hi - lo));
  }
  CHECK(ok);
  CHECK(next > 500);  // the walk went round the storage many times
}

TEST_CASE("FixedRing tryPush refuses and counts when full; push overwrites the oldest", "[core][fixed_ring]") {
  FixedRing<int, 3> r;
  CHECK(r.tryPush(1) == Status::Ok);
  CHECK(r.tryPush(2) == Status::Ok);
  CHECK(r.tryPush(3) == Status::Ok);
  CHECK(r.full());
  CHECK(r.tryPush(4) == Status::CapacityExceeded);
  CHECK(r.tryPush(5) == Status::CapacityExceeded);
  CHECK(r.refusedCount() == 2U);
  CHECK(holdsRun(r, 1, 3));  // refused: nothing changed
  CHECK(r.push(4));          // the overwriting variant drops the oldest instead, not counted
  CHECK(holdsRun(r, 2, 3));
  CHECK(r.refusedCount() == 2U);
  r.clear();
  CHECK(r.refusedCount() == 2U);  // clear() keeps the refusal record
  r.resetRefusedCount();
  CHECK(r.refusedCount() == 0U);
}

TEST_CASE("FixedRing clear empties it at any wrap position", "[core][fixed_ring]") {
  FixedRing<int, 5> r;
  for (int v = 0; v < 13; ++v) {
    (void)r.push(v);
  }
  CHECK(holdsRun(r, 8, 5));
  r.clear();
  CHECK(holdsRun(r, 0, 0));
  r.pop_front();  // on empty: no effect
  CHECK(r.empty());
  for (int v = 20; v < 23; ++v) {
    CHECK_FALSE(r.push(v));
  }
  CHECK(holdsRun(r, 20, 3));
}

TEST_CASE("FixedRing of capacity 1 holds the newest element only", "[core][fixed_ring]") {
  FixedRing<int, 1> r;
  CHECK(r.empty());
  CHECK_FALSE(r.push(7));
  CHECK(r.full());
  CHECK(r.front() == 7);
  CHECK(r.back() == 7);
  CHECK(r.push(8));
  CHECK(r.size() == 1U);
  CHECK(r[0] == 8);
  CHECK(r.tryPush(9) == Status::CapacityExceeded);
  CHECK(r[0] == 8);
  r.pop_front();
  CHECK(r.empty());
  CHECK(r.tryPush(10) == Status::Ok);
  CHECK(r.back() == 10);
}

TEST_CASE("FixedRing copies keep the order and own their elements", "[core][fixed_ring]") {
  FixedRing<int, 4> a;
  for (int v = 0; v < 6; ++v) {
    (void)a.push(v);
  }
  (void)a.tryPush(99);  // refused, counted
  FixedRing<int, 4> b(a);
  CHECK(holdsRun(b, 2, 4));
  CHECK(b.refusedCount() == 1U);
  b[0] = 50;
  CHECK(a[0] == 2);
  FixedRing<int, 4> c;
  (void)c.push(-1);
  c = a;
  CHECK(holdsRun(c, 2, 4));
  CHECK(c.push(6));
  CHECK(holdsRun(c, 3, 4));
  CHECK(holdsRun(a, 2, 4));
}

TEST_CASE("FixedRing constructs elements when pushed and destroys each exactly once", "[core][fixed_ring]") {
  using Ring = FixedRing<Counted, 8>;
  alignas(Ring) static unsigned char buffer[sizeof(Ring)];
  Counted::resetCounts();
  Ring* r = ::new (static_cast<void*>(buffer)) Ring();
  CHECK(Counted::constructed == 0);  // an empty ring constructs no element
  const Counted seed(0);
  for (int v = 1; v <= 20; ++v) {
    Counted c(v);
    (void)r->push(c);
    CHECK(Counted::alive() == 2 + static_cast<int>(r->size()));  // seed, c and the ring's elements
  }
  CHECK(r->size() == 8U);
  CHECK(r->front().value == 13);
  CHECK(r->back().value == 20);
  // Pushing the oldest element itself when full: it becomes the newest, nothing is lost.
  CHECK(r->push(r->front()));
  CHECK(r->back().value == 13);
  CHECK(r->back().live);
  CHECK(r->front().value == 14);
  CHECK(Counted::alive() == 1 + 8);
  CHECK(r->tryPush(seed) == Status::CapacityExceeded);
  CHECK(Counted::alive() == 1 + 8);  // a refused push constructs nothing
  r->pop_front();
  r->pop_front();
  CHECK(Counted::alive() == 1 + 6);
  {
    Ring copy(*r);
    CHECK(Counted::alive() == 1 + 12);
    CHECK(copy[5].value == 13);
    copy.clear();
    CHECK(Counted::alive() == 1 + 6);
    (void)copy.push(seed);
    copy = *r;
    CHECK(Counted::alive() == 1 + 12);
  }
  CHECK(Counted::alive() == 1 + 6);  // the copy's destructor destroyed its elements
  r->~Ring();
  CHECK(Counted::alive() == 1);  // only `seed` is left
}

TEST_CASE("FixedRing works with a type that has no default constructor", "[core][fixed_ring]") {
  FixedRing<NoDefault, 3> r;
  for (int v = 0; v < 5; ++v) {
    (void)r.push(NoDefault(v));
  }
  CHECK(r.size() == 3U);
  CHECK(r[0].value == 2);
  CHECK(r[2].value == 4);
  CHECK(r.tryPush(NoDefault(9)) == Status::CapacityExceeded);
}

TEST_CASE("FixedRing operations never allocate", "[core][fixed_ring][alloc]") {
  static FixedRing<Counted, 64> r;
  AGV_CHECK_NO_ALLOCATIONS({
    for (int v = 0; v < 200; ++v) {
      (void)r.push(Counted(v));
    }
    r.pop_front();
    (void)r.tryPush(Counted(1));
    (void)r.tryPush(Counted(2));
    FixedRing<Counted, 64> copy(r);
    r = copy;
  });
  CHECK(r.size() == 64U);
  CHECK(r.back().value == 1);
  CHECK(r.refusedCount() == 1U);
}
