# Checks of agvnav-replay --json --map-fraction 0.5 on fr079 (localization on the product's own
# maps: static corners and a likelihood field from the first half of the log, the second half
# localized on them), included by tests/support/run_json_program.cmake with the document in `j`.
# The figures measured when this test was written (docs/localization.md, "Scan matching on real
# logs"): 2023 of 2396 scans on the map; there the localizer's error median 0.065 m / 0.80 deg,
# RMS 0.35 m (odometry 7.0 m); 1363 of 2396 matches fused. The bounds leave room for numerical
# differences between machines, not for a regression of the matcher.
expect_keys("${j}" "scans;static_corners;field_surface_cells;field_width_m;field_height_m" mapping_run)
expect_number_in("${j}" 1 1000000000 mapping_run field_surface_cells)
expect_keys("${j}" "attempts;fused;gated;refused" scan_matching)
string(JSON scans GET "${j}" scans)
string(JSON onMap GET "${j}" on_map scans)
string(JSON attempts GET "${j}" scan_matching attempts)
string(JSON fused GET "${j}" scan_matching fused)
math(EXPR need "${scans} * 3 / 4")
if(onMap LESS need)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: ${onMap} of ${scans} scans on the map (expected >= ${need})")
endif()
if(NOT attempts EQUAL scans)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: ${attempts} scan matches attempted for ${scans} scans")
endif()
math(EXPR needFused "${attempts} * 2 / 5")
if(fused LESS needFused)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: ${fused} of ${attempts} scan matches fused (expected >= ${needFused})")
endif()
string(JSON medPos GET "${j}" on_map localizer position_m median)
string(JSON medHead GET "${j}" on_map localizer heading_deg median)
string(JSON rmsPos GET "${j}" on_map localizer position_m rms)
string(JSON odoRms GET "${j}" on_map odometry position_m rms)
if(medPos GREATER 0.10 OR medHead GREATER 1.5)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: on the map, median error ${medPos} m / ${medHead} deg (expected <= 0.10 m / 1.5 deg)")
endif()
if(rmsPos GREATER 1.0)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: on the map, RMS error ${rmsPos} m (expected <= 1 m; odometry ${odoRms} m)")
endif()
message(STATUS "${LOG_NAME}: on the map ${onMap}/${scans}: median ${medPos} m / ${medHead} deg, RMS ${rmsPos} m (odometry ${odoRms} m); fused ${fused}/${attempts}")
