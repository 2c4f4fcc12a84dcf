#pragma once
/// @file calibration.hpp
/// Closed-form calibration of a tricycle AGV from constant-steering path segments and the
/// navigation laser's egomotion: STC (driving scale s_w and one steering offset), ATC (s_w and
/// separate forward/backward steering offsets alpha_F/alpha_B), and the laser mounting pose
/// l = (lx, ly, ltheta), with the observability checks and condition numbers that tell a
/// technician whether the data determine the parameters. Derivation: docs/calibration.md.
///
/// Model of one segment k (signed drive ticks n^k, measured steering a^k, both constant over
/// the segment): the logical point moves by r^k = tricycleArc(s_w n^k, a^k + alpha_dir, L)
/// (alpha_dir = alpha_F for n^k > 0, alpha_B for n^k < 0) and the laser, mounted at pose l in the
/// vehicle frame, observes its own motion s^k = l^-1 ⊕ r^k ⊕ l.
///
/// Precision: double throughout. The rotation sums reach (n^k)^2 ~ 1e9..1e11 per segment and the
/// ATC secular equation is solved near its poles; float's 6e-8 resolution would leave errors of
/// the order of the egomotion noise itself, and the noise-free recovery must be ~1e-9 relative.
/// Heap-free: every solve works on a caller's span and fixed-size Eigen matrices, with loops
/// bounded by kMaxCalibSegments.

#include <cstddef>
#include <cstdint>

#include "agv/core/angle.hpp"
#include "agv/core/capacities.hpp"
#include "agv/core/pose2.hpp"
#include "agv/core/span.hpp"
#include "agv/core/status.hpp"
#include "agv/kinematics/tricycle.hpp"

