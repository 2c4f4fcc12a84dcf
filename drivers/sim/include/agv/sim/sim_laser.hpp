#pragma once
/// @file sim_laser.hpp
/// Simulated 2D navigation laser: ray-cast range scans and reflector detection.

#include <cstdint>
#include <random>

#include "agv/core/angle.hpp"
#include "agv/core/pose2.hpp"
#include "agv/core/status.hpp"
#include "agv/core/timestamp.hpp"
#include "agv/hal/laser_source.hpp"
#include "agv/sim/ray_caster.hpp"

namespace agv::sim {

/// Sensor model. Defaults: a 360 deg navigation laser at 0.25 deg and 12.5 Hz with 1 cm range
/// noise and 1 cm reflector-centre noise.
struct SimLaserParams {
  double fieldOfView = kTwoPi<double>;       ///< [rad] (0, 2*pi], centred on the sensor's x axis
  double angularResolution = deg2rad(0.25);  ///< [rad] beam spacing (0.25..1 deg for the usual devices)
  double scanRate = 12.5;                    ///< [Hz] sweeps per second (one revolution per sweep)
  double rangeNoiseStdDev = 0.01;            ///< [m] Gaussian noise added to every range
  double rangeMin = 0.05;                    ///< [m] closer returns are reported as no-return
  double rangeMax = 50.0;                    ///< [m] farther returns are reported as no-return
  float noReturnValue = 50.0F;               ///< [m] value written for a beam without return;
                                             ///< must be invalid for LaserScan (>= rangeMax, < rangeMin or non-finite)
  bool reportsReflectors = true;             ///< a navigation laser reports reflector centres
  double reflectorNoiseStdDev = 0.01;        ///< [m] Gaussian noise on each centre coordinate
  double reflectorMaxRange = 30.0;           ///< [m] reflectors farther (to the surface) are not detected
  /// Each reflector carries the instant the beam swept over it (`ReflectorObservation::stamp`,
  /// `stamped`), as a NAV350 reports it; false: unstamped, its time follows from its bearing.
  bool stampsReflectors = true;

  /// `Ok` or the first problem: `InvalidArgument` / `NonFiniteInput` for a value out of its domain,
  /// `CapacityExceeded` when the beam count exceeds kMaxScanBeams.
  Status validate() const noexcept;
  /// Beams per sweep: round(fieldOfView / angularResolution).
  std::size_t beamCount() const noexcept;
};

/// Ray-casts sweeps of a laser moving through a world. Also a `hal::LaserSource`: `capture()`
/// takes a sweep and `read()` hands it out once, as a laser driver would.
class SimLaser final : public hal::LaserSource {
 public:
  /// `params` must validate (check `status()`); the caster (and its world) must outlive the laser.
  SimLaser(const RayCaster& caster, const SimLaserParams& params, std::uint64_t seed);

  /// `Ok`, or why the parameters were refused (then every scan fails with it).
  Status status() const noexcept { return status_; }
  const SimLaserParams& params() const noexcept { return params_; }
  /// Time between sweeps, and from the first to the last beam of one sweep.
  Duration period() const noexcept;
  Duration sweepDuration() const noexcept;

  /// One sweep of the sensor (world poses of the sensor frame at the first and last beam; poses
  /// in between are interpolated linearly, so the scan is distorted by the motion as a real
  /// one is). `stamp` = time of the first beam.
  Status scan(const Pose2d& poseFirstBeam, const Pose2d& poseLastBeam, Timestamp stamp,
              hal::LaserMeasurement& out) noexcept;
  /// A sweep from a sensor at rest.
  Status scan(const Pose2d& pose, Timestamp stamp, hal::LaserMeasurement& out) noexcept {
    return scan(pose, pose, stamp, out);
  }

  /// Takes a sweep into the internal buffer for `read()`.
  Status capture(const Pose2d& poseFirstBeam, const Pose2d& poseLastBeam, Timestamp stamp) noexcept;
  /// hal::LaserSource: the captured sweep once (`NotFound` until the next capture).
  Status read(hal::LaserMeasurement& out) noexcept override;
  /// `Ok`, or `DeviceFault` when the parameters were refused (no sweep can be taken).
  Status health() const noexcept override { return status_ == Status::Ok ? Status::Ok : Status::DeviceFault; }

 private:
  Pose2d poseAt(const Pose2d& a, const Pose2d& b, double f) const noexcept;

  const RayCaster* caster_;
  SimLaserParams params_;
  Status status_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  hal::LaserMeasurement pending_;
  bool hasPending_ = false;
};

}  // namespace agv::sim
