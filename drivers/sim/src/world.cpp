#include "agv/sim/world.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>
#include <system_error>

#include "agv/core/angle.hpp"
#include "agv/kinematics/tricycle.hpp"

namespace agv::sim {

namespace {

constexpr double kMinLength = 1e-6;    // [m] shorter walls, boxes and path pieces are degenerate
constexpr double kRackUpright = 0.10;  // [m] side of a rack upright's square section

/// Splits a line at whitespace, dropping a trailing comment.
std::vector<std::string_view> tokenize(std::string_view line) {
  const std::size_t hash = line.find('#');
  if (hash != std::string_view::npos) {
    line = line.substr(0, hash);
  }
  std::vector<std::string_view> tokens;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) {
      ++i;
    }
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r') {
      ++i;
    }
    if (i > start) {
      tokens.push_back(line.substr(start, i - start));
    }
  }
  return tokens;
}

struct LineParser {
  int line = 0;
  WorldParseError* error = nullptr;

  Status fail(Status s, const std::string& msg) const {
    error->line = line;
    error->message = msg;
    return s;
  }

  /// Parses token `t` as a finite decimal number: optional sign, digits with an optional fraction,
  /// optional exponent; no locale, no hexadecimal, the whole token. The grammar of the apps' parser
  /// (agv::report::parseReal), which the drivers cannot link (apps/lib depends on drivers).
  Status number(std::string_view t, const char* field, double* out) const {
    const std::string s(t);
    std::string_view digits = t;
    if (digits.size() > 1 && digits.front() == '+' && digits[1] != '-' && digits[1] != '+') {
      digits.remove_prefix(1);  // from_chars takes '-' only
    }
    double v = 0.0;
    const char* end = digits.data() + digits.size();
    const std::from_chars_result r = std::from_chars(digits.data(), end, v, std::chars_format::general);
    if (r.ec == std::errc::result_out_of_range) {
      return fail(Status::NonFiniteInput, std::string(field) + ": '" + s + "' is not finite");
    }
    if (r.ec != std::errc() || r.ptr != end) {
      return fail(Status::Malformed, std::string(field) + ": '" + s + "' is not a number");
    }
    if (!std::isfinite(v)) {
      return fail(Status::NonFiniteInput, std::string(field) + ": '" + s + "' is not finite");
    }
    *out = v;
    return Status::Ok;
  }

  /// Parses tokens[1..n] as numbers named by `fields`, after checking the count.
  Status numbers(const std::vector<std::string_view>& tok, std::initializer_list<const char*> fields,
                 double* out) const {
    if (tok.size() != fields.size() + 1) {
      std::string names;
      for (const char* f : fields) {
        names += ' ';
        names += f;
      }
      return fail(Status::Malformed, std::string(tok[0]) + " needs " + std::to_string(fields.size()) + " numbers (" +
                                         names.substr(1) + "), got " + std::to_string(tok.size() - 1));
    }
    std::size_t i = 0;
    for (const char* f : fields) {
      const Status s = number(tok[i + 1], f, out + i);
      if (s != Status::Ok) {
        return s;
      }
      ++i;
    }
    return Status::Ok;
  }
};

void addBox(World& w, double x0, double y0, double x1, double y1, ObstacleKind kind) {
  const Point2 p00{x0, y0};
  const Point2 p10{x1, y0};
  const Point2 p11{x1, y1};
  const Point2 p01{x0, y1};
  w.segments.push_back({p00, p10, kind});
  w.segments.push_back({p10, p11, kind});
  w.segments.push_back({p11, p01, kind});
  w.segments.push_back({p01, p00, kind});
}

