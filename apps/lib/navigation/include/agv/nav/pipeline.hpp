#pragma once
/// @file pipeline.hpp
/// The vehicle's navigation cycle, once, written against the HAL only: every program that
/// navigates a vehicle (`agvnav-vehicle` on the real drivers, `agvnav-hil` on the simulated ones,
/// the vcan VM test) constructs this class and calls `cycle()`.
///
/// One cycle, in this order:
///   1. encoders -> `TricycleOdometry` (RK2) -> EKF prediction, and the motion history;
///   2. PLC commands (Localize from a set-pose, Stop, Calibrate: refused, see below);
///   3. one laser sweep -> reflectors (each at its own stamp when the device stamps them, else at
///      its bearing) and FALKO corners (at their beam) moved to the end of the sweep with the
///      odometry's motion (`SweepCompensation`) -> association with the `LandmarkMap`, EKF
///      correction, map lifecycle (`Localizer::correct`);
///   4. when due on the `hal::Clock`, one `hal::PoseReport` with the health bits to the PLC link.
///
/// Lifecycle (in the spirit of ros2_control's hardware-interface split: the devices are opened
/// and closed by their owner; the pipeline only reads and writes them):
///
///   Unconfigured --configure()--> Inactive --activate()--> Active --deactivate()--> Inactive
///         any state --fault(why)--> Fault --configure()--> Inactive
///
/// `configure()` checks the parameters and the map; only an Active pipeline touches the devices.
/// A device whose `read()` reports `InvalidArgument` (it was given a configuration it refuses) can
/// never deliver: the pipeline enters Fault by itself. In Fault it publishes `NavMode::Lost` with
/// the reason every `publishPeriod` and reads nothing else.
///
/// Being Active is not localizing: the pose is tracked from a set-pose (PLC `Localize`, or
/// `setPose()`) until a PLC `Stop` or `deactivate()`; meanwhile reports say `NavMode::Idle`.
///
/// Everything is allocated by the constructor; `cycle()` does not allocate and never blocks (it
/// only polls the devices, which never block by the HAL's contract). Not thread-safe.

#include <cstdint>
#include <memory>

#include "agv/core/pose2.hpp"
#include "agv/core/result.hpp"
#include "agv/core/span.hpp"
#include "agv/core/status.hpp"
#include "agv/core/timestamp.hpp"
#include "agv/falko/falko_params.hpp"
#include "agv/hal/clock.hpp"
#include "agv/hal/encoder_source.hpp"
#include "agv/hal/laser_measurement.hpp"
#include "agv/hal/laser_source.hpp"
#include "agv/hal/plc_link.hpp"
#include "agv/kinematics/tricycle.hpp"
#include "agv/localization/field_relocalizer.hpp"
#include "agv/localization/landmark_map.hpp"
#include "agv/localization/localizer.hpp"
#include "agv/localization/map_changes.hpp"
#include "agv/localization/odometry.hpp"
#include "agv/localization/surface_map.hpp"
#include "agv/loop/global_localizer.hpp"

