# Checks of agvnav-lidar-places --json on the four KITTI 00 scans with m = 0 (included by
# tests/support/run_json_program.cmake with the document in `j`): both consecutive pairs found as
# true loops, nothing else; precision and recall 1; each pair's yaw within 1 deg of poses_00.txt.
expect_keys("${j}" "program;format;parameters;scans;keys;ground_truth;source;summary;pr_curve;yaw;loop_translation;yaw_between_consecutive;loops;per_scan")
expect_number_in("${j}" 4 4 scans)
expect_number_in("${j}" 2 2 summary detected)
expect_number_in("${j}" 2 2 summary true_positives)
expect_number_in("${j}" 2 2 summary positives)
expect_number_in("${j}" 1 1 summary precision)
expect_number_in("${j}" 1 1 summary recall)
expect_number_in("${j}" 2 2 yaw count)
expect_number_in("${j}" 0 1 yaw max_abs_error_deg)
foreach(i 0 1)
  expect_number_in("${j}" -1 1 loops ${i} yaw_error_deg)
endforeach()
expect_number_in("${j}" 95 95 loops 0 frame)
expect_number_in("${j}" 94 94 loops 0 key_frame)
expect_number_in("${j}" 199 199 loops 1 frame)
expect_number_in("${j}" 198 198 loops 1 key_frame)
