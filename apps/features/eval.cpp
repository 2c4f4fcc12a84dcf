#include "eval.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <istream>
#include <ostream>
#include <random>
#include <sstream>

#include "agv/report/number.hpp"

namespace agv {
namespace features {

namespace {

constexpr double kPi = 3.14159265358979323846;

struct ScanData {
  std::unique_ptr<LaserScan> scan;
  Pose2d pose;  // ground-truth laser pose
  std::vector<FalkoKeypoint> keypoints;
  std::vector<BscDescriptor> bsc;
  std::vector<CghDescriptor> cgh;
};

struct Engine {
  explicit Engine(const EvalOptions& o) : detector(o.falko), describer(o.descriptors) {}
  FalkoDetector detector;
  FalkoDescriber describer;
  FalkoKeypoints kps;
  BscDescriptors bsc;
  CghDescriptors cgh;

  void detect(const LaserScan& scan, std::vector<FalkoKeypoint>& out) {
    (void)detector.detect(scan, kps);
    out.assign(kps.begin(), kps.end());
  }
  void detectDescribe(ScanData& d) {
    (void)detector.detect(*d.scan, kps);
    (void)describer.describe(detector.points(), kps, bsc, cgh);
    d.keypoints.assign(kps.begin(), kps.end());
    d.bsc.assign(bsc.begin(), bsc.end());
    d.cgh.assign(cgh.begin(), cgh.end());
  }
};

/// True when scan `s` sees the point q (its own frame): q lies in its field of view and the reading
/// of the beam towards q is valid and within `tol` of |q| (not occluded, not beyond the range).
bool sees(const LaserScan& s, double qx, double qy, double tol) {
  const double n = static_cast<double>(s.size());
  if (s.size() == 0) {
    return false;
  }
  double rel = std::atan2(qy, qx) - static_cast<double>(s.angleMin);
  const double inc = static_cast<double>(s.angleIncrement);
  const double fov = n * inc;
  rel = std::fmod(rel, 2.0 * kPi);
  if (rel < 0.0) {
    rel += 2.0 * kPi;
  }
  const double idx = std::floor(rel / inc + 0.5);
  std::size_t i = 0;
  if (idx < n) {
    i = static_cast<std::size_t>(idx);
  } else if (fov >= 2.0 * kPi - inc && idx < n + 1.0) {
    i = 0;  // wraps onto the first beam
  } else {
    return false;
  }
  if (!s.isValid(i)) {
    return false;
  }
  return std::fabs(static_cast<double>(s.ranges[i]) - std::hypot(qx, qy)) <= tol;
}

struct Counts {
  std::size_t visible = 0;
  std::size_t matched = 0;
};

/// Keypoints of A seen by scan B (poses in a common frame) and how many have a keypoint of B within
/// `match` metres.
void repeat(const std::vector<FalkoKeypoint>& a, const Pose2d& pa, const std::vector<FalkoKeypoint>& b,
            const Pose2d& pb, const LaserScan& scanB, const EvalOptions& o, Counts& c) {
  const Pose2d ab = between(pb, pa);  // A's frame in B
  for (const FalkoKeypoint& k : a) {
    const Pose2d::Vector2 q = ab.transformPoint(Pose2d::Vector2(k.x, k.y));
    if (!sees(scanB, q.x(), q.y(), o.visibilityTolerance)) {
      continue;
    }
    ++c.visible;
    for (const FalkoKeypoint& m : b) {
      if (std::hypot(static_cast<double>(m.x) - q.x(), static_cast<double>(m.y) - q.y()) <= o.matchDistance) {
        ++c.matched;
        break;
      }
    }
  }
}

std::string label(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%g", v);
  return buf;
}

struct MatchRecord {
  double distance = 0.0;
  bool correct = false;
};

std::vector<PrPoint> precisionRecall(std::vector<MatchRecord> rec, std::size_t withTruth,
                                     const std::vector<double>& thresholds) {
  std::vector<PrPoint> out;
  for (const double t : thresholds) {
    std::size_t accepted = 0;
    std::size_t correct = 0;
    for (const MatchRecord& r : rec) {
      if (r.distance <= t) {
        ++accepted;
        correct += r.correct ? 1U : 0U;
      }
    }
    PrPoint p;
    p.threshold = t;
    p.precision = accepted > 0 ? static_cast<double>(correct) / static_cast<double>(accepted) : 1.0;
    p.recall = withTruth > 0 ? static_cast<double>(correct) / static_cast<double>(withTruth) : 0.0;
    out.push_back(p);
  }
  return out;
}

std::string samplingLabel(int factor) {
  return factor < 0 ? "x1/" + std::to_string(-factor) : "x" + std::to_string(factor);
}

/// The scans of a log the evaluation uses: those with ground truth, at most maxScans.
bool loadScans(const std::string& path, const EvalOptions& o, std::vector<ScanData>& data, std::string& error) {
  datasets::CarmenLog log;
  if (!datasets::readCarmenLog(path, log, error)) {
    return false;
  }
  data.clear();
  for (const auto& s : log.scans) {
    if (!s.hasGroundTruth) {
      continue;
    }
    if (o.maxScans > 0 && data.size() >= o.maxScans) {
      break;
    }
    ScanData d;
    d.scan = std::make_unique<LaserScan>();
    (void)s.toLaserScan(*d.scan);
    d.pose = s.groundTruth;
    data.push_back(std::move(d));
  }
  if (data.empty()) {
    error = path + ": no scan with ground truth";
    return false;
  }
  return true;
}

std::vector<Pose2d> posesOf(const std::vector<ScanData>& data) {
  std::vector<Pose2d> poses;
  poses.reserve(data.size());
  for (const ScanData& d : data) {
    poses.push_back(d.pose);
  }
  return poses;
}

/// An external keypoint table must cover exactly the variants and scans of this run.
bool checkExternal(const KeypointTable& table, const std::string& name, const std::vector<ScanVariant>& variants,
                   std::size_t scans, std::string& error) {
  const auto ds = table.find(name);
  if (ds == table.end()) {
    error = "keypoint file: no line for dataset " + name;
    return false;
  }
  for (const auto& v : ds->second) {
    const bool known =
        std::any_of(variants.begin(), variants.end(), [&](const ScanVariant& sv) { return sv.name == v.first; });
    if (!known) {
      error = "keypoint file: " + name + ": unknown variant " + v.first;
      return false;
    }
  }
  for (const ScanVariant& v : variants) {
    const auto it = ds->second.find(v.name);
    if (it == ds->second.end()) {
      error = "keypoint file: " + name + ": no line for variant " + v.name;
      return false;
    }
    for (std::size_t i = 0; i < scans; ++i) {
      if (it->second.count(i) == 0U) {
        error = "keypoint file: " + name + " " + v.name + ": no line for scan " + std::to_string(i);
        return false;
      }
    }
    if (it->second.size() != scans) {
      error = "keypoint file: " + name + " " + v.name + ": scan " + std::to_string(it->second.rbegin()->first) +
              " beyond the " + std::to_string(scans) + " scans of this run (same --max-scans?)";
      return false;
    }
  }
  return true;
}

// The keypoint file's numbers go through the apps' one parser (decimal, locale-free, whole token).
bool parseCount(const std::string& tok, long long& v) {
  std::int64_t x = 0;
  if (!report::toInteger(tok, x)) {
    return false;
  }
  v = x;
  return true;
}

bool parseNumber(const std::string& tok, double& v) {
  return report::toReal(tok, v);  // inf and nan refused
}

}  // namespace

std::vector<ScanVariant> scanVariants(const EvalOptions& o) {
  std::vector<ScanVariant> v;
  v.push_back(ScanVariant{"clean", "", "", 0});
  for (std::size_t l = 0; l < o.noiseLevels.size(); ++l) {
    const std::string lb = label(o.noiseLevels[l]);
    v.push_back(ScanVariant{"noise-" + lb, "noise", lb, l});
  }
  for (std::size_t l = 0; l < o.resampleLevels.size(); ++l) {
    const std::string lb = samplingLabel(o.resampleLevels[l]);
    v.push_back(ScanVariant{"sampling-" + lb, "sampling", lb, l});
  }
  return v;
}

void makeVariant(const ScanVariant& v, std::size_t i, const LaserScan& clean, const EvalOptions& o, LaserScan& out) {
  if (v.test == "noise") {
    out = clean;
    addRangeNoise(out, o.noiseLevels[v.levelIndex], o.seed + static_cast<std::uint32_t>(i * 7919U + v.levelIndex));
  } else if (v.test == "sampling") {
    resampleScan(clean, o.resampleLevels[v.levelIndex], out);
  } else {
    out = clean;
  }
}

std::vector<ScanPair> viewpointPairs(const std::vector<Pose2d>& poses, const EvalOptions& o) {
  std::vector<ScanPair> pairs;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    std::vector<bool> binUsed(o.viewpointLevels.size(), false);
    std::size_t found = 0;
    for (std::size_t j = i + 1; j < poses.size() && j < i + 2000 && found < o.pairsPerScan; ++j) {
      const double d = std::hypot(poses[i].x - poses[j].x, poses[i].y - poses[j].y);
      if (d > o.pairMaxDistance) {
        continue;
      }
      std::size_t bin = 0;
      while (bin < o.viewpointLevels.size() && d > o.viewpointLevels[bin]) {
        ++bin;
      }
      if (bin >= o.viewpointLevels.size() || binUsed[bin]) {
        continue;
      }
      binUsed[bin] = true;
      ++found;
      pairs.push_back(ScanPair{i, j, d, bin});
    }
  }
  return pairs;
}

bool readKeypointTable(std::istream& in, KeypointTable& table, std::string& error) {
  std::string line;
  std::size_t lineNo = 0;
  while (std::getline(in, line)) {
    ++lineNo;
    std::istringstream ls(line);
    std::vector<std::string> tok;
    for (std::string t; ls >> t;) {
      tok.push_back(t);
    }
    if (tok.empty() || tok[0][0] == '#') {
      continue;
    }
    const std::string where = "keypoint file line " + std::to_string(lineNo) + ": ";
    long long scan = 0;
    long long k = 0;
    if (tok.size() < 4 || !parseCount(tok[2], scan) || !parseCount(tok[3], k)) {
      error = where + "expected <dataset> <variant> <scan> <count> <x y>...";
      return false;
    }
    if (scan < 0 || k < 0) {
      error = where + "negative scan index or count";
      return false;
    }
    const std::size_t values = tok.size() - 4;
    if (values != 2U * static_cast<unsigned long long>(k)) {
      error = where + std::to_string(k) + " keypoints need " + std::to_string(2 * k) + " coordinates, found " +
              std::to_string(values);
      return false;
    }
    std::vector<FalkoKeypoint> kps(static_cast<std::size_t>(k));
    for (std::size_t a = 0; a < kps.size(); ++a) {
      double x = 0.0;
      double y = 0.0;
      if (!parseNumber(tok[4 + 2 * a], x) || !parseNumber(tok[5 + 2 * a], y) || !std::isfinite(x) ||
          !std::isfinite(y)) {
        error = where + "keypoint " + std::to_string(a + 1) + " is not a pair of finite numbers";
        return false;
      }
      kps[a].x = static_cast<float>(x);
      kps[a].y = static_cast<float>(y);
    }
    auto& scans = table[tok[0]][tok[1]];
    if (!scans.emplace(static_cast<std::size_t>(scan), std::move(kps)).second) {
      error = where + tok[0] + " " + tok[1] + " scan " + tok[2] + " is listed twice";
      return false;
    }
  }
  if (in.bad()) {
    error = "keypoint file: read error";
    return false;
  }
  return true;
}

std::string keypointLine(const std::string& dataset, const std::string& variant, std::size_t scan,
                         const std::vector<FalkoKeypoint>& keypoints) {
  std::string out = dataset + " " + variant + " " + std::to_string(scan) + " " + std::to_string(keypoints.size());
  char buf[64];
  for (const FalkoKeypoint& k : keypoints) {
    std::snprintf(buf, sizeof(buf), " %.9g %.9g", static_cast<double>(k.x), static_cast<double>(k.y));
    out += buf;
  }
  return out + "\n";
}

std::string scanLine(const std::string& dataset, const std::string& variant, std::size_t scan, const LaserScan& s) {
  std::string out = dataset + " " + variant + " " + std::to_string(scan);
  char buf[64];
  for (const float v : {s.angleMin, s.angleIncrement, s.rangeMin, s.rangeMax}) {
    std::snprintf(buf, sizeof(buf), " %.9g", static_cast<double>(v));
    out += buf;
  }
  out += " " + std::to_string(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) {
    std::snprintf(buf, sizeof(buf), " %.9g", static_cast<double>(s.ranges[i]));
    out += buf;
  }
  return out + "\n";
}

void addRangeNoise(LaserScan& scan, double sigma, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, sigma);
  for (std::size_t i = 0; i < scan.size(); ++i) {
    if (scan.isValid(i)) {
      scan.ranges[i] = static_cast<float>(static_cast<double>(scan.ranges[i]) + g(rng));
    }
  }
}

