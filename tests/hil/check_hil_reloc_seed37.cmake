# Checks of agvnav-hil --seed 37 --no-missions --json (docs/hil.md, "A wrong pose on seed 37"): no
# wrong pose on either relocalization stage (the corner map's cold start 8 was restarted 1.42 m off
# before the net-support rule), the requirement met, and the reflector stage still finding at least
# 16 of its 28 trials (18 measured with and without the rule).
expect_number_in("${j}" 28 28 relocalization count)
expect_number_in("${j}" 0 0 relocalization wrong)
expect_number_in("${j}" 16 28 relocalization found)
expect_number_in("${j}" 28 28 relocalization_corners count)
expect_number_in("${j}" 0 0 relocalization_corners wrong)
expect_true("${j}" requirement_met)
