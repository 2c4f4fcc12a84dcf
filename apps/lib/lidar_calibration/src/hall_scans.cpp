#include "agv/lidar_calibration/hall_scans.hpp"

#include <cmath>
#include <cstdio>
#include <random>

namespace agv::lidar_calibration {

std::vector<CalibrationScan> simulateHallScans(const HallScansConfig& config, const LaserIntrinsics& truth,
                                               std::vector<std::vector<int>>* surfaces) {
  const sim::CalibrationHall hall = sim::calibrationHall(config.hall);
  std::vector<CalibrationScan> scans;
  std::mt19937_64 rng(config.seed);
  sim::ModelScan scan;
  if (surfaces != nullptr) {
    surfaces->clear();
  }
  for (const sim::HallPlacement& p : config.placements) {
    sim::scanModel(hall.world, sim::placementPose(p), truth, config.sensor, rng, scan);
    CalibrationScan s;
    char name[64];
    std::snprintf(name, sizeof name, "%.1f m tilt %.0f deg", p.distance, p.tilt * 180.0 / 3.14159265358979323846);
    s.name = name;
    s.returns = scan.returns;
    scans.push_back(std::move(s));
    if (surfaces != nullptr) {
      surfaces->push_back(scan.surface);
    }
  }
  return scans;
}

TruthComparison compareWithTruth(const IntrinsicCalibrationResult& result, const LaserIntrinsics& truth,
                                 const IntrinsicCalibrationConfig& config) {
  const EstimatedParams& estimated = config.estimate;
  using Vec5 = Eigen::Matrix<double, kLaserParamCount, 1>;
  TruthComparison c;
  c.error.assign(result.lasers.size(), Vec5::Zero());
  std::size_t n = 0;
  double alphaSum = 0.0;
  double alphaStartSum = 0.0;
  double thetaSum = 0.0;
  double thetaStartSum = 0.0;
  for (const LaserReport& l : result.lasers) {
    if (l.estimated && l.laser < truth.size()) {
      alphaSum += l.estimate.alpha - truth.params(l.laser).alpha;
      alphaStartSum += l.start.alpha - truth.params(l.laser).alpha;
      thetaSum += l.estimate.theta - truth.params(l.laser).theta;
      thetaStartSum += l.start.theta - truth.params(l.laser).theta;
      ++n;
    }
  }
  if (n == 0) {
    return c;
  }
  c.commonAlpha = estimated.alpha ? alphaSum / static_cast<double>(n) : 0.0;
  const double commonStart = estimated.alpha ? alphaStartSum / static_cast<double>(n) : 0.0;
  const bool theta = estimated.theta && config.holdMeanTheta;
  c.commonTheta = theta ? thetaSum / static_cast<double>(n) : 0.0;
  const double commonThetaStart = theta ? thetaStartSum / static_cast<double>(n) : 0.0;
  // The common z shift (a gauge when D_corr and V_o are both estimated): its least-squares amount.
  const bool zGauge = estimated.distCorrection && estimated.vertOffset;
  double zShift = 0.0;
  double zShiftStart = 0.0;
  for (const LaserReport& l : result.lasers) {
    if (zGauge && l.estimated && l.laser < truth.size()) {
      const LaserParams& t = truth.params(l.laser);
      const double st = std::sin(l.start.theta);
      const double ct = std::cos(l.start.theta);
      zShift += (st * (l.estimate.distCorrection - t.distCorrection) + ct * (l.estimate.vertOffset - t.vertOffset)) /
                static_cast<double>(n);
      zShiftStart += (st * (l.start.distCorrection - t.distCorrection) + ct * (l.start.vertOffset - t.vertOffset)) /
                     static_cast<double>(n);
    }
  }
  c.commonZ = zShift;
  Vec5 sq = Vec5::Zero();
  for (const LaserReport& l : result.lasers) {
    if (!l.estimated || l.laser >= truth.size()) {
      continue;
    }
    Vec5 e = toVector(l.estimate) - toVector(truth.params(l.laser));
    Vec5 e0 = toVector(l.start) - toVector(truth.params(l.laser));
    e[kAlpha] -= c.commonAlpha;
    e0[kAlpha] -= commonStart;
    e[kTheta] -= c.commonTheta;
    if (zGauge) {
      e[kDistCorrection] -= zShift * std::sin(l.start.theta);
      e[kVertOffset] -= zShift * std::cos(l.start.theta);
      e0[kDistCorrection] -= zShiftStart * std::sin(l.start.theta);
      e0[kVertOffset] -= zShiftStart * std::cos(l.start.theta);
    }
    e0[kTheta] -= commonThetaStart;
    c.error[l.laser] = e;
    for (int k = 0; k < kLaserParamCount; ++k) {
      if (!estimated[k]) {
        continue;
      }
      c.maxAbs[k] = std::max(c.maxAbs[k], std::fabs(e[k]));
      c.maxAbsStart[k] = std::max(c.maxAbsStart[k], std::fabs(e0[k]));
      sq[k] += e[k] * e[k];
      if (l.sigma[k] > 0.0) {
        const double ratio = std::fabs(e[k]) / l.sigma[k];
        c.maxSigmaRatio = std::max(c.maxSigmaRatio, ratio);
        c.beyondThreeSigma += ratio > 3.0 ? 1U : 0U;
        ++c.compared;
        c.beyondByParam[static_cast<std::size_t>(k)] += ratio > 3.0 ? 1U : 0U;
        ++c.comparedByParam[static_cast<std::size_t>(k)];
      }
    }
  }
  c.rms = (sq / static_cast<double>(n)).cwiseSqrt();
  return c;
}

}  // namespace agv::lidar_calibration
