#include "agv/drivers/linux/monotonic_clock.hpp"

#include <ctime>

namespace agv::drivers {

Timestamp monotonicNow() noexcept {
  timespec t{};
  (void)clock_gettime(CLOCK_MONOTONIC, &t);  // cannot fail for CLOCK_MONOTONIC with a valid pointer
  return Timestamp::fromNanoseconds(static_cast<std::int64_t>(t.tv_sec) * 1000000000LL +
                                    static_cast<std::int64_t>(t.tv_nsec));
}

}  // namespace agv::drivers