namespace agv::nav {

/// Which observations a sweep gives and which of them correct the pose.
struct ObservationParams {
  /// Reflector centres reported by the laser correct the pose (when the laser reports them).
  bool reflectors = true;
  /// FALKO corners correct the pose.
  bool corners = false;
  /// Detect FALKO corners even when they do not correct the pose (a mapping run collects them
  /// from `Pipeline::sweepCorners()`). Implied by `corners`.
  bool detectCorners = false;
  /// Keep each sweep's valid beams as points de-skewed to the sweep's reference instant
  /// (`Pipeline::sweepPoints()`, for a mapping run). Implied by a likelihood field being set.
  bool collectScanPoints = false;
  /// Without a likelihood field: match each sweep against the surfaces of the sweeps before it
  /// (`SurfaceMap`, `PipelineParams::surface`) and add the sweep's new surfaces when the cycle
  /// allows (`mayExtendSurfaceMap`): natural navigation without a mapping run, anchored at the
  /// set-pose. The map is dropped at every set-pose and relocalization.
  bool surfaceMap = false;
  /// With a likelihood field: keep the surfaces the mapping run did not see (`map_changes.hpp`:
  /// found at the poses of fused matches, kept in a `SurfaceMap` of their own,
  /// `PipelineParams::surface`) and leave the sweep points that lie on them out of the match. A
  /// pallet moved since the mapping run then no longer pulls the pose towards where it stood.
  bool mapChanges = false;
  /// With a likelihood field: keep a surface map of the localized sweeps (`PipelineParams::surface`,
  /// written per `mayExtendFallbackMap`) and match a sweep against it when its match against the
  /// field is not fused (off the map: a lane the mapping run never drove, a hall extended since):
  /// the estimate follows those surfaces instead of the odometry's drift, the covariance keeps
  /// growing as dead reckoning's (`Localizer::correct` with a fallback). Dropped at every set-pose,
  /// relocalization and re-synchronisation. Off by default: measured on the real logs only
  /// (docs/localization.md, "Off the map: the surface map as the field's fallback").
  bool surfaceFallback = false;
};

/// The pipeline's search: the core defaults with `refutedMargin` 1. The pipeline searches every
/// sweep, the confirming ones too, and a candidate holds only while each sweep's search finds it
/// again and its rivals stay refuted on the evidence of all its sweeps (`RelocConfirmer`); with
/// that, margin 1 against a refuted runner-up gave no more wrong poses under adversarial decoys
/// and missed detections than margin 2, and finds 95.5-95.8 % of the HIL's unique cold starts
/// within 3 sweeps against 92.9-93.8 % (docs/loop-closure.md, "Confirmation by every sweep").
/// `minNetSupport` 3: after the landmarks a place expects in clear view and nothing showed, three
/// must remain, what fixes a rigid motion. On the FALKO corner map (about half the corners in view
/// detected, lanes of identical pallet blocks) a place 1.42 m along a lane won with 4 corners and 2
/// missed, 3 sweeps running (HIL seed 37); with the rule the corner stage finds fewer poses and none
/// wrong, the reflector stage the same (docs/loop-closure.md, "Net support").
inline GlobalLocalizerParams relocalizationSearchDefaults() noexcept {
  GlobalLocalizerParams p;
  p.refutedMargin = 1;
  p.minNetSupport = 3;
  return p;
}

/// Relocalization: finding the pose on the map with no prior (`GlobalLocalizer`), confirming it over
/// the next sweeps (`RelocConfirmer`), and only then (re-)initialising the localizer. With a
/// likelihood field set (natural navigation) the search is the field's instead (`FieldRelocalizer`
/// on a sweep's points, spread over the cycles, confirmed by matching the next sweeps near the
/// candidate carried by the odometry): the surfaces are that vehicle's map, the landmarks a sparse
/// extra.
struct RelocalizationParams {
  /// Search when the localizer is lost, and (with `atStart`) when activated without a set-pose.
  /// A PLC Stop ends the search until the next Localize; a set-pose always wins.
  bool enabled = true;
  bool atStart = true;
  /// `laserMount` is taken from the localizer's laser model.
  GlobalLocalizerParams search = relocalizationSearchDefaults();
  /// Two further sweeps after the search's: three sweeps agree before the restart. Standing, a
  /// confirming sweep adds new detection noise, not a new view: more would only add time.
  RelocConfirmParams confirm{2, 0.15, 4, 0.6};
  double positionStdDev = 0.05;  ///< [m] 1-sigma of the pose the localizer restarts with
  double headingStdDev = 0.02;   ///< [rad]
  /// `HealthBit::Relocalized` stays set this long after a relocalization.
  Duration relocalizedHold = Duration::fromSeconds(2.0);
  /// With a likelihood field: the field search (grid, fit and ambiguity limits, confirmation
  /// window; docs/localization.md, "Field relocalization").
  FieldRelocalizerParams field{};
  /// Grid poses the field search visits per sweep (its time per cycle: about 0.65 us per pose on
  /// the development VM, so 20 000 are ~13 ms; a 41 m x 26 m hall takes ~180 sweeps, 7 s at 25 Hz).
  std::uint32_t fieldPosesPerSweep = 20000;
  /// Sweeps after the search's whose match must confirm the candidate before the restart (and
  /// the motion `field.confirmTravel` / `confirmTurn` asks of them: none by default, the vehicle
  /// stands while lost).
  std::uint32_t fieldConfirmSweeps = 2;
  /// [m] the field search covers this disc around the last estimate when the localizer was lost
  /// (0: the whole field, also at start, where there is no estimate).
  double fieldRegionRadius = 0.0;
};

/// Everything the pipeline needs besides the devices and the map. Defaults are those of a vehicle.
struct PipelineParams {
  TricycleParams kinematics{};          ///< the calibrated vehicle (wheelbase, s_w, alpha_F/B)
  TricycleNoiseParams odometryNoise{};  ///< odometry noise model of the EKF prediction
  LocalizerParams localizer{};          ///< EKF, association, map lifecycle; `laser.mounting` = calibrated l
  ObservationParams observations{};     ///< what corrects the pose
  FalkoParams falko{};                  ///< corner detector (thesis defaults)
  SurfaceMapParams surface{};           ///< with `observations.surfaceMap` or `observations.mapChanges`
  MapChangeParams changes{};            ///< with `observations.mapChanges`
  RelocalizationParams relocalization{};
  /// One report per period on the `hal::Clock` (a late cycle publishes once and the schedule
  /// restarts from it: no burst). Zero: every cycle publishes.
  Duration publishPeriod = Duration::fromMilliseconds(20);
  /// Encoder samples handled per cycle at most (the rest wait in the device for the next cycle).
  std::uint32_t maxSamplesPerCycle = 32;
  /// PLC commands handled per cycle at most.
  std::uint32_t maxCommandsPerCycle = 8;
  double setPosePositionStdDev = 0.05;  ///< [m] 1-sigma of a set-pose, per coordinate
  double setPoseHeadingStdDev = 0.02;   ///< [rad] 1-sigma of a set-pose heading
  /// Published as `HealthBit::CalibrationValid` (the owner loaded and checked a calibration).
  bool calibrationValid = true;

