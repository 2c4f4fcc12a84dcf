# Checks of agvnav-replay --json --map-fraction 0.5 on mit-csail (the static field of the first
# half, the second half localized on it), included by tests/support/run_json_program.cmake with
# the document in `j`. mit-csail keeps one scan per 0.2-1.3 m of Pioneer odometry, off by up to
# 0.2 m and 0.25 rad per step: the field relocalization's confirmation must carry its candidate with
# a window from the odometry noise model (FieldRelocalizer::confirmWindow), or it refuses the right
# poses found at scans 387-396 and then confirms an 11-deg-wrong one (measured with the fixed
# 0.25 m / 0.08 rad window: 2 restarts, 1 wrong, on-map RMS 4.15 m; with the carry's window:
# 2 restarts, 0 wrong, 2.58 m; docs/localization.md, "The confirmation window").
# Checked: at least one confirmed restart, none wrong, and the on-map RMS below 3.5 m (a regression
# bound between the two).
expect_keys("${j}" "searches;found;ambiguous;weak;confirmed;wrong;unconfirmed;seconds" field_relocalization)
string(JSON confirmed GET "${j}" field_relocalization confirmed)
string(JSON wrong GET "${j}" field_relocalization wrong)
string(JSON rmsPos GET "${j}" on_map localizer position_m rms)
string(JSON medPos GET "${j}" on_map localizer position_m median)
message(STATUS "${LOG_NAME}: ${confirmed} field relocalizations (${wrong} wrong); on the map RMS ${rmsPos} m, median ${medPos} m")
if(confirmed LESS 1)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: no field relocalization confirmed")
endif()
if(NOT wrong EQUAL 0)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: ${wrong} field relocalizations restarted the localizer at a wrong pose")
endif()
if(rmsPos GREATER_EQUAL 3.5)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: on-map RMS ${rmsPos} m (regression bound 3.5 m)")
endif()
