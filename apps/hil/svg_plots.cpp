#include "svg_plots.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

namespace agv::hil {

namespace {

constexpr double kScale = 20.0;   // [px/m] map
constexpr double kMargin = 30.0;  // [px]

const char* colourOf(sim::ObstacleKind k) {
  switch (k) {
    case sim::ObstacleKind::Wall:
      return "#444";
    case sim::ObstacleKind::Pallet:
      return "#a0522d";
    case sim::ObstacleKind::Rack:
      return "#3060a0";
    case sim::ObstacleKind::Pillar:
      return "#777";
    case sim::ObstacleKind::Reflector:
      return "#e00000";
  }
  return "#000";
}

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f", v);
  return buf;
}

// 1e-4 -> "0.1 mm", 0.01 -> "10 mm", 1 -> "1 m".
std::string label(double metres) {
  char buf[32];
  if (metres >= 1.0) {
    std::snprintf(buf, sizeof buf, "%g m", metres);
  } else {
    std::snprintf(buf, sizeof buf, "%g mm", metres * 1000.0);
  }
  return buf;
}

bool save(const std::string& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary);
  out << text;
  return static_cast<bool>(out);
}

}  // namespace

bool writeMapSvg(const std::string& file, const sim::World& world, const std::vector<RunResult>& runs) {
  sim::Point2 lo;
  sim::Point2 hi;
  world.bounds(&lo, &hi);
  const double w = (hi.x - lo.x) * kScale + 2 * kMargin;
  const double h = (hi.y - lo.y) * kScale + 2 * kMargin + 40.0;
  auto X = [&](double x) { return num(kMargin + (x - lo.x) * kScale); };
  auto Y = [&](double y) { return num(kMargin + (hi.y - y) * kScale); };
  std::ostringstream s;
  s << "<svg xmlns='http://www.w3.org/2000/svg' width='" << num(w) << "' height='" << num(h)
    << "' font-family='sans-serif' font-size='12'>\n";
  s << "<rect width='100%' height='100%' fill='white'/>\n";
  for (const sim::Segment& g : world.segments) {
    s << "<line x1='" << X(g.a.x) << "' y1='" << Y(g.a.y) << "' x2='" << X(g.b.x) << "' y2='" << Y(g.b.y)
      << "' stroke='" << colourOf(g.kind) << "' stroke-width='1.5'/>\n";
  }
  for (const sim::Circle& c : world.circles) {
    const double r = std::max(c.radius * kScale, c.kind == sim::ObstacleKind::Reflector ? 3.0 : 1.0);
    s << "<circle cx='" << X(c.centre.x) << "' cy='" << Y(c.centre.y) << "' r='" << num(r) << "' fill='"
      << colourOf(c.kind) << "'/>\n";
  }
  for (const sim::Path& p : world.paths) {
    s << "<polyline fill='none' stroke='#bbb' stroke-width='6' stroke-linecap='round' points='";
    for (const Pose2d& q : p.points) {
      s << X(q.x) << ',' << Y(q.y) << ' ';
    }
    s << "'/>\n<text x='" << X(p.start.x) << "' y='" << Y(p.start.y) << "' dx='-18' dy='4'>" << p.name << "</text>\n";
  }
  // First run of each path.
  const char* colours[4] = {"#000", "#1a9850", "#f46d43", "#2166ac"};
  for (const RunResult& r : runs) {
    if (r.run != 1) {
      continue;
    }
    for (int k = 0; k < 4; ++k) {
      s << "<polyline fill='none' stroke='" << colours[k] << "' stroke-width='1.2' points='";
      for (const TrajectorySample& t : r.history) {
        const Pose2d& q = k == 0 ? t.truth : (k == 1 ? t.withTruth : (k == 2 ? t.withNominal : t.withEstimate));
        s << X(q.x) << ',' << Y(q.y) << ' ';
      }
      s << "'/>\n";
    }
  }
  const double ly = h - 18.0;
  s << "<text x='" << num(kMargin) << "' y='" << num(ly) << "'>"
    << "<tspan fill='#000'>truth</tspan>  <tspan fill='#1a9850'>dead reckoning, true parameters</tspan>  "
    << "<tspan fill='#f46d43'>dead reckoning, nominal parameters</tspan>  "
    << "<tspan fill='#2166ac'>dead reckoning, estimated parameters</tspan>  <tspan fill='#e00000'>reflectors</tspan>  "
    << "<tspan fill='#a0522d'>pallet blocks</tspan>  <tspan fill='#3060a0'>racks</tspan>  (1 px = 5 cm)</text>\n";
  s << "</svg>\n";
  return save(file, s.str());
}

