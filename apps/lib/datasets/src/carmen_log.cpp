#include "agv/datasets/carmen_log.hpp"

#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string_view>

#include "agv/report/number.hpp"

namespace agv {
namespace datasets {

namespace {

/// `x` with one decimal ("%.1f").
std::string oneDecimal(double x) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.1f", x);
  return buf;
}

/// Whitespace tokenizer over one line, with numeric conversions that report failure.
class Tokens {
 public:
  explicit Tokens(std::string_view line) : line_(line) {}

  bool next(std::string_view& tok) {
    while (pos_ < line_.size() && (line_[pos_] == ' ' || line_[pos_] == '\t' || line_[pos_] == '\r')) {
      ++pos_;
    }
    if (pos_ >= line_.size()) {
      return false;
    }
    const std::size_t start = pos_;
    while (pos_ < line_.size() && line_[pos_] != ' ' && line_[pos_] != '\t' && line_[pos_] != '\r') {
      ++pos_;
    }
    tok = line_.substr(start, pos_ - start);
    return true;
  }
  /// The next token as a decimal number (report::parseReal: locale-free, whole token); infinity
  /// and NaN only where `nonFinite` allows them (range readings: "inf" is a reading without echo).
  bool number(double& v, report::NonFinite nonFinite = report::NonFinite::Refuse) {
    std::string_view tok;
    return next(tok) && report::toReal(tok, v, nonFinite);
  }
  bool integer(long& v) {
    double d = 0.0;
    if (!number(d) || d != std::floor(d) || std::fabs(d) > 1e15) {
      return false;
    }
    v = static_cast<long>(d);
    return true;
  }
  bool pose(Pose2d& p) {
    double x = 0.0;
    double y = 0.0;
    double t = 0.0;
    if (!number(x) || !number(y) || !number(t)) {
      return false;
    }
    p = Pose2d{x, y, t};
    return true;
  }
  bool skip(std::size_t n) {
    std::string_view tok;
    for (std::size_t i = 0; i < n; ++i) {
      if (!next(tok)) {
        return false;
      }
    }
    return true;
  }

 private:
  std::string_view line_;
  std::size_t pos_ = 0;
};

constexpr long kMaxReadings = 100000;

bool readRanges(Tokens& tk, long count, std::vector<float>& out) {
  if (count < 0 || count > kMaxReadings) {
    return false;
  }
  out.resize(static_cast<std::size_t>(count));
  for (long i = 0; i < count; ++i) {
    double r = 0.0;
    if (!tk.number(r, report::NonFinite::Allow)) {
      return false;
    }
    out[static_cast<std::size_t>(i)] = static_cast<float>(r);
  }
  return true;
}

class Parser {
 public:
  explicit Parser(const CarmenReadOptions& o) : opt_(o) {}

  void line(std::string_view text) {
    ++log.lines;
    const std::size_t no = log.lines;
    Tokens tk(text);
    std::string_view kind;
    if (!tk.next(kind) || kind.front() == '#') {
      ++log.ignoredLines;
      return;
    }
    if (kind == "ROBOTLASER1") {
      robotLaser(tk, no);
    } else if (kind == "FLASER") {
      flaser(tk, no);
    } else if (kind == "ODOM") {
      odom(tk, no);
    } else if (kind == "VERTEX2") {
      vertex(tk, no);
    } else if (kind == "PARAM") {
      param(tk, no);
    } else {
      ++log.ignoredLines;
    }
  }

  CarmenLog log;

 private:
  void issue(std::size_t no, const char* what) { log.issues.push_back(LogIssue{no, what}); }

  /// PARAM name value ...: only the front laser's offset is used (the rest are counted as ignored).
  void param(Tokens& tk, std::size_t no) {
    std::string_view name;
    if (!tk.next(name) || name != "robot_frontlaser_offset") {
      ++log.ignoredLines;
      return;
    }
    double v = 0.0;
    if (!tk.number(v) || std::fabs(v) > 10.0) {
      issue(no, "PARAM robot_frontlaser_offset: not a number of at most 10 m");
      return;
    }
    log.frontLaserOffset = v;
    log.frontLaserOffsetLine = no;
  }

