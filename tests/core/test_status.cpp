#include <cstring>

#include "agv/core/result.hpp"
#include "agv/core/status.hpp"
#include "agv_test.hpp"

namespace {
agv::Result<double> safeSqrt(double v) {
  if (!(v == v)) {
    return agv::Status::NonFiniteInput;
  }
  if (v < 0.0) {
    return agv::Status::InvalidArgument;
  }
  return std::sqrt(v);
}
}  // namespace

TEST_CASE("every status has a distinct, stable name", "[core][status]") {
  for (std::uint8_t i = 0; i < agv::kStatusCount; ++i) {
    const char* name = agv::toString(static_cast<agv::Status>(i));
    REQUIRE(name != nullptr);
    CHECK(std::strcmp(name, "unknown status") != 0);
    for (std::uint8_t j = 0; j < i; ++j) {
      CHECK(std::strcmp(name, agv::toString(static_cast<agv::Status>(j))) != 0);
    }
  }
  CHECK(std::strcmp(agv::toString(agv::Status::Ok), "ok") == 0);
  CHECK(std::strcmp(agv::toString(static_cast<agv::Status>(agv::kStatusCount)), "unknown status") == 0);
  CHECK(agv::isOk(agv::Status::Ok));
  CHECK_FALSE(agv::isOk(agv::Status::Unobservable));
}

TEST_CASE("Result carries a value or names the failure", "[core][status]") {
  const agv::Result<double> good = safeSqrt(9.0);
  REQUIRE(good.ok());
  CHECK(good.status() == agv::Status::Ok);
  CHECK(good.value() == 3.0);
  CHECK(static_cast<bool>(good));

  const agv::Result<double> negative = safeSqrt(-1.0);
  CHECK_FALSE(negative.ok());
  CHECK(negative.status() == agv::Status::InvalidArgument);
  CHECK(negative.valueOr(-7.0) == -7.0);

  const agv::Result<double> nan = safeSqrt(std::nan(""));
  CHECK(nan.status() == agv::Status::NonFiniteInput);

  // A "failure" built from Ok would be a lie: it is turned into InvalidArgument.
  const agv::Result<int> bogus{agv::Status::Ok};
  CHECK_FALSE(bogus.ok());
  CHECK(bogus.status() == agv::Status::InvalidArgument);
}

TEST_CASE("Result and Status never allocate", "[core][status][alloc]") {
  double sum = 0.0;
  AGV_CHECK_NO_ALLOCATIONS(for (int i = -5; i < 50; ++i) { sum += safeSqrt(i).valueOr(0.0); });
  CHECK(sum > 0.0);
}