void resampleScan(const LaserScan& in, int factor, LaserScan& out) {
  out.stamp = in.stamp;
  out.sweepDuration = in.sweepDuration;
  out.angleMin = in.angleMin;
  out.rangeMin = in.rangeMin;
  out.rangeMax = in.rangeMax;
  out.ranges.clear();
  if (factor < 0) {
    const auto k = static_cast<std::size_t>(-factor);
    out.angleIncrement = in.angleIncrement * static_cast<float>(k);
    for (std::size_t i = 0; i < in.size(); i += k) {
      (void)out.ranges.push_back(in.ranges[i]);
    }
    return;
  }
  const auto k = static_cast<std::size_t>(factor < 1 ? 1 : factor);
  out.angleIncrement = in.angleIncrement / static_cast<float>(k);
  const float invalid = std::numeric_limits<float>::infinity();
  for (std::size_t i = 0; i < in.size(); ++i) {
    (void)out.ranges.push_back(in.ranges[i]);
    if (i + 1 == in.size()) {
      break;
    }
    for (std::size_t s = 1; s < k; ++s) {
      const float f = static_cast<float>(s) / static_cast<float>(k);
      const bool ok = in.isValid(i) && in.isValid(i + 1) && std::fabs(in.ranges[i] - in.ranges[i + 1]) <= 0.1F;
      (void)out.ranges.push_back(ok ? in.ranges[i] + f * (in.ranges[i + 1] - in.ranges[i]) : invalid);
    }
  }
}

