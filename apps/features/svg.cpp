#include "svg.hpp"

#include <algorithm>
#include <cmath>
#include <string_view>

#include "agv/report/number.hpp"
#include "agv/report/svg.hpp"

namespace agv {
namespace features {
namespace {

using report::SvgDocument;
using report::SvgPoints;

/// Sort key of a repeatability level: "0.05" -> 0.05, "x2" -> 2, "x1/4" -> 0.25; 0 when the level
/// is not one of those forms.
double levelKey(std::string_view level) {
  double v = 0.0;
  if (level.rfind("x1/", 0) == 0) {
    return report::toReal(level.substr(3), v) && v != 0.0 ? 1.0 / v : 0.0;
  }
  if (!level.empty() && level.front() == 'x') {
    level.remove_prefix(1);
  }
  return report::toReal(level, v) ? v : 0.0;
}

/// A tick label: 0, 0.25, 0.5, ... without trailing zeros.
std::string tickLabel(double v) {
  std::string s = report::svgNumber(v);
  while (s.back() == '0') {
    s.pop_back();
  }
  if (s.back() == '.') {
    s.pop_back();
  }
  return s;
}

}  // namespace

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
  SvgDocument svg(w, h);
  svg.add("circle", {{"cx", px(0)}, {"cy", py(0)}, {"r", "6"}, {"fill", "blue"}});
  for (std::size_t i = 0; i < scan.size(); ++i) {
    if (!scan.isValid(i)) {
      continue;
    }
    const double a = static_cast<double>(scan.angle(i));
    const double r = static_cast<double>(scan.ranges[i]);
    svg.add("circle", {{"cx", px(r * std::cos(a))}, {"cy", py(r * std::sin(a))}, {"r", "1.5"}, {"fill", "#555"}});
  }
  for (const FalkoKeypoint& k : keypoints) {
    const double x = static_cast<double>(k.x);
    const double y = static_cast<double>(k.y);
    const double o = static_cast<double>(k.orientation);
    const double len = 0.3;
    svg.add("circle", {{"cx", px(x)},
                       {"cy", py(y)},
                       {"r", static_cast<double>(k.radius) * scale},
                       {"fill", "none"},
                       {"stroke", "red"}});
    svg.add("circle", {{"cx", px(x)}, {"cy", py(y)}, {"r", "3"}, {"fill", "red"}});
    const double ex = x + len * std::cos(o);
    const double ey = y + len * std::sin(o);
    svg.add("line",
            {{"x1", px(x)}, {"y1", py(y)}, {"x2", px(ex)}, {"y2", py(ey)}, {"stroke", "red"}, {"stroke-width", "2"}});
    // arrow head
    for (const double side : {-0.5, 0.5}) {
      const double hx = ex - 0.08 * std::cos(o + side);
      const double hy = ey - 0.08 * std::sin(o + side);
      svg.add(
          "line",
          {{"x1", px(ex)}, {"y1", py(ey)}, {"x2", px(hx)}, {"y2", py(hy)}, {"stroke", "red"}, {"stroke-width", "2"}});
    }
  }
  return svg.str();
}

std::string curveSvg(const std::vector<DatasetResult>& results, const std::string& test) {
  const double w = 480.0;
  const double h = 320.0;
  const double m = 50.0;
  const char* colours[] = {"#d62728", "#1f77b4", "#2ca02c", "#9467bd", "#ff7f0e"};
  SvgDocument svg(w, h);
  svg.addText("text", {{"x", m}, {"y", "20"}, {"font-size", "14"}}, "repeatability / " + test);
  svg.add("line", {{"x1", m}, {"y1", h - m}, {"x2", w - m}, {"y2", h - m}, {"stroke", "black"}});
  svg.add("line", {{"x1", m}, {"y1", m}, {"x2", m}, {"y2", h - m}, {"stroke", "black"}});
  for (int t = 0; t <= 4; ++t) {
    const double y = h - m - (h - 2 * m) * t / 4.0;
    svg.addText("text", {{"x", "10"}, {"y", y + 4}, {"font-size", "11"}}, tickLabel(t * 0.25));
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
      pts.push_back({levelKey(lv.first), {lv.first, lv.second}});
    }
    std::sort(pts.begin(), pts.end());
    const double n = static_cast<double>(pts.size());
    const auto xAt = [&](std::size_t i) { return m + (w - 2 * m) * (n > 1 ? static_cast<double>(i) / (n - 1) : 0.5); };
    SvgPoints line;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      line.add(xAt(i), h - m - (h - 2 * m) * pts[i].second.second);
    }
    svg.add("polyline", {{"fill", "none"}, {"stroke", colours[c % 5]}, {"stroke-width", "2"}, {"points", line.str()}});
    for (std::size_t i = 0; i < pts.size() && c == 0; ++i) {
      svg.addText("text", {{"x", xAt(i) - 10}, {"y", h - m + 16}, {"font-size", "11"}}, pts[i].second.first);
    }
    svg.addText(
        "text",
        {{"x", w - m - 80}, {"y", m + 16 * static_cast<double>(c)}, {"font-size", "12"}, {"fill", colours[c % 5]}},
        r.name);
    ++c;
  }
  return svg.str();
}

}  // namespace features
}  // namespace agv
