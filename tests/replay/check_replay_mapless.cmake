# Checks of agvnav-replay --json on a corrected log with its defaults (dynamic corner map and the
# surface map of the earlier scans, no surveyed map), included by tests/support/run_json_program.cmake
# with the document in `j` (fr079's check_replay_json.cmake includes it too):
# - the localizer never declared itself lost: a map-less localizer has nothing to reset to, and the
#   covariance growth of dead reckoning must not latch it (aces went lost 135 times in a loop), and
#   no cycle contradicts a field (the field check is for static maps);
# - the surface map ran and took points (and moved by shift when SURFACE_SHIFT says so);
# - its mean position and heading errors per metre are below the raw odometry's, the heading by at
#   least MIN_HEADING_REDUCTION (a fraction of the odometry's; 0 when not given).
expect_keys("${j}" "keypoints;used;fix_cycles;bad_cycles;field_contradicted;lost_events;lost_cycles;no_fix_cycles;map_restarts;rejected_gate;rejected_ambiguous;rejected_duplicate;rejected_update;rejected_field;mean_test_ratio;map_size;map_inserted;map_deleted;expected_in_view;occluded_or_no_return" localizer)
string(JSON lost GET "${j}" localizer lost_events)
if(NOT lost EQUAL 0)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: the localizer went lost ${lost} times")
endif()
# The field check judges a static map only: the surface map is the localizer's own, never a
# contradiction.
expect_number_in("${j}" 0 0 localizer field_contradicted)
expect_number_in("${j}" 1 1000000000 localizer used)
string(JSON surface GET "${j}" surface_map enabled)
if(NOT surface)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: the map-less run did not use the surface map")
endif()
expect_number_in("${j}" 1000 1000000000 surface_map pieces)
# With SURFACE_SHIFT the run must say its surface map moved by whole cells (--surface-shift).
if(DEFINED SURFACE_SHIFT)
  string(JSON shift GET "${j}" surface_map recentre_by_shift)
  if(NOT shift STREQUAL "${SURFACE_SHIFT}")
    message(FATAL_ERROR "JSON: ${LOG_NAME}: surface_map.recentre_by_shift is ${shift}, expected ${SURFACE_SHIFT}")
  endif()
endif()
string(JSON odoPos GET "${j}" odometry_per_metre position_m mean)
string(JSON locPos GET "${j}" localizer_per_metre position_m mean)
if(NOT locPos LESS odoPos)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: localizer position per metre ${locPos} m not below raw odometry ${odoPos} m")
endif()
string(JSON odo GET "${j}" odometry_per_metre heading_deg mean)
string(JSON loc GET "${j}" localizer_per_metre heading_deg mean)
if(NOT DEFINED MIN_HEADING_REDUCTION)
  set(MIN_HEADING_REDUCTION 0)
endif()
# CMake's arithmetic is integer only: compare in millionths.
function(to_millionths value out)
  if(NOT value MATCHES "^([0-9]+)(\\.([0-9]*))?$")
    message(FATAL_ERROR "JSON: ${LOG_NAME}: '${value}' is not a plain non-negative decimal")
  endif()
  set(whole "${CMAKE_MATCH_1}")
  string(SUBSTRING "${CMAKE_MATCH_3}000000" 0 6 fraction)
  string(REGEX REPLACE "^0+([0-9])" "\\1" fraction "${fraction}")
  math(EXPR result "${whole} * 1000000 + ${fraction}")
  set(${out} ${result} PARENT_SCOPE)
endfunction()
to_millionths("${odo}" odoU)
to_millionths("${loc}" locU)
to_millionths("${MIN_HEADING_REDUCTION}" reductionU)
# loc <= odo * (1 - reduction)  <=>  loc * 1e6 <= odo * (1e6 - reduction * 1e6)  (in millionths^2 / 1e6)
math(EXPR limitU "${odoU} * (1000000 - ${reductionU}) / 1000000")
if(NOT locU LESS limitU)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: localizer heading per metre ${loc} deg not ${MIN_HEADING_REDUCTION} below "
                      "raw odometry ${odo} deg (limit ${limitU} millionths)")
endif()
message(STATUS "${LOG_NAME}: per metre localizer ${locPos} m / ${loc} deg, odometry ${odoPos} m / ${odo} deg; lost ${lost}")
