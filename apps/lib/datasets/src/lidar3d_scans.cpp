#include "agv/datasets/lidar3d_scans.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string_view>

#include "agv/report/number.hpp"
#include "agv/report/text_file.hpp"

namespace agv {
namespace datasets {

namespace {
constexpr std::size_t kMaxScanBytes = 64U * 1024U * 1024U;

template <typename T>
T readLe(const char* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));  // the data and every target of the tools are little-endian
  return v;
}
/// The whole file as bytes, refused unless its size is a whole number of `recordSize` records.
bool readRecords(const std::string& path, std::size_t recordSize, std::string& bytes, std::string& error) {
  if (!report::readTextFile(path, bytes, error, kMaxScanBytes)) {
    return false;
  }
  if (bytes.size() % recordSize != 0U) {
    error = path + ": size " + std::to_string(bytes.size()) + " is not a multiple of " + std::to_string(recordSize) +
            " bytes";
    return false;
  }
  return true;
}
}  // namespace

bool readKittiVelodyne(const std::string& path, Revolution& out, std::string& error) {
  out = Revolution{};
  std::string bytes;
  if (!readRecords(path, 16U, bytes, error)) {
    return false;
  }
  const std::size_t n = bytes.size() / 16U;
  out.points.reserve(n);
  long ring = 0;
  long maxRing = 0;
  double prev = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const char* p = bytes.data() + 16U * i;
    const Eigen::Vector3f pt(readLe<float>(p), readLe<float>(p + 4), readLe<float>(p + 8));
    const double a = std::atan2(-static_cast<double>(pt.y()), -static_cast<double>(pt.x()));
    if (i > 0) {
      const double d = a - prev;
      if (d < -M_PI) {
        ++ring;
      } else if (d > M_PI) {
        --ring;
      }
    }
    prev = a;
    if (ring < 0 || ring > 65535) {
      error = path + ": ring recovery failed at point " + std::to_string(i);
      return false;
    }
    maxRing = std::max(maxRing, ring);
    out.points.push_back(RingPoint{pt, static_cast<std::uint16_t>(ring)});
  }
  out.rings = n > 0 ? static_cast<std::size_t>(maxRing) + 1U : 0U;
  return true;
}

bool readNcltVelodyne(const std::string& path, Revolution& out, std::string& error) {
  out = Revolution{};
  std::string bytes;
  if (!readRecords(path, 8U, bytes, error)) {
    return false;
  }
  const std::size_t n = bytes.size() / 8U;
  std::vector<std::uint8_t> laser(n);
  out.points.resize(n);
  std::array<double, 256> elevationSum{};
  std::array<std::size_t, 256> count{};
  for (std::size_t i = 0; i < n; ++i) {
    const char* p = bytes.data() + 8U * i;
    const auto coord = [&](std::size_t k) {
      return static_cast<float>(static_cast<double>(readLe<std::uint16_t>(p + 2 * k)) * 0.005 - 100.0);
    };
    const Eigen::Vector3f pt(coord(0), coord(1), coord(2));
    out.points[i].point = pt;
    laser[i] = static_cast<std::uint8_t>(p[7]);
    const double r = pt.norm();
    if (r > 0.0) {
      elevationSum[laser[i]] += std::asin(static_cast<double>(pt.z()) / r);
      ++count[laser[i]];
    }
  }
  // Rows: the lasers seen, ranked by mean elevation.
  std::vector<std::pair<double, std::size_t>> order;
  for (std::size_t id = 0; id < 256; ++id) {
    if (count[id] > 0) {
      order.emplace_back(elevationSum[id] / static_cast<double>(count[id]), id);
    }
  }
  std::sort(order.begin(), order.end());
  std::array<std::uint16_t, 256> rowOf{};
  for (std::size_t r = 0; r < order.size(); ++r) {
    rowOf[order[r].second] = static_cast<std::uint16_t>(r);
  }
  for (std::size_t i = 0; i < n; ++i) {
    out.points[i].ring = rowOf[laser[i]];
  }
  out.rings = order.size();
  return true;
}

