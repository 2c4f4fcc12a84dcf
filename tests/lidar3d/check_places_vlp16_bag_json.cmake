# Checks of agvnav-lidar-places --format vlp16-bag --json on the nebula VLP-16 ROS 2 bag (the
# VelodyneScan messages' packets through the decoder, the revolution assembler and buildFromFirings).
# Expected figures from the data README / metadata.yaml (4 messages, 150-151 packets each, dual
# return) and from the bag's bytes read independently of agvnav (Python's sqlite3 and struct: the
# CDR packet counts, the non-zero distances of all blocks, the block azimuth wraps and the non-zero
# first returns between them; docs/lidar-places.md): 603 packets, 116 827 returns, 4 wraps (the
# first message begins at 0.66 deg, after the cut: its turn counts as begun mid-turn, 3 complete
# revolutions follow), first returns per complete revolution 14 631, 14 668, 14 674. No poses.
expect_keys("${j}" "program;format;parameters;scans;keys;ground_truth;source;summary;pr_curve;yaw;loop_translation;yaw_between_consecutive;packets;loops;per_scan")
string(JSON format GET "${j}" format)
if(NOT format STREQUAL "vlp16-bag")
  message(FATAL_ERROR "format ${format}")
endif()
string(JSON truth GET "${j}" ground_truth)
if(truth)
  message(FATAL_ERROR "the nebula bag has no poses, ground_truth = ${truth}")
endif()
expect_number_in("${j}" 1 1 packets files)
expect_number_in("${j}" 4 4 packets messages)
expect_number_in("${j}" 603 603 packets packets)
expect_number_in("${j}" 0 0 packets refused_packets)
expect_number_in("${j}" 0 0 packets skipped_blocks)
expect_number_in("${j}" 116827 116827 packets records)
expect_number_in("${j}" 4 4 packets revolutions_assembled)
expect_number_in("${j}" 1 1 packets revolutions_incomplete_skipped)
expect_number_in("${j}" 0 0 packets refused_records)
expect_number_in("${j}" 3 3 scans)
# The assembler cuts at the first record past the wrap, the count above at the block pair: the
# revolutions agree within one packet's first returns (6 pairs x 32 = 192).
set(first 14631 14668 14674)
foreach(i RANGE 2)
  list(GET first ${i} n)
  math(EXPR lo "${n} - 192")
  math(EXPR hi "${n} + 192")
  string(JSON status GET "${j}" per_scan ${i} status)
  if(NOT status STREQUAL "ok")
    message(FATAL_ERROR "revolution ${i}: ${status}")
  endif()
  expect_number_in("${j}" ${lo} ${hi} per_scan ${i} points)
  expect_number_in("${j}" 100 ${hi} per_scan ${i} normals)
  expect_number_in("${j}" 0.99999 1.00001 per_scan ${i} signature_sum)
endforeach()
# Without poses the relative yaw between consecutive revolutions is what the program can report.
expect_number_in("${j}" 2 2 yaw_between_consecutive count)
expect_type("${j}" NUMBER per_scan 1 yaw_from_previous_deg)
expect_type("${j}" NUMBER per_scan 2 yaw_from_previous_deg)
