#pragma once
/// @file sim_vehicle.hpp
/// Simulated tricycle forklift: true kinematics, servos, wheel slip and encoders.

#include <cstdint>
#include <deque>
#include <random>

#include "agv/core/angle.hpp"
#include "agv/core/pose2.hpp"
#include "agv/hal/drive_control.hpp"
#include "agv/hal/encoder_source.hpp"
#include "agv/kinematics/tricycle.hpp"

namespace agv::sim {

/// The vehicle's *true* parameters and its imperfections. The estimators never see this struct:
/// they get ticks and measured angles and must find s_w, the steering offsets and the laser
/// mount themselves (calibration).
struct SimVehicleParams {
  /// True kinematics: L, s_w [m/tick], alpha_F, alpha_B (true wheel angle = measured + offset,
  /// the offset depending on the direction of travel).
  TricycleParams truth{1.5, 1.0085e-4, deg2rad(0.55), deg2rad(0.35)};
  Pose2d laserMount{1.62, 0.025, deg2rad(0.7)};  ///< true laser pose in the logical-point frame
  double slipBias = 0.0;                         ///< relative ground-vs-wheel travel bias (0.01 = ground 1 % farther)
  double slipNoise = 0.002;                      ///< [m/sqrt(m)] random-walk std of ground travel vs wheel travel
  /// Longitudinal traction slip per m/s^2 of acceleration along the travel: the ground travel is
  /// the wheel's times (1 - accelSlip * a) (the wheel spins ahead when accelerating, skids behind
  /// when braking). 0: none.
  double accelSlip = 0.0;
  /// Lateral slip of the steered drive wheel per m/s^2 of lateral acceleration [rad]: the wheel's
  /// travel direction lags its angle by turnSlip * v^2 sin(alpha) / L, towards straight. 0: none.
  double turnSlip = 0.0;
  /// Relative change of the drive wheel's effective radius since calibration (tyre wear, load
  /// compressing the tread): the ground travel is the wheel's times (1 + radiusChange).
  double radiusChange = 0.0;
  /// [rad] steering gear backlash: the wheel lags the (motor-side) measured angle by half of it
  /// against the direction of the last steering motion. 0: none.
  double steerBacklash = 0.0;
  /// [rad] steering encoder offset error since calibration (drift): the measured angle is the
  /// servo's plus this.
  double steerEncoderDrift = 0.0;
  double steerEncoderBits = 14.0;       ///< steering encoder resolution: 2^bits counts per revolution
  double steerNoiseStdDev = 2e-4;       ///< [rad] Gaussian noise of the measured steering angle (before quantisation)
  double maxSpeed = 2.0;                ///< [m/s] |speed set-point| limit
  double acceleration = 0.5;            ///< [m/s^2] drive ramp
  double maxSteering = deg2rad(85.0);   ///< [rad] |steering set-point| limit (measured angle)
  double steeringRate = deg2rad(45.0);  ///< [rad/s] steering servo slew rate
  double standstillSpeed = 1e-3;        ///< [m/s] below this the drive reports standstill
  Duration substep = Duration::fromMilliseconds(1);         ///< integration step
  Duration encoderPeriod = Duration::fromMilliseconds(10);  ///< encoder sample period (CAN SYNC)
  std::size_t encoderQueue = 4096;                          ///< unread samples kept; older ones are dropped and counted
};

/// The simulated vehicle: integrates the true motion of the logical point with `tricycleArc` over
/// fixed sub-steps, and is the `hal::DriveControl` (speed and steering servos) and the
/// `hal::EncoderSource` (drive ticks, quantised noisy steering angle) of the vehicle.
///
/// The steering servo closes its loop on the *measured* angle (as a real one does on its
/// encoder); the wheel's true angle is that plus the direction-dependent offset. The drive
/// wheel's rotation is counted by the encoder (floor of travel / s_w); the ground travel differs
/// from it by the slip.
class SimVehicle final : public hal::DriveControl, public hal::EncoderSource {
 public:
  SimVehicle(const SimVehicleParams& params, std::uint64_t seed);

  /// Places the vehicle at rest at `pose` (logical point, world frame) at time `t`; clears the
  /// encoder queue and the servo set-points (the tick counter keeps counting, as a real one does).
  void reset(const Pose2d& pose, Timestamp t) noexcept;
  /// Integrates up to time `t` (no effect if `t` is not after `now()`).
  void advanceTo(Timestamp t) noexcept;

  Timestamp now() const noexcept { return now_; }
  const SimVehicleParams& params() const noexcept { return params_; }
  /// True pose of the logical point, world frame.
  const Pose2d& truePose() const noexcept { return pose_; }
  /// True pose of the laser, world frame.
  Pose2d trueLaserPose() const noexcept { return pose_.compose(params_.laserMount); }
  /// True wheel surface speed [m/s] and servo (measured-frame) steering angle [rad].
  double speed() const noexcept { return speed_; }
  double servoAngle() const noexcept { return servo_; }
  /// Total ground distance travelled by the drive wheel [m] (absolute, both directions).
  double odometer() const noexcept { return odometer_; }
  /// Encoder samples dropped because nobody read them.
  std::uint64_t droppedSamples() const noexcept { return dropped_; }

  // hal::DriveControl
  Status command(const hal::DriveCommand& cmd) noexcept override;
  Status stop() noexcept override;
  bool isStandstill() const noexcept override;
  // hal::EncoderSource
  Status read(hal::EncoderSample& out) noexcept override;
  /// Always `Ok`: the raw measurements of the simulated vehicle do not fail (faults are injected
  /// on the CAN bus, `CanEncoderSource`).
  Status health() const noexcept override { return Status::Ok; }

 private:
  void substep(double dt) noexcept;
  void emitSample() noexcept;

  SimVehicleParams params_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  Timestamp now_;
  Timestamp nextSample_;
  Pose2d pose_;
  double speed_ = 0.0;
  double speedSet_ = 0.0;
  double servo_ = 0.0;
  double servoSet_ = 0.0;
  double backlashSide_ = 0.0;  // sign of the last steering motion (0: none yet)
  double wheelTravel_ = 0.0;   // [m] signed drive-wheel surface travel since construction
  double odometer_ = 0.0;
  std::deque<hal::EncoderSample> queue_;
  std::uint64_t dropped_ = 0;
};

}  // namespace agv::sim
