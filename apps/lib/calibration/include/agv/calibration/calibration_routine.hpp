#pragma once
/// @file calibration_routine.hpp
/// The on-vehicle calibration routine: plans half-circle segments at several steering angles,
/// left and right, forward and backward (the four phases), checks that they fit in the free area,
/// drives them through `hal::DriveControl`, cuts the encoder stream into segments
/// (`CalibSegmentBuilder`), measures the laser egomotion of each segment between its two
/// standstill scans (from reflectors, `alignReflectors`, or from FALKO keypoints,
/// `alignKeypoints`), and solves STC, ATC and the joint refinement.
///
/// Application code (host): it uses the standard containers. The routine itself is one stepwise,
/// non-blocking state machine, `CalibrationRun`: its owner feeds it the encoder samples and the
/// sweeps it reads anyway and calls `step()` once per control cycle (`agvnav-vehicle` from its
/// navigation cycle). `runCalibrationRoutine` drives the same state machine against a
/// `CalibrationVehicle` (the HAL devices plus the passage of time), so the simulated vehicle
/// (sim_calibration_vehicle.hpp, `agvnav-calibrate`, `agvnav-hil`) and a real one run one copy.

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "agv/calib/calibration.hpp"
#include "agv/calib/calibration_file.hpp"
#include "agv/calib/refinement.hpp"
#include "agv/core/angle.hpp"
#include "agv/core/pose2.hpp"
#include "agv/core/timestamp.hpp"
#include "agv/hal/drive_control.hpp"
#include "agv/hal/encoder_source.hpp"
#include "agv/hal/laser_measurement.hpp"
#include "agv/hal/laser_source.hpp"
#include "agv/kinematics/tricycle.hpp"

namespace agv::calibration {

/// An axis-aligned rectangle of the world the vehicle may sweep [m].
struct FreeArea {
  double xMin = 0.0;
  double yMin = 0.0;
  double xMax = 0.0;
  double yMax = 0.0;
};

/// What the technician gives: the vehicle's geometry and limits, where it stands, the free area
/// around it and the shape of the plan.
struct PlanRequest {
  double wheelbase = 1.5;                ///< L [m] (from the drawing)
  double steeringLimit = deg2rad(85.0);  ///< largest |steering| the vehicle accepts [rad]
  double minSteering = deg2rad(18.0);    ///< smallest |steering| of the plan [rad]
  double maxSteering = deg2rad(50.0);    ///< largest |steering| of the plan [rad]
  int segmentsPerPhase = 6;              ///< n_seg: steering angles, one segment each per phase
  double rotation = kPi<double>;         ///< beta: nominal rotation of every segment [rad], (0, 2 pi)
  Pose2d start{10.0, 12.5, 0.0};         ///< logical point's pose at the start, world frame
  FreeArea area{2.5, 0.5, 24.0, 23.0};   ///< default: the open floor of the built-in warehouse
  double clearance = 0.8;                ///< [m] the vehicle's half width plus a margin
  double frontOverhang = 2.0;            ///< [m] from the logical point to the vehicle's front
};

/// Phase of a segment: direction of travel x side of the turn.
enum class Phase : int { ForwardLeft = 0, ForwardRight, BackwardLeft, BackwardRight };
const char* phaseName(Phase phase) noexcept;

/// One planned segment.
struct PlannedSegment {
  double steering = 0.0;     ///< measured steering set-point [rad] (+ left)
  int direction = 1;         ///< +1 forward, -1 backward
  double wheelTravel = 0.0;  ///< nominal drive-wheel travel for the rotation beta [m]
  Phase phase = Phase::ForwardLeft;
};

/// The plan: for each steering angle (n_seg spread from the smallest to the largest), left then
/// right, a forward segment followed by the backward one that retraces it, so the vehicle comes
/// back to the start after every pair and sweeps only the forward half circles. 4 n_seg segments.
struct CalibrationPlan {
  PlanRequest request;
  std::vector<PlannedSegment> segments;
};

/// Builds and checks the plan. Ok; InvalidArgument with `error` naming the bad value; OutOfRange
/// when a circle does not fit in the free area (`error` says which and where).
Status planCalibration(const PlanRequest& request, CalibrationPlan& plan, std::string& error);

/// The vehicle as the routine sees it: its devices and the passage of time.
class CalibrationVehicle {
 public:
  virtual ~CalibrationVehicle() = default;
  virtual hal::DriveControl& drive() = 0;
  virtual hal::EncoderSource& encoders() = 0;
  virtual hal::LaserSource& laser() = 0;
  /// The vehicle's monotonic clock.
  virtual Timestamp now() = 0;
  /// Lets `period` pass (a simulation advances, a real vehicle sleeps).
  virtual void wait(Duration period) = 0;
};

/// Where the egomotion of the segments comes from.
enum class EgomotionSource { Reflectors, Keypoints };

/// Settings of the routine.
struct RoutineOptions {
  TricycleParams nominal{1.5, 1.0e-4, 0.0, 0.0};  ///< drawing values: the solve's start and guesses
  Pose2d nominalLaser{1.6, 0.0, 0.0};             ///< drawing laser mount
  EgomotionSource egomotion = EgomotionSource::Reflectors;
  double speed = 0.5;                            ///< [m/s] drive set-point on the segments
  double deceleration = 0.5;                     ///< [m/s^2] the drive's ramp (braking distance)
  Duration settle = Duration::fromSeconds(1.5);  ///< standstill before each observation
  Duration controlPeriod = Duration::fromMilliseconds(20);
  /// Longest wait for a standstill, the steering set-point or the planned travel (else `Timeout`).
  Duration waitLimit = Duration::fromSeconds(2000.0);
  /// Longest wait for the first sweep after a standstill (else that observation is missing and the
  /// segments on either side of it are not aligned).
  Duration observeLimit = Duration::fromSeconds(10.0);
  double reflectorGate = 1.0;  ///< [m] association gate of the reflector alignment
  /// Keypoint alignment: hypotheses farther than this from the odometry's guess are discarded.
  double keypointGuessTranslation = 1.0;         ///< [m]
  double keypointGuessRotation = deg2rad(10.0);  ///< [rad]
  RefinementOptions refinement{};                ///< noise model of the joint refinement (reflector egomotion)
  /// Noise model of the joint refinement with keypoint egomotion: FALKO corners scatter more in
  /// translation and less in rotation than the reflector figures say (measured in the built-in
  /// warehouse, 0.25 deg laser, 1 cm range noise, half circles of 18..50 deg: 8.6 / 9.2 mm per
  /// axis, 0.038 deg; docs/calibration.md). With the reflector figures the refinement trusts the
  /// translations some 25 times too much relative to the rotations, and the translations of
  /// keypoint egomotion are short (corners on round pillars move with the viewpoint): through
  /// the laser's lever arm that pulled s_w down by about 450 ppm.
  RefinementOptions keypointRefinement = keypointRefinementOptions();

