# Checks of agvnav-replay --json --map-fraction 0.5 (and 0.6) on fr079 (localization on the
# product's own maps: static corners and a likelihood field from the first half of the log, or
# the first 60 %, the rest localized on them), included by tests/support/run_json_program.cmake
# with the document in `j`. With COLD_START the run was given no pose (--cold-start).
# End to end: the field is built, three quarters of the localized scans lie on the map, every
# scan is matched, no field relocalization or resync restarted the localizer at a wrong pose. The tracking
# is checked against a regression bound, not the issue's 10 cm RMS target, which it does not meet
# on every on-map scan (docs/localization.md, "Laser odometry as the prediction", the default
# since 2026-12-07: fr079 measures 0.29-0.58 m RMS and 6-7 cm median on the on-map scans at map
# fractions 0.4-0.6, the RMS from the rooms the mapping run saw only through their doors; with the
# wheel steps 0.41-0.43 m): median below 10 cm, RMS below 1 m. The matcher's accuracy on these
# logs is checked apart from the tracking by replay.scan_match_real.
# On the mapping run's route (the localized scans within 1 m of a mapping scan, where a taught
# natural-navigation vehicle drives) the issue's figures are checked as they stand: 10 cm and
# 1 deg RMS (measured 0.053 m and 0.59 deg on 725 of 2394 scans at 0.5 with no pose given,
# 0.055 m and 0.59 deg on 583 of 1917 at 0.6; docs/localization.md).
expect_keys("${j}" "scans;static_corners;field_surface_cells;field_width_m;field_height_m" mapping_run)
expect_number_in("${j}" 1 1000000000 mapping_run field_surface_cells)
expect_number_in("${j}" 1 1000000000 mapping_run static_corners)
expect_keys("${j}" "attempts;fit_scatter;fused;gated;map_changes;refused;resync_wrong;resyncs;surface_fallback"
            scan_matching)
string(JSON fitScatter GET "${j}" scan_matching fit_scatter)
if(NOT fitScatter EQUAL 0.5)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: fit_scatter ${fitScatter}, expected the replay's default 0.5")
endif()
expect_keys("${j}" "attempts;clears;enabled;fused;pieces" scan_matching surface_fallback)
expect_keys("${j}" "enabled;pieces;points_dropped" scan_matching map_changes)
expect_keys("${j}" "scans;localizer;odometry" on_map)
expect_keys("${j}" "enabled;found;scans_before_fix;seconds_to_fix;path_to_fix_m;wrong" cold_start)
string(JSON scans GET "${j}" scans)
string(JSON coldStart GET "${j}" cold_start enabled)
if(COLD_START)
  # No pose given (--cold-start): the whole-field search must find the vehicle, rightly, within a
  # few scans (fr079 at 0.4, 0.5 and 0.6: after 8, 5 and 5, the search's scan and the confirming
  # scans that span 0.5 m or 0.5 rad, at most 8; after 2 when two scans were enough);
  # the figures below then cover the scans from that restart on.
  expect_true("${j}" cold_start enabled)
  expect_true("${j}" cold_start found)
  string(JSON coldWrong GET "${j}" cold_start wrong)
  if(coldWrong)
    message(FATAL_ERROR "JSON: ${LOG_NAME}: the cold start restarted the localizer at a wrong pose")
  endif()
  expect_number_in("${j}" 0 10 cold_start scans_before_fix)
  string(JSON before GET "${j}" cold_start scans_before_fix)
  message(STATUS "${LOG_NAME}: cold start: first restart after ${before} scans")
  math(EXPR scans "${scans} - ${before}")
  math(EXPR toMatch "${scans} - 1")  # the restart's scan is placed by the relocalization, not matched
elseif(coldStart)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: a cold start where the corrected pose was given")
endif()
if(NOT COLD_START)
  set(toMatch ${scans})
endif()
string(JSON onMap GET "${j}" on_map scans)
string(JSON attempts GET "${j}" scan_matching attempts)
string(JSON fused GET "${j}" scan_matching fused)
string(JSON gated GET "${j}" scan_matching gated)
string(JSON refused GET "${j}" scan_matching refused)
math(EXPR need "${scans} * 3 / 4")
if(onMap LESS need)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: ${onMap} of ${scans} scans on the map (expected >= ${need})")
endif()
if(NOT attempts EQUAL toMatch)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: ${attempts} scan matches attempted, expected ${toMatch}")
endif()
math(EXPR sum "${fused} + ${gated} + ${refused}")
if(NOT sum EQUAL attempts OR fused LESS 1)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: fused ${fused} + gated ${gated} + refused ${refused} != ${attempts} attempts (or none fused)")
endif()
string(JSON medPos GET "${j}" on_map localizer position_m median)
string(JSON rmsPos GET "${j}" on_map localizer position_m rms)
string(JSON odoRms GET "${j}" on_map odometry position_m rms)
message(STATUS "${LOG_NAME}: on the map ${onMap}/${scans}: localizer median ${medPos} m, RMS ${rmsPos} m (odometry ${odoRms} m); fused ${fused}/${attempts}")
expect_keys("${j}" "searches;found;ambiguous;weak;confirmed;wrong;unconfirmed;seconds" field_relocalization)
expect_no_wrong_restart("${j}" "${LOG_NAME}")
# The regression bound of the RMS: fr079 at F = 0.5 and 0.6 measured 0.54 and 0.58 m before field
# support and the field check (docs/localization.md), 0.235 and 0.231 m with them, 0.203 and
# 0.177 m with the fit scatter; at 0.65 (RMS_BOUND 0.8) 0.487 m with the confirmation by motion,
# 3.81 m with its wrong restart before, 0.705 m with the fit scatter (the room that changed upstairs
# is left later: docs/localization.md, "Fit scatter"). The bound still separates a wrong restart.
if(NOT DEFINED RMS_BOUND)
  set(RMS_BOUND 0.40)
endif()
if(medPos GREATER_EQUAL 0.10 OR rmsPos GREATER_EQUAL RMS_BOUND)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: on-map tracking median ${medPos} m / RMS ${rmsPos} m (regression bound 0.10 / ${RMS_BOUND} m)")
endif()
expect_keys("${j}" "scans;distance_m;localizer;odometry" on_route)
string(JSON onRoute GET "${j}" on_route scans)
string(JSON routeRms GET "${j}" on_route localizer position_m rms)
string(JSON routeHdg GET "${j}" on_route localizer heading_deg rms)
message(STATUS "${LOG_NAME}: on the route ${onRoute}/${scans}: localizer RMS ${routeRms} m, ${routeHdg} deg")
math(EXPR needRoute "${scans} / 5")
if(onRoute LESS needRoute)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: ${onRoute} of ${scans} scans on the route (expected >= ${needRoute})")
endif()
if(routeRms GREATER_EQUAL 0.10 OR routeHdg GREATER_EQUAL 1.0)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: on-route RMS ${routeRms} m / ${routeHdg} deg (target 0.10 m / 1 deg)")
endif()
# The field check (docs/localization.md, "Lost"): counted among the bad cycles, and on fr079 rare
# (measured 0 of 2396 at --map-fraction 0.5: its second half stays on the map or near it).
string(JSON contradicted GET "${j}" localizer field_contradicted)
string(JSON bad GET "${j}" localizer bad_cycles)
if(contradicted GREATER bad)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: ${contradicted} cycles contradicting the field, more than the ${bad} bad cycles")
endif()
