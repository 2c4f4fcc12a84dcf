#include <new>

#include "agv/core/fixed_vector.hpp"
#include "agv/core/span.hpp"
#include "agv_test.hpp"
#include "counted.hpp"

using agv::test::Counted;
using agv::test::NoDefault;

namespace {
// One function for every capacity: the point of IVector.
int sumAndAppend(agv::IVector<int>& v, int extra, agv::Status* status) {
  int sum = 0;
  for (int x : v) {
    sum += x;
  }
  *status = v.push_back(extra);
  return sum;
}

struct Landmarkish {
  double x = 0.0;
  double y = 0.0;
  int hits = 1;
};
}  // namespace

TEST_CASE("FixedVector refuses and counts pushes beyond its capacity", "[core][fixed_vector]") {
  agv::FixedVector<int, 4> v;
  CHECK(v.empty());
  CHECK(v.capacity() == 4);
  for (int i = 0; i < 4; ++i) {
    CHECK(v.push_back(i * 10) == agv::Status::Ok);
  }
  CHECK(v.full());
  CHECK(v.available() == 0);
  CHECK(v.push_back(99) == agv::Status::CapacityExceeded);
  CHECK(v.append() == nullptr);
  CHECK(v.refusedCount() == 2);
  CHECK(v.size() == 4);
  CHECK(v.back() == 30);  // nothing was overwritten
  v.clear();
  CHECK(v.empty());
  CHECK(v.refusedCount() == 2);  // clear() keeps the refusal record
  v.resetRefusedCount();
  CHECK(v.refusedCount() == 0);
}

TEST_CASE("IVector serves vectors of every capacity", "[core][fixed_vector]") {
  agv::FixedVector<int, 3> small;
  agv::FixedVector<int, 100> large;
  agv::Status st = agv::Status::Ok;
  CHECK(sumAndAppend(small, 1, &st) == 0);
  CHECK(st == agv::Status::Ok);
  CHECK(sumAndAppend(small, 2, &st) == 1);
  CHECK(sumAndAppend(small, 3, &st) == 3);
  CHECK(sumAndAppend(small, 4, &st) == 6);
  CHECK(st == agv::Status::CapacityExceeded);
  for (int i = 0; i < 50; ++i) {
    (void)sumAndAppend(large, i, &st);
  }
  CHECK(large.size() == 50);
  CHECK(sumAndAppend(large, 0, &st) == 49 * 50 / 2);
}

TEST_CASE("FixedVector insert, erase and unordered erase keep the right elements", "[core][fixed_vector]") {
  agv::FixedVector<int, 8> v;
  for (int i = 0; i < 5; ++i) {
    REQUIRE(v.push_back(i) == agv::Status::Ok);  // 0 1 2 3 4
  }
  CHECK(v.insert(2, 42) == agv::Status::Ok);  // 0 1 42 2 3 4
  CHECK(v.size() == 6);
  CHECK(v[2] == 42);
  CHECK(v[3] == 2);
  CHECK(v.insert(7, 1) == agv::Status::OutOfRange);
  CHECK(v.erase(0) == agv::Status::Ok);  // 1 42 2 3 4
  CHECK(v.front() == 1);
  CHECK(v.eraseUnordered(1) == agv::Status::Ok);  // 1 4 2 3
  CHECK(v.size() == 4);
  CHECK(v[1] == 4);
  CHECK(v.erase(4) == agv::Status::OutOfRange);
  CHECK(v.eraseUnordered(10) == agv::Status::OutOfRange);
  CHECK(v.at(3) != nullptr);
  CHECK(v.at(4) == nullptr);
  v.pop_back();
  v.pop_back();
  v.pop_back();
  v.pop_back();
  v.pop_back();  // on empty: no effect
  CHECK(v.empty());
  CHECK(v.resize(9) == agv::Status::CapacityExceeded);
  CHECK(v.resize(3) == agv::Status::Ok);
  CHECK(v.size() == 3);
  CHECK(v[2] == 0);  // value-initialised
}

TEST_CASE("FixedVector copies own their storage; assign truncates and says so", "[core][fixed_vector]") {
  agv::FixedVector<Landmarkish, 6> a;
  for (int i = 0; i < 5; ++i) {
    Landmarkish* l = a.append();
    REQUIRE(l != nullptr);
    l->x = i;
    l->hits = i + 1;
  }
  agv::FixedVector<Landmarkish, 6> b = a;
  CHECK(b.size() == 5);
  CHECK(b.data() != a.data());
  b[0].x = 100.0;
  CHECK(a[0].x == 0.0);
  agv::FixedVector<Landmarkish, 6> c;
  c = b;
  CHECK(c[0].x == 100.0);
  CHECK(c[4].hits == 5);

  agv::FixedVector<Landmarkish, 3> small;
  CHECK(small.assign(a) == agv::Status::CapacityExceeded);
  CHECK(small.size() == 3);
  CHECK(small.refusedCount() == 2);
  CHECK(small[2].hits == 3);
  agv::FixedVector<Landmarkish, 16> big;
  CHECK(big.assign(a) == agv::Status::Ok);
  CHECK(big.size() == 5);
  CHECK(big.assign(big) == agv::Status::Ok);
  CHECK(big.size() == 5);
}

TEST_CASE("Span views a FixedVector or an array without copying", "[core][span]") {
  agv::FixedVector<float, 8> v;
  REQUIRE(v.push_back(1.0F) == agv::Status::Ok);
  REQUIRE(v.push_back(2.0F) == agv::Status::Ok);
  agv::Span<float> s(v);
  CHECK(s.size() == 2);
  CHECK(s.data() == v.data());
  s[1] = 5.0F;
  CHECK(v[1] == 5.0F);
  const unsigned char bytes[5] = {1, 2, 3, 4, 5};
  agv::Span<const unsigned char> b(bytes);
  CHECK(b.size() == 5);
  CHECK(b.subspan(3, 10).size() == 2);
  CHECK(b.subspan(3, 10)[0] == 4);
  CHECK(b.subspan(9, 1).empty());
}