namespace agv {

/// One constant-steering, constant-direction path segment between two standstills.
struct CalibSegment {
  std::int64_t ticks = 0;  ///< n^k: signed drive-encoder ticks over the segment (+ forward)
  double steering = 0.0;   ///< a^k [rad]: constant measured steering angle (encoder, without offset)
  Pose2d egomotion{};      ///< s^k: laser pose at the end expressed in the laser frame at the start [m, rad]
};

/// Tolerances and prior knowledge for the closed-form solves. Defaults suit a forklift driving
/// beta = 180 deg arcs at 18..50 deg steering.
struct CalibrationOptions {
  /// Nominal vehicle: `wheelbase` is the known L [m] used as is; `driveScale` and the offsets are
  /// only used to unwrap the laser's rotation (observed in (-pi, pi]) to the full segment
  /// rotation, so the nominal rotation of every segment must be within pi of the true one
  /// (e.g. s_w within +-30 % for half circles).
  TricycleParams nominal{};
  /// Two steering angles count as different when |sin(a_i - a_j)| >= sin of this [rad].
  double minSteeringSeparation = deg2rad(1.0);
  /// A segment has non-zero travel when |n^k| >= this many ticks.
  std::int64_t minTicks = 1;
  /// The laser rotation of a segment is "not a multiple of 2 pi" when it differs from one by at
  /// least this much [rad].
  double minRotation = deg2rad(5.0);
  /// The laser translation of a segment is "non-zero" when its length is at least this [m].
  double minTranslation = 0.05;
  /// Refuse (IllConditioned) when a condition number exceeds this.
  double maxConditionNumber = 1e8;
};

/// The observability condition a solve checked; `None` when all held.
enum class CalibCondition : std::uint8_t {
  None = 0,
  SegmentCount,               ///< at least two segments (and at most kMaxCalibSegments)
  FiniteInput,                ///< every steering angle and egomotion is finite
  SteeringDiversity,          ///< STC: two segments with travel and steering not differing by k*pi
  ForwardSteeringDiversity,   ///< ATC: the same among forward segments
  BackwardSteeringDiversity,  ///< ATC: the same among backward segments
  LaserRotation,              ///< a segment whose laser rotation is not a multiple of 2 pi
  LaserTranslation,           ///< a segment with non-zero laser translation
  OdometryConditioning,       ///< condition number of the odometry normal matrix within bounds
  LaserConditioning,          ///< condition number of the laser-pose normal matrix within bounds
  PositiveScale,              ///< the solved driving scale is finite and positive
};

/// Short stable name of a condition (e.g. "backward steering diversity"). Never null.
const char* toString(CalibCondition condition) noexcept;

/// What a solve found about its data: which conditions hold, how well conditioned the problem
/// is, and how well the model fits. Filled even when the solve is refused.
struct CalibrationReport {
  Status status = Status::NotInitialized;        ///< the solve's result
  CalibCondition failed = CalibCondition::None;  ///< first condition that failed (None on success)
  std::size_t segmentCount = 0;
  std::size_t forwardCount = 0;           ///< segments with n^k >= minTicks
  std::size_t backwardCount = 0;          ///< segments with n^k <= -minTicks
  std::size_t firstNonFinite = SIZE_MAX;  ///< index of the first segment with a non-finite value
  bool steeringDiverse = false;           ///< STC condition over all segments
  bool forwardSteeringDiverse = false;    ///< ATC condition, forward segments
  bool backwardSteeringDiverse = false;   ///< ATC condition, backward segments
  bool laserRotationObserved = false;     ///< some laser rotation is not a multiple of 2 pi
  bool laserTranslationObserved = false;  ///< some laser translation is non-zero
  /// Condition numbers (max/min eigenvalue) of the 2x2 odometry normal matrices, rows
  /// n^k (sin a^k, cos a^k); for symmetric steering sets they equal
  /// max(n, sum cot^2 a)/min(n, sum cot^2 a). Infinity when singular, 0 when not computed.
  double conditionStc = 0.0;
  double conditionForward = 0.0;
  double conditionBackward = 0.0;
  /// Condition number of the laser-pose normal matrix (unknowns l_t [m] and the unit rotation).
  double conditionLaser = 0.0;
  double rotationRms = 0.0;     ///< RMS of the segment rotation residuals of the odometry fit [rad]
  double translationRms = 0.0;  ///< RMS of the laser-pose translation residuals [m]
  double lambda = 0.0;          ///< ATC Lagrange multiplier (0 for STC)
};

/// Result of a closed-form calibration.
struct CalibrationResult {
  TricycleParams params{};  ///< wheelbase copied from the options; s_w, alpha_F, alpha_B solved
  Pose2d laserPose{};       ///< l: laser frame in the vehicle (logical point) frame
  CalibrationReport report{};
};

/// Which odometry model a solve uses.
enum class CalibModel : std::uint8_t {
  Stc,  ///< one steering offset for both directions (alpha_F = alpha_B)
  Atc,  ///< separate forward and backward offsets
};

/// Checks the observability conditions of `model` on `segments` and fills `report` (counts,
/// flags, odometry condition numbers, `failed`, `status`). Returns Ok, NotEnoughData,
/// CapacityExceeded, NonFiniteInput, Unobservable or IllConditioned (the first failure, in the
/// order of CalibCondition). Does not solve.
Status checkCalibrationObservability(Span<const CalibSegment> segments, CalibModel model,
                                     const CalibrationOptions& options, CalibrationReport& report) noexcept;

/// STC closed form: s_w and alpha_F = alpha_B from the segment rotations (linear least squares),
/// then the laser pose (see estimateLaserPose). Fills `result` (report even on refusal).
Status calibrateStc(Span<const CalibSegment> segments, const CalibrationOptions& options,
                    CalibrationResult& result) noexcept;

/// ATC closed form: s_w, alpha_F, alpha_B as the least-squares fit of the rotations under the
/// quadratic equality constraint |psi_F| = |psi_B| (one bracketed 1-D root search for the
/// multiplier), then the laser pose. Needs forward and backward segments.
Status calibrateAtc(Span<const CalibSegment> segments, const CalibrationOptions& options,
                    CalibrationResult& result) noexcept;

/// Laser-pose closed form for known odometry `params`: least squares of l ⊕ s^k = r^k ⊕ l over
/// (lx, ly, cos ltheta, sin ltheta) with cos^2 + sin^2 = 1; of the two stationary points the one
/// with the lower cost is returned. Updates report.conditionLaser / translationRms /
/// laser flags; refuses (Unobservable) without a rotating and a translating segment.
Status estimateLaserPose(Span<const CalibSegment> segments, const TricycleParams& params,
                         const CalibrationOptions& options, Pose2d& laserPose, CalibrationReport& report) noexcept;

/// Full rotation of segment k, unwrapped from the laser's (-pi, pi] rotation with the nominal
/// parameters of `options` [rad].
double unwrappedSegmentRotation(const CalibSegment& segment, const CalibrationOptions& options) noexcept;

/// The laser egomotion the model predicts for `segment`: l^-1 ⊕ r ⊕ l.
Pose2d predictedEgomotion(const CalibSegment& segment, const TricycleParams& params, const Pose2d& laserPose) noexcept;

}  // namespace agv