bool writeErrorSvg(const std::string& file, const std::vector<RunResult>& runs, double requirement) {
  const double w = 800.0;
  const double h = 480.0;
  const double left = 80.0;
  const double right = 20.0;
  const double top = 20.0;
  const double bottom = 60.0;
  double maxDist = 1.0;
  for (const RunResult& r : runs) {
    maxDist = std::max(maxDist, r.distance);
  }
  maxDist = std::ceil(maxDist);
  const double logLo = -4.0;  // 0.1 mm
  const double logHi = 1.0;   // 10 m
  auto X = [&](double d) { return num(left + d / maxDist * (w - left - right)); };
  auto Y = [&](double e) {
    const double l = std::clamp(std::log10(std::max(e, 1e-12)), logLo, logHi);
    return num(top + (logHi - l) / (logHi - logLo) * (h - top - bottom));
  };
  std::ostringstream s;
  s << "<svg xmlns='http://www.w3.org/2000/svg' width='" << num(w) << "' height='" << num(h)
    << "' font-family='sans-serif' font-size='12'>\n";
  s << "<rect width='100%' height='100%' fill='white'/>\n";
  for (int e = static_cast<int>(logLo); e <= static_cast<int>(logHi); ++e) {
    const double v = std::pow(10.0, e);
    s << "<line x1='" << num(left) << "' x2='" << num(w - right) << "' y1='" << Y(v) << "' y2='" << Y(v)
      << "' stroke='#ddd'/><text x='" << num(left - 6) << "' y='" << Y(v) << "' dy='4' text-anchor='end'>" << label(v)
      << "</text>\n";
  }
  for (int d = 0; d <= static_cast<int>(maxDist); d += 2) {
    s << "<line y1='" << num(top) << "' y2='" << num(h - bottom) << "' x1='" << X(d) << "' x2='" << X(d)
      << "' stroke='#eee'/><text x='" << X(d) << "' y='" << num(h - bottom + 16) << "' text-anchor='middle'>" << d
      << "</text>\n";
  }
  s << "<text x='" << num(left + (w - left - right) / 2) << "' y='" << num(h - bottom + 34)
    << "' text-anchor='middle'>distance travelled [m]</text>\n";
  s << "<text transform='translate(16," << num(top + (h - top - bottom) / 2)
    << ") rotate(-90)' text-anchor='middle'>position error (log)</text>\n";
  s << "<line x1='" << num(left) << "' x2='" << num(w - right) << "' y1='" << Y(requirement) << "' y2='"
    << Y(requirement) << "' stroke='#d73027' stroke-dasharray='6,4'/>\n";
  s << "<text x='" << num(w - right - 4) << "' y='" << Y(requirement)
    << "' dy='-4' text-anchor='end' fill='#d73027'>requirement " << num(requirement * 100.0) << " cm</text>\n";
  for (const RunResult& r : runs) {
    const char* colours[3] = {"#1a9850", "#f46d43", "#2166ac"};
    for (int k = 0; k < 3; ++k) {
      s << "<polyline fill='none' stroke-opacity='0.6' stroke='" << colours[k] << "' points='";
      double lastD = -1.0;
      for (const TrajectorySample& t : r.history) {
        if (t.distance - lastD < 0.05) {
          continue;
        }
        lastD = t.distance;
        const Pose2d& q = k == 0 ? t.withTruth : (k == 1 ? t.withNominal : t.withEstimate);
        s << X(t.distance) << ',' << Y(positionError(q, t.truth)) << ' ';
      }
      s << "'/>\n";
    }
  }
  s << "<text x='" << num(left + 8) << "' y='" << num(top + 14)
    << "'>dead reckoning with: <tspan fill='#1a9850'>true parameters</tspan>   "
    << "<tspan fill='#f46d43'>nominal parameters</tspan>   <tspan fill='#2166ac'>estimated parameters</tspan></text>\n";
  s << "</svg>\n";
  return save(file, s.str());
}

}  // namespace agv::hil