TEST_CASE("FixedVector operations never allocate", "[core][fixed_vector][alloc]") {
  agv::FixedVector<Landmarkish, 64> v;
  agv::FixedVector<Landmarkish, 64> w;
  AGV_CHECK_NO_ALLOCATIONS({
    for (int i = 0; i < 100; ++i) {
      (void)v.push_back(Landmarkish{1.0 * i, 2.0, i});
    }
    (void)v.erase(3);
    (void)v.insert(5, Landmarkish{});
    (void)v.eraseUnordered(0);
    w = v;
    agv::FixedVector<Landmarkish, 64> copy(w);
    (void)copy.resize(10);
  });
  CHECK(v.size() == 63);  // 64 kept of 100, one erased, one inserted, one erased
  CHECK(v.refusedCount() == 36);
}

TEST_CASE("FixedVector constructs no element up front and destroys each one exactly once", "[core][fixed_vector]") {
  using Big = agv::FixedVector<Counted, 1000>;
  alignas(Big) static unsigned char buffer[sizeof(Big)];
  Counted::resetCounts();
  Big* v = ::new (static_cast<void*>(buffer)) Big();
  CHECK(Counted::constructed == 0);  // a default-constructed array would have made 1000
  CHECK(v->empty());
  for (int i = 0; i < 10; ++i) {
    REQUIRE(v->push_back(Counted(i)) == agv::Status::Ok);
  }
  CHECK(Counted::alive() == 10);  // the temporaries are gone, the 10 elements live
  REQUIRE(v->emplace_back(10) == agv::Status::Ok);
  CHECK(Counted::alive() == 11);
  Counted* appended = v->append();
  REQUIRE(appended != nullptr);
  CHECK(appended->value == -1);  // freshly constructed, not a leftover
  CHECK(Counted::alive() == 12);
  v->pop_back();
  CHECK(Counted::alive() == 11);
  REQUIRE(v->erase(2) == agv::Status::Ok);  // 0 1 3 4 ... 10
  CHECK(Counted::alive() == 10);
  CHECK((*v)[2].value == 3);
  REQUIRE(v->eraseUnordered(0) == agv::Status::Ok);  // 10 1 3 4 ... 9
  CHECK(Counted::alive() == 9);
  CHECK(v->front().value == 10);
  REQUIRE(v->insert(1, Counted(42)) == agv::Status::Ok);  // 10 42 1 3 ...
  CHECK(Counted::alive() == 10);
  CHECK((*v)[1].value == 42);
  CHECK((*v)[2].value == 1);
  REQUIRE(v->resize(25) == agv::Status::Ok);
  CHECK(Counted::alive() == 25);
  CHECK(v->back().value == -1);
  REQUIRE(v->resize(4) == agv::Status::Ok);
  CHECK(Counted::alive() == 4);
  {
    Big copy(*v);  // copies the 4 live elements only
    CHECK(Counted::alive() == 8);
    REQUIRE(copy.push_back(Counted(7)) == agv::Status::Ok);
    CHECK(Counted::alive() == 9);
    copy = *v;  // shrinks back to 4: the surplus element is destroyed
    CHECK(Counted::alive() == 8);
    agv::FixedVector<Counted, 2> small;
    CHECK(small.assign(copy) == agv::Status::CapacityExceeded);
    CHECK(Counted::alive() == 10);
    CHECK(small[1].value == 42);
  }
  CHECK(Counted::alive() == 4);
  v->clear();
  CHECK(Counted::alive() == 0);
  REQUIRE(v->push_back(Counted(1)) == agv::Status::Ok);
  v->~Big();
  CHECK(Counted::alive() == 0);  // the destructor destroyed the live element
  CHECK(Counted::constructed > 0);
}

TEST_CASE("FixedVector works with a type that has no default constructor", "[core][fixed_vector]") {
  agv::FixedVector<NoDefault, 4> v;
  CHECK(v.push_back(NoDefault(1)) == agv::Status::Ok);
  CHECK(v.emplace_back(2) == agv::Status::Ok);
  CHECK(v.insert(0, NoDefault(0)) == agv::Status::Ok);  // 0 1 2
  CHECK(v.insert(1, v[2]) == agv::Status::Ok);          // an element of the vector itself: 0 2 1 2
  CHECK(v.size() == 4);
  CHECK(v[0].value == 0);
  CHECK(v[1].value == 2);
  CHECK(v[2].value == 1);
  CHECK(v[3].value == 2);
  CHECK(v.emplace_back(5) == agv::Status::CapacityExceeded);
  CHECK(v.refusedCount() == 1);
  CHECK(v.erase(0) == agv::Status::Ok);  // 2 1 2
  CHECK(v.front().value == 2);
  agv::FixedVector<NoDefault, 4> w(v);
  CHECK(v.eraseUnordered(0) == agv::Status::Ok);  // 2 1
  CHECK(v.back().value == 1);
  w = v;
  CHECK(w.size() == 2);
  CHECK(w[0].value == 2);
  CHECK(w[1].value == 1);
  agv::FixedVector<NoDefault, 8> big;
  CHECK(big.assign(w) == agv::Status::Ok);
  CHECK(big.size() == 2);
  big.pop_back();
  CHECK(big.size() == 1);
  CHECK(big[0].value == 2);
}
