# Checks of agvnav-lidar-places --sim vlp16|hdl64 --json (reduced route: one revolution every 4 m,
# or every 2 m with -DSCANS=360; the sensor's threshold set and the geometric verification of
# docs/lidar-places.md): loops are found in both directions with precision 1 and recall >= 0.8, the
# yaw of every loop (same and opposite direction) within 1 deg of the truth, and the alignment's
# translation within 0.5 m. With -DPACKETS=ON the same through packets.
if(PACKETS)
  # --sim-packets: the same route through VLP-16 packets (75 per revolution: 1800 firings, 24 per
  # packet), the decoder and the revolution assembler; one more packet cuts the last revolution.
  expect_keys("${j}" "program;format;parameters;scans;keys;ground_truth;source;summary;pr_curve;yaw;loop_translation;yaw_between_consecutive;packets;loops;per_scan")
  expect_number_in("${j}" 13501 13501 packets packets)
  expect_number_in("${j}" 0 0 packets refused_packets)
  expect_number_in("${j}" 180 180 packets revolutions_assembled)
  expect_number_in("${j}" 0 0 packets refused_records)
  string(JSON source GET "${j}" source)
  if(NOT source STREQUAL "sim:vlp16:packets")
    message(FATAL_ERROR "source ${source}")
  endif()
else()
  expect_keys("${j}" "program;format;parameters;scans;keys;ground_truth;source;summary;pr_curve;yaw;loop_translation;yaw_between_consecutive;loops;per_scan")
endif()
if(NOT DEFINED SCANS)
  set(SCANS 180)
endif()
expect_number_in("${j}" ${SCANS} ${SCANS} scans)
expect_number_in("${j}" 1 1 summary precision)
expect_number_in("${j}" 0.8 1 summary recall)
expect_number_in("${j}" 40 1000 yaw count)
expect_number_in("${j}" 0 1 yaw mean_abs_error_deg)
expect_number_in("${j}" 0 1 yaw max_abs_error_deg)
expect_number_in("${j}" 1 1 yaw within_1deg)
expect_number_in("${j}" 10 1000 yaw same_direction count)
expect_number_in("${j}" 10 1000 yaw opposite_direction count)
# -DLASER_STEP, -DCHI2, -DSORENSEN: the sensor's documented set (docs/lidar-places.md), when the run
# relies on the program's set for --sim.
if(DEFINED LASER_STEP)
  expect_number_in("${j}" ${LASER_STEP} ${LASER_STEP} parameters laser_step)
  expect_number_in("${j}" ${CHI2} ${CHI2} parameters chi_square_threshold)
  expect_number_in("${j}" ${SORENSEN} ${SORENSEN} parameters sorensen_threshold)
endif()
expect_number_in("${j}" 4.5 4.5 parameters loop_translation_m)
expect_number_in("${j}" 0.6 0.6 parameters min_aligned_fraction)
string(JSON nt GET "${j}" loop_translation count)
string(JSON ny GET "${j}" yaw count)
if(NOT nt EQUAL ny)
  message(FATAL_ERROR "aligned loops ${nt}, loops with a yaw ${ny}")
endif()
expect_number_in("${j}" 0 0.5 loop_translation max_error_m)