  /// The keypoint noise model above: sigmaTranslation 10 mm, sigmaRotation 0.04 deg, the
  /// steering figures of `RefinementOptions`.
  static RefinementOptions keypointRefinementOptions() noexcept {
    RefinementOptions o;
    o.sigmaTranslation = 0.010;
    o.sigmaRotation = deg2rad(0.04);
    return o;
  }
  /// The refinement options for `egomotion`.
  const RefinementOptions& refinementFor(EgomotionSource source) const noexcept {
    return source == EgomotionSource::Keypoints ? keypointRefinement : refinement;
  }
};

/// Progress after each segment.
struct RoutineProgress {
  int segment = 0;  ///< segments done (1..total)
  int total = 0;
  double elapsed = 0.0;    ///< [s] since the start
  double remaining = 0.0;  ///< [s] estimate (mean time per segment so far)
};

/// What the routine did and found.
struct CalibrationOutcome {
  Status status = Status::NotInitialized;  ///< of the ATC solve (or of the data collection)
  std::string message;                     ///< the failure reason in words (empty on success)
  CalibrationResult result;                ///< ATC closed form + observability report
  Status stcStatus = Status::NotInitialized;
  CalibrationResult stc;  ///< STC closed form (one steering offset)
  Status refinedStatus = Status::NotInitialized;
  RefinementResult refined;  ///< joint refinement from the ATC closed form
  int segmentsDriven = 0;
  int segmentsUsed = 0;           ///< closed by the builder and aligned
  int segmentsRejected = 0;       ///< rejected by the segment builder or without an alignment
  double seconds = 0.0;           ///< [s] duration of the data collection
  double meanAlignmentRms = 0.0;  ///< [m] alignment residual (reflectors or keypoints)
  double meanMatches = 0.0;       ///< reflector pairs / keypoint inliers per aligned segment
};

/// The refinement's a posteriori variance factor: max(1, final cost / (3 N - 6)) with N the
/// segments used (1 without degrees of freedom), so residuals larger than the noise model (wheel
/// slip, keypoint noise) widen the written sigmas.
double refinementVarianceFactor(const CalibrationOutcome& outcome) noexcept;

/// The values to write: the refined ones with their 1-sigma (covariance scaled by
/// `refinementVarianceFactor`) when the refinement succeeded, else the closed-form ATC values
/// (sigmas 0 = not known).
VehicleCalibration calibrationToWrite(const CalibrationOutcome& outcome) noexcept;

/// State of a `CalibrationRun`. The numeric values are published on the PLC (docs/plc-link.md,
/// register 44) and stay stable.
enum class RoutineState : std::uint8_t {
  Idle = 0,       ///< not started
  Settling = 1,   ///< at rest before the first observation, steering straight ahead, `settle` long
  Steering = 2,   ///< at rest, steering to the segment's set-point (and `settle` long)
  Driving = 3,    ///< driving the segment at `RoutineOptions::speed`
  Stopping = 4,   ///< braking, then at rest `settle` long with the steering on its set-point
  Observing = 5,  ///< waiting for the first sweep that starts after the standstill
  Solving = 6,    ///< every segment collected: the next `step()` solves
  Done = 7,       ///< solved; `outcome()` holds the result (its `status` may still be a refusal)
  Aborted = 8,    ///< stopped by `abort()`, a set-point the drive refused or a wait limit
};
/// "idle", "settling", ... (static strings).
const char* routineStateName(RoutineState state) noexcept;

/// The routine as a stepwise, non-blocking state machine: one copy for every program.
///
/// Use: `start(plan, now)`; then once per control cycle feed every encoder sample
/// (`onEncoderSample`) and every sweep (`onSweep`) read since the last cycle, and call `step(now)`,
/// which sends the set-point of the current state to the drive (every call: it also feeds the
/// drive controller's set-point watchdog) and moves on when the state's condition holds, until
/// `finished()`. `abort()` stops it at once (PLC Stop, a heartbeat loss seen by the owner).
///
/// Allocation: `start()` reserves the segment records and the observation storage for the whole
/// plan; the per-cycle calls (`onEncoderSample`, `step` while collecting) do not allocate; the
/// observation at each standstill copies the sweep's reflectors into reserved storage (the keypoint
/// detector runs there when the egomotion is `Keypoints`); only the final solve allocates. The
/// solve runs inside one `step()` (tens of milliseconds for 24 segments: that cycle overruns once,
/// with the vehicle at rest).
class CalibrationRun {
 public:
  /// `drive` must outlive the run. The options are copied.
  CalibrationRun(hal::DriveControl& drive, const RoutineOptions& options);
  ~CalibrationRun();
  CalibrationRun(const CalibrationRun&) = delete;
  CalibrationRun& operator=(const CalibrationRun&) = delete;

