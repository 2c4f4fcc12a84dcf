#include "agv/datasets/velodyne_calibration.hpp"

#include <cstdio>

#include <cmath>
#include <cstdint>
#include <vector>

#include "agv/report/number.hpp"
#include "agv/report/text_file.hpp"

namespace agv::datasets {

namespace {
constexpr double kPi = 3.14159265358979323846;

/// One laser as read, in SI units; `seen` marks the fields present.
struct Entry {
  std::int64_t id = -1;
  LaserParams p{};
  unsigned seen = 0;
};
enum Field : unsigned { kId = 1, kRot = 2, kVert = 4, kDist = 8, kVOff = 16, kHOff = 32 };

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '\r' || s.front() == '\n')) {
    s.remove_prefix(1);
  }
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r' || s.back() == '\n')) {
    s.remove_suffix(1);
  }
  return s;
}

bool real(std::string_view text, const std::string& what, double& out, std::string& error) {
  const report::NumberError e = report::parseReal(trim(text), out);
  if (e != report::NumberError::None) {
    error = what + ": " + report::describe(e) + " ('" + std::string(trim(text)) + "')";
    return false;
  }
  return true;
}

/// Entries -> table: ids 0..n-1 each exactly once, every geometric field present (YAML: the
/// offsets may be absent, meaning 0).
bool fill(std::vector<Entry>& entries, double resolution, std::int64_t declared, unsigned required,
          LaserIntrinsics& out, std::string& error) {
  if (entries.empty()) {
    error = "no laser";
    return false;
  }
  if (declared >= 0 && static_cast<std::size_t>(declared) != entries.size()) {
    error =
        "num_lasers is " + std::to_string(declared) + " but " + std::to_string(entries.size()) + " lasers are listed";
    return false;
  }
  LaserIntrinsics table;
  const Status st = table.reset(entries.size());
  if (st != Status::Ok) {
    error = std::to_string(entries.size()) + " lasers: " + toString(st);
    return false;
  }
  if (table.setDistanceResolution(resolution) != Status::Ok) {
    error = "distance resolution " + std::to_string(resolution) + " m is not in (0, 0.1]";
    return false;
  }
  std::vector<bool> have(entries.size(), false);
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const Entry& e = entries[i];
    const std::string name = "laser entry " + std::to_string(i);
    if ((e.seen & required) != required) {
      error = name + ": a required field is missing (laser_id / id_, rot, vert, dist corrections)";
      return false;
    }
    if (e.id < 0 || static_cast<std::size_t>(e.id) >= entries.size()) {
      error = name + ": laser id " + std::to_string(e.id) + " outside 0.." + std::to_string(entries.size() - 1);
      return false;
    }
    const auto id = static_cast<std::size_t>(e.id);
    if (have[id]) {
      error = name + ": laser id " + std::to_string(e.id) + " appears twice";
      return false;
    }
    have[id] = true;
    const Status s = table.set(id, e.p);
    if (s != Status::Ok) {
      error = "laser " + std::to_string(e.id) + ": " + toString(s);
      return false;
    }
  }
  out = table;
  return true;
}

/// The text between <tag> and </tag> inside `scope`, or false.
bool xmlValue(std::string_view scope, std::string_view tag, std::string_view& value) {
  const std::string open = "<" + std::string(tag) + ">";
  const std::string close = "</" + std::string(tag) + ">";
  const std::size_t a = scope.find(open);
  if (a == std::string_view::npos) {
    return false;
  }
  const std::size_t b = scope.find(close, a + open.size());
  if (b == std::string_view::npos) {
    return false;
  }
  value = scope.substr(a + open.size(), b - a - open.size());
  return true;
}

