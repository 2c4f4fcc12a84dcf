#include "svg.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace agv {
namespace features {

std::string scanSvg(const LaserScan& scan, const std::vector<FalkoKeypoint>& keypoints) {
  double minX = -0.5;
  double maxX = 0.5;
  double minY = -0.5;
  double maxY = 0.5;
  for (std::size_t i = 0; i < scan.size(); ++i) {
    if (!scan.isValid(i)) {
      continue;
    }
    const double a = static_cast<double>(scan.angle(i));
    const double r = static_cast<double>(scan.ranges[i]);
    minX = std::min(minX, r * std::cos(a));
    maxX = std::max(maxX, r * std::cos(a));
    minY = std::min(minY, r * std::sin(a));
    maxY = std::max(maxY, r * std::sin(a));
  }
  const double scale = 100.0;  // px per metre
  const double w = (maxX - minX + 1.0) * scale;
  const double h = (maxY - minY + 1.0) * scale;
  auto px = [&](double x) { return (x - minX + 0.5) * scale; };
  auto py = [&](double y) { return (maxY - y + 0.5) * scale; };  // y up
  std::ostringstream s;
  s.precision(5);
  s << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << w << "\" height=\"" << h << "\">\n";
  s << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  s << "<circle cx=\"" << px(0) << "\" cy=\"" << py(0) << "\" r=\"6\" fill=\"blue\"/>\n";
  for (std::size_t i = 0; i < scan.size(); ++i) {
    if (!scan.isValid(i)) {
      continue;
    }
    const double a = static_cast<double>(scan.angle(i));
    const double r = static_cast<double>(scan.ranges[i]);
    s << "<circle cx=\"" << px(r * std::cos(a)) << "\" cy=\"" << py(r * std::sin(a))
      << "\" r=\"1.5\" fill=\"#555\"/>\n";
  }
  for (const FalkoKeypoint& k : keypoints) {
    const double x = static_cast<double>(k.x);
    const double y = static_cast<double>(k.y);
    const double o = static_cast<double>(k.orientation);
    const double len = 0.3;
    s << "<circle cx=\"" << px(x) << "\" cy=\"" << py(y) << "\" r=\"" << static_cast<double>(k.radius) * scale
      << "\" fill=\"none\" stroke=\"red\"/>\n";
    s << "<circle cx=\"" << px(x) << "\" cy=\"" << py(y) << "\" r=\"3\" fill=\"red\"/>\n";
    const double ex = x + len * std::cos(o);
    const double ey = y + len * std::sin(o);
    s << "<line x1=\"" << px(x) << "\" y1=\"" << py(y) << "\" x2=\"" << px(ex) << "\" y2=\"" << py(ey)
      << "\" stroke=\"red\" stroke-width=\"2\"/>\n";
    // arrow head
    for (const double side : {-0.5, 0.5}) {
      const double hx = ex - 0.08 * std::cos(o + side);
      const double hy = ey - 0.08 * std::sin(o + side);
      s << "<line x1=\"" << px(ex) << "\" y1=\"" << py(ey) << "\" x2=\"" << px(hx) << "\" y2=\"" << py(hy)
        << "\" stroke=\"red\" stroke-width=\"2\"/>\n";
    }
  }
  s << "</svg>\n";
  return s.str();
}

std::string curveSvg(const std::vector<DatasetResult>& results, const std::string& test) {
  const double w = 480.0;
  const double h = 320.0;
  const double m = 50.0;
  const char* colours[] = {"#d62728", "#1f77b4", "#2ca02c", "#9467bd", "#ff7f0e"};
  std::ostringstream s;
  s.precision(5);
  s << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << w << "\" height=\"" << h << "\">\n";
  s << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  s << "<text x=\"" << m << "\" y=\"20\" font-size=\"14\">repeatability / " << test << "</text>\n";
  s << "<line x1=\"" << m << "\" y1=\"" << h - m << "\" x2=\"" << w - m << "\" y2=\"" << h - m
    << "\" stroke=\"black\"/>\n";
  s << "<line x1=\"" << m << "\" y1=\"" << m << "\" x2=\"" << m << "\" y2=\"" << h - m << "\" stroke=\"black\"/>\n";
  for (int t = 0; t <= 4; ++t) {
    const double y = h - m - (h - 2 * m) * t / 4.0;
    s << "<text x=\"10\" y=\"" << y + 4 << "\" font-size=\"11\">" << t * 0.25 << "</text>\n";
  }
  std::size_t c = 0;
  for (const DatasetResult& r : results) {
    const auto it = r.repeatability.find(test);
    if (it == r.repeatability.end() || it->second.empty()) {
      continue;
    }
    // Levels in numeric order where they are numbers, else as stored.
    std::vector<std::pair<double, std::pair<std::string, double>>> pts;
    for (const auto& lv : it->second) {
      const std::string& l = lv.first;
      double key = 0.0;
      if (l.rfind("x1/", 0) == 0) {
        key = 1.0 / std::atof(l.c_str() + 3);
      } else if (l[0] == 'x') {
        key = std::atof(l.c_str() + 1);
      } else {
        key = std::atof(l.c_str());
      }
      pts.push_back({key, {l, lv.second}});
    }
    std::sort(pts.begin(), pts.end());
    const double n = static_cast<double>(pts.size());
    s << "<polyline fill=\"none\" stroke=\"" << colours[c % 5] << "\" stroke-width=\"2\" points=\"";
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const double x = m + (w - 2 * m) * (n > 1 ? static_cast<double>(i) / (n - 1) : 0.5);
      const double y = h - m - (h - 2 * m) * pts[i].second.second;
      s << x << "," << y << " ";
    }
    s << "\"/>\n";
    for (std::size_t i = 0; i < pts.size() && c == 0; ++i) {
      const double x = m + (w - 2 * m) * (n > 1 ? static_cast<double>(i) / (n - 1) : 0.5);
      s << "<text x=\"" << x - 10 << "\" y=\"" << h - m + 16 << "\" font-size=\"11\">" << pts[i].second.first
        << "</text>\n";
    }
    s << "<text x=\"" << w - m - 80 << "\" y=\"" << m + 16 * static_cast<double>(c) << "\" font-size=\"12\" fill=\""
      << colours[c % 5] << "\">" << r.name << "</text>\n";
    ++c;
  }
  s << "</svg>\n";
  return s.str();
}

}  // namespace features
}  // namespace agv