  /// `Ok`, or the first refusal (`NonFiniteInput` for a NaN / infinite value, `InvalidArgument` for
  /// a value outside its domain) of: `kinematics.validate()`, `odometryNoise.validate()`,
  /// `localizer.validate()`, `validate(falko)`, `surface.validate()` (with
  /// `observations.surfaceMap` or `mapChanges`), `changes.validate()` (with `mapChanges`), then the pipeline's own
  /// values (negative set-pose sigma or publish period, zero per-cycle bounds).
  Status validate() const noexcept;
};

/// Lifecycle state (see the file comment).
enum class PipelineState : std::uint8_t { Unconfigured, Inactive, Active, Fault };
/// Stable lower-case name of a state. Never null.
const char* toString(PipelineState state) noexcept;

/// Running totals.
struct PipelineCounters {
  std::uint64_t cycles = 0;
  std::uint64_t encoderSamples = 0;   ///< samples read
  std::uint64_t sweeps = 0;           ///< laser sweeps read
  std::uint64_t corrections = 0;      ///< sweeps that corrected the pose (localizing)
  std::uint64_t publications = 0;     ///< reports given to the PLC link
  std::uint64_t publishFailures = 0;  ///< of those, refused by the link (not queued: the next one follows)
  std::uint64_t commands = 0;         ///< PLC commands read
  std::uint64_t refusedCommands = 0;  ///< of which not carried out (Calibrate)
  std::uint64_t setPoses = 0;         ///< set-poses applied
  std::uint64_t searches = 0;         ///< global localization calls (every sweep while searching or confirming)
  std::uint64_t fieldSearches = 0;    ///< field searches started (with a likelihood field; each spans sweeps)
  std::uint64_t candidates = 0;       ///< of which found a unique, supported pose (then confirmed or not)
  std::uint64_t ambiguous = 0;        ///< of which refused as ambiguous
  std::uint64_t unconfirmed = 0;      ///< candidates a later sweep did not support
  std::uint64_t relocalizations = 0;  ///< confirmed: the localizer restarted at the found pose
};

/// What the last cycle did: enough for a caller to collect figures without touching the devices.
struct CycleReport {
  std::uint32_t encoderSamples = 0;             ///< samples read in this cycle
  Status encoderRead = Status::NotInitialized;  ///< status of the last encoder read
  Status laserRead = Status::NotInitialized;    ///< status of the laser read
  bool sweep = false;                           ///< a sweep was read (see `lastMeasurement()`, `sweepCorners()`)
  bool corrected = false;                       ///< ... and it corrected the pose (`localizer().health()`)
  Timestamp sweepReference;                     ///< end of that sweep: the stamp of its compensated points
  std::uint16_t reflectors = 0;                 ///< reflectors the laser reported in that sweep
  std::uint16_t corners = 0;                    ///< refined FALKO corners detected in that sweep
  bool published = false;                       ///< a report went to the PLC link
  bool searching = false;                       ///< relocalizing (see `RelocalizationParams`)
  bool relocalized = false;                     ///< this cycle restarted the localizer at a found pose
  RelocOutcome searchOutcome = RelocOutcome::EmptyInput;  ///< of this cycle's search (when one ran)
  bool searched = false;                                  ///< a search ran in this cycle
  /// With a likelihood field: a field search ended in this cycle, and how.
  bool fieldSearchEnded = false;
  FieldRelocOutcome fieldSearchOutcome = FieldRelocOutcome::NoCandidate;
  /// Sweep points left out of this cycle's match as lying on surfaces changed since the mapping
  /// run (`ObservationParams::mapChanges`).
  std::uint32_t changedPointsDropped = 0;
  /// With `ObservationParams::surfaceFallback`: the sweep was matched against the fallback surface
  /// map (its field match was not fused), and that match moved the estimate.
  bool fallbackMatched = false;
  bool fallbackFused = false;
};

/// Receives one line per noteworthy event (device state changes, refused commands, lifecycle
/// transitions); rare, never in the steady state. `context` is the pointer given with it.
using PipelineLogSink = void (*)(void* context, const char* line);

/// The devices the pipeline reads and publishes to; the caller owns them, opens and closes them,
/// and keeps them alive as long as the pipeline.
struct PipelineDevices {
  hal::EncoderSource& encoders;
  hal::LaserSource& laser;
  hal::PlcLink& plc;
  const hal::Clock& clock;
};

class Pipeline {
 public:
  /// Capacity of `sweepCorners()`.
  static constexpr std::size_t kMaxCorners = kMaxKeypoints;

