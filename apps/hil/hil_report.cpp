#include "hil_report.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include "agv/core/angle.hpp"

namespace agv::hil {
namespace {

using report::Json;

Json paramsJson(const TricycleParams& k, const Pose2d& laser) {
  return Json{{"wheelbase_m", k.wheelbase},
              {"drive_scale_m_per_tick", k.driveScale},
              {"steer_offset_forward_deg", rad2deg(k.steerOffsetForward)},
              {"steer_offset_backward_deg", rad2deg(k.steerOffsetBackward)},
              {"laser_x_m", laser.x},
              {"laser_y_m", laser.y},
              {"laser_theta_deg", rad2deg(laser.theta)}};
}

// Parameter errors (value - truth) in the units of paramsJson.
Json paramDiffJson(const NominalVehicle& v, const sim::SimVehicleParams& truth) {
  const TricycleParams& k = v.kinematics;
  const TricycleParams& t = truth.truth;
  return Json{{"drive_scale_m_per_tick", k.driveScale - t.driveScale},
              {"steer_offset_forward_deg", rad2deg(k.steerOffsetForward - t.steerOffsetForward)},
              {"steer_offset_backward_deg", rad2deg(k.steerOffsetBackward - t.steerOffsetBackward)},
              {"laser_x_m", v.laserMount.x - truth.laserMount.x},
              {"laser_y_m", v.laserMount.y - truth.laserMount.y},
              {"laser_theta_deg", rad2deg(angleDiff(v.laserMount.theta, truth.laserMount.theta))}};
}

Json calibrationJson(const ScenarioConfig& cfg, const SessionResults& s) {
  return Json{{"truth", paramsJson(cfg.vehicle.truth, cfg.vehicle.laserMount)},
              {"estimate", paramsJson(cfg.estimate.kinematics, cfg.estimate.laserMount)},
              {"nominal", paramsJson(cfg.nominal.kinematics, cfg.nominal.laserMount)},
              {"estimate_error", paramDiffJson(cfg.estimate, cfg.vehicle)},
              {"nominal_error", paramDiffJson(cfg.nominal, cfg.vehicle)},
              {"estimate_source", s.calibration.status == Status::Ok ? "calibration_atc" : "nominal"},
              {"status", s.calibrationStatus},
              {"segments_used", s.calibration.segmentsUsed}};
}

Json canJson(const ScenarioConfig& cfg, const sim::CanBusCounters& c) {
  return Json{{"drive_node", unsigned{cfg.can.bus.drive.nodeId}},
              {"steering_node", unsigned{cfg.can.bus.steering.nodeId}},
              {"sync", cfg.can.bus.syncPeriod.ns > 0},
              {"frames_decoded", c.framesDecoded()},
              {"drive_pdos", c.drivePositions},
              {"steering_pdos", c.steeringPositions},
              {"heartbeats", c.heartbeats},
              {"frames_to_nodes", c.framesToNodes},
              {"frames_dropped", c.framesDropped},
              {"malformed", c.malformed},
              {"measurements", c.measurements},
              {"samples_decoded", c.samples},
              {"sample_mismatches", c.sampleMismatches},
              {"samples_withheld", c.samplesWithheld},
              {"drive_counter_wraps", c.driveCounterWraps}};
}

Json localizerRunJson(const RunResult& r) {
  return Json{{"mode", modeName(r.mode)},
              {"path", r.path},
              {"run", r.run},
              {"final_position_error_m", positionError(r.finalLocalized, r.finalTruth)},
              {"final_heading_error_deg", rad2deg(headingError(r.finalLocalized, r.finalTruth))},
              {"distance_m", r.distance},
              {"finished", r.finished},
              {"lost", r.localizerLost},
              {"required", requiredMode(r.mode)},
              {"landmarks_used_per_scan", r.meanUsedPerScan},
              {"scans_without_fix", r.scansWithoutFix},
              {"keypoints_per_scan", r.meanKeypointsPerScan}};
}

// Dead reckoning of one run with the true, nominal and estimated parameters.
void appendDeadReckoning(const RunResult& r, Json& runs) {
  const std::pair<const char*, const Pose2d*> entries[3] = {
      {"truth", &r.finalWithTruth}, {"nominal", &r.finalWithNominal}, {"estimate", &r.finalWithEstimate}};
  for (const auto& [params, pose] : entries) {
    runs.push_back(Json{{"mode", "dead_reckoning"},
                        {"parameters", params},
                        {"path", r.path},
                        {"run", r.run},
                        {"final_position_error_m", positionError(*pose, r.finalTruth)},
                        {"final_heading_error_deg", rad2deg(headingError(*pose, r.finalTruth))},
                        {"distance_m", r.distance},
                        {"finished", r.finished}});
  }
}

Json poseErrorJson(const Pose2d& estimate, const Pose2d& truth) {
  return Json{{"position_error_m", positionError(estimate, truth)},
              {"heading_error_deg", rad2deg(headingError(estimate, truth))}};
}

Json missionRunJson(const RunResult& r) {
  Json stops = Json::array();
  double maxP = 0.0;
  double maxH = 0.0;
  double sumP2 = 0.0;
  double sumH2 = 0.0;
  for (const OperationPoint& op : r.stops) {
    const double e = positionError(op.localized, op.truth);
    const double h = rad2deg(headingError(op.localized, op.truth));
    maxP = std::max(maxP, e);
    maxH = std::max(maxH, h);
    sumP2 += e * e;
    sumH2 += h * h;
    stops.push_back(Json{{"index", op.index},
                         {"distance_m", op.distance},
                         {"x_m", op.truth.x},
                         {"y_m", op.truth.y},
                         {"heading_deg", rad2deg(op.truth.theta)},
                         {"position_error_m", e},
                         {"heading_error_deg", h},
                         {"lost", op.lost},
                         {"within_requirement", stopMeetsRequirement(op)},
                         {"dead_reckoning",
                          {{"truth", poseErrorJson(op.withTruth, op.truth)},
                           {"nominal", poseErrorJson(op.withNominal, op.truth)},
                           {"estimate", poseErrorJson(op.withEstimate, op.truth)}}}});
  }
  const double n = std::max<double>(1.0, static_cast<double>(r.stops.size()));
  return Json{{"mode", modeName(r.mode)},
              {"mission", r.path},
              {"run", r.run},
              {"finished", r.finished},
              {"lost", r.localizerLost},
              {"distance_m", r.distance},
              {"sim_seconds", r.simSeconds},
              {"landmarks_used_per_scan", r.meanUsedPerScan},
              {"scans_without_fix", r.scansWithoutFix},
              {"max_position_error_m", maxP},
              {"rms_position_error_m", std::sqrt(sumP2 / n)},
              {"max_heading_error_deg", maxH},
              {"rms_heading_error_deg", std::sqrt(sumH2 / n)},
              {"within_requirement", missionRunMeetsRequirement(r)},
              {"pallets",
               {{"boxes", r.pallets.boxes},
                {"moved", r.pallets.moved},
                {"removed", r.pallets.removed},
                {"added", r.pallets.added},
                {"kept_for_clearance", r.pallets.keptForClearance},
                {"max_shift_m", r.pallets.maxShift},
                {"layout_fingerprint", r.palletFingerprint}}},
              {"operation_points", std::move(stops)}};
}

/// Per mode and mission: max / RMS over every operation point of every run, and how many meet
/// the requirement; per mission the same for dead reckoning (the reflector-mode runs).
Json missionSummaryJson(const SessionResults& s) {
  Json summary = Json::object();
  const auto stats = [](const std::vector<std::pair<double, double>>& errors, int within) {
    double maxP = 0.0;
    double maxH = 0.0;
    double sumP2 = 0.0;
    double sumH2 = 0.0;
    for (const auto& [e, h] : errors) {
      maxP = std::max(maxP, e);
      maxH = std::max(maxH, h);
      sumP2 += e * e;
      sumH2 += h * h;
    }
    const double n = std::max<double>(1.0, static_cast<double>(errors.size()));
    return Json{{"operation_points", errors.size()}, {"within_requirement", within},
                {"max_position_error_m", maxP},      {"rms_position_error_m", std::sqrt(sumP2 / n)},
                {"max_heading_error_deg", maxH},     {"rms_heading_error_deg", std::sqrt(sumH2 / n)}};
  };
  std::vector<std::string> missions;
  for (const RunResult& r : s.missionRuns) {
    if (std::find(missions.begin(), missions.end(), r.path) == missions.end()) {
      missions.push_back(r.path);
    }
  }
  for (const LocalizationMode mode : {LocalizationMode::Reflectors, LocalizationMode::StaticFalko,
                                      LocalizationMode::Natural, LocalizationMode::Dynamic}) {
    Json perMission = Json::object();
    for (const std::string& name : missions) {
      std::vector<std::pair<double, double>> errors;
      int within = 0;
      for (const RunResult& r : s.missionRuns) {
        if (r.mode != mode || r.path != name) {
          continue;
        }
        for (const OperationPoint& op : r.stops) {
          errors.emplace_back(positionError(op.localized, op.truth), rad2deg(headingError(op.localized, op.truth)));
          within += stopMeetsRequirement(op) ? 1 : 0;
        }
      }
      if (!errors.empty()) {
        perMission[name] = stats(errors, within);
      }
    }
    summary[modeName(mode)] = std::move(perMission);
  }
  Json dr = Json::object();
  const std::pair<const char*, Pose2d OperationPoint::*> params[3] = {{"truth", &OperationPoint::withTruth},
                                                                      {"nominal", &OperationPoint::withNominal},
                                                                      {"estimate", &OperationPoint::withEstimate}};
  for (const auto& [key, member] : params) {
    Json perMission = Json::object();
    for (const std::string& name : missions) {
      std::vector<std::pair<double, double>> errors;
      int within = 0;
      for (const RunResult& r : s.missionRuns) {
        if (r.mode != LocalizationMode::Reflectors || r.path != name) {
          continue;  // every mode repeats these vehicle runs (same seeds)
        }
        for (const OperationPoint& op : r.stops) {
          errors.emplace_back(positionError(op.*member, op.truth), rad2deg(headingError(op.*member, op.truth)));
          within += meetsRequirement(op.*member, op.truth) ? 1 : 0;
        }
      }
      if (!errors.empty()) {
        perMission[name] = stats(errors, within);
      }
    }
    dr[key] = std::move(perMission);
  }
  summary["dead_reckoning"] = std::move(dr);
  return summary;
}

Json missionsJson(const ScenarioConfig& cfg, const SessionResults& s) {
  Json runs = Json::array();
  bool met = true;
  for (const RunResult& r : s.missionRuns) {
    runs.push_back(missionRunJson(r));
    if (requiredMode(r.mode)) {
      met = met && missionRunMeetsRequirement(r);
    }
  }
  Json mapping = Json::array();
  for (const RunResult& r : s.missionMappingRuns) {
    mapping.push_back(missionRunJson(r));
  }
  const sim::PalletMoveParams& pm = cfg.palletMoves;
  return Json{{"ran", s.missionsRan},
              {"runs_per_mission", cfg.runsPerMission},
              {"dwell_s", cfg.dwellSeconds},
              {"required", missionsRequired()},
              {"requirement_met", s.missionsRan && met && s.missionNaturalError.empty()},
              {"pallet_moves",
               {{"remove_probability", pm.removeProbability},
                {"move_probability", pm.moveProbability},
                {"max_shift_m", pm.maxShift},
                {"max_rotation_deg", rad2deg(pm.maxRotation)},
                {"added", pm.added},
                {"clearance_m", pm.clearance}}},
              {"mapping",
               {{"frozen_corners", s.missionMapCorners},
                {"field_surface_cells", s.missionFieldSurfacePoints},
                {"natural_error", s.missionNaturalError},
                {"runs", std::move(mapping)}}},
              {"summary", missionSummaryJson(s)},
              {"runs", std::move(runs)}};
}

}  // namespace

bool missionsRequired() noexcept {
  return false;
}

bool stopMeetsRequirement(const OperationPoint& op) {
  return !op.lost && meetsRequirement(op.localized, op.truth);
}

bool missionRunMeetsRequirement(const RunResult& r) {
  if (!r.finished || r.stops.empty()) {
    return false;
  }
  for (const OperationPoint& op : r.stops) {
    if (!stopMeetsRequirement(op)) {
      return false;
    }
  }
  return true;
}

bool meetsRequirement(const Pose2d& estimate, const Pose2d& truth) {
  return positionError(estimate, truth) <= kPositionRequirement &&
         rad2deg(headingError(estimate, truth)) <= kHeadingRequirementDeg;
}

bool requiredMode(LocalizationMode mode) noexcept {
  return mode == LocalizationMode::Reflectors || mode == LocalizationMode::Natural;
}

bool runMeetsRequirement(const RunResult& r) {
  return r.finished && !r.localizerLost && meetsRequirement(r.finalLocalized, r.finalTruth);
}

sim::CanBusCounters canTotals(const SessionResults& s) {
  sim::CanBusCounters c = s.calibration.can;
  for (const std::vector<RunResult>* set : {&s.runs, &s.mappingRuns, &s.missionRuns, &s.missionMappingRuns}) {
    for (const RunResult& r : *set) {
      c += r.can;
    }
  }
  return c;
}

ColdStartSummary coldStartSummary(const std::vector<RelocTrial>& trials, std::size_t ambiguityMargin) {
  ColdStartSummary c;
  for (const RelocTrial& tr : trials) {
    if (tr.kidnapped) {
      continue;
    }
    if (tr.unique) {
      ++c.unique;
      c.uniqueFound += tr.found ? 1U : 0U;
      c.uniqueWithin3 += tr.found && tr.sweeps <= 3 ? 1U : 0U;
    } else {
      ++c.ambiguous;
      c.ambiguousRefused += tr.found ? 0U : 1U;
    }
    c.wrong += tr.wrong ? 1U : 0U;
    if (tr.unique && tr.otherSupport + ambiguityMargin < tr.visibleReflectors) {
      ++c.uniqueBeyondMargin;
      c.uniqueBeyondMarginFound += tr.found ? 1U : 0U;
    }
  }
  return c;
}

const char* relocOutcomeName(RelocOutcome outcome) noexcept {
  switch (outcome) {
    case RelocOutcome::Found:
      return "found";
    case RelocOutcome::InvalidParams:
      return "invalid_params";
    case RelocOutcome::EmptyInput:
      return "empty_input";
    case RelocOutcome::NonFiniteInput:
      return "non_finite_input";
    case RelocOutcome::OverCapacity:
      return "over_capacity";
    case RelocOutcome::WindowOverCapacity:
      return "window_over_capacity";
    case RelocOutcome::WeakSupport:
      return "weak_support";
    case RelocOutcome::Ambiguous:
      return "ambiguous";
    case RelocOutcome::WorkBoundHit:
      return "work_bound_hit";
  }
  return "unknown";
}

namespace {

/// One relocalization stage's trials and sums (on the corner map `visible_reflectors` counts the
/// map corners in clear view).
Json relocalizationJson(const std::vector<RelocTrial>& reloc, std::size_t margin) {
  Json trials = Json::array();
  const ColdStartSummary cs = coldStartSummary(reloc, margin);
  std::size_t found = 0;
  std::size_t wrong = 0;
  for (const RelocTrial& tr : reloc) {
    found += tr.found ? 1U : 0U;
    wrong += tr.wrong ? 1U : 0U;
    Json trial{{"kind", tr.kidnapped ? "kidnapped" : "cold_start"},
               {"x_m", tr.truth.x},
               {"y_m", tr.truth.y},
               {"heading_deg", rad2deg(tr.truth.theta)},
               {"lost_detected", tr.lostDetected},
               {"found", tr.found},
               {"sweeps", tr.sweeps},
               {"position_error_m", tr.positionError},
               {"heading_error_deg", rad2deg(tr.headingError)},
               {"wrong", tr.wrong},
               {"ambiguous_searches", tr.ambiguous},
               {"unique", tr.unique},
               {"visible_reflectors", tr.visibleReflectors},
               {"distinct_pose_support", tr.otherSupport},
               {"decoys", tr.decoys},
               {"searches", tr.searches},
               {"candidates", tr.candidates},
               {"unconfirmed", tr.unconfirmed},
               {"last_search", tr.found ? Json()
                                        : Json{{"detected", tr.detected},
                                               {"outcome", relocOutcomeName(tr.lastOutcome)},
                                               {"inliers", tr.lastInliers},
                                               {"runner_up_inliers", tr.lastSecondInliers},
                                               {"missed", tr.lastMissed},
                                               {"runner_up_missed", tr.lastSecondMissed}}}};
    if (tr.onField) {
      // On the field: no oracle and no landmark search; the field searches instead.
      trial.erase("last_search");
      trial["field_searches"] = tr.fieldSearches;
      trial["last_field_search"] = tr.fieldSearchEnded ? Json(toString(tr.lastFieldOutcome)) : Json(nullptr);
    }
    trials.push_back(std::move(trial));
  }
  return Json{{"trials", std::move(trials)},
              {"found", found},
              {"wrong", wrong},
              {"count", reloc.size()},
              {"cold_starts",
               {{"unique", cs.unique},
                {"found_unique", cs.uniqueFound},
                {"found_unique_within_3_sweeps", cs.uniqueWithin3},
                {"ambiguous", cs.ambiguous},
                {"refused_ambiguous", cs.ambiguousRefused},
                {"wrong", cs.wrong},
                {"unique_beyond_margin", cs.uniqueBeyondMargin},
                {"found_unique_beyond_margin", cs.uniqueBeyondMarginFound}}}};
}

}  // namespace

report::Json sessionJson(const ScenarioConfig& cfg, const std::vector<Stage>& stages, const SessionResults& s,
                         bool requirementMet) {
  Json stageStates = Json::object();
  for (const Stage& st : stages) {
    stageStates[st.key] = st.failed ? "failed" : (st.wired ? "run" : "not wired");
  }
  Json runs = Json::array();
  for (const RunResult& r : s.runs) {
    runs.push_back(localizerRunJson(r));
  }
  for (const RunResult& r : s.runs) {
    if (r.mode == LocalizationMode::Reflectors) {  // every mode repeats these vehicle runs (same seeds)
      appendDeadReckoning(r, runs);
    }
  }
  Json mappingRuns = Json::array();
  for (const RunResult& r : s.mappingRuns) {
    mappingRuns.push_back(localizerRunJson(r));
  }
  Json doc{{"calibration", calibrationJson(cfg, s)},
           {"requirement", {{"position_m", kPositionRequirement}, {"heading_deg", kHeadingRequirementDeg}}},
           {"can_encoders", canJson(cfg, canTotals(s))},
           {"stages", std::move(stageStates)},
           {"runs", std::move(runs)},
           {"static_falko_mapping",
            {{"frozen_corners", s.mapCorners},
             {"surface_map", cfg.cornerModesSurfaceMap},
             {"field_surface_cells", s.fieldSurfacePoints},
             {"runs", std::move(mappingRuns)}}},
           {"relocalization", relocalizationJson(s.reloc, cfg.relocAmbiguityMargin)},
           {"relocalization_corners", relocalizationJson(s.relocCorners, cfg.relocAmbiguityMargin)},
           {"missions", missionsJson(cfg, s)},
           {"requirement_met", requirementMet}};
  if (cfg.relocField) {  // only when run (`--reloc-field`): the default document keeps its keys
    doc["relocalization_field"] = relocalizationJson(s.relocField, cfg.relocAmbiguityMargin);
  }
  return doc;
}

}  // namespace agv::hil
