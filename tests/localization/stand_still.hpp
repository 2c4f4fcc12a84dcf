#pragma once
// Test helper: a standing vehicle's odometry, one zero increment per 10 ms.
#include <Eigen/Core>

#include "agv/localization/localizer.hpp"
#include "agv_test.hpp"

namespace agv::test {

/// Feeds `steps` zero increments of 10 ms to `loc`, advancing `t`.
inline void standStill(Localizer& loc, Timestamp& t, int steps) {
  for (int i = 0; i < steps; ++i) {
    t = t + Duration::fromMilliseconds(10);
    OdometryIncrement inc;
    inc.stamp = t;
    inc.covariance = Eigen::Matrix3d::Identity() * 1e-9;
    REQUIRE(loc.predict(inc) == Status::Ok);
  }
}

}  // namespace agv::test