  /// Starts `plan` (copied) at `now`: state `Settling`. `InvalidArgument` for a plan without
  /// segments, `Rejected` while a run is in progress (abort it first); the state is unchanged then.
  Status start(const CalibrationPlan& plan, Timestamp now);
  /// One encoder sample (any state; used while collecting).
  void onEncoderSample(const hal::EncoderSample& sample) noexcept;
  /// One sweep: taken as the standstill observation when the run is `Observing` and the sweep
  /// starts after the standstill was reached; otherwise ignored.
  void onSweep(const hal::LaserMeasurement& sweep);
  /// One control cycle at `now` (see the class comment); returns the state after it.
  RoutineState step(Timestamp now);
  /// Stops the drive (`hal::DriveControl::stop`) in this call and ends the run as `Aborted` with
  /// `why` and `reason` in `outcome()`. Nothing when the run is not in progress.
  void abort(Status why, const char* reason, Timestamp now);

  RoutineState state() const noexcept;
  /// True in `Idle`, `Done` and `Aborted` (no set-point is sent any more).
  bool finished() const noexcept;
  /// The segment being prepared, driven or observed, 1-based (0 before the first).
  int segment() const noexcept;
  /// Segments driven and observed so far.
  int segmentsCompleted() const noexcept;
  /// Segments of the plan.
  int total() const noexcept;
  /// Phase of `segment()` (of the first segment before it starts).
  Phase phase() const noexcept;
  /// When the run started.
  Timestamp startTime() const noexcept;
  /// The result once `Done`; the reason once `Aborted` (`status`, `message`).
  const CalibrationOutcome& outcome() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Runs `plan` on `vehicle` to the end: a `CalibrationRun` stepped every
/// `options.controlPeriod` after `vehicle.wait()`, fed with every encoder sample and sweep the
/// vehicle delivers. `progress` (may be empty) is called after each segment.
CalibrationOutcome runCalibrationRoutine(CalibrationVehicle& vehicle, const CalibrationPlan& plan,
                                         const RoutineOptions& options,
                                         const std::function<void(const RoutineProgress&)>& progress);

}  // namespace agv::calibration
