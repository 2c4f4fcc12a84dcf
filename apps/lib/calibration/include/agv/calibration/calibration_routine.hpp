#pragma once
/// @file calibration_routine.hpp
/// The on-vehicle calibration routine: plans half-circle segments at several steering angles,
/// left and right, forward and backward (the four phases), checks that they fit in the free area,
/// drives them through `hal::DriveControl`, cuts the encoder stream into segments
/// (`CalibSegmentBuilder`), measures the laser egomotion of each segment between its two
/// standstill scans (from reflectors, `alignReflectors`, or from FALKO keypoints,
/// `alignKeypoints`), and solves STC, ATC and the joint refinement.
///
/// Application code (host): it uses the standard containers. The vehicle is reached only through
/// `CalibrationVehicle` (the HAL devices plus the passage of time), so the simulated vehicle
/// (sim_calibration_vehicle.hpp) and a real one plug in alike.

#include <functional>
#include <string>
#include <vector>

#include "agv/calib/calibration.hpp"
#include "agv/calib/refinement.hpp"
#include "agv/core/angle.hpp"
#include "agv/core/pose2.hpp"
#include "agv/core/timestamp.hpp"
#include "agv/hal/drive_control.hpp"
#include "agv/hal/encoder_source.hpp"
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

/// Runs `plan` on `vehicle`. `progress` (may be empty) is called after each segment.
CalibrationOutcome runCalibrationRoutine(CalibrationVehicle& vehicle, const CalibrationPlan& plan,
                                         const RoutineOptions& options,
                                         const std::function<void(const RoutineProgress&)>& progress);

}  // namespace agv::calibration
