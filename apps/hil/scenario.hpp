#pragma once
/// @file scenario.hpp
/// The HIL scenario: the simulated vehicle drives the world's paths while the navigation side
/// (the localizer, with dead reckoning as a comparison) estimates its pose; results per run with the
/// trajectories for plots.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "agv/core/pose2.hpp"
#include "agv/kinematics/tricycle.hpp"
#include "agv/localization/landmark_map.hpp"
#include "agv/localization/likelihood_field.hpp"
#include "agv/loop/global_localizer.hpp"
#include "agv/mapping/corner_mapper.hpp"
#include "agv/mapping/surface_mapper.hpp"
#include "agv/nav/pipeline.hpp"
#include "agv/sim/can_encoder_source.hpp"
#include "agv/sim/pallet_moves.hpp"
#include "agv/sim/sim_laser.hpp"
#include "agv/sim/sim_vehicle.hpp"
#include "agv/sim/world.hpp"

namespace agv::hil {

/// What a vehicle's navigation believes about it before calibration (drawing values).
struct NominalVehicle {
  TricycleParams kinematics{1.5, 1.0e-4, 0.0, 0.0};
  Pose2d laserMount{1.6, 0.0, 0.0};
};

/// What the localizer is fed with in a run (docs/hil.md, "Localization modes").
enum class LocalizationMode {
  Reflectors,  ///< reflector centres against the surveyed reflector map (static)
  Mapping,     ///< reflectors (surveyed) for the pose; FALKO corners accumulated into a corner map
  /// FALKO corners against the frozen map of the mapping runs (no reflector), and the surface map
  /// of the run's sweeps unless `ScenarioConfig::cornerModesSurfaceMap` is off
  StaticFalko,
  /// FALKO corners in a dynamic map starting empty, and the surface map of the run's sweeps unless
  /// `ScenarioConfig::cornerModesSurfaceMap` is off
  Dynamic,
  /// Natural navigation: the frozen FALKO corners of the mapping runs and scan matching against
  /// the likelihood field of their scans (no reflector)
  Natural,
};
/// JSON / printout name of a mode.
const char* modeName(LocalizationMode mode) noexcept;

/// What a run reads or fills besides the landmark map.
struct RunMaps {
  mapping::CornerMapper* corners = nullptr;    ///< Mapping: the FALKO corners are accumulated here
  mapping::SurfaceMapper* surfaces = nullptr;  ///< Mapping: every sweep's points, at the localizer's pose
  const LikelihoodFieldBase* field = nullptr;  ///< Natural: the scans are matched against it
};

/// How far a real floor and drive train take odometry from the calibrated model, per run of a
/// session (docs/hil.md, "Odometry error sources"). The vehicle-constant effects (traction and
/// lateral slip, steering backlash) are in `sim::SimVehicleParams` (see `floorVehicle`); these
/// change between calibration and operation and are drawn per run.
struct FloorEffects {
  /// Relative change of the drive wheel's effective radius since calibration: a loaded pallet
  /// compressing the polyurethane tread, and wear (std per run).
  double radiusChangeStdDev = 0.002;
  /// [rad] steering encoder offset drift since calibration (std per run).
  double steerDriftStdDev = deg2rad(0.05);
};

/// The simulated vehicle with the odometry error sources of a real floor and drive train on top of
/// `SimVehicleParams`' defaults: traction slip 1 % per m/s^2, lateral slip 0.01 rad per m/s^2,
/// steering backlash 0.3 deg (values in docs/hil.md, "Odometry error sources").
sim::SimVehicleParams floorVehicle();

/// Settings of one HIL session.
struct ScenarioConfig {
  int runsPerPath = 6;
  std::uint64_t seed = 1;
  sim::SimVehicleParams vehicle = floorVehicle();  ///< the truth (at calibration)
  FloorEffects floor;                              ///< what changes between calibration and each run
  NominalVehicle nominal;                          ///< what the estimators start from (drawing values)
  NominalVehicle estimate;                         ///< what the navigation uses: the calibration result, else nominal
  sim::SimLaserParams laser;
  /// The encoders' CAN bus (nodes, mapping, counter start): every encoder sample the navigation
  /// and the calibration routine get is decoded from its frames. 14-bit steering encoder, as
  /// `vehicle.steerEncoderBits`.
  sim::SimCanEncodersParams can = sim::defaultSimCanEncoders(1U << 14U);
  double startPositionStdDev = 0.01;  ///< [m] how precisely the vehicle is placed at a path start
  double startHeadingStdDev = 0.002;  ///< [rad]
  Duration controlPeriod = Duration::fromMilliseconds(20);
  double maxRunSeconds = 120.0;  ///< a run not finished by then is an error
  /// Relocalization stage: cold starts and kidnappings (see `runRelocalization`).
  int relocColdStarts = 20;
  int relocKidnaps = 8;
  double relocSeconds = 4.0;  ///< [s] of simulated time per trial at most
  /// Also run the trials on the natural mode's likelihood field (stage `relocalization_field`:
  /// the field search spread over the sweeps; measured, off by default for the main job's time).
  bool relocField = false;
  /// [s] per field trial at most: a whole-hall search (41 m x 26 m, ~3.6 M grid poses at 20 000 per
  /// sweep, 12.5 Hz) takes ~15 s, then 12 refining and 2 confirming sweeps.
  double relocFieldSeconds = 25.0;
  /// Spurious reflector detections per sweep in each relocalization trial (0: none, the default):
  /// fixed places 1-20 m from the standing vehicle, as shiny objects nearby would give.
  int relocSpurious = 0;
  /// Probability that the laser misses a visible reflector in a sweep of a relocalization trial
  /// (0: none, the default; the simulated laser itself detects every visible pole).
  double relocMissProbability = 0.0;
  /// Adversarial decoys per relocalization trial (0: none, the default): reflector detections at
  /// the places where the oracle's best wrong pose expects landmarks the true view lacks (see
  /// `relocDecoys` in scenario.cpp), the worst case for the ambiguity margin.
  int relocDecoys = 0;
  /// The relocalization search's ambiguity margin (GlobalLocalizerParams::ambiguityMargin).
  std::size_t relocAmbiguityMargin = nav::relocalizationSearchDefaults().ambiguityMargin;
  /// The margin against a negative-evidence-refuted runner-up (GlobalLocalizerParams::refutedMargin;
  /// the pipeline's default, nav::relocalizationSearchDefaults()).
  std::size_t relocRefutedMargin = nav::relocalizationSearchDefaults().refutedMargin;
  /// Dynamic mode: matches before a new corner corrects the pose (`LocalizerParams::minHitsToCorrect`).
  std::int16_t dynamicMinHitsToCorrect = 10;
  /// Missions (`runMissions`): runs per mission, standstill at each operation point (pick or drop)
  /// before the next leg, and how the pallets are rearranged for each run.
  int runsPerMission = 4;
  double dwellSeconds = 2.0;
  sim::PalletMoveParams palletMoves;
  /// The FALKO corner modes (dynamic and static_falko): scan matching against the surfaces of the
  /// run's earlier sweeps (`ObservationParams::surfaceMap`) next to the corner map, dynamic or
  /// frozen; off: the corners alone.
  bool cornerModesSurfaceMap = true;
  /// Scan matching in every mode: `ScanMatchParams::adaptiveBand` (off by default).
  bool adaptiveBand = false;
  /// Natural mode: the surfaces the mapping run did not see are kept and their points left out of
  /// the match (`ObservationParams::mapChanges`).
  bool mapChanges = true;
  /// The natural mode keeps a surface map of its sweeps as the field's fallback off the map
  /// (`ObservationParams::surfaceFallback`; a measured option, off by default).
  bool surfaceFallback = false;
  /// Threads running the localizing runs of a mode side by side (0: the machine's cores, at most 8;
  /// mapping runs always run one after the other). Every run is seeded by its index and localizes
  /// on its own copy of the map, so the results do not depend on this.
  int jobs = 0;
};

/// One sample of a run's history (every control period).
struct TrajectorySample {
  double distance = 0.0;  ///< [m] travelled by the logical point
  Pose2d truth;
  Pose2d withTruth;     ///< dead reckoning with the true parameters
  Pose2d withNominal;   ///< dead reckoning with the nominal (uncalibrated) parameters
  Pose2d withEstimate;  ///< dead reckoning with the parameters the navigation has (calibrated)
  Pose2d localized;     ///< the localizer's pose (what the PLC receives)
};

/// Where a run stopped at an operation point (the end of a path, every `stop` of a mission).
struct OperationPoint {
  int index = 0;          ///< 1-based
  double distance = 0.0;  ///< [m] travelled since the start of the run
  Pose2d truth;
  Pose2d localized;  ///< the last pose the PLC received at the stop
  Pose2d withTruth;
  Pose2d withNominal;
  Pose2d withEstimate;
  bool lost = false;  ///< the localizer was lost at the stop
};

/// Result of one run along one path (or one mission).
struct RunResult {
  std::string path;
  int run = 0;
  bool finished = false;  ///< reached the end point and stopped
  double simSeconds = 0.0;
  double distance = 0.0;  ///< [m] logical-point travel
  Pose2d finalTruth;
  Pose2d finalWithTruth;
  Pose2d finalWithNominal;
  Pose2d finalWithEstimate;  ///< calibrated dead reckoning at the end (comparison)
  LocalizationMode mode = LocalizationMode::Reflectors;
  Pose2d finalLocalized;  ///< the last pose published to the PLC (the localizer's)
  bool localizerLost = false;
  double meanUsedPerScan = 0.0;       ///< landmarks used per correction
  std::size_t scansWithoutFix = 0;    ///< corrections with fewer than 2 landmarks used
  double meanKeypointsPerScan = 0.0;  ///< FALKO keypoints per scan (corner modes)
  std::size_t plcReports = 0;
  std::size_t scans = 0;
  double meanReflectorsPerScan = 0.0;
  std::size_t minReflectorsPerScan = 0;
  double meanValidBeamFraction = 0.0;
  sim::CanBusCounters can;  ///< the encoder frames of the run
  std::vector<TrajectorySample> history;
  std::vector<OperationPoint> stops;  ///< one per operation point reached (a path: its end)
  bool mission = false;               ///< `path` names a mission
  sim::PalletChanges pallets;         ///< missions: how the pallets were rearranged for this run
  double palletFingerprint = 0.0;     ///< missions: `sim::palletFingerprint` of the run's layout
};

/// Runs `runsPerPath` runs of `mode` on each path of `world` listed in `pathIndices` (all when
/// empty), the localizer using `map` (Dynamic mode clears it before each run and runs the
/// lifecycle on it); in Mapping mode the FALKO corners and the scans are accumulated into `maps`;
/// in Natural mode the scans are matched against `maps.field`; `seedSalt` separates the
/// random streams of sessions that must not repeat each other (mapping runs). The runs go on
/// `config.jobs` threads (see there), each on its own copy of `map`; `progress` is called on the
/// calling thread after each run, in run order.
/// Returns false (with `error`) on a setup problem (no path, invalid laser parameters, Natural without a field).
bool runScenario(const sim::World& world, const ScenarioConfig& config, LocalizationMode mode, LandmarkMap& map,
                 const RunMaps& maps, const std::vector<std::size_t>& pathIndices, int runsPerPath,
                 std::uint64_t seedSalt, const std::function<void(const RunResult&, int index, int total)>& progress,
                 std::vector<RunResult>* results, std::string* error);

/// Runs `runsPerMission` runs of `mode` on each mission of `world` (the maps as in `runScenario`).
/// Each run drives the mission's legs one after the other with one pipeline, standing
/// `dwellSeconds` at each operation point; with `movePallets` the run's world is `world` with its
/// pallets rearranged (`sim::rearrangePallets`, seeded by the session seed, the mission and the
/// run, not by the mode: every mode meets the same layouts), else `world` itself (mapping runs).
/// Returns false (with `error`) on a setup problem (no mission, invalid laser parameters, ...).
bool runMissions(const sim::World& world, const ScenarioConfig& config, LocalizationMode mode, LandmarkMap& map,
                 const RunMaps& maps, int runsPerMission, std::uint64_t seedSalt, bool movePallets,
                 const std::function<void(const RunResult&, int index, int total)>& progress,
                 std::vector<RunResult>* results, std::string* error);

/// The points the rearranged pallets keep clear of: every sample of the missions' legs and the
/// laser's position 1.7 m ahead of it.
std::vector<sim::Point2> missionKeepClear(const sim::World& world);

/// One relocalization trial: the vehicle standing at `truth`, the pipeline on the surveyed
/// reflector map with no set-pose (a cold start), or localized by a set-pose elsewhere and then
/// carried to `truth` without odometry (kidnapped).
struct RelocTrial {
  bool kidnapped = false;
  Pose2d truth;                 ///< where the vehicle stands (after the kidnapping)
  bool lostDetected = false;    ///< kidnapped: the localizer declared itself lost
  bool found = false;           ///< the pipeline localized by relocalization
  std::size_t sweeps = 0;       ///< sweeps from the start of the search to the restart
  double positionError = 0.0;   ///< [m] of the pose published after the restart
  double headingError = 0.0;    ///< [rad]
  bool wrong = false;           ///< found, but more than 0.1 m or 1 deg from the truth
  std::uint64_t ambiguous = 0;  ///< searches refused as ambiguous
  // The uniqueness oracle (reloc_oracle.hpp) at `truth`, independent of the localizer.
  bool unique = false;                ///< no pose 0.5 m / 10 deg away explains the same reflectors
  std::size_t visibleReflectors = 0;  ///< reflectors visible from `truth` (noise-free)
  std::size_t otherSupport = 0;       ///< of those, the most a distinct pose puts on the map
  std::size_t decoys = 0;             ///< adversarial decoys placed (`ScenarioConfig::relocDecoys`)
  // Why a trial was not found: the pipeline's counters (searches, those that gave a candidate,
  // candidates a later sweep rejected) and, on the last sweep, a search of the same reflectors
  // with the pipeline's parameters: their count, its outcome, its best pose's inliers and the
  // landmarks that pose expects in clear view undetected, the same for its runner-up.
  std::uint64_t searches = 0;
  std::uint64_t candidates = 0;
  std::uint64_t unconfirmed = 0;
  std::size_t detected = 0;
  RelocOutcome lastOutcome = RelocOutcome::EmptyInput;
  std::size_t lastInliers = 0;
  std::size_t lastMissed = 0;
  std::size_t lastSecondInliers = 0;
  std::size_t lastSecondMissed = 0;
  // On the likelihood field (natural navigation): the field searches started and how the last
  // one that ended ended (no uniqueness oracle there: `unique` stays false).
  bool onField = false;
  std::uint64_t fieldSearches = 0;
  bool fieldSearchEnded = false;
  FieldRelocOutcome lastFieldOutcome = FieldRelocOutcome::NoCandidate;
};

/// `count` cold starts and `kidnaps` kidnappings at poses drawn on the world's paths (free space)
/// with random headings; each trial runs up to `maxSeconds` of simulated time. `map` is a static
/// map (only read) searched for landmarks of `kind`: `Reflector` (the surveyed map, the pipeline in
/// the reflector mode) or `Corner` (frozen FALKO corners, the pipeline in the static_falko mode;
/// the oracle then judges the map corners in clear view within FALKO's extraction range).
/// With `field` set, the pipeline runs in the natural mode on that likelihood field (and `map`'s
/// frozen corners) and searches the field (`FieldRelocalizer`, spread over the sweeps); `kind` is
/// then ignored and no oracle judges the trial.
std::vector<RelocTrial> runRelocalization(const sim::World& world, const ScenarioConfig& config, LandmarkMap& map,
                                          int count, int kidnaps, double maxSeconds,
                                          LandmarkKind kind = LandmarkKind::Reflector,
                                          const LikelihoodFieldBase* field = nullptr);

/// The surveyed reflector map: every reflector pole centre of `world` with Gaussian survey noise
/// `sigma` [m] per coordinate (seeded), as static surveyed landmarks with that sigma.
Status buildSurveyedReflectorMap(const sim::World& world, double sigma, std::uint64_t seed, LandmarkMap& map);

/// Position error [m] and absolute heading error [rad] of `estimate` against `truth`.
double positionError(const Pose2d& estimate, const Pose2d& truth) noexcept;
double headingError(const Pose2d& estimate, const Pose2d& truth) noexcept;

}  // namespace agv::hil
