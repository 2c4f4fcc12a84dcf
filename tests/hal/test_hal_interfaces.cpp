// The HAL interfaces can be implemented and driven through references without heap or RTTI, and
// the message defaults are neutral (zero motion, empty reflector list, zero covariance).
#include <cstdint>
#include <type_traits>

#include "agv/hal/clock.hpp"
#include "agv/hal/drive_control.hpp"
#include "agv/hal/encoder_source.hpp"
#include "agv/hal/laser_source.hpp"
#include "agv/hal/plc_link.hpp"
#include "agv_test.hpp"

namespace {

// A device replaying three encoder samples, then reporting NotFound.
class ReplayEncoders final : public agv::hal::EncoderSource {
 public:
  agv::Status read(agv::hal::EncoderSample& out) noexcept override {
    if (next_ >= 3) {
      return agv::Status::NotFound;
    }
    out.stamp = agv::Timestamp::fromNanoseconds(static_cast<std::int64_t>(next_ + 1) * 10000000);
    out.driveTicks = static_cast<std::int64_t>(next_) * 100;
    out.steeringAngle = 0.1;
    ++next_;
    return agv::Status::Ok;
  }
  agv::Status health() const noexcept override { return next_ > 0 ? agv::Status::Ok : agv::Status::NotInitialized; }

 private:
  int next_ = 0;
};

class FixedClock final : public agv::hal::Clock {
 public:
  agv::Timestamp now() const noexcept override { return agv::Timestamp::fromSeconds(2.5); }
};

class CountingPlc final : public agv::hal::PlcLink {
 public:
  agv::Status publish(const agv::hal::PoseReport& r) noexcept override {
    ++published;
    last = r;
    return agv::Status::Ok;
  }
  agv::Status readCommand(agv::hal::PlcCommand&) noexcept override { return agv::Status::NotFound; }
  int published = 0;
  agv::hal::PoseReport last;
};

// Loop code written against the interfaces only: drains the encoders, publishes one report.
int drainAndPublish(agv::hal::EncoderSource& enc, agv::hal::PlcLink& plc, const agv::hal::Clock& clock) {
  agv::hal::EncoderSample s;
  int n = 0;
  for (int guard = 0; guard < 100; ++guard) {
    if (enc.read(s) != agv::Status::Ok) {
      break;
    }
    ++n;
  }
  agv::hal::PoseReport r;
  r.stamp = clock.now();
  r.pose = agv::Pose2d{1.0, 2.0, 0.5};
  r.health.mode = agv::hal::NavMode::Localizing;
  if (plc.publish(r) != agv::Status::Ok) {
    return -1;
  }
  return n;
}

}  // namespace

TEST_CASE("HAL interfaces dispatch to the implementation without allocating", "[hal]") {
  ReplayEncoders enc;
  CountingPlc plc;
  FixedClock clock;
  int n = 0;
  AGV_CHECK_NO_ALLOCATIONS(n = drainAndPublish(enc, plc, clock));
  CHECK(n == 3);
  CHECK(plc.published == 1);
  CHECK(plc.last.stamp == agv::Timestamp::fromSeconds(2.5));
  CHECK(plc.last.health.mode == agv::hal::NavMode::Localizing);
  // Drained: a further read reports NotFound and leaves the output untouched.
  agv::hal::EncoderSample s;
  s.driveTicks = 42;
  CHECK(enc.read(s) == agv::Status::NotFound);
  CHECK(s.driveTicks == 42);
}

TEST_CASE("HAL message defaults are neutral", "[hal]") {
  const agv::hal::DriveCommand cmd;
  CHECK(cmd.speed == 0.0);
  CHECK(cmd.steeringAngle == 0.0);
  const agv::hal::LaserMeasurement m;
  CHECK(m.scan.size() == 0U);
  CHECK(m.reflectors.empty());
  CHECK(m.reflectors.capacity() == agv::kMaxReflectors);
  CHECK_FALSE(m.hasReflectors);
  const agv::hal::PoseReport r;
  CHECK(r.covariance.isZero(0.0));
  CHECK(r.health.mode == agv::hal::NavMode::Idle);
  const agv::hal::PlcCommand c;
  CHECK(c.kind == agv::hal::PlcCommandKind::None);
  // Interfaces cannot be destroyed through a base pointer (protected destructor) nor copied into.
  CHECK_FALSE(std::is_destructible<agv::hal::EncoderSource>::value);
  CHECK_FALSE(std::is_destructible<agv::hal::LaserSource>::value);
  CHECK_FALSE(std::is_destructible<agv::hal::DriveControl>::value);
}
