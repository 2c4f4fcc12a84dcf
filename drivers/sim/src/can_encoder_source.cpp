#include "agv/sim/can_encoder_source.hpp"

#include <cmath>
#include <utility>

namespace agv::sim {

namespace canopen = drivers::canopen;
using drivers::CanFrame;

CanBusCounters& CanBusCounters::operator+=(const CanBusCounters& o) noexcept {
  framesToDecoder += o.framesToDecoder;
  framesToNodes += o.framesToNodes;
  framesDropped += o.framesDropped;
  drivePositions += o.drivePositions;
  steeringPositions += o.steeringPositions;
  heartbeats += o.heartbeats;
  emcys += o.emcys;
  malformed += o.malformed;
  ignored += o.ignored;
  measurements += o.measurements;
  samples += o.samples;
  sampleMismatches += o.sampleMismatches;
  samplesWithheld += o.samplesWithheld;
  faultReads += o.faultReads;
  driveCounterWraps += o.driveCounterWraps;
  return *this;
}

CanEncoderSource::CanEncoderSource(hal::EncoderSource& measurements, const SimCanEncodersParams& params)
    : measurements_(measurements), nodes_(params), decoder_(params.bus) {}

Status CanEncoderSource::validate() const noexcept {
  return validateSimCanEncoders(nodes_.params());
}

CanBusCounters CanEncoderSource::counters() const noexcept {
  CanBusCounters c = counters_;
  c.driveCounterWraps = nodes_.counters().driveCounterWraps;
  return c;
}

bool CanEncoderSource::deliver(const CanFrame& frame, bool toDecoder) {
  if (filter_ && !filter_(frame, toDecoder)) {
    ++counters_.framesDropped;
    return false;
  }
  if (!toDecoder) {
    ++counters_.framesToNodes;
    nodes_.receive(frame);
    return true;
  }
  ++counters_.framesToDecoder;
  switch (decoder_.onFrame(frame)) {
    case canopen::FrameKind::DrivePosition:
      ++counters_.drivePositions;
      break;
    case canopen::FrameKind::SteeringPosition:
      ++counters_.steeringPositions;
      break;
    case canopen::FrameKind::Heartbeat:
      ++counters_.heartbeats;
      break;
    case canopen::FrameKind::Emcy:
      ++counters_.emcys;
      break;
    case canopen::FrameKind::Malformed:
      ++counters_.malformed;
      break;
    case canopen::FrameKind::Ignored:
      ++counters_.ignored;
      break;
  }
  return true;
}

void CanEncoderSource::step(const hal::EncoderSample& measurement) {
  ++counters_.measurements;
  CanFrame frames[SimCanEncoders::kMaxFramesPerMeasurement];
  if (!started_) {  // the vehicle's bus comes up: NMT Start to both nodes
    started_ = true;
    const std::size_t n = decoder_.startupFrames(Span<CanFrame>(frames));
    for (std::size_t i = 0; i < n; ++i) {
      deliver(frames[i], false);
    }
  }
  // The vehicle's periodic service at this instant (SYNC, NMT Start after a boot-up, heartbeat
  // supervision), then what the nodes send.
  std::size_t n = decoder_.service(measurement.stamp, Span<CanFrame>(frames));
  for (std::size_t i = 0; i < n; ++i) {
    deliver(frames[i], false);
  }
  lastSent_ = measurement;
  n = nodes_.measure(measurement, Span<CanFrame>(frames));
  for (std::size_t i = 0; i < n; ++i) {
    deliver(frames[i], true);
  }
}

Status CanEncoderSource::read(hal::EncoderSample& out) noexcept {
  // Bounded by the measurements pending in the vehicle's encoder queue.
  for (;;) {
    hal::EncoderSample m;
    if (measurements_.read(m) != Status::Ok) {
      break;
    }
    step(m);
    hal::EncoderSample s;
    if (!decoder_.takeSample(s)) {
      continue;
    }
    ++counters_.samples;
    const hal::EncoderSample expected = nodes_.expectedDecoded(lastSent_);
    if (s.stamp != expected.stamp || s.driveTicks != expected.driveTicks ||
        std::fabs(s.steeringAngle - expected.steeringAngle) > 1e-12) {
      ++counters_.sampleMismatches;
    }
    const Status health = decoder_.health();
    if (health == Status::Timeout || health == Status::DeviceFault) {
      ++counters_.samplesWithheld;
      continue;
    }
    out = s;
    return Status::Ok;
  }
  const Status health = decoder_.health();
  if (health == Status::Timeout || health == Status::DeviceFault) {
    ++counters_.faultReads;
    return health;
  }
  return Status::NotFound;
}

}  // namespace agv::sim