bool readKittiPoses(const std::string& path, std::vector<Eigen::Matrix<double, 3, 4>>& out, std::string& error) {
  out.clear();
  std::string text;
  if (!report::readTextFile(path, text, error, kMaxScanBytes)) {
    return false;
  }
  std::size_t lineNo = 0;
  std::size_t start = 0;
  while (start < text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string::npos) {
      end = text.size();
    }
    const std::string_view line(text.data() + start, end - start);
    start = end + 1;
    ++lineNo;
    if (line.find_first_not_of(" \t\r") == std::string_view::npos) {
      continue;
    }
    Eigen::Matrix<double, 3, 4> m;
    std::size_t pos = 0;
    for (int k = 0; k < 12; ++k) {
      while (pos < line.size() && (line[pos] == ' ' || line[pos] == '\t' || line[pos] == '\r')) {
        ++pos;
      }
      std::size_t e = pos;
      while (e < line.size() && line[e] != ' ' && line[e] != '\t' && line[e] != '\r') {
        ++e;
      }
      double v = 0.0;
      if (!report::toReal(line.substr(pos, e - pos), v)) {
        error = path + ":" + std::to_string(lineNo) + ": expected 12 numbers";
        return false;
      }
      m(k / 4, k % 4) = v;
      pos = e;
    }
    out.push_back(m);
  }
  return true;
}

bool readVelodyneCalibration(const std::string& path, std::vector<double>& elevation,
                             std::vector<double>& azimuthOffset, std::string& error) {
  elevation.clear();
  azimuthOffset.clear();
  std::string text;
  if (!report::readTextFile(path, text, error)) {
    return false;
  }
  struct Laser {
    double id = -1.0;
    double rot = std::nan("");
    double vert = std::nan("");
  };
  std::vector<Laser> lasers;
  std::size_t start = 0;
  std::size_t lineNo = 0;
  while (start < text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string::npos) {
      end = text.size();
    }
    std::string_view line(text.data() + start, end - start);
    start = end + 1;
    ++lineNo;
    const std::size_t first = line.find_first_not_of(' ');
    if (first == std::string_view::npos) {
      continue;
    }
    line.remove_prefix(first);
    if (line.substr(0, 2) == "- ") {
      lasers.emplace_back();
      line.remove_prefix(2);
    }
    const std::size_t colon = line.find(':');
    if (colon == std::string_view::npos || lasers.empty()) {
      continue;
    }
    const std::string_view key = line.substr(0, colon);
    std::string_view value = line.substr(colon + 1);
    while (!value.empty() && (value.front() == ' ' || value.back() == '\r' || value.back() == ' ')) {
      value = value.front() == ' ' ? value.substr(1) : value.substr(0, value.size() - 1);
    }
    double v = 0.0;
    if (key == "laser_id" || key == "rot_correction" || key == "vert_correction") {
      if (!report::toReal(value, v)) {
        error = path + ":" + std::to_string(lineNo) + ": " + std::string(key) + " is not a number";
        return false;
      }
      Laser& l = lasers.back();
      if (key == "laser_id") {
        l.id = v;
      } else if (key == "rot_correction") {
        l.rot = v;
      } else {
        l.vert = v;
      }
    }
  }
  elevation.assign(lasers.size(), std::nan(""));
  azimuthOffset.assign(lasers.size(), std::nan(""));
  for (const Laser& l : lasers) {
    const std::size_t id = l.id < 0.0 ? lasers.size() : static_cast<std::size_t>(l.id);
    if (id >= lasers.size() || static_cast<double>(id) != l.id || !std::isfinite(l.rot) || !std::isfinite(l.vert) ||
        std::isfinite(elevation[id])) {
      error = path + ": laser entries incomplete, repeated or not numbered 0..n-1";
      return false;
    }
    elevation[id] = l.vert;
    azimuthOffset[id] = l.rot;
  }
  if (lasers.empty()) {
    error = path + ": no laser";
    return false;
  }
  return true;
}

double kittiRelativeYaw(const Eigen::Matrix<double, 3, 4>& a, const Eigen::Matrix<double, 3, 4>& b) {
  const Eigen::Matrix3d r = a.leftCols<3>().transpose() * b.leftCols<3>();
  return -std::atan2(r(0, 2), r(2, 2));
}

Eigen::Vector2d kittiPosition(const Eigen::Matrix<double, 3, 4>& pose) {
  return {pose(0, 3), pose(2, 3)};
}

}  // namespace datasets
}  // namespace agv