/// Appends samples of a constant-curvature piece (curvature k [1/m], length len) to `path`.
void samplePiece(Path& path, double k, double len) {
  const Pose2d origin = path.points.back();
  const int n = std::max(1, static_cast<int>(std::ceil(len / kPathSampleStep)));
  for (int i = 1; i <= n; ++i) {
    const double s = len * static_cast<double>(i) / static_cast<double>(n);
    // A constant-curvature arc is a tricycle arc with L = 1 and steering atan(k): use the core's
    // cancellation-free formula (ds*cos(alpha) = s after scaling by 1/cos(alpha)).
    const double alpha = std::atan(k);
    const Pose2d inc = tricycleArc(s / std::cos(alpha), alpha, 1.0);
    path.points.push_back(origin.compose(inc));
  }
}

/// Parses the path pieces tok[i..] (S len | L r deg | R r deg) into `path` (its points start with
/// the start pose). With `mission`, `stop` ends a leg at an operation point: `path` is moved into
/// the mission's legs and restarted at its end; the mission must end with `stop`.
Status parsePieces(const LineParser& p, const std::vector<std::string_view>& tok, std::size_t i, Path& path,
                   Mission* mission) {
  double v[2] = {};
  Status s = Status::Ok;
  const char* what = mission != nullptr ? "mission" : "path";
  bool legOpen = false;  // a piece since the last stop
  while (i < tok.size()) {
    const std::string_view piece = tok[i];
    if (piece == "S") {
      if (i + 1 >= tok.size()) {
        return p.fail(Status::Malformed, std::string(what) + " piece S needs a length");
      }
      s = p.number(tok[i + 1], "S length", v);
      if (s != Status::Ok) {
        return s;
      }
      if (v[0] < kMinLength) {
        return p.fail(Status::InvalidArgument, std::string(what) + " piece S: length must be > 0");
      }
      samplePiece(path, 0.0, v[0]);
      path.length += v[0];
      i += 2;
      legOpen = true;
    } else if (piece == "L" || piece == "R") {
      if (i + 2 >= tok.size()) {
        return p.fail(Status::Malformed,
                      std::string(what) + " piece " + std::string(piece) + " needs radius and angle_deg");
      }
      s = p.number(tok[i + 1], "arc radius", v);
      if (s == Status::Ok) {
        s = p.number(tok[i + 2], "arc angle_deg", v + 1);
      }
      if (s != Status::Ok) {
        return s;
      }
      if (v[0] < kMinLength || v[1] <= 0.0 || v[1] > 360.0) {
        return p.fail(Status::InvalidArgument,
                      std::string(what) + " arc: radius must be > 0 and angle in (0, 360] deg");
      }
      const double len = v[0] * deg2rad(v[1]);
      samplePiece(path, (piece == "L" ? 1.0 : -1.0) / v[0], len);
      path.length += len;
      i += 3;
      legOpen = true;
    } else if (mission != nullptr && piece == "stop") {
      if (!legOpen) {
        return p.fail(Status::InvalidArgument, "mission: stop " + std::to_string(mission->legs.size() + 1) +
                                                   " has no piece before it (a leg must move)");
      }
      const Pose2d end = path.points.back();
      path.name = mission->name + "/" + std::to_string(mission->legs.size() + 1);
      mission->length += path.length;
      mission->legs.push_back(std::move(path));
      path = Path{};
      path.start = end;
      path.points.push_back(end);
      ++i;
      legOpen = false;
    } else {
      return p.fail(Status::Malformed,
                    std::string(what) + ": unknown piece '" + std::string(piece) +
                        (mission != nullptr ? "' (expected S, L, R or stop)" : "' (expected S, L or R)"));
    }
  }
  if (mission != nullptr && (legOpen || mission->legs.empty())) {
    return p.fail(Status::InvalidArgument,
                  "mission: must end with stop (its last operation point); pieces after the last stop go nowhere");
  }
  return Status::Ok;
}

}  // namespace

const Mission* World::findMission(std::string_view name) const noexcept {
  for (const Mission& m : missions) {
    if (m.name == name) {
      return &m;
    }
  }
  return nullptr;
}

