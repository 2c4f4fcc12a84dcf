# Checks of agvnav-replay --json --map-fraction 0.5 on intel, whose defaults with a mapping run
# are the laser odometry as the prediction input and the noise model fitted on its steps
# (docs/localization.md, "Laser odometry as the prediction"), included by
# tests/support/run_json_program.cmake with the document in `j`.
# The laser odometry ran over the whole log and matched nearly every scan (measured 895 of 910);
# its steps beat the wheels' per metre over the localized scans (measured 0.062 m / 0.89 deg
# against 0.130 m / 5.92 deg); the noise model was fitted on its steps; no restart was wrong; and
# the static-map localization holds intel, which it lost with the wheel steps (5.54 m on-map RMS):
# measured 0.098 m and 1.20 deg RMS on 330 on-map scans (0.112 m / 0.97 deg with the fit
# scatter). Bounds: 0.2 m and 2 deg (a regression bound). replay.intel_scan_odometry_grid runs the
# same on another grid (--surface-grid-offset 0.031 0.006), where the laser odometry took one
# wheel step 9.4 deg off before the wider retry and the run ended 1.32 m / 7.96 deg RMS on the
# map; 0.055 m / 1.31 deg with it.
expect_keys("${j}" "enabled;matched;scans;retry;retried;per_metre" scan_odometry)
expect_true("${j}" scan_odometry enabled)
# The wider retry of a refused match (the replay's default 2; docs/localization.md, "Laser
# odometry: the wider retry"), and the grid the run drew (GRID_OFFSET_X, _Y, when given).
expect_number_in("${j}" 2 2 scan_odometry retry)
expect_number_in("${j}" 0 1000000 scan_odometry retried)
if(DEFINED GRID_OFFSET_X)
  expect_number_in("${j}" ${GRID_OFFSET_X} ${GRID_OFFSET_X} surface_map grid_offset_m 0)
  expect_number_in("${j}" ${GRID_OFFSET_Y} ${GRID_OFFSET_Y} surface_map grid_offset_m 1)
endif()
string(JSON matched GET "${j}" scan_odometry matched)
string(JSON seen GET "${j}" scan_odometry scans)
math(EXPR need "${seen} * 9 / 10")
if(matched LESS need)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: the laser odometry matched ${matched} of ${seen} scans (expected >= ${need})")
endif()
string(JSON soPos GET "${j}" scan_odometry per_metre position_m mean)
string(JSON soHdg GET "${j}" scan_odometry per_metre heading_deg mean)
string(JSON odoPos GET "${j}" odometry_per_metre position_m mean)
string(JSON odoHdg GET "${j}" odometry_per_metre heading_deg mean)
message(STATUS "${LOG_NAME}: laser odometry ${matched}/${seen} matched, per metre ${soPos} m / ${soHdg} deg (wheels ${odoPos} m / ${odoHdg} deg)")
if(NOT soPos LESS odoPos OR NOT soHdg LESS odoHdg)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: the laser odometry's steps (${soPos} m / ${soHdg} deg per metre) do not beat the wheels' (${odoPos} / ${odoHdg})")
endif()
string(JSON fitted GET "${j}" odometry_noise fitted_steps)
if(fitted LESS 20)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: the noise model was not fitted (${fitted} steps)")
endif()
expect_no_wrong_restart("${j}" "${LOG_NAME}")
string(JSON rmsPos GET "${j}" on_map localizer position_m rms)
string(JSON rmsHdg GET "${j}" on_map localizer heading_deg rms)
string(JSON onMap GET "${j}" on_map scans)
message(STATUS "${LOG_NAME}: on the map (${onMap} scans): localizer RMS ${rmsPos} m, ${rmsHdg} deg")
if(NOT rmsPos LESS 0.2 OR NOT rmsHdg LESS 2.0)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: on-map RMS ${rmsPos} m / ${rmsHdg} deg (regression bound 0.2 m / 2 deg)")
endif()