bool evaluateLog(const std::string& name, const std::string& path, const EvalOptions& o, DatasetResult& result,
                 std::string& error, const KeypointTable* external) {
  std::vector<ScanData> data;
  if (!loadScans(path, o, data, error)) {
    return false;
  }
  const std::vector<ScanVariant> variants = scanVariants(o);
  if (external != nullptr && !checkExternal(*external, name, variants, data.size(), error)) {
    return false;
  }
  // The external keypoints of this dataset (checked complete above), or the detector.
  const auto* table = external != nullptr ? &external->at(name) : nullptr;
  const std::unique_ptr<Engine> engine = table == nullptr ? std::make_unique<Engine>(o) : nullptr;
  result = DatasetResult{};
  result.name = name;
  result.scans = data.size();
  std::size_t total = 0;
  for (std::size_t i = 0; i < data.size(); ++i) {
    if (table != nullptr) {
      data[i].keypoints = table->at(variants.front().name).at(i);
    } else {
      engine->detectDescribe(data[i]);
    }
    total += data[i].keypoints.size();
  }
  result.keypointsPerScan = static_cast<double>(total) / static_cast<double>(data.size());

  // 1. Viewpoint: pairs within pairMaxDistance, at most one partner per distance bin and scan.
  std::vector<Counts> vp(o.viewpointLevels.size());
  std::vector<MatchRecord> bscRec;
  std::vector<MatchRecord> cghRec;
  std::size_t withTruth = 0;
  for (const ScanPair& p : viewpointPairs(posesOf(data), o)) {
    const std::size_t i = p.i;
    const std::size_t j = p.j;
    ++result.pairs;
    repeat(data[i].keypoints, data[i].pose, data[j].keypoints, data[j].pose, *data[j].scan, o, vp[p.bin]);
    repeat(data[j].keypoints, data[j].pose, data[i].keypoints, data[i].pose, *data[i].scan, o, vp[p.bin]);
    if (table != nullptr) {
      continue;  // the descriptors need this describer's keypoints
    }
    // Descriptors: nearest neighbour in j of each keypoint of i seen by j.
    const Pose2d ij = between(data[j].pose, data[i].pose);
    for (std::size_t a = 0; a < data[i].keypoints.size(); ++a) {
      const FalkoKeypoint& k = data[i].keypoints[a];
      const Pose2d::Vector2 q = ij.transformPoint(Pose2d::Vector2(k.x, k.y));
      if (!sees(*data[j].scan, q.x(), q.y(), o.visibilityTolerance) || data[j].keypoints.empty()) {
        continue;
      }
      std::size_t truth = data[j].keypoints.size();
      double best = o.matchDistance;
      for (std::size_t b = 0; b < data[j].keypoints.size(); ++b) {
        const double e = std::hypot(static_cast<double>(data[j].keypoints[b].x) - q.x(),
                                    static_cast<double>(data[j].keypoints[b].y) - q.y());
        if (e <= best) {
          best = e;
          truth = b;
        }
      }
      withTruth += truth < data[j].keypoints.size() ? 1U : 0U;
      std::size_t nnB = 0;
      std::size_t nnC = 0;
      double dB = 1e300;
      double dC = 1e300;
      for (std::size_t b = 0; b < data[j].keypoints.size(); ++b) {
        const double db = bscDistance(data[i].bsc[a], data[j].bsc[b]);
        const double dc = static_cast<double>(cghDistance(data[i].cgh[a], data[j].cgh[b]));
        if (db < dB) {
          dB = db;
          nnB = b;
        }
        if (dc < dC) {
          dC = dc;
          nnC = b;
        }
      }
      bscRec.push_back(MatchRecord{dB, nnB == truth});
      cghRec.push_back(MatchRecord{dC, nnC == truth});
    }
  }
  for (std::size_t b = 0; b < vp.size(); ++b) {
    const std::string l = label(o.viewpointLevels[b]);
    result.samples["viewpoint"][l] = vp[b].visible;
    result.repeatability["viewpoint"][l] =
        vp[b].visible > 0 ? static_cast<double>(vp[b].matched) / static_cast<double>(vp[b].visible) : 0.0;
  }
  if (table == nullptr) {
    result.bsc = precisionRecall(bscRec, withTruth, {2, 4, 6, 8, 10, 12, 16, 20, 24, 32, 48, 64, 128});
    result.cgh = precisionRecall(cghRec, withTruth, {0.01, 0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.5, 0.75, 1.0});
  }

  // 2. Range noise and 3. angular resampling: the same scan and pose, modified vs clean.
  auto modified = std::make_unique<LaserScan>();
  std::vector<FalkoKeypoint> kp;
  const Pose2d identity;
  for (std::size_t v = 1; v < variants.size(); ++v) {
    const ScanVariant& var = variants[v];
    Counts c;
    for (std::size_t i = 0; i < data.size(); ++i) {
      makeVariant(var, i, *data[i].scan, o, *modified);
      if (table != nullptr) {
        kp = table->at(var.name).at(i);
      } else {
        engine->detect(*modified, kp);
      }
      repeat(data[i].keypoints, identity, kp, identity, *modified, o, c);
      repeat(kp, identity, data[i].keypoints, identity, *data[i].scan, o, c);
    }
    result.samples[var.test][var.level] = c.visible;
    result.repeatability[var.test][var.level] =
        c.visible > 0 ? static_cast<double>(c.matched) / static_cast<double>(c.visible) : 0.0;
  }
  return true;
}

