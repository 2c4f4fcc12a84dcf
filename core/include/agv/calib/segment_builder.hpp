#pragma once
/// @file segment_builder.hpp
/// Cuts a timestamped encoder stream (accumulated drive ticks, measured steering angle) into the
/// constant-steering, constant-direction segments between standstills that the calibration
/// solves use, and rejects segments whose steering varied beyond a tolerance or whose direction
/// reversed. O(1) work and no storage per sample.
///
/// The builder does not measure egomotion: when it reports a closed segment, the caller aligns
/// the laser observations taken at the two standstills (e.g. with alignReflectors) and pairs the
/// result with the segment (`toCalibSegment`).
///
/// Precision: double for the steering statistics (a running sum of up to ~1e6 samples must keep
/// the mean to ~1e-6 rad); ticks are integers.

#include <cstdint>

#include "agv/calib/calibration.hpp"
#include "agv/core/timestamp.hpp"

namespace agv {

/// Settings of the segment builder.
struct SegmentBuilderOptions {
  /// The vehicle is at a standstill once the drive count has not changed for this long.
  Duration standstillTime = Duration::fromMilliseconds(500);
  /// Largest deviation of a steering sample from the segment's mean steering [rad] (the segment
  /// is rejected beyond it).
  double steeringTolerance = deg2rad(0.5);
  /// Segments with fewer ticks are reported as too short.
  std::int64_t minTicks = 100;
};

/// What one sample did.
enum class SegmentEvent : std::uint8_t {
  None = 0,  ///< nothing closed
  Closed,    ///< a valid segment closed: see lastSegment()
  Rejected,  ///< a segment closed but was rejected: lastSegment().status says why
};

/// A segment as cut from the encoder stream.
struct BuiltSegment {
  std::int64_t ticks = 0;     ///< signed drive ticks from standstill to standstill
  double steering = 0.0;      ///< mean measured steering while moving [rad]
  double steeringMin = 0.0;   ///< smallest steering sample while moving [rad]
  double steeringMax = 0.0;   ///< largest steering sample while moving [rad]
  std::uint32_t samples = 0;  ///< samples while moving
  Timestamp start{};          ///< last standstill sample before the motion
  Timestamp end{};            ///< last sample with motion (the vehicle stands still from here)
  /// Ok; Rejected when the steering varied beyond the tolerance or the direction reversed
  /// (`directionReversed` tells which); NotEnoughData when shorter than minTicks;
  /// NonFiniteInput when a steering sample was NaN/inf.
  Status status = Status::NotInitialized;
  bool directionReversed = false;
};

/// Streaming segment cutter. Feed samples in time order with addSample().
class CalibSegmentBuilder {
 public:
  explicit CalibSegmentBuilder(const SegmentBuilderOptions& options = {}) noexcept : options_(options) {}

  /// Processes one encoder sample. Returns Ok, or InvalidArgument for a sample older than the
  /// previous one, or NonFiniteInput for a NaN/inf steering angle (both samples are ignored and
  /// counted in ignoredSamples(); a non-finite steering while moving also rejects the segment).
  /// `event` (optional) says whether a segment closed with this sample.
  Status addSample(Timestamp stamp, std::int64_t driveTicks, double steering, SegmentEvent* event = nullptr) noexcept;

  /// The most recently closed segment (valid or rejected).
  const BuiltSegment& lastSegment() const noexcept { return last_; }
  /// True while the vehicle is moving (a segment is open).
  bool moving() const noexcept { return moving_; }
  /// Samples ignored since construction (out of order or non-finite).
  std::uint32_t ignoredSamples() const noexcept { return ignored_; }
  /// Segments closed valid / rejected since construction.
  std::uint32_t closedCount() const noexcept { return closed_; }
  std::uint32_t rejectedCount() const noexcept { return rejected_; }
  /// Forgets the stream (the next sample is a standstill reference).
  void reset() noexcept;

 private:
  void close(SegmentEvent* event) noexcept;

  SegmentBuilderOptions options_;
  bool started_ = false;
  bool moving_ = false;
  bool nonFinite_ = false;
  Timestamp lastStamp_{};
  Timestamp lastMotion_{};
  std::int64_t lastTicks_ = 0;
  std::int64_t startTicks_ = 0;
  int direction_ = 0;
  double steeringSum_ = 0.0;
  BuiltSegment open_{};
  BuiltSegment last_{};
  std::uint32_t ignored_ = 0;
  std::uint32_t closed_ = 0;
  std::uint32_t rejected_ = 0;
};

/// A calibration segment from a built one and the laser egomotion measured between its two
/// standstills.
inline CalibSegment toCalibSegment(const BuiltSegment& segment, const Pose2d& egomotion) noexcept {
  CalibSegment s;
  s.ticks = segment.ticks;
  s.steering = segment.steering;
  s.egomotion = egomotion;
  return s;
}

}  // namespace agv
