#pragma once
/// @file keypoint_scan_sim.hpp
/// Test support (host): FALKO keypoints and descriptors of a ray-cast standstill scan of a
/// simulated world (drivers/sim), for the keypoint egomotion tests and benchmark.

#include <cstdint>

#include "agv/calib/keypoint_alignment.hpp"
#include "agv/falko/falko_descriptors.hpp"
#include "agv/falko/falko_detector.hpp"
#include "agv/sim/ray_caster.hpp"
#include "agv/sim/sim_laser.hpp"

namespace agv::test {

/// Keypoints and descriptors of one standstill scan.
struct KeypointScan {
  FalkoKeypoints keypoints;
  BscDescriptors bsc;
  CghDescriptors cgh;
  KeypointScanView view() const {
    return {{keypoints.data(), keypoints.size()}, {bsc.data(), bsc.size()}, {cgh.data(), cgh.size()}};
  }
};

/// One sweep of a laser at rest at `laserPose` (world frame) with `params` and `seed`, then FALKO
/// detection (default parameters) and both descriptors into `out`. Ok or the first failure.
inline Status simulateKeypointScan(const sim::RayCaster& caster, const Pose2d& laserPose,
                                   const sim::SimLaserParams& params, std::uint64_t seed, KeypointScan& out) {
  sim::SimLaser laser(caster, params, seed);
  static hal::LaserMeasurement m;  // large: kept off the stack
  static FalkoDetector detector;
  static const FalkoDescriber describer;
  Status s = laser.status();
  if (s == Status::Ok) {
    s = laser.scan(laserPose, Timestamp{}, m);
  }
  if (s == Status::Ok) {
    s = detector.detect(m.scan, out.keypoints);
  }
  if (s == Status::Ok) {
    s = describer.describe(detector.points(), out.keypoints, out.bsc, out.cgh);
  }
  return s;
}

}  // namespace agv::test
