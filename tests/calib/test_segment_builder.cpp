// Segment builder on simulated encoder streams: a whole calibration run cut into segments and
// solved, and the streams it must reject.
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "agv/calib/segment_builder.hpp"
#include "agv_test.hpp"
#include "calib_sim.hpp"

using agv::BuiltSegment;
using agv::CalibSegmentBuilder;
using agv::deg2rad;
using agv::Duration;
using agv::SegmentEvent;
using agv::Status;
using agv::Timestamp;

namespace {

/// Encoder stream at 100 Hz: the steering is set during a 1 s standstill, then the vehicle
/// drives `ticks` at 2000 ticks/s (1 m/s at 5e-4 m/tick) with steering `steer(t)`.
struct Stream {
  CalibSegmentBuilder builder;
  std::int64_t ns = 0;
  std::int64_t ticks = 0;
  std::vector<BuiltSegment> closed;
  std::vector<BuiltSegment> rejected;

  void sample(double steering) {
    SegmentEvent ev = SegmentEvent::None;
    CHECK(builder.addSample(Timestamp::fromNanoseconds(ns), ticks, steering, &ev) == Status::Ok);
    if (ev == SegmentEvent::Closed) {
      closed.push_back(builder.lastSegment());
    } else if (ev == SegmentEvent::Rejected) {
      rejected.push_back(builder.lastSegment());
    }
    ns += 10000000;  // 10 ms
  }
  template <typename SteerFn>
  void drive(std::int64_t count, SteerFn steer) {
    for (int i = 0; i < 100; ++i) {
      sample(steer(0.0));
    }
    const std::int64_t target = ticks + count;
    const std::int64_t step = count > 0 ? 20 : -20;
    double t = 0.0;
    while (ticks != target) {
      ticks = (count > 0) ? std::min(ticks + step, target) : std::max(ticks + step, target);
      sample(steer(t));
      t += 0.01;
    }
  }
  void standstill(double steering, int samples = 100) {
    for (int i = 0; i < samples; ++i) {
      sample(steering);
    }
  }
};

}  // namespace

TEST_CASE("segment builder cuts a calibration run that the ATC solve recovers exactly", "[calib][segments]") {
  agv::test::CalibSimConfig cfg;
  std::mt19937_64 rng(41);
  const std::vector<agv::CalibSegment> planned = simulateCalibration(cfg, rng);
  Stream s;
  for (const agv::CalibSegment& p : planned) {
    s.drive(p.ticks, [&](double) { return p.steering; });
  }
  s.standstill(0.0);
  REQUIRE(s.closed.size() == planned.size());
  CHECK(s.rejected.empty());
  std::vector<agv::CalibSegment> segs;
  for (std::size_t k = 0; k < planned.size(); ++k) {
    CHECK(s.closed[k].ticks == planned[k].ticks);
    AGV_CHECK_NEAR(s.closed[k].steering, planned[k].steering, 1e-12);
    CHECK(s.closed[k].end > s.closed[k].start);
    if (k > 0) {
      CHECK(s.closed[k].start > s.closed[k - 1].end);
    }
    segs.push_back(agv::toCalibSegment(s.closed[k], planned[k].egomotion));
  }
  agv::CalibrationResult r;
  REQUIRE(agv::calibrateAtc(agv::Span<const agv::CalibSegment>(segs.data(), segs.size()),
                            agv::test::nominalOptions(cfg), r) == Status::Ok);
  CHECK(std::fabs(r.params.driveScale / cfg.truth.driveScale - 1.0) < 1e-9);
  CHECK(std::fabs(r.params.steerOffsetBackward / cfg.truth.steerOffsetBackward - 1.0) < 1e-9);
  CHECK(s.builder.closedCount() == planned.size());
}

TEST_CASE("segment builder rejects varying steering, reversals and short moves", "[calib][segments]") {
  Stream s;
  const double a = deg2rad(30.0);
  // steering noise within the tolerance: accepted, mean kept
  s.drive(8000, [&](double t) { return a + deg2rad(0.2) * std::sin(7.0 * t); });
  s.standstill(a);
  REQUIRE(s.closed.size() == 1U);
  CHECK(std::fabs(s.closed[0].steering - a) < deg2rad(0.02));
  // steering ramps by 2 deg during the segment: rejected
  s.drive(8000, [&](double t) { return a + deg2rad(2.0) * t / 4.0; });
  s.standstill(a);
  REQUIRE(s.rejected.size() == 1U);
  CHECK(s.rejected[0].status == Status::Rejected);
  CHECK_FALSE(s.rejected[0].directionReversed);
  // forward then backward without a standstill in between: rejected as a reversal
  s.drive(4000, [&](double) { return a; });
  for (int i = 0; i < 20; ++i) {
    s.ticks -= 20;
    s.sample(a);
  }
  s.standstill(a);
  REQUIRE(s.rejected.size() == 2U);
  CHECK(s.rejected[1].directionReversed);
  // a nudge of 40 ticks: too short
  s.drive(40, [&](double) { return a; });
  s.standstill(a);
  REQUIRE(s.rejected.size() == 3U);
  CHECK(s.rejected[2].status == Status::NotEnoughData);
  CHECK(s.builder.rejectedCount() == 3U);
  CHECK(s.builder.closedCount() == 1U);
}

TEST_CASE("segment builder ignores out-of-order and non-finite samples, without allocating", "[calib][segments]") {
  CalibSegmentBuilder b;
  Status st = Status::NotInitialized;
  AGV_CHECK_NO_ALLOCATIONS(st = b.addSample(Timestamp::fromSeconds(1.0), 0, 0.3));
  CHECK(st == Status::Ok);
  CHECK(b.addSample(Timestamp::fromSeconds(0.5), 10, 0.3) == Status::InvalidArgument);
  CHECK(b.ignoredSamples() == 1U);
  CHECK(b.addSample(Timestamp::fromSeconds(1.1), 200, 0.3) == Status::Ok);
  CHECK(b.moving());
  CHECK(b.addSample(Timestamp::fromSeconds(1.2), 400, std::numeric_limits<double>::quiet_NaN()) ==
        Status::NonFiniteInput);
  SegmentEvent ev = SegmentEvent::None;
  CHECK(b.addSample(Timestamp::fromSeconds(2.0), 400, 0.3, &ev) == Status::Ok);
  CHECK(ev == SegmentEvent::Rejected);
  CHECK(b.lastSegment().status == Status::NonFiniteInput);
  CHECK(b.lastSegment().ticks == 400);
  CHECK_FALSE(b.moving());
  // a segment exactly at the standstill boundary closes on the first sample that reaches it
  CHECK(b.addSample(Timestamp::fromSeconds(2.1), 1000, 0.3, &ev) == Status::Ok);
  CHECK(b.addSample(Timestamp::fromSeconds(2.1) + Duration::fromMilliseconds(499), 1000, 0.3, &ev) == Status::Ok);
  CHECK(ev == SegmentEvent::None);
  CHECK(b.addSample(Timestamp::fromSeconds(2.1) + Duration::fromMilliseconds(500), 1000, 0.3, &ev) == Status::Ok);
  CHECK(ev == SegmentEvent::Closed);
  CHECK(b.lastSegment().ticks == 600);
}
