#pragma once
// Shared by calibrate.session and vehicle.calibration: a calibration file written by the routine,
// read back and checked against the simulator's truth within the tolerance of calibrate.app
// (5 standard deviations of the Monte-Carlo figures scaled to 8 segments, docs/calibration.md:
// s_w 2000 ppm, offsets 0.1 deg, lx/ly 8 mm, ltheta 0.3 deg; the nominal values lie outside).
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include "agv/calib/calibration_file.hpp"
#include "agv/sim/sim_vehicle.hpp"
#include "agv_test.hpp"

namespace agv::test {

inline std::string readFile(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

inline bool fileExists(const std::string& path) {
  std::ifstream f(path);
  return f.good();
}

/// Parses the calibration file `path`, prints its errors against `truth` after `label`, checks
/// them within the tolerance above times `scale` and returns the values.
inline VehicleCalibration checkCalibrationFile(const std::string& path, const sim::SimVehicleParams& truth,
                                               const char* label, double scale = 1.0) {
  const std::string text = readFile(path);
  VehicleCalibration got;
  REQUIRE(parseCalibrationFile(Span<const char>(text.data(), text.size()), got) == Status::Ok);
  const TricycleParams& t = truth.truth;
  const Pose2d& l = truth.laserMount;
  std::printf(
      "%s: s_w %+.0f ppm, alpha_F %+.4f deg, alpha_B %+.4f deg, lx %+.2f mm, ly %+.2f mm, ltheta %+.4f deg "
      "(refined - truth)\n",
      label, 1e6 * (got.params.driveScale / t.driveScale - 1.0),
      rad2deg(got.params.steerOffsetForward - t.steerOffsetForward),
      rad2deg(got.params.steerOffsetBackward - t.steerOffsetBackward), 1e3 * (got.laserPose.x - l.x),
      1e3 * (got.laserPose.y - l.y), rad2deg(got.laserPose.theta - l.theta));
  CHECK(std::fabs(got.params.driveScale / t.driveScale - 1.0) < scale * 2000e-6);
  CHECK(std::fabs(got.params.steerOffsetForward - t.steerOffsetForward) < scale * deg2rad(0.1));
  CHECK(std::fabs(got.params.steerOffsetBackward - t.steerOffsetBackward) < scale * deg2rad(0.1));
  CHECK(std::fabs(got.laserPose.x - l.x) < scale * 0.008);
  CHECK(std::fabs(got.laserPose.y - l.y) < scale * 0.008);
  CHECK(std::fabs(got.laserPose.theta - l.theta) < scale * deg2rad(0.3));
  return got;
}

}  // namespace agv::test