bool exportLog(const std::string& name, const std::string& path, const EvalOptions& o, const ExportStreams& out,
               std::string& error) {
  std::vector<ScanData> data;
  if (!loadScans(path, o, data, error)) {
    return false;
  }
  if (out.scans != nullptr || out.keypoints != nullptr) {
    const std::unique_ptr<Engine> engine = out.keypoints != nullptr ? std::make_unique<Engine>(o) : nullptr;
    auto modified = std::make_unique<LaserScan>();
    std::vector<FalkoKeypoint> kp;
    for (const ScanVariant& v : scanVariants(o)) {
      for (std::size_t i = 0; i < data.size(); ++i) {
        makeVariant(v, i, *data[i].scan, o, *modified);
        if (out.scans != nullptr) {
          *out.scans << scanLine(name, v.name, i, *modified);
        }
        if (out.keypoints != nullptr) {
          engine->detect(*modified, kp);
          *out.keypoints << keypointLine(name, v.name, i, kp);
        }
      }
    }
  }
  if (out.pairs != nullptr) {
    char buf[128];
    for (const ScanPair& p : viewpointPairs(posesOf(data), o)) {
      std::snprintf(buf, sizeof(buf), "%s %zu %zu %.4f %s\n", name.c_str(), p.i, p.j, p.distance,
                    label(o.viewpointLevels[p.bin]).c_str());
      *out.pairs << buf;
    }
  }
  for (std::ostream* s : {out.scans, out.keypoints, out.pairs}) {
    if (s != nullptr && !*s) {
      error = "export: write failed";
      return false;
    }
  }
  return true;
}

