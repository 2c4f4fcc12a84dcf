#include "svg_plots.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "agv/report/svg.hpp"

namespace agv::hil {

namespace {

using report::SvgDocument;
using report::SvgPoints;

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

/// A legend line: `before` then each (colour, text) as a coloured tspan, separated by `gap`.
void legend(SvgDocument& svg, double x, double y, const char* before,
            std::initializer_list<std::pair<const char*, const char*>> entries, const char* gap, const char* after) {
  svg.open("text", {{"x", x}, {"y", y}});
  svg.text(before);
  bool first = true;
  for (const auto& [colour, text] : entries) {
    if (!first) {
      svg.text(gap);
    }
    svg.addText("tspan", {{"fill", colour}}, text);
    first = false;
  }
  svg.text(after);
  svg.close();
}

}  // namespace

bool writeMapSvg(const std::string& file, const sim::World& world, const std::vector<RunResult>& runs,
                 std::string& error) {
  sim::Point2 lo;
  sim::Point2 hi;
  world.bounds(&lo, &hi);
  const double w = (hi.x - lo.x) * kScale + 2 * kMargin;
  const double h = (hi.y - lo.y) * kScale + 2 * kMargin + 40.0;
  auto X = [&](double x) { return kMargin + (x - lo.x) * kScale; };
  auto Y = [&](double y) { return kMargin + (hi.y - y) * kScale; };
  SvgDocument svg(w, h, {{"font-family", "sans-serif"}, {"font-size", "12"}});
  for (const sim::Segment& g : world.segments) {
    svg.add("line", {{"x1", X(g.a.x)},
                     {"y1", Y(g.a.y)},
                     {"x2", X(g.b.x)},
                     {"y2", Y(g.b.y)},
                     {"stroke", colourOf(g.kind)},
                     {"stroke-width", "1.5"}});
  }
  for (const sim::Circle& c : world.circles) {
    const double r = std::max(c.radius * kScale, c.kind == sim::ObstacleKind::Reflector ? 3.0 : 1.0);
    svg.add("circle", {{"cx", X(c.centre.x)}, {"cy", Y(c.centre.y)}, {"r", r}, {"fill", colourOf(c.kind)}});
  }
  for (const sim::Path& p : world.paths) {
    SvgPoints pts;
    for (const Pose2d& q : p.points) {
      pts.add(X(q.x), Y(q.y));
    }
    svg.add("polyline", {{"fill", "none"},
                         {"stroke", "#bbb"},
                         {"stroke-width", "6"},
                         {"stroke-linecap", "round"},
                         {"points", pts.str()}});
    svg.addText("text", {{"x", X(p.start.x)}, {"y", Y(p.start.y)}, {"dx", "-18"}, {"dy", "4"}}, p.name);
  }
  // First run of each path (reflector mode): truth, dead reckoning, localizer.
  const char* colours[5] = {"#000", "#1a9850", "#f46d43", "#2166ac", "#762a83"};
  for (const RunResult& r : runs) {
    if (r.run != 1 || r.mode != LocalizationMode::Reflectors) {
      continue;
    }
    for (int k = 0; k < 5; ++k) {
      SvgPoints pts;
      for (const TrajectorySample& t : r.history) {
        const Pose2d& q = k == 0   ? t.truth
                          : k == 1 ? t.withTruth
                          : k == 2 ? t.withNominal
                          : k == 3 ? t.withEstimate
                                   : t.localized;
        pts.add(X(q.x), Y(q.y));
      }
      svg.add("polyline", {{"fill", "none"}, {"stroke", colours[k]}, {"stroke-width", "1.2"}, {"points", pts.str()}});
    }
  }
  legend(svg, kMargin, h - 18.0, "",
         {{"#000", "truth"},
          {"#1a9850", "dead reckoning, true parameters"},
          {"#f46d43", "dead reckoning, nominal parameters"},
          {"#2166ac", "dead reckoning, estimated parameters"},
          {"#762a83", "localizer (reflectors)"},
          {"#e00000", "reflectors"},
          {"#a0522d", "pallet blocks"},
          {"#3060a0", "racks"}},
         "  ", "  (1 px = 5 cm)");
  return svg.save(file, error);
}

bool writeErrorSvg(const std::string& file, const std::vector<RunResult>& runs, double requirement,
                   std::string& error) {
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
  auto X = [&](double d) { return left + d / maxDist * (w - left - right); };
  auto Y = [&](double e) {
    const double l = std::clamp(std::log10(std::max(e, 1e-12)), logLo, logHi);
    return top + (logHi - l) / (logHi - logLo) * (h - top - bottom);
  };
  SvgDocument svg(w, h, {{"font-family", "sans-serif"}, {"font-size", "12"}});
  for (int e = static_cast<int>(logLo); e <= static_cast<int>(logHi); ++e) {
    const double v = std::pow(10.0, e);
    svg.add("line", {{"x1", left}, {"x2", w - right}, {"y1", Y(v)}, {"y2", Y(v)}, {"stroke", "#ddd"}});
    svg.addText("text", {{"x", left - 6}, {"y", Y(v)}, {"dy", "4"}, {"text-anchor", "end"}}, label(v));
  }
  for (int d = 0; d <= static_cast<int>(maxDist); d += 2) {
    svg.add("line", {{"y1", top}, {"y2", h - bottom}, {"x1", X(d)}, {"x2", X(d)}, {"stroke", "#eee"}});
    svg.addText("text", {{"x", X(d)}, {"y", h - bottom + 16}, {"text-anchor", "middle"}}, std::to_string(d));
  }
  svg.addText("text", {{"x", left + (w - left - right) / 2}, {"y", h - bottom + 34}, {"text-anchor", "middle"}},
              "distance travelled [m]");
  svg.addText("text",
              {{"transform", "translate(16," + report::svgNumber(top + (h - top - bottom) / 2) + ") rotate(-90)"},
               {"text-anchor", "middle"}},
              "position error (log)");
  svg.add("line", {{"x1", left},
                   {"x2", w - right},
                   {"y1", Y(requirement)},
                   {"y2", Y(requirement)},
                   {"stroke", "#d73027"},
                   {"stroke-dasharray", "6,4"}});
  svg.addText("text",
              {{"x", w - right - 4}, {"y", Y(requirement)}, {"dy", "-4"}, {"text-anchor", "end"}, {"fill", "#d73027"}},
              "requirement " + report::svgNumber(requirement * 100.0) + " cm");
  for (const RunResult& r : runs) {
    // Dead reckoning (once: every mode repeats the vehicle runs), then the localizer by mode.
    const char* colours[4] = {"#1a9850", "#f46d43", "#2166ac", "#762a83"};
    if (r.mode == LocalizationMode::StaticFalko) {
      colours[3] = "#e08214";
    } else if (r.mode == LocalizationMode::Dynamic) {
      colours[3] = "#35978f";
    }
    for (int k = r.mode == LocalizationMode::Reflectors ? 0 : 3; k < 4; ++k) {
      SvgPoints pts;
      double lastD = -1.0;
      for (const TrajectorySample& t : r.history) {
        if (t.distance - lastD < 0.05) {
          continue;
        }
        lastD = t.distance;
        const Pose2d& q = k == 0 ? t.withTruth : (k == 1 ? t.withNominal : (k == 2 ? t.withEstimate : t.localized));
        pts.add(X(t.distance), Y(positionError(q, t.truth)));
      }
      svg.add("polyline", {{"fill", "none"}, {"stroke-opacity", "0.6"}, {"stroke", colours[k]}, {"points", pts.str()}});
    }
  }
  svg.open("text", {{"x", left + 8}, {"y", top + 14}});
  svg.text("dead reckoning with: ");
  svg.addText("tspan", {{"fill", "#1a9850"}}, "true parameters");
  svg.text("   ");
  svg.addText("tspan", {{"fill", "#f46d43"}}, "nominal parameters");
  svg.text("   ");
  svg.addText("tspan", {{"fill", "#2166ac"}}, "estimated parameters");
  svg.text("; localizer: ");
  svg.addText("tspan", {{"fill", "#762a83"}}, "reflectors");
  svg.text(" ");
  svg.addText("tspan", {{"fill", "#e08214"}}, "static FALKO");
  svg.text(" ");
  svg.addText("tspan", {{"fill", "#35978f"}}, "dynamic");
  svg.close();
  return svg.save(file, error);
}

}  // namespace agv::hil