  /// Builds the odometry, the localizer and the detector (allocates here, once). `map` is kept by
  /// reference (the dynamic map is updated in place). State: Unconfigured.
  Pipeline(const PipelineParams& params, LandmarkMap& map, const PipelineDevices& devices);
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  /// Unconfigured / Inactive / Fault -> Inactive: checks the parameters (`PipelineParams::validate`)
  /// and resets the odometry, the localizer, the counters and the schedule. The map is kept.
  /// The parameters' status when refused (state unchanged); `InvalidArgument` while Active.
  Status configure() noexcept;
  /// Inactive -> Active. `NotInitialized` unless Inactive.
  Status activate() noexcept;
  /// Active -> Inactive: stops localizing and publishes one Idle report. `NotInitialized` unless Active.
  Status deactivate() noexcept;
  /// Any state -> Fault, with `why` published as the last status (a non-Ok value; `Ok` is taken
  /// as `DeviceFault`). Localizing stops.
  void fault(Status why) noexcept;
  PipelineState state() const noexcept;
  /// The reason of the Fault state (`Ok` otherwise).
  Status faultReason() const noexcept;

  /// Starts localizing at `pose` (map frame, logical point) with the set-pose sigmas of the
  /// parameters: exactly as a PLC `Localize`, applied in the next active cycle after its encoder
  /// samples (the pose holds at the newest one). `NonFiniteInput` for a non-finite pose;
  /// `NotInitialized` in Unconfigured or Fault.
  Status setPose(const Pose2d& pose) noexcept;

