#include "loops.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>

#include "agv/core/angle.hpp"
#include "agv/falko/falko_detector.hpp"
#include "agv/loop/affine_hough.hpp"
#include "agv/loop/correspondence_graph.hpp"
#include "agv/loop/glarot_database.hpp"
#include "agv/loop/ransac_association.hpp"
#include "agv/loop/scan_overlap.hpp"
#include "agv/mapping/scan_odometry.hpp"
#include "agv/report/svg.hpp"

namespace agv {
namespace loops {
namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

Span<const Eigen::Vector2f> view(const std::vector<Eigen::Vector2f>& v) {
  return Span<const Eigen::Vector2f>(v.data(), v.size());
}

// ~1.3 kB per entry: on the heap.
using Database = GlarotDatabase<kMaxDatabaseScans>;

// Whether `rel` (a relative pose) is inside the online skip box.
bool insideSkipBox(const Pose2d& rel, const EvalOptions& o) {
  return std::fabs(rel.x) < o.onlineSkipX && std::fabs(rel.y) < o.onlineSkipY &&
         std::fabs(normalizeAngle(rel.theta)) < o.onlineSkipTheta;
}

// Number of scans just before `i` left out online: walking back from i-1 while their pose relative
// to scan i stays inside the skip box.
std::size_t onlineSkipCount(const std::vector<Pose2d>& truth, std::size_t i, const EvalOptions& o) {
  std::size_t n = 0;
  while (n < i && insideSkipBox(between(truth[i - 1 - n], truth[i]), o)) {
    ++n;
  }
  return n;
}

}  // namespace

void addSubmapPoints(const std::vector<Eigen::Vector2f>& points, const Pose2d& toThis, float mergeRadius,
                     std::size_t limit, std::vector<Eigen::Vector2f>& submap) {
  limit = std::min(limit, kMaxLoopPoints);
  const double c = std::cos(toThis.theta);
  const double sn = std::sin(toThis.theta);
  for (const Eigen::Vector2f& q : points) {
    const Eigen::Vector2f p(
        static_cast<float>(toThis.x + c * static_cast<double>(q.x()) - sn * static_cast<double>(q.y())),
        static_cast<float>(toThis.y + sn * static_cast<double>(q.x()) + c * static_cast<double>(q.y())));
    bool near = false;
    for (const Eigen::Vector2f& e : submap) {
      near = near || (e - p).norm() < mergeRadius;
    }
    if (!near && submap.size() < limit) {
      submap.push_back(p);
    }
  }
}

bool extractFeatures(const datasets::CarmenLog& log, const ScanSelection& selection, ScanFeatures& out,
                     std::string& error) {
  out = ScanFeatures{};
  if (selection.stride == 0) {
    error = "the stride must be at least 1";
    return false;
  }
  auto detector = std::make_unique<FalkoDetector>(selection.falko);
  auto keypoints = std::make_unique<FalkoKeypoints>();
  auto scan = std::make_unique<LaserScan>();
  std::size_t withTruth = 0;
  double keypointSum = 0.0;
  double ms = 0.0;
  for (std::size_t s = 0; s < log.scans.size(); ++s) {
    const datasets::LogScan& line = log.scans[s];
    if (!line.hasGroundTruth) {
      continue;
    }
    if (withTruth++ % selection.stride != 0) {
      continue;
    }
    if (selection.maxScans != 0 && out.points.size() >= selection.maxScans) {
      break;
    }
    const auto t0 = Clock::now();
    if (!line.toLaserScan(*scan)) {
      error = "line " + std::to_string(line.line) + ": more readings than a LaserScan holds";
      return false;
    }
    if (detector->detect(*scan, *keypoints) != Status::Ok) {
      keypoints->clear();  // a scan without corners: empty signature, never associated
    }
    std::vector<FalkoKeypoint> sorted(keypoints->begin(), keypoints->end());
    keypointSum += static_cast<double>(sorted.size());
    if (sorted.size() > kMaxLoopPoints) {
      // The sharpest corners (lowest score) are kept.
      std::sort(sorted.begin(), sorted.end(),
                [](const FalkoKeypoint& a, const FalkoKeypoint& b) { return a.score < b.score; });
      sorted.resize(kMaxLoopPoints);
      ++out.truncated;
    }
    std::vector<Eigen::Vector2f> pts;
    pts.reserve(sorted.size());
    for (const FalkoKeypoint& k : sorted) {
      pts.emplace_back(k.x, k.y);
    }
    GlarotSignature sig;
    // Fewer than two points leave an all-zero signature of the right shape (documented in glarot.hpp).
    if (selection.glarotScanPoints == 0) {
      (void)computeGlarot(view(pts), selection.glarot, sig);
    } else {
      std::vector<std::size_t> valid;
      for (std::size_t b = 0; b < scan->size(); ++b) {
        if (scan->isValid(b)) {
          valid.push_back(b);
        }
      }
      std::vector<Eigen::Vector2f> spread;
      const std::size_t m = std::min(std::min(selection.glarotScanPoints, valid.size()), kMaxKeypoints);
      for (std::size_t k = 0; k < m; ++k) {
        const std::size_t b = valid[k * valid.size() / m];
        const float a = scan->angle(b);
        spread.emplace_back(scan->ranges[b] * std::cos(a), scan->ranges[b] * std::sin(a));
      }
      (void)computeGlarot(view(spread), selection.glarot, sig);
    }
    ms += msSince(t0);
    out.points.push_back(std::move(pts));
    out.scans.push_back(*scan);
    out.signatures.push_back(sig);
    out.truth.push_back(line.groundTruth);
    out.logScan.push_back(s);
  }
  if (out.points.empty()) {
    error = withTruth == 0 ? "no scan with a ground-truth pose (VERTEX2) in the log" : "no scan selected";
    return false;
  }
  if (selection.submapScans > 1) {
    // The simulated odometry of the selected scans (see ScanSelection): noisy ground-truth steps.
    std::mt19937_64 rng(selection.submapNoiseSeed);
    std::normal_distribution<double> unit(0.0, 1.0);
    std::vector<Pose2d> odometry{out.truth.front()};
    for (std::size_t i = 1; i < out.truth.size(); ++i) {
      const Pose2d step = between(out.truth[i - 1], out.truth[i]);
      const double d = std::hypot(step.x, step.y);
      const double sp = std::sqrt(selection.submapPositionVariancePerMetre * d);
      const double sh = std::sqrt(selection.submapHeadingVariancePerMetre * d);
      const double nx = sp * unit(rng);
      const double ny = sp * unit(rng);
      const double nt = sh * unit(rng);
      odometry.push_back(odometry.back().compose(Pose2d{step.x + nx, step.y + ny, step.theta + nt}));
    }
    if (selection.submapMatched) {
      // The poses are the laser's: no mounting.
      std::vector<Pose2d> steps(odometry.size());
      std::vector<Eigen::Matrix3d> covariances(odometry.size(), Eigen::Matrix3d::Zero());
      for (std::size_t i = 1; i < odometry.size(); ++i) {
        steps[i] = between(odometry[i - 1], odometry[i]);
        const double d = std::hypot(steps[i].x, steps[i].y);
        covariances[i].diagonal() << selection.submapPositionVariancePerMetre * d + 1e-6,
            selection.submapPositionVariancePerMetre * d + 1e-6, selection.submapHeadingVariancePerMetre * d + 1e-6;
      }
      std::vector<Pose2d> matched;
      (void)mapping::scanMatchedTrack(out.scans, Pose2d{}, odometry.front(), steps, covariances, matched);
      odometry = std::move(matched);
    }
    // Each scan's association set: its keypoints and, while it holds fewer than submapPoints, the
    // previous submapScans - 1 selected scans', placed by that odometry, newest first.
    std::vector<std::vector<Eigen::Vector2f>> submaps(out.points.size());
    for (std::size_t i = 0; i < out.points.size(); ++i) {
      for (std::size_t k = 0; k < selection.submapScans && k <= i; ++k) {
        addSubmapPoints(out.points[i - k], between(odometry[i], odometry[i - k]), selection.falko.nmsRadius,
                        k == 0 ? kMaxLoopPoints : selection.submapPoints, submaps[i]);
      }
    }
    out.points = std::move(submaps);
  }
  const double n = static_cast<double>(out.points.size());
  out.meanKeypoints = keypointSum / n;
  out.detectMs = ms / n;
  return true;
}

void evaluate(const ScanFeatures& f, bool online, const EvalOptions& o, ModeResult& out) {
  out = ModeResult{};
  const std::size_t n = f.points.size();
  auto db = std::make_unique<Database>();
  for (std::size_t i = 0; i < n; ++i) {
    (void)db->insert(f.signatures[i], f.truth[i]);  // n <= capacity is checked by the caller
  }
  auto cg = std::make_unique<CorrespondenceGraphMatcher>();
  auto ah = std::make_unique<AffineHoughMatcher>();
  auto ransac = std::make_unique<RansacMatcher>();
  auto assoc = std::make_unique<PointAssociation>();
  auto queryScan = std::make_unique<ScanOverlap>();
  auto candidateScan = std::make_unique<ScanOverlap>();
  (void)queryScan->setParams(o.overlap);  // invalid parameters: the defaults stay
  (void)candidateScan->setParams(o.overlap);
  std::FILE* dump = o.dumpPath.empty() ? nullptr : std::fopen(o.dumpPath.c_str(), "a");
  GlarotCandidates found;
  for (std::size_t i = 0; i < n; ++i) {
    GlarotQuery q;
    q.k = o.candidates;
    std::size_t end = n;
    if (online) {
      end = i - onlineSkipCount(f.truth, i, o);
      if (end == 0) {
        continue;  // nothing earlier to compare with
      }
      q.end = end;
    } else {
      q.excludeIndex = i;
    }
    // The recall's reference: some eligible scan was taken near this pose.
    bool loop = false;
    for (std::size_t j = 0; j < end && !loop; ++j) {
      const Pose2d rel = between(f.truth[j], f.truth[i]);
      loop = j != i && std::hypot(rel.x, rel.y) < o.revisitDistance &&
             std::fabs(normalizeAngle(rel.theta)) < o.revisitAngle;
    }
    out.hasLoop.push_back(loop);
    out.withLoop += loop ? 1U : 0U;
    ++out.scans;

    auto t0 = Clock::now();
    (void)db->query(f.signatures[i], q, found);
    out.glarotMsPerScan.push_back(msSince(t0));
    const bool verify = o.verify || dump != nullptr;
    for (std::size_t m = 0; m < kMethods; ++m) {
      BestLoop best;
      double bestRms = 0.0;
      t0 = Clock::now();
      for (std::size_t r = 0; r < found.size(); ++r) {
        const GlarotCandidate& c = found[r];
        Status st = Status::InvalidArgument;
        if (m == 0) {
          st = cg->match(view(f.points[c.index]), view(f.points[i]), *assoc);
        } else if (m == 1) {
          st = ah->match(view(f.points[c.index]), view(f.points[i]), *assoc);
        } else {
          st = ransac->match(view(f.points[c.index]), view(f.points[i]), *assoc);
        }
        if (st != Status::Ok) {
          continue;
        }
        MutualOverlap ov;
        bool verified = true;
        if (verify) {
          // A scan without a valid reading verifies nothing (0 hits, all conflicts).
          (void)mutualOverlap(*candidateScan, f.scans[c.index], *queryScan, f.scans[i], assoc->transform, ov);
          verified = !o.verify || (ov.hitFraction >= o.minOverlap && ov.conflictFraction <= o.maxConflict);
          if (!verified && dump == nullptr) {
            continue;
          }
        }
        const std::size_t pairs = assoc->pairs.size();
        const Pose2d aligned = f.truth[c.index].compose(assoc->transform);
        const Pose2d err = between(f.truth[i], aligned);
        const bool correct =
            std::hypot(err.x, err.y) < o.correctDistance && std::fabs(normalizeAngle(err.theta)) < o.correctAngle;
        if (dump != nullptr) {
          const Pose2d rel = between(f.truth[c.index], f.truth[i]);
          std::fprintf(dump, "%s,%d,%zu,%zu,%zu,%s,%zu,%.4f,%.4f,%.4f,%d,%d,%.3f,%.3f,%zu,%zu,%.3f,%.3f,%.4f\n",
                       o.dumpName.c_str(), online ? 1 : 0, i, static_cast<std::size_t>(c.index), r, kMethodNames[m],
                       pairs, assoc->rms, ov.hitFraction, ov.conflictFraction, correct ? 1 : 0, loop ? 1 : 0,
                       std::hypot(rel.x, rel.y), std::fabs(normalizeAngle(rel.theta)), f.points[i].size(),
                       f.points[c.index].size(), std::hypot(err.x, err.y), std::fabs(normalizeAngle(err.theta)),
                       ov.inViewFraction);
          if (!verified) {
            continue;
          }
        }
        if (pairs > best.pairs || (pairs == best.pairs && assoc->rms < bestRms)) {
          best.pairs = pairs;
          best.candidate = c.index;
          best.transform = assoc->transform;
          best.correct = correct;
          best.overlap = ov.hitFraction;
          best.conflict = ov.conflictFraction;
          bestRms = assoc->rms;
        }
      }
      out.msPerScan[m].push_back(msSince(t0));
      out.best[m].push_back(best);
    }
    if (dump != nullptr) {
      // The scan's own line: keypoints, and whether a candidate was a revisit (rank -1 = none).
      long revisitRank = -1;
      for (std::size_t r = 0; r < found.size() && revisitRank < 0; ++r) {
        const Pose2d rel = between(f.truth[found[r].index], f.truth[i]);
        if (std::hypot(rel.x, rel.y) < o.revisitDistance && std::fabs(normalizeAngle(rel.theta)) < o.revisitAngle) {
          revisitRank = static_cast<long>(r);
        }
      }
      std::fprintf(dump, "%s,%d,%zu,-1,%ld,scan,0,0,0,0,0,%d,0,0,%zu,0,0,0,0\n", o.dumpName.c_str(), online ? 1 : 0, i,
                   revisitRank, loop ? 1 : 0, f.points[i].size());
    }
  }
  if (dump != nullptr) {
    std::fclose(dump);
  }
  for (std::size_t m = 0; m < kMethods; ++m) {
    out.curves[m] = prCurve(out.best[m], out.hasLoop, o.maxMinPairs);
  }
}

std::vector<PrPoint> prCurve(const std::vector<BestLoop>& best, const std::vector<bool>& hasLoop,
                             std::size_t maxMinPairs) {
  std::size_t withLoop = 0;
  for (bool b : hasLoop) {
    withLoop += b ? 1U : 0U;
  }
  std::vector<PrPoint> curve;
  for (std::size_t nMin = 0; nMin <= maxMinPairs; ++nMin) {
    PrPoint p;
    p.minPairs = nMin;
    for (std::size_t i = 0; i < best.size(); ++i) {
      // pairs == 0: no association at all, never a loop (even at N_min = 0).
      if (best[i].pairs == 0 || best[i].pairs < nMin) {
        continue;
      }
      ++p.accepted;
      if (best[i].correct) {
        ++p.correct;
        p.recalled += hasLoop[i] ? 1U : 0U;
      }
    }
    p.precision = p.accepted == 0 ? 1.0 : static_cast<double>(p.correct) / static_cast<double>(p.accepted);
    p.recall = withLoop == 0 ? 0.0 : static_cast<double>(p.recalled) / static_cast<double>(withLoop);
    curve.push_back(p);
  }
  return curve;
}

CurveSummary summarize(const std::vector<PrPoint>& curve) {
  CurveSummary s;
  for (std::size_t k = 0; k < curve.size(); ++k) {
    const PrPoint& p = curve[k];
    // The first N_min where precision reaches recall after being below it.
    if (s.breakEvenMinPairs < 0 && k > 0 && p.accepted > 0 && p.precision >= p.recall &&
        curve[k - 1].precision < curve[k - 1].recall) {
      s.breakEvenMinPairs = static_cast<long>(p.minPairs);
      s.breakEven = 0.5 * (p.precision + p.recall);
    }
    if (p.accepted > 0 && p.precision >= 1.0 && (s.recallAtPrecision1MinPairs < 0 || p.recall > s.recallAtPrecision1)) {
      s.recallAtPrecision1 = p.recall;
      s.recallAtPrecision1MinPairs = static_cast<long>(p.minPairs);
    }
  }
  return s;
}

report::Json timingJson(std::vector<double> values) {
  report::Json j = report::Json::object();
  j["scans"] = values.size();
  if (values.empty()) {
    j["mean"] = 0.0;
    j["median"] = 0.0;
    j["p95"] = 0.0;
    return j;
  }
  std::sort(values.begin(), values.end());
  double sum = 0.0;
  for (double v : values) {
    sum += v;
  }
  const auto at = [&](double q) {
    const std::size_t k = static_cast<std::size_t>(std::ceil(q * static_cast<double>(values.size()))) - 1;
    return values[std::min(k, values.size() - 1)];
  };
  j["mean"] = sum / static_cast<double>(values.size());
  j["median"] = at(0.5);
  j["p95"] = at(0.95);
  return j;
}

std::string prSvg(const std::string& dataset, const ModeResult& offline, const ModeResult& online) {
  const double w = 900.0;
  const double h = 380.0;
  const double m = 50.0;
  const double pw = (w - 3 * m) / 2.0;
  const char* colours[] = {"#d62728", "#1f77b4", "#2ca02c"};
  report::SvgDocument svg(w, h, {{"font-family", "sans-serif"}});
  const ModeResult* modes[] = {&offline, &online};
  const char* modeNames[] = {"offline", "online"};
  for (std::size_t k = 0; k < 2; ++k) {
    const double x0 = m + static_cast<double>(k) * (pw + m);
    const double y0 = h - m;
    const double ph = h - 2 * m;
    svg.addText("text", {{"x", x0}, {"y", m - 15}, {"font-size", 14}},
                dataset + " " + modeNames[k] + ": precision (x) vs recall (y), N_min 0..20");
    svg.add("rect", {{"x", x0}, {"y", m}, {"width", pw}, {"height", ph}, {"fill", "none"}, {"stroke", "black"}});
    for (int t = 0; t <= 4; ++t) {
      const double f = t / 4.0;
      char label[8];
      std::snprintf(label, sizeof label, "%.2f", f);
      svg.addText("text", {{"x", x0 + f * pw - 10}, {"y", y0 + 15}, {"font-size", 10}}, label);
      svg.addText("text", {{"x", x0 - 30}, {"y", y0 - f * ph + 4}, {"font-size", 10}}, label);
    }
    for (std::size_t mi = 0; mi < kMethods; ++mi) {
      report::SvgPoints line;
      for (const PrPoint& p : modes[k]->curves[mi]) {
        if (p.accepted > 0) {
          line.add(x0 + p.precision * pw, y0 - p.recall * ph);
        }
      }
      if (!line.empty()) {
        svg.add("polyline", {{"fill", "none"}, {"stroke", colours[mi]}, {"stroke-width", 2}, {"points", line.str()}});
      }
      svg.addText(
          "text",
          {{"x", x0 + 10}, {"y", m + 16 + 14 * static_cast<double>(mi)}, {"font-size", 12}, {"fill", colours[mi]}},
          std::string("GLAROT-") + kMethodNames[mi]);
    }
  }
  return svg.str();
}

}  // namespace loops
}  // namespace agv
