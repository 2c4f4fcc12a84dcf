#pragma once
/// @file hil_report.hpp
/// What a HIL session reports: the stages it runs, the calibration stage's outcome, the summary
/// counts, and the JSON summary (`--json`, docs/hil.md) built from them.

#include <cstddef>
#include <string>
#include <vector>

#include "agv/calibration/calibration_routine.hpp"
#include "agv/report/json.hpp"
#include "agv/sim/can_encoder_source.hpp"
#include "scenario.hpp"

namespace agv::hil {

constexpr double kPositionRequirement = 0.02;   ///< [m] at the operation point
constexpr double kHeadingRequirementDeg = 0.1;  ///< [deg]

/// A stage of the full HIL and whether this build runs it (a wired stage may still fail).
struct Stage {
  const char* key;
  const char* name;
  bool wired;
  bool failed = false;
};

/// The calibration stage's outcome and the encoder frames its routine exchanged over CAN.
struct HilCalibration : calibration::CalibrationOutcome {
  sim::CanBusCounters can;
};

/// Everything the session measured, as the reports need it.
struct SessionResults {
  HilCalibration calibration;
  std::string calibrationStatus;       ///< the status name, or the failure message
  std::vector<RunResult> runs;         ///< localizer runs of every mode (dead reckoning inside)
  std::vector<RunResult> mappingRuns;  ///< the static FALKO mode's mapping runs
  std::size_t mapCorners = 0;          ///< corners frozen into the static FALKO map
  std::size_t fieldSurfacePoints = 0;  ///< surface points of the natural mode's likelihood field
  std::string naturalError;            ///< why the natural mode could not run (empty: it ran)
  std::vector<RelocTrial> reloc;       ///< the relocalization stage's trials (surveyed reflector map)
  /// The same trials' poses searched on the static FALKO corner map (`mapCorners` corners): the
  /// pipeline in the static_falko mode, no reflector in use.
  std::vector<RelocTrial> relocCorners;
  /// With `ScenarioConfig::relocField`: the same trials' poses searched on the natural mode's
  /// likelihood field (empty when not run).
  std::vector<RelocTrial> relocField;
  /// Missions (docs/hil.md, "Missions"): the runs of every mode with the pallets rearranged, the
  /// mapping runs on the original layout, and the maps built from them.
  std::vector<RunResult> missionRuns;
  std::vector<RunResult> missionMappingRuns;
  std::size_t missionMapCorners = 0;
  std::size_t missionFieldSurfacePoints = 0;
  std::string missionNaturalError;  ///< why the natural mode could not run on the missions
  bool missionsRan = false;         ///< the world has missions and they were driven
};

/// Whether the missions' operation points count toward `requirement_met` (reflectors and natural;
/// docs/hil.md, "Missions": measured on seeds 1-20).
bool missionsRequired() noexcept;

/// An operation point within 2 cm / 0.1 deg, the localizer not lost there.
bool stopMeetsRequirement(const OperationPoint& op);

/// A mission run meets the requirement when it reached its last operation point and met it at
/// every one.
bool missionRunMeetsRequirement(const RunResult& r);

/// Within 2 cm / 0.1 deg of the truth (dead reckoning and localizer poses).
bool meetsRequirement(const Pose2d& estimate, const Pose2d& truth);

/// A localizer run meets the requirement when it reached the operation point, the pose sent to
/// the PLC is within 2 cm / 0.1 deg and the localizer is not lost (a lost localizer stops the
/// vehicle through the PLC interlock, whatever its last pose).
bool runMeetsRequirement(const RunResult& r);

/// The modes the product holds 2 cm / 0.1 deg with: reflectors and natural navigation (FALKO
/// corners and scan matching). The FALKO-corner-only modes (static_falko, dynamic) are measured
/// and reported, not required: on the built-in warehouse with the floor's odometry errors too few
/// corners are seen per sweep to hold it (docs/hil.md, "Which modes the requirement covers").
bool requiredMode(LocalizationMode mode) noexcept;

/// The encoder frames of the whole session (calibration routine and every run), decoded by the
/// vehicle's CANopen decoder: the only way the encoder samples reach the navigation.
sim::CanBusCounters canTotals(const SessionResults& s);

/// Cold starts judged by the uniqueness oracle (`RelocTrial::unique`); kidnappings not counted.
struct ColdStartSummary {
  std::size_t unique = 0;            ///< cold starts whose pose the map makes unique
  std::size_t uniqueFound = 0;       ///< ... found
  std::size_t uniqueWithin3 = 0;     ///< ... found within 3 sweeps
  std::size_t ambiguous = 0;         ///< cold starts whose pose is not unique
  std::size_t ambiguousRefused = 0;  ///< ... not found (refused)
  std::size_t wrong = 0;             ///< cold starts found at a wrong pose
  /// Unique beyond the localizer's ambiguity margin: every distinct pose explains at least
  /// margin + 1 fewer reflectors than the truth (`RelocTrial::otherSupport`), and of those found.
  std::size_t uniqueBeyondMargin = 0;
  std::size_t uniqueBeyondMarginFound = 0;
};
ColdStartSummary coldStartSummary(const std::vector<RelocTrial>& trials, std::size_t ambiguityMargin);

/// Name of a relocalization outcome, as in the JSON ("found", "ambiguous", "weak_support", ...).
const char* relocOutcomeName(RelocOutcome outcome) noexcept;

/// The JSON summary: calibration (truth, estimate, nominal and their errors), requirement, CAN
/// encoders, stages, runs (localizer runs, then dead reckoning of the reflector-mode runs),
/// static FALKO mapping, requirement_met.
report::Json sessionJson(const ScenarioConfig& cfg, const std::vector<Stage>& stages, const SessionResults& s,
                         bool requirementMet);

}  // namespace agv::hil