std::string paramsLine(const FalkoParams& p) {
  char buf[256];
  std::snprintf(buf, sizeof(buf),
                "FALKO parameters: a %.3g m, b %.3g 1/m, beta %.3g, sectors %zu, max score %.3g, NMS %.3g m",
                static_cast<double>(p.neighA), static_cast<double>(p.neighB), static_cast<double>(p.beta),
                p.gridSectors, static_cast<double>(p.maxScore), static_cast<double>(p.nmsRadius));
  return buf;
}

report::Json resultsToJson(const std::vector<DatasetResult>& results, const FalkoParams& params,
                           const std::string& keypointsFile) {
  using report::Json;
  Json repeatability = Json::object();
  Json keypointsPerScan = Json::object();
  Json scans = Json::object();
  Json descriptors = Json::object();
  for (const DatasetResult& r : results) {
    Json tests = Json::object();
    for (const auto& [test, levels] : r.repeatability) {
      Json byLevel = Json::object();
      for (const auto& [level, value] : levels) {
        byLevel[level] = value;
      }
      tests[test] = std::move(byLevel);
    }
    repeatability[r.name] = std::move(tests);
    keypointsPerScan[r.name] = r.keypointsPerScan;
    scans[r.name] = r.scans;
    Json curves = Json::object();
    for (int k = 0; k < 2; ++k) {
      Json points = Json::array();
      for (const PrPoint& p : k == 0 ? r.bsc : r.cgh) {
        points.push_back(Json{{"threshold", p.threshold}, {"precision", p.precision}, {"recall", p.recall}});
      }
      curves[k == 0 ? "bsc" : "cgh"] = std::move(points);
    }
    descriptors[r.name] = std::move(curves);
  }
  Json doc{{"repeatability", std::move(repeatability)},
           {"keypoints_per_scan", std::move(keypointsPerScan)},
           {"scans", std::move(scans)},
           {"descriptors", std::move(descriptors)}};
  if (!keypointsFile.empty()) {
    doc["keypoints_file"] = keypointsFile;
    return doc;
  }
  doc["falko_params"] = Json{
      {"neigh_a", report::shortestDouble(params.neighA)},     {"neigh_b", report::shortestDouble(params.neighB)},
      {"beta", report::shortestDouble(params.beta)},          {"grid_sectors", params.gridSectors},
      {"max_score", report::shortestDouble(params.maxScore)}, {"nms_radius", report::shortestDouble(params.nmsRadius)}};
  return doc;
}