  void robotLaser(Tokens& tk, std::size_t no) {
    LogScan s;
    s.line = no;
    long type = 0;
    double start = 0.0;
    double fov = 0.0;
    double res = 0.0;
    double maxRange = 0.0;
    double accuracy = 0.0;
    long remissionMode = 0;
    long n = 0;
    if (!tk.integer(type) || !tk.number(start) || !tk.number(fov) || !tk.number(res) || !tk.number(maxRange) ||
        !tk.number(accuracy) || !tk.integer(remissionMode) || !tk.integer(n)) {
      issue(no, "ROBOTLASER1: bad header fields");
      return;
    }
    if (!(res > 0.0) || !std::isfinite(start)) {
      issue(no, "ROBOTLASER1: non-positive angular resolution");
      return;
    }
    if (!readRanges(tk, n, s.ranges)) {
      issue(no, "ROBOTLASER1: missing or bad range readings");
      return;
    }
    long nRem = 0;
    if (!tk.integer(nRem) || nRem < 0 || nRem > kMaxReadings || !tk.skip(static_cast<std::size_t>(nRem))) {
      issue(no, "ROBOTLASER1: bad remission block");
      return;
    }
    double tv = 0.0;
    double rv = 0.0;
    double tmp = 0.0;
    double ipcTime = 0.0;
    std::string_view host;
    if (!tk.pose(s.laserPose) || !tk.pose(s.robotPose) || !tk.number(tv) || !tk.number(rv) || !tk.number(tmp) ||
        !tk.number(tmp) || !tk.number(tmp) || !tk.number(ipcTime) || !tk.next(host) || !tk.number(s.timestamp)) {
      issue(no, "ROBOTLASER1: bad pose or timestamp fields");
      return;
    }
    s.angleMin = static_cast<float>(start);
    s.angleIncrement = static_cast<float>(res);
    const auto mr = static_cast<float>(maxRange);
    s.maxRange = (mr > 0.0F && mr < opt_.maxValidRange) ? mr : opt_.maxValidRange;
    if (pendingVertex_) {
      // Ground truth of the robot composed with the laser offset written in this line.
      s.groundTruth = pendingVertexPose_.compose(between(s.robotPose, s.laserPose));
      s.hasGroundTruth = true;
      s.vertexId = pendingVertexId_;
      pendingVertex_ = false;
    }
    log.scans.push_back(std::move(s));
  }

  void flaser(Tokens& tk, std::size_t no) {
    LogScan s;
    s.line = no;
    long n = 0;
    if (!tk.integer(n) || !readRanges(tk, n, s.ranges)) {
      issue(no, "FLASER: missing or bad range readings");
      return;
    }
    double ipcTime = 0.0;
    std::string_view host;
    if (!tk.pose(s.laserPose) || !tk.pose(s.robotPose) || !tk.number(ipcTime) || !tk.next(host) ||
        !tk.number(s.timestamp)) {
      issue(no, "FLASER: bad pose or timestamp fields");
      return;
    }
    if (n == 0) {
      issue(no, "FLASER: no readings");
      return;
    }
    // FLASER carries no geometry: 180 deg from -90 deg; an odd count includes both ends.
    const double pi = 3.14159265358979323846;
    const auto count = static_cast<double>(n);
    s.angleMin = static_cast<float>(-0.5 * pi);
    s.angleIncrement = static_cast<float>((n % 2 == 1 && n > 1) ? pi / (count - 1.0) : pi / count);
    s.maxRange = opt_.maxValidRange;
    // In the corrected logs the pose of the line is the corrected (SLAM) pose.
    s.groundTruth = s.laserPose;
    s.hasGroundTruth = true;
    log.scans.push_back(std::move(s));
  }

  void odom(Tokens& tk, std::size_t no) {
    LogOdometry o;
    o.line = no;
    double accel = 0.0;
    double ipcTime = 0.0;
    std::string_view host;
    if (!tk.pose(o.pose) || !tk.number(o.tv) || !tk.number(o.rv) || !tk.number(accel) || !tk.number(ipcTime) ||
        !tk.next(host) || !tk.number(o.timestamp)) {
      issue(no, "ODOM: bad fields");
      return;
    }
    log.odometry.push_back(o);
  }

  void vertex(Tokens& tk, std::size_t no) {
    LogVertex v;
    v.line = no;
    if (!tk.integer(v.id) || !tk.pose(v.pose)) {
      issue(no, "VERTEX2: bad fields");
      return;
    }
    log.vertices.push_back(v);
    pendingVertex_ = true;
    pendingVertexPose_ = v.pose;
    pendingVertexId_ = v.id;
  }