const Path* World::findPath(std::string_view name) const noexcept {
  for (const Path& p : paths) {
    if (p.name == name) {
      return &p;
    }
  }
  return nullptr;
}

void World::bounds(Point2* lo, Point2* hi) const noexcept {
  bool any = false;
  Point2 a{};
  Point2 b{};
  auto grow = [&](double x, double y) {
    if (!any) {
      a = {x, y};
      b = {x, y};
      any = true;
      return;
    }
    a.x = std::min(a.x, x);
    a.y = std::min(a.y, y);
    b.x = std::max(b.x, x);
    b.y = std::max(b.y, y);
  };
  for (const Segment& s : segments) {
    grow(s.a.x, s.a.y);
    grow(s.b.x, s.b.y);
  }
  for (const Circle& c : circles) {
    grow(c.centre.x - c.radius, c.centre.y - c.radius);
    grow(c.centre.x + c.radius, c.centre.y + c.radius);
  }
  *lo = a;
  *hi = b;
}

std::size_t World::reflectorCount() const noexcept {
  return static_cast<std::size_t>(
      std::count_if(circles.begin(), circles.end(), [](const Circle& c) { return c.kind == ObstacleKind::Reflector; }));
}

Status parseWorld(std::string_view text, World& out, WorldParseError& error) {
  World w;
  error = WorldParseError{};
  LineParser p;
  p.error = &error;
  std::size_t pos = 0;
  while (pos <= text.size()) {
    std::size_t eol = text.find('\n', pos);
    if (eol == std::string_view::npos) {
      eol = text.size();
    }
    const std::string_view line = text.substr(pos, eol - pos);
    pos = eol + 1;
    ++p.line;
    const std::vector<std::string_view> tok = tokenize(line);
    if (tok.empty()) {
      continue;
    }
    const std::string_view key = tok[0];
    double v[8] = {};
    Status s = Status::Ok;
    if (key == "wall") {
      s = p.numbers(tok, {"x0", "y0", "x1", "y1"}, v);
      if (s != Status::Ok) {
        return s;
      }
      if (std::hypot(v[2] - v[0], v[3] - v[1]) < kMinLength) {
        return p.fail(Status::InvalidArgument, "wall: both ends are the same point");
      }
      w.segments.push_back({{v[0], v[1]}, {v[2], v[3]}, ObstacleKind::Wall});
    } else if (key == "hall" || key == "pallet") {
      s = p.numbers(tok, {"xmin", "ymin", "xmax", "ymax"}, v);
      if (s != Status::Ok) {
        return s;
      }
      if (v[2] - v[0] < kMinLength || v[3] - v[1] < kMinLength) {
        return p.fail(Status::InvalidArgument, std::string(key) + ": needs xmax > xmin and ymax > ymin");
      }
      if (key == "pallet") {
        w.pallets.push_back(PalletBox{v[0], v[1], v[2], v[3], w.segments.size()});
      }
      addBox(w, v[0], v[1], v[2], v[3], key == "hall" ? ObstacleKind::Wall : ObstacleKind::Pallet);
    } else if (key == "rack") {
      s = p.numbers(tok, {"x0", "y0", "x1", "y1", "depth", "pitch"}, v);
      if (s != Status::Ok) {
        return s;
      }
      const double dx = v[2] - v[0];
      const double dy = v[3] - v[1];
      const double len = std::hypot(dx, dy);
      if (len < kMinLength) {
        return p.fail(Status::InvalidArgument, "rack: both ends are the same point");
      }
      if (v[4] <= kRackUpright || v[5] <= kRackUpright) {
        return p.fail(Status::InvalidArgument, "rack: depth and pitch must exceed the 0.1 m upright");
      }
      const int bays = static_cast<int>(std::floor(len / v[5] + 1e-9));
      if (bays > 10000) {
        return p.fail(Status::InvalidArgument, "rack: more than 10000 bays");
      }
      const double ux = dx / len;
      const double uy = dy / len;
      const double h = 0.5 * kRackUpright;
      for (int i = 0; i <= bays; ++i) {
        const double t = std::min(len, static_cast<double>(i) * v[5]);
        for (int side = 0; side < 2; ++side) {
          const double cx = v[0] + ux * t - uy * v[4] * side;
          const double cy = v[1] + uy * t + ux * v[4] * side;
          addBox(w, cx - h, cy - h, cx + h, cy + h, ObstacleKind::Rack);
        }
      }
    } else if (key == "pillar" || key == "reflector") {
      s = p.numbers(tok, {"x", "y", "radius"}, v);
      if (s != Status::Ok) {
        return s;
      }
      if (v[2] <= 0.0) {
        return p.fail(Status::InvalidArgument, std::string(key) + ": radius must be > 0");
      }
      w.circles.push_back({{v[0], v[1]}, v[2], key == "pillar" ? ObstacleKind::Pillar : ObstacleKind::Reflector});
    } else if (key == "path") {
      if (tok.size() < 7) {
        return p.fail(Status::Malformed,
                      "path needs NAME x y heading_deg and at least one piece (S len | L r deg | R r deg)");
      }
      Path path;
      path.name = std::string(tok[1]);
      if (w.findPath(path.name) != nullptr || w.findMission(path.name) != nullptr) {
        return p.fail(Status::InvalidArgument, "path: duplicate name '" + path.name + "'");
      }
      for (int i = 0; i < 3; ++i) {
        static const char* const kFields[3] = {"x", "y", "heading_deg"};
        s = p.number(tok[static_cast<std::size_t>(i) + 2], kFields[i], v + i);
        if (s != Status::Ok) {
          return s;
        }
      }
      path.start = Pose2d{v[0], v[1], normalizeAngle(deg2rad(v[2]))};
      path.points.push_back(path.start);
      s = parsePieces(p, tok, 5, path, nullptr);
      if (s != Status::Ok) {
        return s;
      }
      w.paths.push_back(std::move(path));
    } else if (key == "mission") {
      if (tok.size() < 8) {
        return p.fail(Status::Malformed,
                      "mission needs NAME x y heading_deg and pieces with at least one stop (S len | L r deg | R r deg "
                      "| stop)");
      }
      Mission mission;
      mission.name = std::string(tok[1]);
      if (w.findMission(mission.name) != nullptr || w.findPath(mission.name) != nullptr) {
        return p.fail(Status::InvalidArgument, "mission: duplicate name '" + mission.name + "' (paths and missions)");
      }
      for (int i = 0; i < 3; ++i) {
        static const char* const kFields[3] = {"x", "y", "heading_deg"};
        s = p.number(tok[static_cast<std::size_t>(i) + 2], kFields[i], v + i);
        if (s != Status::Ok) {
          return s;
        }
      }
      mission.start = Pose2d{v[0], v[1], normalizeAngle(deg2rad(v[2]))};
      Path leg;
      leg.start = mission.start;
      leg.points.push_back(leg.start);
      s = parsePieces(p, tok, 5, leg, &mission);
      if (s != Status::Ok) {
        return s;
      }
      w.missions.push_back(std::move(mission));
    } else {
      return p.fail(Status::Malformed, "unknown keyword '" + std::string(key) +
                                           "' (expected wall, hall, pallet, rack, pillar, reflector, path or mission)");
    }
  }
  if (w.segments.empty() && w.circles.empty()) {
    error.line = 0;
    error.message = "the world has no obstacle";
    return Status::EmptyInput;
  }
  out = std::move(w);
  return Status::Ok;
}

