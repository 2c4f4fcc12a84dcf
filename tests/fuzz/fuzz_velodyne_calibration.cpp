// libFuzzer targets fuzz_velodyne_yaml and fuzz_velodyne_dbxml (this file built twice, the latter
// with AGV_FUZZ_DBXML): the velodyne_pointcloud YAML / factory db.xml calibration parser on arbitrary text.
// Invariants: no crash or sanitizer report; on success a table of 1..kMaxLidarLasers lasers with
// finite parameters and angles within pi; on failure a reason.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "agv/datasets/velodyne_calibration.hpp"
#include "fuzz_support.hpp"

using agv::fuzz::check;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  agv::LaserIntrinsics table;
  std::string error;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
#ifdef AGV_FUZZ_DBXML
  const bool ok = agv::datasets::parseVelodyneDbXml(text, table, error);
#else
  const bool ok = agv::datasets::parseVelodyneYaml(text, table, error);
#endif
  if (ok) {
    check(table.size() >= 1U && table.size() <= agv::kMaxLidarLasers);
    for (std::size_t i = 0; i < table.size(); ++i) {
      const agv::LaserParams& p = table.params(i);
      check(std::isfinite(p.distCorrection) && std::isfinite(p.vertOffset) && std::isfinite(p.horizOffset));
      check(std::fabs(p.theta) <= 3.1415927 && std::fabs(p.alpha) <= 3.1415927);
    }
  } else {
    check(!error.empty());
  }
  return 0;
}