  CarmenReadOptions opt_;
  bool pendingVertex_ = false;
  Pose2d pendingVertexPose_;
  long pendingVertexId_ = -1;
};

}  // namespace

bool LogScan::toLaserScan(LaserScan& scan) const {
  scan.angleMin = angleMin;
  scan.angleIncrement = angleIncrement;
  scan.rangeMin = 0.0F;
  scan.rangeMax = maxRange;
  scan.stamp = Timestamp::fromSeconds(timestamp);
  scan.ranges.clear();
  bool all = true;
  for (const float r : ranges) {
    if (!isOk(scan.ranges.push_back(r))) {
      all = false;
    }
  }
  return all;
}

CarmenLog parseCarmenLog(const std::string& text, const CarmenReadOptions& options) {
  Parser p(options);
  std::size_t start = 0;
  while (start < text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string::npos) {
      end = text.size();
    }
    p.line(std::string_view(text).substr(start, end - start));
    start = end + 1;
  }
  return std::move(p.log);
}

bool readCarmenLog(const std::string& path, CarmenLog& log, std::string& error, const CarmenReadOptions& options) {
  gzFile f = gzopen(path.c_str(), "rb");
  if (f == nullptr) {
    error = "cannot open " + path;
    return false;
  }
  gzbuffer(f, 1U << 17U);
  Parser p(options);
  std::string line;
  char chunk[8192];
  bool ok = true;
  for (;;) {
    if (gzgets(f, chunk, static_cast<int>(sizeof(chunk))) == nullptr) {
      int err = Z_OK;
      const char* msg = gzerror(f, &err);
      if (err != Z_OK && err != Z_STREAM_END) {
        error = std::string("read error in ") + path + ": " + msg;
        ok = false;
      }
      break;
    }
    const std::size_t len = std::strlen(chunk);
    if (len > 0 && chunk[len - 1] == '\n') {
      line.append(chunk, len - 1);
      p.line(line);
      line.clear();
    } else {
      line.append(chunk, len);
    }
  }
  if (ok && !line.empty()) {
    p.line(line);
  }
  gzclose(f);
  log = std::move(p.log);
  return ok;
}

bool checkCorrectedLog(const CarmenLog& log, std::string& error) {
  if (!log.vertices.empty() || (!log.scans.empty() && log.scans.front().vertexId >= 0)) {
    const std::size_t line = log.vertices.empty() ? log.scans.front().line : log.vertices.front().line;
    error = "line " + std::to_string(line) +
            ": a FLIRTLib log (ROBOTLASER1 + VERTEX2), not a gmapping-corrected CARMEN log (FLASER + ODOM)";
    return false;
  }
  if (log.odometry.empty()) {
    error = "no ODOM line: not a gmapping-corrected CARMEN log (FLASER + ODOM)";
    return false;
  }
  // The first step beyond physics (over 10 m and over 20 m/s) in a sequence of timestamped poses.
  const auto firstJump = [&error](const auto& records, const auto& poseOf, const char* what) {
    for (std::size_t i = 1; i < records.size(); ++i) {
      const Pose2d& a = poseOf(records[i - 1]);
      const Pose2d& b = poseOf(records[i]);
      const double step = std::hypot(b.x - a.x, b.y - a.y);
      const double dt = std::max(0.0, records[i].timestamp - records[i - 1].timestamp);
      if (step > kMaxPlausibleStep && step > kMaxPlausibleSpeed * dt) {
        error = "line " + std::to_string(records[i].line) + ": " + what + " jumps " + oneDecimal(step) + " m" +
                " from line " + std::to_string(records[i - 1].line) + " (beyond physics)";
        return true;
      }
    }
    return false;
  };
  if (firstJump(
          log.scans, [](const LogScan& s) -> const Pose2d& { return s.robotPose; }, "the corrected pose") ||
      firstJump(
          log.odometry, [](const LogOdometry& o) -> const Pose2d& { return o.pose; }, "the odometry")) {
    return false;
  }
  return true;
}

std::size_t odometryIncrements(const CarmenLog& log, std::size_t scans, std::vector<Pose2d>& increments) {
  increments.assign(scans, Pose2d{});
  std::size_t zero = 0;
  std::size_t k = 0;  // next ODOM line
  for (std::size_t i = 0; i < scans; ++i) {
    const std::size_t line = log.scans[i].line;
    const LogOdometry* last = nullptr;
    for (; k < log.odometry.size() && log.odometry[k].line < line; ++k) {
      // Timestamp 0: the repeated corrected pose written after each FLASER line (not odometry).
      if (log.odometry[k].timestamp != 0.0) {
        last = &log.odometry[k];
      }
    }
    if (i == 0) {
      continue;
    }
    if (last == nullptr) {
      ++zero;
      continue;
    }
    increments[i] = between(log.scans[i - 1].robotPose, last->pose);
  }
  return zero;
}

}  // namespace datasets
}  // namespace agv
