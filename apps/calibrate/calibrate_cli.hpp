#pragma once
/// @file calibrate_cli.hpp
/// agvnav-calibrate: the command line of the on-vehicle calibration routine (options, progress,
/// report, calibration file). In a library so that the tests run it end to end.

#include <cstdio>

namespace agv::calibration {

/// Runs the program with `argv` (as main gets it), printing to `out` / `err`. Exit codes: 0 the
/// calibration file was written; 1 the calibration failed (data not good enough, nothing written);
/// 2 bad options, a plan that does not fit, or a file that cannot be written.
int calibrateMain(int argc, const char* const* argv, std::FILE* out, std::FILE* err);

}  // namespace agv::calibration
