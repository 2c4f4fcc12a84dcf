# Checks of agvnav-loops --pose-graph --json on corrected logs (MAP_NAMES = the dataset keys),
# included by tests/support/run_json_program.cmake with the document in `j`: for each dataset the
# documented keys, the optimised trajectory below the raw odometry in RMS position and heading
# error against the corrected poses, at least one loop accepted, and no accepted loop that the
# corrected poses call wrong (> 0.5 m or 10 deg).
expect_keys("${j}" "pose_graph")
expect_keys("${j}" "${MAP_NAMES}" pose_graph)
foreach(name ${MAP_NAMES})
  foreach(key odometry_ate_m optimised_ate_m odometry_ate_deg optimised_ate_deg loops_accepted loops_rejected
              accepted_wrong)
    expect_type("${j}" NUMBER pose_graph ${name} ${key})
  endforeach()
  string(JSON odo GET "${j}" pose_graph ${name} odometry_ate_m)
  string(JSON opt GET "${j}" pose_graph ${name} optimised_ate_m)
  string(JSON odoDeg GET "${j}" pose_graph ${name} odometry_ate_deg)
  string(JSON optDeg GET "${j}" pose_graph ${name} optimised_ate_deg)
  if(NOT opt LESS odo OR NOT optDeg LESS odoDeg)
    message(FATAL_ERROR "JSON: ${name}: optimised ATE ${opt} m / ${optDeg} deg not below odometry ${odo} m / ${odoDeg} deg")
  endif()
  expect_number_in("${j}" 1 1000000 pose_graph ${name} loops_accepted)
  expect_number_in("${j}" 0 0 pose_graph ${name} accepted_wrong)
  message(STATUS "${name}: ATE ${odo} m -> ${opt} m, ${odoDeg} deg -> ${optDeg} deg")
endforeach()
