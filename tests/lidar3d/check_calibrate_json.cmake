# Checks of agvnav-lidar-calibrate --json on a reduced protocol (3 distances x 3 tilts, firings
# within +-50 deg, along-beam residual; docs/lidar-calibration.md): every laser estimated, the
# plane residual at the noise floor (final / truth 1.0014 measured), no parameter error beyond
# 3 sigma (max 2.55 measured), D_corr within 10 mm of the truth (5.7 mm measured from 50 mm), the
# written YAML read back as the same table.
expect_keys("${j}" "program;factory;lasers;input;placements;noise_m;scan_count;residual;returns;ok;cost_start_m2;cost_final_m2;cost_final_joint_m2;max_plane_angle_rad;worst_rms_final_over_truth;noise_sigma_m;range_sigma_m;cost_calibrated_m2;noise_bias_correction;iterations;wall_time_s;seconds;lasers_estimated;lasers_held;errors_vs_truth;common_alpha_offset_rad;common_theta_offset_rad;max_error_over_sigma;beyond_three_sigma;conditioning_start;conditioning;scans;laser_reports;output")
expect_number_in("${j}" 64 64 lasers_estimated)
expect_number_in("${j}" 9 9 placements)
expect_number_in("${j}" 0.97 1.03 worst_rms_final_over_truth)
expect_number_in("${j}" 0 0 beyond_three_sigma)
expect_number_in("${j}" 0 0.010 errors_vs_truth D_corr final_max)
expect_number_in("${j}" 0.018 0.022 noise_sigma_m)
string(JSON same GET "${j}" output read_back_equal)
if(NOT same STREQUAL "ON" AND NOT same STREQUAL "true")
  message(FATAL_ERROR "the written YAML did not read back as the same table (${same})")
endif()
