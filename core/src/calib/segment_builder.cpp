#include "agv/calib/segment_builder.hpp"

#include <cmath>

namespace agv {

void CalibSegmentBuilder::reset() noexcept {
  started_ = false;
  moving_ = false;
  nonFinite_ = false;
  steeringSum_ = 0.0;
  open_ = BuiltSegment{};
}

void CalibSegmentBuilder::close(SegmentEvent* event) noexcept {
  BuiltSegment& s = open_;
  s.ticks = lastTicks_ - startTicks_;
  s.end = lastMotion_;
  s.steering = s.samples > 0 ? steeringSum_ / static_cast<double>(s.samples) : 0.0;
  if (nonFinite_) {
    s.status = Status::NonFiniteInput;
  } else if (s.directionReversed || s.samples == 0 || s.steeringMax - s.steering > options_.steeringTolerance ||
             s.steering - s.steeringMin > options_.steeringTolerance) {
    s.status = Status::Rejected;
  } else if (s.ticks < options_.minTicks && s.ticks > -options_.minTicks) {
    s.status = Status::NotEnoughData;
  } else {
    s.status = Status::Ok;
  }
  last_ = s;
  moving_ = false;
  if (s.status == Status::Ok) {
    ++closed_;
  } else {
    ++rejected_;
  }
  if (event != nullptr) {
    *event = s.status == Status::Ok ? SegmentEvent::Closed : SegmentEvent::Rejected;
  }
}

Status CalibSegmentBuilder::addSample(Timestamp stamp, std::int64_t driveTicks, double steering,
                                      SegmentEvent* event) noexcept {
  if (event != nullptr) {
    *event = SegmentEvent::None;
  }
  if (started_ && stamp < lastStamp_) {
    ++ignored_;
    return Status::InvalidArgument;
  }
  const bool finite = std::isfinite(steering);
  Status result = Status::Ok;
  if (!finite) {
    ++ignored_;
    result = Status::NonFiniteInput;
  }
  if (!started_) {
    started_ = true;
    lastStamp_ = stamp;
    lastMotion_ = stamp;
    lastTicks_ = driveTicks;
    return result;
  }
  const std::int64_t delta = driveTicks - lastTicks_;
  if (delta != 0) {
    const int dir = delta > 0 ? 1 : -1;
    if (!moving_) {
      moving_ = true;
      startTicks_ = lastTicks_;
      direction_ = dir;
      steeringSum_ = 0.0;
      nonFinite_ = false;
      open_ = BuiltSegment{};
      open_.start = lastStamp_;
      open_.steeringMin = steering;
      open_.steeringMax = steering;
    } else if (dir != direction_) {
      open_.directionReversed = true;
    }
    lastTicks_ = driveTicks;
    lastMotion_ = stamp;
    // steering statistics only over samples with motion: the wheel may be turned for the next
    // segment during the standstill that closes this one
    if (finite) {
      steeringSum_ += steering;
      ++open_.samples;
      open_.steeringMin = std::fmin(open_.steeringMin, steering);
      open_.steeringMax = std::fmax(open_.steeringMax, steering);
    } else {
      nonFinite_ = true;
    }
  } else if (moving_ && stamp - lastMotion_ >= options_.standstillTime) {
    close(event);
  }
  lastStamp_ = stamp;
  return result;
}

}  // namespace agv
