#pragma once
/// @file falko_keypoint.hpp
/// One FALKO keypoint (a corner of the scan) in the sensor frame.

#include <cstdint>

namespace agv {

/// A corner found by `FalkoDetector`, in the sensor frame of its scan.
struct FalkoKeypoint {
  float x = 0.0F;  ///< [m] corner position (sub-beam refined when `refined`)
  float y = 0.0F;  ///< [m]
  /// [rad] direction, from the corner, of the sum of the vectors to the centroids of its two
  /// sides (points into the corner's opening angle); descriptors are aligned to it.
  float orientation = 0.0F;
  float radius = 0.0F;          ///< [m] neighbourhood radius used (a * exp(b * range))
  float score = 0.0F;           ///< cornerness score, lower is sharper (mean sector distance)
  std::uint32_t beamIndex = 0;  ///< index of the beam the corner was detected at
  bool refined = false;         ///< true when the two-line intersection was accepted
};

}  // namespace agv
