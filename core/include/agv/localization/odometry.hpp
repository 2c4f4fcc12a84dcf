#pragma once
/// @file odometry.hpp
/// Odometry increments for the localizer's prediction, and the two sources that produce them:
/// the tricycle drive/steering encoders (RK2, process noise derived from the encoder and steering
/// noise) and a differential/unicycle pose increment (e.g. a recorded log's odometry).
///
/// Precision: double. The increment of one encoder sample is sub-millimetre while the pose it is
/// composed with may be hundreds of metres from the origin; float (24-bit mantissa, 15 um at
/// 200 m) would lose it. The covariance entries span ~1e-12 .. 1e2 and feed the EKF (see
/// pose_ekf.hpp for the same argument).

#include <Eigen/Core>
#include <cstdint>

#include "agv/core/pose2.hpp"
#include "agv/core/result.hpp"
#include "agv/core/timestamp.hpp"
#include "agv/kinematics/tricycle.hpp"

namespace agv {

/// Motion of the logical point between two instants, as a pose increment expressed in the start
/// pose's frame, with the covariance of (dx, dy, dtheta) in that frame. This is the only thing
/// the EKF prediction consumes, so any odometry source can drive it.
struct OdometryIncrement {
  Timestamp stamp;                                       ///< end of the interval
  Pose2d delta;                                          ///< motion in the start frame [m, m, rad]
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  ///< of delta [m^2, rad^2]

  /// True when every number is finite and the covariance is symmetric with a non-negative diagonal.
  bool isValid() const noexcept;
};

/// One encoder reading in SI units (mirrors hal::EncoderSample without depending on the HAL).
struct TricycleSample {
  Timestamp stamp;              ///< acquisition time
  std::int64_t driveTicks = 0;  ///< accumulated drive ticks, unwrapped, + forward
  double steeringAngle = 0.0;   ///< measured steering angle [rad], + left, before offset correction
};

/// Noise of the tricycle encoders; the process noise of every increment is derived from these by
/// first-order propagation (docs/localization.md, "Process noise").
struct TricycleNoiseParams {
  /// Drive-wheel slip: variance of the rolled distance grows by this per metre rolled [m^2/m]
  /// (a random walk in distance; 4e-6 = 2 mm after 1 m). Default: a polyurethane drive wheel on
  /// sealed concrete.
  double slipVariancePerMetre = 4e-6;
  /// Standard deviation of one steering-angle reading [rad] (white, independent per sample).
  /// Default 0.1 deg: a 14-bit absolute encoder plus backlash.
  double steeringSigma = 0.1 * 3.14159265358979323846 / 180.0;
  /// Systematic errors the calibration cannot remove because they change after it: a steering
  /// angle bias [rad] (gear backlash, encoder offset drift) and a relative distance bias (tyre
  /// wear and load changing the effective radius, traction slip while accelerating), each unknown
  /// within +-sigma. Unlike white noise they do not average out over the samples of one correction
  /// interval: they are carried fully correlated over it (variance x samplesPerCorrection per
  /// sample). 0 (the default): the calibrated model is exact between corrections.
  double steeringBiasSigma = 0.0;
  double scaleBiasSigma = 0.0;
  /// Encoder samples between two laser corrections (encoder rate / laser rate). The tick count
  /// quantisation error does not accumulate (it telescopes), so its variance s_w^2/6 over any
  /// window is spread over this many samples; the variance predicted at the next correction is
  /// then exact. Must be >= 1.
  double samplesPerCorrection = 10.0;
  /// Largest plausible |tick change| between two samples; a larger jump is refused as a fault.
  std::int64_t maxTicksPerSample = 100000;

  /// `Ok`, `NonFiniteInput`, or `InvalidArgument` (a negative variance or sigma (bias sigmas
  /// included), samplesPerCorrection below 1, maxTicksPerSample not positive).
  Status validate() const noexcept;
};

/// Tricycle odometry: turns consecutive encoder samples into RK2 increments (`tricycleRk2Step`) of
/// the logical point, with their covariance. Heap-free, O(1) per sample.
class TricycleOdometry {
 public:
  TricycleOdometry() noexcept = default;
  TricycleOdometry(const TricycleParams& vehicle, const TricycleNoiseParams& noise) noexcept
      : vehicle_(vehicle), noise_(noise) {}

  /// Forgets the previous sample; the next `step` starts a new sequence.
  void reset() noexcept { hasPrevious_ = false; }

  /// Consumes one sample. Returns the increment since the previous accepted sample, or:
  /// `NotEnoughData` for the first sample of a sequence (stored, nothing to integrate yet);
  /// `NonFiniteInput` for a NaN/inf steering angle (sample ignored, state unchanged);
  /// `InvalidArgument` for a stamp not after the previous one (ignored, state unchanged);
  /// `OutOfRange` for a tick jump above `maxTicksPerSample` (the sequence restarts at this
  /// sample: the motion across the jump is lost and must be reported by the caller).
  Result<OdometryIncrement> step(const TricycleSample& sample) noexcept;

  /// The increment (and its covariance) of rolling `ds` [m] with true steering angles
  /// `alphaPrev` -> `alphaCur` [rad]; `tickChanged` says whether the drive count changed (only then
  /// is the quantisation term added). Exposed for tests and tools.
  OdometryIncrement increment(Timestamp stamp, double ds, double alphaPrev, double alphaCur,
                              bool tickChanged) const noexcept;

  const TricycleParams& vehicle() const noexcept { return vehicle_; }
  const TricycleNoiseParams& noise() const noexcept { return noise_; }

 private:
  TricycleParams vehicle_{};
  TricycleNoiseParams noise_{};
  TricycleSample previous_{};
  double previousAlphaTrue_ = 0.0;
  bool hasPrevious_ = false;
};

/// Noise of a differential/unicycle odometry increment (classic odometry motion model): variances
/// grow with the distance and rotation of the increment.
struct UnicycleNoiseParams {
  double translationVariancePerMetre = 1e-4;  ///< [m^2/m] along and across the motion
  double rotationVariancePerRadian = 1e-3;    ///< [rad^2/rad] from turning
  double rotationVariancePerMetre = 2e-4;     ///< [rad^2/m] heading drift from translation
  double floorVariance = 1e-12;               ///< added to every diagonal term (keeps Q > 0)
};

/// Wraps a measured pose increment `delta` (start frame) ending at `stamp` with a covariance from
/// `noise`. Use it for odometry that is already integrated (differential drive, recorded logs).
OdometryIncrement unicycleIncrement(Timestamp stamp, const Pose2d& delta, const UnicycleNoiseParams& noise) noexcept;

/// The fraction `f` in [0, 1] of an increment (same chord direction relative to the half-way
/// heading, rotation and distance scaled by f, covariance scaled by f). `between(part(f), delta)`
/// is the rest. Used to split an odometry interval at a scan time.
Pose2d partialIncrement(const Pose2d& delta, double f) noexcept;

}  // namespace agv
