#pragma once
/// @file calib_sim.hpp
/// Physically simulated calibration runs with known ground truth: a tricycle driving
/// constant-steering arcs (true distance and steering), the drive and steering encoders that
/// measure them (tick and 14-bit quantisation, jitter), and the laser's egomotion with noise.

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "agv/calib/calibration.hpp"

namespace agv::test {

struct CalibSimConfig {
  TricycleParams truth{1.5, 5e-4, deg2rad(1.0), deg2rad(-0.5)};
  Pose2d laser{1.6, 0.4, deg2rad(5.0)};
  double beta = kPi<double>;        ///< target rotation of each arc [rad]
  int perDirection = 10;            ///< segments per driving direction (half left, half right)
  double steerMin = deg2rad(18.0);  ///< smallest |steering| [rad]
  double steerMax = deg2rad(50.0);  ///< largest |steering| [rad]
  bool forward = true;
  bool backward = true;
  double sigmaXY = 0.0;         ///< egomotion noise per axis [m]
  double sigmaTheta = 0.0;      ///< egomotion rotation noise [rad]
  bool quantiseTicks = false;   ///< true distance is continuous, ticks are its rounding
  int steerBits = 0;            ///< steering encoder resolution over 2 pi (0: exact)
  double steerPlacement = 0.0;  ///< the achieved steering differs from the planned one by U(-x, x) [rad]
  double steerJitter = 0.0;     ///< extra N(0, x) steering-encoder error per segment [rad]
};

/// One simulated run. Noise-free when every noise field is zero (ticks are then exact integers
/// of the true distance).
inline std::vector<CalibSegment> simulateCalibration(const CalibSimConfig& cfg, std::mt19937_64& rng) {
  std::vector<CalibSegment> out;
  std::normal_distribution<double> unit(0.0, 1.0);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  const int levels = cfg.perDirection / 2 > 1 ? cfg.perDirection / 2 : 1;
  for (int dir = 1; dir >= -1; dir -= 2) {
    if ((dir > 0 && !cfg.forward) || (dir < 0 && !cfg.backward)) {
      continue;
    }
    const double offset = dir > 0 ? cfg.truth.steerOffsetForward : cfg.truth.steerOffsetBackward;
    for (int i = 0; i < cfg.perDirection; ++i) {
      const double side = (i % 2 == 0) ? 1.0 : -1.0;
      const int level = (i / 2) % levels;
      const double mag =
          levels > 1 ? cfg.steerMin + (cfg.steerMax - cfg.steerMin) * level / (levels - 1) : cfg.steerMin;
      const double alphaTrue = side * mag + (cfg.steerPlacement > 0.0 ? cfg.steerPlacement * uni(rng) : 0.0);
      double ds = dir * cfg.beta * cfg.truth.wheelbase / std::fabs(std::sin(alphaTrue));
      const double ticksReal = ds / cfg.truth.driveScale;
      CalibSegment s;
      s.ticks = static_cast<std::int64_t>(std::llround(ticksReal));
      if (!cfg.quantiseTicks) {
        ds = static_cast<double>(s.ticks) * cfg.truth.driveScale;
      }
      double raw = alphaTrue - offset;
      if (cfg.steerBits > 0) {
        const double q = kTwoPi<double> / std::ldexp(1.0, cfg.steerBits);
        raw = q * std::round(raw / q);
      }
      if (cfg.steerJitter > 0.0) {
        raw += cfg.steerJitter * unit(rng);
      }
      s.steering = raw;
      const Pose2d arc = tricycleArc(ds, alphaTrue, cfg.truth.wheelbase);
      Pose2d ego = cfg.laser.inverse().compose(arc).compose(cfg.laser);
      if (cfg.sigmaXY > 0.0 || cfg.sigmaTheta > 0.0) {
        ego.x += cfg.sigmaXY * unit(rng);
        ego.y += cfg.sigmaXY * unit(rng);
        ego.theta = normalizeAngle(ego.theta + cfg.sigmaTheta * unit(rng));
      }
      s.egomotion = ego;
      out.push_back(s);
    }
  }
  return out;
}

/// Options whose nominal vehicle is the truth with the driving scale off by `scaleError`
/// (relative) and zero offsets: what a technician types in from the drawing.
inline CalibrationOptions nominalOptions(const CalibSimConfig& cfg, double scaleError = 0.03) {
  CalibrationOptions opt;
  opt.nominal.wheelbase = cfg.truth.wheelbase;
  opt.nominal.driveScale = cfg.truth.driveScale * (1.0 + scaleError);
  opt.nominal.steerOffsetForward = 0.0;
  opt.nominal.steerOffsetBackward = 0.0;
  return opt;
}

/// Running mean / standard deviation.
struct Stats {
  double n = 0.0;
  double mean = 0.0;
  double m2 = 0.0;
  void add(double x) {
    n += 1.0;
    const double d = x - mean;
    mean += d / n;
    m2 += d * (x - mean);
  }
  double stddev() const { return n > 1.0 ? std::sqrt(m2 / (n - 1.0)) : 0.0; }
  double rms() const { return std::sqrt(mean * mean + (n > 1.0 ? m2 / n : 0.0)); }
  /// |mean| within 3 standard errors.
  bool unbiased() const { return std::fabs(mean) < 3.0 * stddev() / std::sqrt(n); }
};

}  // namespace agv::test
