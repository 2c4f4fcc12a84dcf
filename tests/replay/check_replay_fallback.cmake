# Checks of agvnav-replay --json --map-fraction 0.5 --surface-fallback on intel (the static map of
# the first half, with a surface map of the localized scans as the field's fallback off the map),
# included by tests/support/run_json_program.cmake with the document in `j`. The fallback ran
# (matched the scans the field's match did not fuse, fused some, took surfaces), no relocalization
# or resync restarted the localizer at a wrong pose, and the on-map tracking stays within a
# regression bound: measured 1.62 m RMS / 0.057 m median where the same run without the fallback
# measures 5.54 / 0.059 (docs/localization.md, "Off the map: the surface map as the field's
# fallback"); bound 3 m RMS, 0.10 m median. Not the issue's 10 cm target, which it does not meet.
expect_keys("${j}" "attempts;clears;enabled;fused;pieces" scan_matching surface_fallback)
string(JSON enabled GET "${j}" scan_matching surface_fallback enabled)
string(JSON attempts GET "${j}" scan_matching surface_fallback attempts)
string(JSON fusedFb GET "${j}" scan_matching surface_fallback fused)
string(JSON pieces GET "${j}" scan_matching surface_fallback pieces)
string(JSON matchAttempts GET "${j}" scan_matching attempts)
string(JSON matchFused GET "${j}" scan_matching fused)
if(NOT enabled)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: surface_fallback not enabled")
endif()
math(EXPR notFused "${matchAttempts} - ${matchFused}")
if(attempts LESS 1 OR attempts GREATER notFused OR fusedFb LESS 1 OR fusedFb GREATER attempts OR pieces LESS 1)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: fallback ${fusedFb} fused of ${attempts} attempts (field matches not fused: ${notFused}), ${pieces} pieces")
endif()
expect_no_wrong_restart("${j}" "${LOG_NAME}")
string(JSON medPos GET "${j}" on_map localizer position_m median)
string(JSON rmsPos GET "${j}" on_map localizer position_m rms)
message(STATUS "${LOG_NAME}: fallback ${fusedFb}/${attempts} fused; on the map: median ${medPos} m, RMS ${rmsPos} m")
if(medPos GREATER_EQUAL 0.10 OR rmsPos GREATER_EQUAL 3.0)
  message(FATAL_ERROR "JSON: ${LOG_NAME}: on-map tracking median ${medPos} m / RMS ${rmsPos} m (regression bound 0.10 / 3.0 m)")
endif()
