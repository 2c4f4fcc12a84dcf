# Checks of agvnav-replay --json on a corrected log with its defaults (dynamic map, no surveyed
# map), included by tests/support/run_json_program.cmake with the document in `j`:
# - the localizer never declared itself lost: a map-less localizer has nothing to reset to, and the
#   covariance growth of dead reckoning must not latch it (aces went lost 135 times in a loop);
# - its mean heading error per metre is below the raw odometry's.
expect_keys("${j}" "keypoints;used;fix_cycles;bad_cycles;lost_events;lost_cycles;no_fix_cycles;map_restarts;rejected_gate;rejected_ambiguous;rejected_duplicate;rejected_update;mean_test_ratio;map_size;map_inserted;map_deleted;expected_in_view;occluded_or_no_return" localizer)
string(JSON lost GET "${j}" localizer lost_events)
if(NOT lost EQUAL 0)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: the localizer went lost ${lost} times")
endif()
expect_number_in("${j}" 1 1000000000 localizer used)
string(JSON odo GET "${j}" odometry_per_metre heading_deg mean)
string(JSON loc GET "${j}" localizer_per_metre heading_deg mean)
if(NOT loc LESS odo)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: localizer heading per metre ${loc} deg not below raw odometry ${odo} deg")
endif()
message(STATUS "${LOG_NAME}: heading per metre localizer ${loc} deg, odometry ${odo} deg; lost ${lost}")