std::string resultsToTables(const std::vector<DatasetResult>& results) {
  std::ostringstream out;
  char buf[256];
  for (const DatasetResult& r : results) {
    std::snprintf(buf, sizeof(buf), "== %s: %zu scans, %.2f keypoints/scan, %zu viewpoint pairs\n", r.name.c_str(),
                  r.scans, r.keypointsPerScan, r.pairs);
    out << buf;
    for (const auto& test : r.repeatability) {
      out << "  repeatability / " << test.first << "\n";
      for (const auto& level : test.second) {
        const std::size_t n = r.samples.at(test.first).at(level.first);
        std::snprintf(buf, sizeof(buf), "    %-8s %6.3f  (%zu keypoints)\n", level.first.c_str(), level.second, n);
        out << buf;
      }
    }
    if (r.bsc.empty() && r.cgh.empty()) {
      out << "  descriptors: not evaluated (keypoints from a file)\n";
      continue;
    }
    for (int k = 0; k < 2; ++k) {
      out << "  " << (k == 0 ? "BSC" : "CGH") << " nearest-neighbour matching: threshold precision recall\n";
      for (const PrPoint& p : k == 0 ? r.bsc : r.cgh) {
        std::snprintf(buf, sizeof(buf), "    %8.3f %6.3f %6.3f\n", p.threshold, p.precision, p.recall);
        out << buf;
      }
    }
  }
  return out.str();
}

}  // namespace features
}  // namespace agv