/// One YAML `key: value` of a laser entry or of the top level.
bool yamlField(std::string_view key, std::string_view value, Entry* e, double& resolution, std::int64_t& declared,
               std::string& error) {
  double v = 0.0;
  const std::string what = "'" + std::string(key) + "'";
  if (e == nullptr) {
    if (key == "distance_resolution") {
      return real(value, what, resolution, error);
    }
    if (key == "num_lasers") {
      if (!report::toInteger(trim(value), declared)) {
        error = what + ": not an integer";
        return false;
      }
    }
    return true;  // other top-level keys are not ours
  }
  if (key == "laser_id") {
    if (!report::toInteger(trim(value), e->id)) {
      error = what + ": not an integer ('" + std::string(trim(value)) + "')";
      return false;
    }
    e->seen |= kId;
    return true;
  }
  struct Map {
    const char* name;
    double LaserParams::*field;
    unsigned bit;
  };
  static const Map maps[] = {{"rot_correction", &LaserParams::alpha, kRot},
                             {"vert_correction", &LaserParams::theta, kVert},
                             {"dist_correction", &LaserParams::distCorrection, kDist},
                             {"vert_offset_correction", &LaserParams::vertOffset, kVOff},
                             {"horiz_offset_correction", &LaserParams::horizOffset, kHOff}};
  for (const Map& m : maps) {
    if (key == m.name) {
      if (!real(value, what, v, error)) {
        return false;
      }
      e->p.*m.field = v;
      e->seen |= m.bit;
      return true;
    }
  }
  return true;  // two-point, focal, intensity fields: not part of the thesis model
}
}  // namespace

bool parseVelodyneDbXml(std::string_view text, LaserIntrinsics& out, std::string& error) {
  double lsbCm = 0.2;
  std::string_view v;
  if (xmlValue(text, "distLSB_", v) && !real(v, "distLSB_", lsbCm, error)) {
    return false;
  }
  const std::size_t points = text.find("<points_");
  if (points == std::string_view::npos) {
    error = "no <points_> element: not a Velodyne db.xml";
    return false;
  }
  std::vector<Entry> entries;
  std::size_t pos = points;
  while ((pos = text.find("<px", pos)) != std::string_view::npos) {
    const std::size_t end = text.find("</px>", pos);
    if (end == std::string_view::npos) {
      error = "laser entry " + std::to_string(entries.size()) + ": <px> not closed";
      return false;
    }
    const std::string_view px = text.substr(pos, end - pos);
    Entry e;
    const std::string name = "laser entry " + std::to_string(entries.size());
    if (xmlValue(px, "id_", v)) {
      if (!report::toInteger(trim(v), e.id)) {
        error = name + ": id_ is not an integer";
        return false;
      }
      e.seen |= kId;
    }
    struct Map {
      const char* tag;
      double LaserParams::*field;
      double scale;  // xml unit -> SI
      unsigned bit;
    };
    const Map maps[] = {{"rotCorrection_", &LaserParams::alpha, kPi / 180.0, kRot},
                        {"vertCorrection_", &LaserParams::theta, kPi / 180.0, kVert},
                        {"distCorrection_", &LaserParams::distCorrection, 0.01, kDist},
                        {"vertOffsetCorrection_", &LaserParams::vertOffset, 0.01, kVOff},
                        {"horizOffsetCorrection_", &LaserParams::horizOffset, 0.01, kHOff}};
    for (const Map& m : maps) {
      double x = 0.0;
      if (xmlValue(px, m.tag, v)) {
        if (!real(v, name + " " + m.tag, x, error)) {
          return false;
        }
        e.p.*m.field = x * m.scale;
        e.seen |= m.bit;
      }
    }
    entries.push_back(e);
    pos = end;
  }
  return fill(entries, lsbCm * 0.01, -1, kId | kRot | kVert | kDist | kVOff | kHOff, out, error);
}

