#include "hil_report.hpp"

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

}  // namespace

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
  for (const std::vector<RunResult>* set : {&s.runs, &s.mappingRuns}) {
    for (const RunResult& r : *set) {
      c += r.can;
    }
  }
  return c;
}

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
  Json trials = Json::array();
  std::size_t found = 0;
  std::size_t wrong = 0;
  for (const RelocTrial& tr : s.reloc) {
    found += tr.found ? 1U : 0U;
    wrong += tr.wrong ? 1U : 0U;
    trials.push_back(Json{{"kind", tr.kidnapped ? "kidnapped" : "cold_start"},
                          {"x_m", tr.truth.x},
                          {"y_m", tr.truth.y},
                          {"heading_deg", rad2deg(tr.truth.theta)},
                          {"lost_detected", tr.lostDetected},
                          {"found", tr.found},
                          {"sweeps", tr.sweeps},
                          {"position_error_m", tr.positionError},
                          {"heading_error_deg", rad2deg(tr.headingError)},
                          {"wrong", tr.wrong},
                          {"ambiguous_searches", tr.ambiguous}});
  }
  Json mappingRuns = Json::array();
  for (const RunResult& r : s.mappingRuns) {
    mappingRuns.push_back(localizerRunJson(r));
  }
  return Json{{"calibration", calibrationJson(cfg, s)},
              {"requirement", {{"position_m", kPositionRequirement}, {"heading_deg", kHeadingRequirementDeg}}},
              {"can_encoders", canJson(cfg, canTotals(s))},
              {"stages", std::move(stageStates)},
              {"runs", std::move(runs)},
              {"static_falko_mapping",
               {{"frozen_corners", s.mapCorners},
                {"field_surface_cells", s.fieldSurfacePoints},
                {"runs", std::move(mappingRuns)}}},
              {"relocalization",
               {{"trials", std::move(trials)}, {"found", found}, {"wrong", wrong}, {"count", s.reloc.size()}}},
              {"requirement_met", requirementMet}};
}

}  // namespace agv::hil
