#pragma once
/// @file chi_square.hpp
/// Named chi-square quantiles used for gating innovations and checking filter consistency.
/// Values are the inverse CDF of the chi-square distribution (to 4 significant decimals).

namespace agv {

/// P(chi2_2 <= q) = 0.95: 2-D innovation gate at 95 %.
inline constexpr double kChiSquare2Dof95 = 5.9915;
/// P(chi2_2 <= q) = 0.99: default 2-D innovation gate (1 % of true associations rejected).
inline constexpr double kChiSquare2Dof99 = 9.2103;
/// P(chi2_2 <= q) = 0.999.
inline constexpr double kChiSquare2Dof999 = 13.8155;
/// P(chi2_3 <= q) = 0.95 / 0.99: 3-D pose tests (NEES of one run).
inline constexpr double kChiSquare3Dof95 = 7.8147;
inline constexpr double kChiSquare3Dof99 = 11.3449;

}  // namespace agv
