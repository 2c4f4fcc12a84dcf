#pragma once
// SVG output of agvnav-features: one scan with its keypoints, and repeatability curves.

#include <string>
#include <vector>

#include "agv/falko/falko_keypoint.hpp"
#include "agv/scan/laser_scan.hpp"
#include "eval.hpp"

namespace agv {
namespace features {

/// The valid points of the scan (grey), the keypoints (red circles of their neighbourhood
/// radius) and their orientations (arrows), sensor frame with x to the right and y up.
std::string scanSvg(const LaserScan& scan, const std::vector<FalkoKeypoint>& keypoints);

/// Repeatability of `test` against its levels, one polyline per dataset.
std::string curveSvg(const std::vector<DatasetResult>& results, const std::string& test);

}  // namespace features
}  // namespace agv
