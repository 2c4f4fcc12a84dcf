#include "agv/core/timestamp.hpp"
#include "agv_test.hpp"

TEST_CASE("Duration converts units exactly and rounds seconds to the nearest ns", "[core][time]") {
  CHECK(agv::Duration::fromMilliseconds(50).ns == 50000000);
  CHECK(agv::Duration::fromMicroseconds(-3).ns == -3000);
  CHECK(agv::Duration::fromSeconds(0.05).ns == 50000000);
  CHECK(agv::Duration::fromSeconds(1e-9 * 0.6).ns == 1);
  CHECK(agv::Duration::fromSeconds(-1e-9 * 0.6).ns == -1);
  CHECK(agv::Duration::fromSeconds(-2.5).ns == -2500000000LL);
  AGV_CHECK_NEAR(agv::Duration::fromNanoseconds(1234567).seconds(), 1.234567e-3, 1e-15);
}

TEST_CASE("Timestamp arithmetic is exact over a year of uptime", "[core][time]") {
  const std::int64_t year_ns = 365LL * 24 * 3600 * 1000000000LL;
  const agv::Timestamp t0 = agv::Timestamp::fromNanoseconds(year_ns);
  const agv::Timestamp t1 = t0 + agv::Duration::fromNanoseconds(1);
  CHECK((t1 - t0).ns == 1);  // a double in seconds could not tell these apart
  CHECK(t1 > t0);
  CHECK(t0 < t1);
  CHECK(t0 <= t0);
  CHECK(t0 != t1);
  CHECK((t1 - agv::Duration::fromNanoseconds(1)) == t0);
  CHECK((t0 - t1) == -(t1 - t0));
  CHECK(agv::Timestamp::fromSeconds(12.5).ns == 12500000000LL);
  CHECK(agv::Duration::fromMilliseconds(20) < agv::Duration::fromMilliseconds(50));
  CHECK(agv::Duration::fromMilliseconds(20) + agv::Duration::fromMilliseconds(30) ==
        agv::Duration::fromMilliseconds(50));
}
