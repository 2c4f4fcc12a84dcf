// FalkoParams::keepFarCorners on the real FLIRTLib logs (intel, fr079, mit-csail): keypoints per
// scan with the option off (the default detector) and on (candidates whose walls meet away from
// the beam point kept unrefined, thesis), and no allocation in either. Figures: docs/falko.md,
// "Unrefined candidates".
#include <cstddef>
#include <cstdio>
#include <memory>
#include <string>

#include "agv/datasets/carmen_log.hpp"
#include "agv/falko/falko_detector.hpp"
#include "agv_test.hpp"

namespace {
const std::string kData = std::string(AGV_SHARED_DATA_DIR) + "/laser2d/";

// Mean keypoints per scan over the scans with a ground-truth pose (those of agvnav-loops).
double perScan(const std::string& rel, bool keepFar) {
  agv::datasets::CarmenLog log;
  std::string err;
  REQUIRE(agv::datasets::readCarmenLog(kData + rel, log, err));  // a missing data folder fails loudly
  agv::FalkoParams params;
  params.keepFarCorners = keepFar;
  // ~190 kB of buffers: on the heap (a host test), not the stack.
  const std::unique_ptr<agv::FalkoDetector> detector(new agv::FalkoDetector(params));
  static agv::LaserScan scan;
  static agv::FalkoKeypoints kps;
  std::size_t scans = 0;
  std::size_t keypoints = 0;
  for (const agv::datasets::LogScan& s : log.scans) {
    if (!s.hasGroundTruth) {
      continue;
    }
    REQUIRE(s.toLaserScan(scan));
    agv::Status st = agv::Status::InvalidArgument;
    AGV_CHECK_NO_ALLOCATIONS(st = detector->detect(scan, kps));  // the set-aside path too
    REQUIRE(st == agv::Status::Ok);
    ++scans;
    keypoints += kps.size();
  }
  const double mean = static_cast<double>(keypoints) / static_cast<double>(scans);
  std::printf("%-28s keepFarCorners %d: %zu scans, %.2f keypoints per scan\n", rel.c_str(), keepFar ? 1 : 0, scans,
              mean);
  return mean;
}
}  // namespace

TEST_CASE("falko keepFarCorners: keypoints per scan on the FLIRTLib logs", "[falko][realdata]") {
  struct Log {
    const char* rel;
    double off;  ///< measured with the option off (the default)
    double on;   ///< measured with it on
  };
  const Log logs[] = {{"intel/intel-lab.log.gz", 2.39, 3.54},
                      {"fr079/fr079.log.gz", 4.16, 8.76},
                      {"mit-csail/mit-cscail.log.gz", 3.38, 6.17}};
  for (const Log& l : logs) {
    INFO(l.rel);
    const double off = perScan(l.rel, false);
    const double on = perScan(l.rel, true);
    CHECK(off == Approx(l.off).margin(0.01));  // the default detector is unchanged
    CHECK(on == Approx(l.on).margin(0.01));
  }
}