bool parseVelodyneYaml(std::string_view text, LaserIntrinsics& out, std::string& error) {
  std::vector<Entry> entries;
  double resolution = 0.002;
  std::int64_t declared = -1;
  bool inLasers = false;
  std::size_t lineNo = 0;
  while (!text.empty()) {
    ++lineNo;
    const std::size_t nl = text.find('\n');
    std::string_view line = text.substr(0, nl);
    text.remove_prefix(nl == std::string_view::npos ? text.size() : nl + 1);
    const std::size_t hash = line.find('#');
    if (hash != std::string_view::npos) {
      line = line.substr(0, hash);
    }
    if (trim(line).empty()) {
      continue;
    }
    const bool topLevel = line.front() != ' ' && line.front() != '\t' && line.front() != '-';
    std::string_view body = trim(line);
    if (topLevel) {
      inLasers = false;
      const std::size_t colon = body.find(':');
      if (colon == std::string_view::npos) {
        error = "line " + std::to_string(lineNo) + ": expected 'key: value'";
        return false;
      }
      const std::string_view key = trim(body.substr(0, colon));
      if (key == "lasers" && trim(body.substr(colon + 1)).empty()) {
        inLasers = true;
        continue;
      }
      if (!yamlField(key, body.substr(colon + 1), nullptr, resolution, declared, error)) {
        error = "line " + std::to_string(lineNo) + ": " + error;
        return false;
      }
      continue;
    }
    if (!inLasers) {
      continue;  // nested content of a key that is not ours
    }
    if (body.front() == '-') {
      entries.emplace_back();
      body = trim(body.substr(1));
    } else if (entries.empty()) {
      error = "line " + std::to_string(lineNo) + ": laser field before the first '-'";
      return false;
    }
    // Block style has one `key: value` per line; flow style `{k: v, k: v,` may span lines.
    std::string_view rest = body;
    while (!rest.empty()) {
      const std::size_t comma = rest.find(',');
      std::string_view item = trim(rest.substr(0, comma));
      rest = comma == std::string_view::npos ? std::string_view{} : rest.substr(comma + 1);
      while (!item.empty() && (item.front() == '{' || item.front() == ' ')) {
        item.remove_prefix(1);
      }
      while (!item.empty() && (item.back() == '}' || item.back() == ' ')) {
        item.remove_suffix(1);
      }
      if (item.empty()) {
        continue;
      }
      const std::size_t colon = item.find(':');
      if (colon == std::string_view::npos) {
        error = "line " + std::to_string(lineNo) + ": expected 'key: value' in a laser entry";
        return false;
      }
      if (!yamlField(trim(item.substr(0, colon)), item.substr(colon + 1), &entries.back(), resolution, declared,
                     error)) {
        error = "line " + std::to_string(lineNo) + ": " + error;
        return false;
      }
    }
  }
  if (entries.empty()) {
    error = "no 'lasers:' list";
    return false;
  }
  return fill(entries, resolution, declared, kId | kRot | kVert | kDist, out, error);
}

bool readVelodyneCalibration(const std::string& path, LaserIntrinsics& out, std::string& error) {
  std::string text;
  if (!report::readTextFile(path, text, error)) {
    return false;
  }
  const bool xml = trim(text).substr(0, 1) == "<";
  const bool ok = xml ? parseVelodyneDbXml(text, out, error) : parseVelodyneYaml(text, out, error);
  if (!ok) {
    error = path + ": " + error;
  }
  return ok;
}

std::string formatVelodyneYaml(const LaserIntrinsics& table, const std::string& comment) {
  std::string out;
  std::size_t from = 0;
  while (!comment.empty() && from <= comment.size()) {
    const std::size_t nl = comment.find('\n', from);
    out += "# " + comment.substr(from, nl == std::string::npos ? std::string::npos : nl - from) + "\n";
    if (nl == std::string::npos) {
      break;
    }
    from = nl + 1;
  }
  char buf[128];
  std::snprintf(buf, sizeof buf, "distance_resolution: %.17g\nnum_lasers: %zu\nlasers:\n", table.distanceResolution(),
                table.size());
  out += buf;
  for (std::size_t l = 0; l < table.size(); ++l) {
    const LaserParams& p = table.params(l);
    std::snprintf(buf, sizeof buf, "- laser_id: %zu\n", l);
    out += buf;
    const std::pair<const char*, double> fields[] = {{"dist_correction", p.distCorrection},
                                                     {"horiz_offset_correction", p.horizOffset},
                                                     {"rot_correction", p.alpha},
                                                     {"vert_correction", p.theta},
                                                     {"vert_offset_correction", p.vertOffset}};
    for (const auto& [name, value] : fields) {
      std::snprintf(buf, sizeof buf, "  %s: %.17g\n", name, value);
      out += buf;
    }
    out += "  two_pt_correction_available: false\n";
  }
  return out;
}

}  // namespace agv::datasets