  /// Replaces the calibration (kinematics and the laser's mounting), e.g. after the on-vehicle
  /// calibration routine wrote a new file: the odometry, the localizer and the relocalization
  /// search are rebuilt with it (this allocates: once per calibration, never per cycle). A
  /// localizing pipeline goes on from its current pose as from a set-pose (with the set-pose
  /// sigmas); the counters are kept. `InvalidArgument` (nothing changed) when the parameters
  /// refuse the values; `NotInitialized` in Unconfigured or Fault.
  Status recalibrate(const TricycleParams& kinematics, const Pose2d& laserMounting);

  /// One cycle (see the file comment). Returns `Ok` when Active, else the state's status
  /// (`NotInitialized`, or the fault reason in Fault, where only the report is published).
  Status cycle() noexcept;

  /// True while the pose is tracked (from a set-pose or a relocalization until Stop / deactivate /
  /// fault).
  bool localizing() const noexcept;
  /// True while relocalizing (searching the map, or confirming a candidate).
  bool searching() const noexcept;
  const Localizer& localizer() const noexcept;
  const LandmarkMap& map() const noexcept;
  const PipelineCounters& counters() const noexcept;
  const CycleReport& lastCycle() const noexcept;
  /// `hal::HealthBit`s of the last report.
  std::uint16_t healthBits() const noexcept;
  /// The last sweep read (valid when a cycle reported `sweep`; kept until the next sweep).
  const hal::LaserMeasurement& lastMeasurement() const noexcept;
  /// Refined FALKO corners of the last sweep, in the sensor frame at `lastCycle().sweepReference`
  /// (empty unless corners are detected, see `ObservationParams`).
  Span<const Pose2d::Vector2> sweepCorners() const noexcept;
  /// The valid beams of the last sweep as points in the sensor frame at
  /// `lastCycle().sweepReference` (empty unless `collectScanPoints`, a likelihood field or the
  /// surface map is set; with the surface map alone only the beams within its range).
  Span<const MatchPoint> sweepPoints() const noexcept;
  /// The surface map of the earlier sweeps (`ObservationParams::surfaceMap`), null without one.
  const SurfaceMapBase* surfaceMap() const noexcept;
  /// The surfaces the mapping run did not see (`ObservationParams::mapChanges`), null without.
  const SurfaceMapBase* mapChanges() const noexcept;
  /// The localizer's pose carried to `t` with the odometry's motion between its stamp and `t`
  /// (within the motion history's reach, 0.5 s). `NotEnoughData` without a history, `Lost` when not
  /// localizing.
  Result<Pose2d> poseAt(Timestamp t) const noexcept;

  /// The surfaces of a mapping run for scan-to-map matching (`Localizer::correct` with a
  /// likelihood field; each sweep's valid beams de-skewed to its reference instant). Null: none
  /// (the default). The owner keeps the field alive and unchanged while it is set. The first field
  /// set allocates the field search's scratch (about 90 KB; a set-up call, never in the cycle);
  /// a field search under way is abandoned.
  void setLikelihoodField(const LikelihoodFieldBase* field);

  /// Where the log lines go (none by default).
  void setLogSink(PipelineLogSink sink, void* context) noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace agv::nav