Status loadWorldFile(const std::string& path, World& out, WorldParseError& error) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    error.line = 0;
    error.message = "cannot read '" + path + "'";
    return Status::NotFound;
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  return parseWorld(ss.str(), out, error);
}

std::string_view defaultWorldText() noexcept {
  static constexpr const char kText[] = R"WORLD(
# agvnav default warehouse: 40 m x 25 m hall, block storage with four lanes (y = 6, 10, 14, 18)
# Units: metres and degrees. Format: docs/world-format.md
hall 0 0 40 25
# pallet rack rows (uprights only are at laser height)
rack 2 23.4 20 23.4 1.0 2.7
rack 1.0 20 1.0 3 1.0 2.7
# building pillars
pillar 12 8 0.25
pillar 12 17 0.25
pillar 28 23.5 0.25
# block storage: rows of pallet blocks between the lanes
pallet 24.99 3.26 27.41 4.65
pallet 27.60 3.28 29.98 4.70
pallet 30.17 3.29 32.58 4.65
pallet 32.80 3.34 35.18 4.67
pallet 35.41 3.35 37.81 4.69
pallet 25.03 7.25 27.42 8.67
pallet 27.58 7.25 29.99 8.74
pallet 30.18 7.31 32.61 8.68
pallet 32.81 7.25 35.18 8.66
pallet 35.41 7.29 37.79 8.71
pallet 25.00 11.28 27.42 12.72
pallet 27.59 11.31 30.00 12.75
pallet 30.22 11.27 32.63 12.65
pallet 32.80 11.33 35.18 12.70
pallet 35.37 11.32 37.82 12.71
pallet 25.02 15.28 27.41 16.71
pallet 27.61 15.29 30.02 16.75
pallet 30.20 15.32 32.58 16.72
pallet 32.81 15.36 35.22 16.67
pallet 35.40 15.32 37.77 16.70
pallet 24.98 19.25 27.38 20.73
pallet 27.58 19.27 30.00 20.74
pallet 30.18 19.29 32.61 20.75
pallet 32.82 19.34 35.19 20.69
pallet 35.39 19.35 37.83 20.66
# reflector poles (radius 4 cm)
reflector 2.3 8 0.04
reflector 2.3 16 0.04
reflector 6 0.4 0.04
reflector 14 0.4 0.04
reflector 22 0.4 0.04
reflector 22 24.6 0.04
reflector 34 24.6 0.04
reflector 39.6 6 0.04
reflector 39.6 10 0.04
reflector 39.6 14 0.04
reflector 39.6 18 0.04
reflector 24.6 4.9 0.04
reflector 24.6 8.9 0.04
reflector 24.6 12.9 0.04
reflector 24.6 16.9 0.04
reflector 24.6 19.1 0.04
reflector 16 4 0.04
reflector 16 21 0.04
# reference paths of the logical point (all end 5 m inside a lane)
path P1 18 10 0 S 12
path P2 18.490371 12 0 L 4 41.409622 R 4 41.409622 S 6.218126
path P3 20.712389 2 90 S 1 R 3 90 S 6.287611
path P4 23 18 0 S 7
# missions: operation points (stop) in lanes and at rack faces, through the far aisle (x = 38.6)
mission M1 14 10 0 S 16 stop S 7.4 L 1.2 90 S 1.6 L 1.2 90 S 5.4 stop S 10 R 3 90 S 2.7 L 2.5 90 S 4.5 stop
mission M2 20 5.5 180 S 13.5 R 3 90 S 3.5 stop S 5 stop S 2.2 R 3 90 S 3.5 stop S 10 R 2.1 90 L 2.1 90 S 5.8 stop
mission M3 14 2 0 S 6.6 L 2 90 R 2 90 S 5.4 stop S 7.4 L 1.2 90 S 9.6 L 1.2 90 S 4.4 stop S 9 R 3 41.409622 L 3 41.409622 S 13.031373 L 3.5 90 S 4 stop S 3.5 L 3 90 S 6.5 stop
)WORLD";
  return std::string_view(kText + 1, sizeof(kText) - 2);  // without the leading newline and the NUL
}

}  // namespace agv::sim
