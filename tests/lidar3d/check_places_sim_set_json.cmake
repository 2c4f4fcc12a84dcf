# Checks of agvnav-lidar-places --sim vlp16 --laser-step 2 --loop-translation 0: the two options given
# win, the others keep the VLP-16 set of docs/lidar-places.md (T_chi2 9e-4, T_Sor 0.105, inlier share 0.6).
expect_number_in("${j}" 2 2 parameters laser_step)
expect_number_in("${j}" 0 0 parameters loop_translation_m)
expect_number_in("${j}" 0.0009 0.0009 parameters chi_square_threshold)
expect_number_in("${j}" 0.105 0.105 parameters sorensen_threshold)
expect_number_in("${j}" 0.6 0.6 parameters min_aligned_fraction)
string(JSON source GET "${j}" source)
if(NOT source STREQUAL "sim:vlp16")
  message(FATAL_ERROR "source ${source}")
endif()
