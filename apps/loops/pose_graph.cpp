#include "pose_graph.hpp"

#include <ceres/ceres.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <set>
#include <utility>

#include "agv/core/angle.hpp"
#include "agv/datasets/trajectory_error.hpp"
#include "agv/loop/correspondence_graph.hpp"
#include "agv/loop/glarot_database.hpp"
#include "agv/mapping/scan_odometry.hpp"
#include "agv/report/svg.hpp"
#include "loops.hpp"

namespace agv {
namespace loops {
namespace {

template <typename T>
T wrapAngle(const T& a) {
  const T twoPi(2.0 * M_PI);
  return a - twoPi * ceres::floor((a + T(M_PI)) / twoPi);
}

// Residual of a relative-pose measurement between two poses (x, y, theta), whitened.
struct RelativePoseError {
  RelativePoseError(const Pose2d& z, double sigmaXY, double sigmaTheta)
      : x(z.x), y(z.y), theta(z.theta), wXY(1.0 / sigmaXY), wTheta(1.0 / sigmaTheta) {}

  template <typename T>
  bool operator()(const T* a, const T* b, T* r) const {
    const T c = ceres::cos(a[2]);
    const T s = ceres::sin(a[2]);
    const T dx = b[0] - a[0];
    const T dy = b[1] - a[1];
    r[0] = T(wXY) * (c * dx + s * dy - T(x));
    r[1] = T(wXY) * (-s * dx + c * dy - T(y));
    r[2] = T(wTheta) * wrapAngle(b[2] - a[2] - T(theta));
    return true;
  }

  double x, y, theta, wXY, wTheta;
};

struct Edge {
  std::size_t from = 0;
  std::size_t to = 0;
  Pose2d z{};
  double sigmaXY = 0.0;
  double sigmaTheta = 0.0;
  bool robust = false;
};

double whitenedSquared(const Edge& e, const std::vector<std::array<double, 3>>& p) {
  const RelativePoseError f(e.z, e.sigmaXY, e.sigmaTheta);
  double r[3];
  (void)f(p[e.from].data(), p[e.to].data(), r);
  return r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
}

// Optimises the nodes 0..n-1 (node 0 fixed) over the edges between them; `robust`: the loop edges
// through a Cauchy loss.
void optimiseOnce(const std::vector<Edge>& odometry, const std::vector<Edge>& loops, std::size_t n,
                  std::vector<std::array<double, 3>>& p, bool robust) {
  ceres::Problem::Options po;
  po.loss_function_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  const auto add = [&](const Edge& e) {
    if (e.to >= n || e.from >= n) {
      return;
    }
    auto* cost = new ceres::AutoDiffCostFunction<RelativePoseError, 3, 3, 3>(
        new RelativePoseError(e.z, e.sigmaXY, e.sigmaTheta));
    problem.AddResidualBlock(cost, robust && e.robust ? new ceres::CauchyLoss(1.0) : nullptr, p[e.from].data(),
                             p[e.to].data());
  };
  for (const Edge& e : odometry) {
    add(e);
  }
  for (const Edge& e : loops) {
    add(e);
  }
  if (!problem.HasParameterBlock(p[0].data())) {
    return;
  }
  problem.SetParameterBlockConstant(p[0].data());
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  so.max_num_iterations = 200;
  so.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
}

// Least squares first: from the odometry's start a true loop closing a long cycle has a residual
// of hundreds of sigmas, where the Cauchy loss would give it no weight; the loops reaching here
// passed the consistency gates. Then the Cauchy loss from that solution.
void optimise(const std::vector<Edge>& odometry, const std::vector<Edge>& loops, std::size_t n,
              std::vector<std::array<double, 3>>& p) {
  optimiseOnce(odometry, loops, n, p, false);
  optimiseOnce(odometry, loops, n, p, true);
}

Pose2d toPose(const std::array<double, 3>& a) {
  return Pose2d{a[0], a[1], normalizeAngle(a[2])};
}

bool wrongByTruth(const Pose2d& z, const Pose2d& truthFrom, const Pose2d& truthTo) {
  const Pose2d e = between(between(truthFrom, truthTo), z);
  return std::hypot(e.x, e.y) > 0.5 || std::fabs(normalizeAngle(e.theta)) > 0.17453292519943295;
}

// Valid beam endpoints of a scan in its laser frame.
std::vector<Eigen::Vector2d> scanPoints(const datasets::LogScan& s) {
  std::vector<Eigen::Vector2d> pts;
  for (std::size_t b = 0; b < s.ranges.size(); ++b) {
    const double range = static_cast<double>(s.ranges[b]);
    if (!(range > 0.0) || range >= static_cast<double>(s.maxRange)) {
      continue;
    }
    const double a = static_cast<double>(s.angleMin) + static_cast<double>(b) * static_cast<double>(s.angleIncrement);
    pts.emplace_back(range * std::cos(a), range * std::sin(a));
  }
  return pts;
}

// Fraction of the second scan's points that land, moved by `t` (second laser pose in the first's
// frame), within about `cell` of a point of the first scan (grid cells dilated by one).
double overlap(const std::vector<Eigen::Vector2d>& first, const std::vector<Eigen::Vector2d>& second, const Pose2d& t,
               double cell) {
  if (second.empty()) {
    return 0.0;
  }
  std::set<std::pair<long, long>> occupied;
  for (const Eigen::Vector2d& p : first) {
    const long cx = std::lround(p.x() / cell);
    const long cy = std::lround(p.y() / cell);
    for (long dx = -1; dx <= 1; ++dx) {
      for (long dy = -1; dy <= 1; ++dy) {
        occupied.insert({cx + dx, cy + dy});
      }
    }
  }
  const double c = std::cos(t.theta);
  const double s = std::sin(t.theta);
  std::size_t hits = 0;
  for (const Eigen::Vector2d& p : second) {
    const double x = t.x + c * p.x() - s * p.y();
    const double y = t.y + s * p.x() + c * p.y();
    hits += occupied.count({std::lround(x / cell), std::lround(y / cell)}) != 0 ? 1U : 0U;
  }
  return static_cast<double>(hits) / static_cast<double>(second.size());
}

// Standard deviations of an odometry edge of increment `inc`: a constant plus a part per metre
// travelled (and, for the heading, per radian turned).
mapping::StepSigmas odometrySigmas(const MappingOptions& o) {
  return mapping::StepSigmas{o.odoSigmaXY, o.odoSigmaXYPerM, o.odoSigmaTheta, o.odoSigmaThetaPerM,
                             o.odoSigmaThetaPerRad};
}

double odometrySigmaXY(const MappingOptions& o, const Pose2d& inc) {
  return odometrySigmas(o).sigmaXY(inc);
}

double odometrySigmaTheta(const MappingOptions& o, const Pose2d& inc) {
  return odometrySigmas(o).sigmaTheta(inc);
}

// A loop found by the correspondence graph, waiting for a partner.
struct Hypothesis {
  Edge edge;
  std::size_t pairs = 0;
  double overlap = 0.0;
  bool paired = false;
};

}  // namespace

bool mapOnline(const datasets::CarmenLog& log, const MappingOptions& o, MappingResult& r, std::string& error) {
  r = MappingResult{};
  if (!datasets::checkCorrectedLog(log, error)) {
    return false;
  }
  const auto t0 = std::chrono::steady_clock::now();
  const std::size_t n = o.maxScans == 0 ? log.scans.size() : std::min(o.maxScans, log.scans.size());
  if (n < 2) {
    error = "fewer than 2 scans";
    return false;
  }
  if (n > kMaxDatabaseScans) {
    error = "more than " + std::to_string(kMaxDatabaseScans) + " scans; use --map-max-scans";
    return false;
  }
  ScanSelection selection;
  selection.maxScans = n;
  ScanFeatures features;
  if (!extractFeatures(log, selection, features, error)) {
    return false;
  }
  if (features.points.size() != n) {
    error = "a scan has no corrected pose";
    return false;
  }
  r.scans = n;
  r.laserX = log.frontLaserOffset;
  const Pose2d mount{log.frontLaserOffset, 0.0, 0.0};
  std::vector<Pose2d> inc;
  r.zeroIncrements = datasets::odometryIncrements(log, n, inc);
  for (std::size_t i = 0; i < n; ++i) {
    r.truth.push_back(log.scans[i].robotPose);
    r.odometry.push_back(i == 0 ? r.truth[0] : r.odometry[i - 1].compose(inc[i]));
  }
  // The front end: the raw steps corrected by scan matching, searched over the odometry edges'
  // sigmas; from here on the increments are the front end's.
  r.scanMatching = o.scanMatching;
  r.frontEnd = r.odometry;
  if (o.scanMatching) {
    std::vector<Eigen::Matrix3d> covariances(n, Eigen::Matrix3d::Zero());
    for (std::size_t i = 1; i < n; ++i) {
      covariances[i] = odometrySigmas(o).covariance(inc[i]);
    }
    r.scansMatched = mapping::scanMatchedTrack(features.scans, mount, r.truth[0], inc, covariances, r.frontEnd);
    for (std::size_t i = 1; i < n; ++i) {
      inc[i] = between(r.frontEnd[i - 1], r.frontEnd[i]);
    }
  }
  std::vector<double> travel(n, 0.0);
  for (std::size_t i = 1; i < n; ++i) {
    travel[i] = travel[i - 1] + std::hypot(inc[i].x, inc[i].y);
  }
  if (o.submapScans == 0) {
    error = "the submap needs at least 1 scan";
    return false;
  }
  // Keypoints (and signature) of each scan's submap: its own keypoints and those of the previous
  // submapScans - 1 scans, moved into its laser frame by the front end; newest first, one of each
  // pair closer than the FALKO suppression radius, at most kMaxLoopPoints.
  std::vector<std::vector<Eigen::Vector2f>> points(n);
  std::vector<GlarotSignature> signatures(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Pose2d laserI = r.frontEnd[i].compose(mount);
    for (std::size_t k = 0; k < o.submapScans && k <= i; ++k) {
      addSubmapPoints(features.points[i - k], between(laserI, r.frontEnd[i - k].compose(mount)),
                      selection.falko.nmsRadius, kMaxLoopPoints, points[i]);
    }
    (void)computeGlarot(Span<const Eigen::Vector2f>(points[i].data(), points[i].size()), GlarotParams{}, signatures[i]);
  }

  std::vector<Edge> odoEdges;
  for (std::size_t i = 1; i < n; ++i) {
    odoEdges.push_back(Edge{i - 1, i, inc[i], odometrySigmaXY(o, inc[i]), odometrySigmaTheta(o, inc[i]), false});
  }
  std::vector<Edge> loopEdges;
  std::vector<std::size_t> loopPairs;
  std::vector<std::array<double, 3>> est(n);
  est[0] = {r.truth[0].x, r.truth[0].y, r.truth[0].theta};

  auto db = std::make_unique<GlarotDatabase<kMaxDatabaseScans>>();
  auto cg = std::make_unique<CorrespondenceGraphMatcher>();
  auto assoc = std::make_unique<PointAssociation>();
  GlarotCandidates found;
  std::vector<Hypothesis> pending;
  bool dirty = false;
  std::size_t lastOptimised = 0;
  const auto accept = [&](const Hypothesis& h) {
    loopEdges.push_back(h.edge);
    loopPairs.push_back(h.pairs);
    dirty = true;
  };

  for (std::size_t i = 0; i < n; ++i) {
    if (i > 0) {
      est[i] = {0.0, 0.0, 0.0};
      const Pose2d p = toPose(est[i - 1]).compose(inc[i]);
      est[i] = {p.x, p.y, p.theta};
    }
    GlarotQuery q;
    q.k = o.candidates;
    q.excludeRecentTravel = o.excludeTravel;
    if (db->size() > 0 && db->query(signatures[i], q, found) == Status::Ok) {
      Hypothesis best;
      double bestRms = 0.0;
      for (const GlarotCandidate& c : found) {
        const auto& a = points[c.index];
        const auto& b = points[i];
        if (cg->match(Span<const Eigen::Vector2f>(a.data(), a.size()), Span<const Eigen::Vector2f>(b.data(), b.size()),
                      *assoc) != Status::Ok) {
          continue;
        }
        const std::size_t pairs = assoc->pairs.size();
        if (assoc->rms > o.maxRms || pairs < best.pairs || (pairs == best.pairs && assoc->rms >= bestRms)) {
          continue;
        }
        const double ov =
            overlap(scanPoints(log.scans[c.index]), scanPoints(log.scans[i]), assoc->transform, o.overlapCell);
        if (ov >= o.minOverlap) {
          best.overlap = ov;
          best.pairs = pairs;
          bestRms = assoc->rms;
          best.edge.from = c.index;
          best.edge.to = i;
          // Laser transform -> robot transform: mount (+) T (+) mount^-1.
          best.edge.z = mount.compose(assoc->transform).compose(mount.inverse());
        }
      }
      if (best.pairs >= o.minPairs) {
        ++r.hypotheses;
        if (o.traceHypotheses) {
          std::fprintf(stderr,
                       "loop hypothesis: scan %zu -> %zu, %zu pairs, overlap %.3f, wrong by the corrected poses: %d\n",
                       best.edge.from, i, best.pairs, best.overlap,
                       wrongByTruth(best.edge.z, r.truth[best.edge.from], r.truth[i]) ? 1 : 0);
        }
        best.edge.sigmaXY = o.loopSigmaXY;
        best.edge.sigmaTheta = o.loopSigmaTheta;
        best.edge.robust = true;
        r.hypothesesWrong += wrongByTruth(best.edge.z, r.truth[best.edge.from], r.truth[i]) ? 1U : 0U;
        // Gate 1: agreement with the estimate within the uncertainty the odometry accumulated along
        // the chain from the reference scan.
        const double d = travel[i] - travel[best.edge.from];
        const Pose2d e = between(between(toPose(est[best.edge.from]), toPose(est[i])), best.edge.z);
        const double sXY = o.gateXY + o.gateXYPerM * d;
        const double sTh = std::min(M_PI, o.gateTheta + o.gateThetaPerM * d);
        if (std::hypot(e.x, e.y) > 3.0 * sXY || std::fabs(normalizeAngle(e.theta)) > 3.0 * sTh) {
          ++r.rejectedGate;
        } else {
          // Gate 2: a partner among the pending hypotheses of the last `window` scans.
          const Pose2d implied = toPose(est[best.edge.from]).compose(best.edge.z);
          for (Hypothesis& h : pending) {
            const Pose2d impliedH = toPose(est[h.edge.from]).compose(h.edge.z);
            const Pose2d d2 = between(between(impliedH, implied), between(toPose(est[h.edge.to]), toPose(est[i])));
            const double dab = travel[i] - travel[h.edge.to];
            if (std::hypot(d2.x, d2.y) < o.pairXY + o.pairXYPerM * dab &&
                std::fabs(normalizeAngle(d2.theta)) < o.pairTheta + o.pairThetaPerM * dab) {
              if (!h.paired) {
                h.paired = true;
                accept(h);
              }
              best.paired = true;
            }
          }
          if (best.paired) {
            accept(best);
          }
          pending.push_back(best);
        }
      }
    }
    // Hypotheses out of the window: unpaired ones are rejected.
    for (auto it = pending.begin(); it != pending.end();) {
      if (it->edge.to + o.window < i + 1) {
        r.rejectedUnpaired += it->paired ? 0U : 1U;
        it = pending.erase(it);
      } else {
        ++it;
      }
    }
    if (dirty && i >= lastOptimised + o.optimiseEvery) {
      optimise(odoEdges, loopEdges, i + 1, est);
      ++r.optimisations;
      lastOptimised = i;
      dirty = false;
    }
    (void)db->insert(signatures[i], r.frontEnd[i]);
  }
  for (const Hypothesis& h : pending) {
    r.rejectedUnpaired += h.paired ? 0U : 1U;
  }
  optimise(odoEdges, loopEdges, n, est);
  ++r.optimisations;
  // Final check: loops the optimised graph cannot explain are dropped, then one more optimisation.
  std::vector<Edge> kept;
  std::vector<std::size_t> keptPairs;
  for (std::size_t k = 0; k < loopEdges.size(); ++k) {
    if (whitenedSquared(loopEdges[k], est) > o.chi2Final) {
      ++r.rejectedFinal;
    } else {
      kept.push_back(loopEdges[k]);
      keptPairs.push_back(loopPairs[k]);
    }
  }
  if (kept.size() != loopEdges.size()) {
    optimise(odoEdges, kept, n, est);
    ++r.optimisations;
  }
  for (std::size_t k = 0; k < kept.size(); ++k) {
    LoopEdge e{kept[k].from, kept[k].to, kept[k].z, keptPairs[k],
               wrongByTruth(kept[k].z, r.truth[kept[k].from], r.truth[kept[k].to])};
    r.acceptedWrong += e.wrong ? 1U : 0U;
    r.loops.push_back(e);
  }
  r.loopsAccepted = kept.size();
  r.loopsRejected = r.rejectedGate + r.rejectedUnpaired + r.rejectedFinal;
  for (const auto& p : est) {
    r.optimised.push_back(toPose(p));
  }
  // First poses coincide (odometry starts at truth[0], node 0 is fixed there): no further alignment.
  const datasets::AbsoluteError odo = datasets::absoluteError(r.truth, r.odometry);
  const datasets::AbsoluteError front = datasets::absoluteError(r.truth, r.frontEnd);
  const datasets::AbsoluteError opt = datasets::absoluteError(r.truth, r.optimised);
  r.odometryAteM = odo.position.rms;
  r.frontEndAteM = front.position.rms;
  r.optimisedAteM = opt.position.rms;
  r.odometryAteDeg = odo.heading.rms * 180.0 / M_PI;
  r.frontEndAteDeg = front.heading.rms * 180.0 / M_PI;
  r.optimisedAteDeg = opt.heading.rms * 180.0 / M_PI;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return true;
}

report::Json mappingJson(const MappingResult& r) {
  report::Json j = report::Json::object();
  j["odometry_ate_m"] = r.odometryAteM;
  j["optimised_ate_m"] = r.optimisedAteM;
  j["odometry_ate_deg"] = r.odometryAteDeg;
  j["optimised_ate_deg"] = r.optimisedAteDeg;
  j["front_end"] = r.scanMatching ? "scan_matching" : "odometry";
  j["front_end_ate_m"] = r.frontEndAteM;
  j["front_end_ate_deg"] = r.frontEndAteDeg;
  j["scans_matched"] = r.scansMatched;
  j["loops_accepted"] = r.loopsAccepted;
  j["loops_rejected"] = r.loopsRejected;
  j["scans"] = r.scans;
  j["zero_odometry_increments"] = r.zeroIncrements;
  j["hypotheses"] = r.hypotheses;
  j["hypotheses_wrong"] = r.hypothesesWrong;
  j["accepted_wrong"] = r.acceptedWrong;
  j["rejected_gate"] = r.rejectedGate;
  j["rejected_unpaired"] = r.rejectedUnpaired;
  j["rejected_final"] = r.rejectedFinal;
  j["optimisations"] = r.optimisations;
  j["seconds"] = r.seconds;
  return j;
}

std::string mapSvg(const std::string& dataset, const datasets::CarmenLog& log, const MappingResult& r) {
  // Scan points on a 0.1 m grid (one mark per occupied cell) at each trajectory, same scale.
  struct Panel {
    const char* title;
    const std::vector<Pose2d>* track;
    double ateM;
    double ateDeg;
  };
  std::vector<Panel> panels{{"raw odometry", &r.odometry, r.odometryAteM, r.odometryAteDeg}};
  if (r.scanMatching) {
    panels.push_back({"scan matching", &r.frontEnd, r.frontEndAteM, r.frontEndAteDeg});
  }
  panels.push_back({"pose graph (Ceres)", &r.optimised, r.optimisedAteM, r.optimisedAteDeg});
  const double cell = 0.10;
  const Pose2d mount{r.laserX, 0.0, 0.0};
  std::vector<std::set<std::pair<long, long>>> cells(panels.size());
  double minX = 1e9;
  double minY = 1e9;
  double maxX = -1e9;
  double maxY = -1e9;
  for (std::size_t k = 0; k < panels.size(); ++k) {
    for (std::size_t i = 0; i < r.scans; ++i) {
      const datasets::LogScan& s = log.scans[i];
      const Pose2d laser = (*panels[k].track)[i].compose(mount);
      for (std::size_t b = 0; b < s.ranges.size(); b += 2) {
        const double range = static_cast<double>(s.ranges[b]);
        if (!(range > 0.0) || range >= static_cast<double>(s.maxRange)) {
          continue;
        }
        const double a = laser.theta + static_cast<double>(s.angleMin) +
                         static_cast<double>(b) * static_cast<double>(s.angleIncrement);
        const double x = laser.x + range * std::cos(a);
        const double y = laser.y + range * std::sin(a);
        cells[k].insert({std::lround(x / cell), std::lround(y / cell)});
        minX = std::min(minX, x);
        minY = std::min(minY, y);
        maxX = std::max(maxX, x);
        maxY = std::max(maxY, y);
      }
    }
  }
  const double panel = 600.0;
  const double margin = 30.0;
  const double scale = panel / std::max(1.0, std::max(maxX - minX, maxY - minY));
  const double count = static_cast<double>(panels.size());
  report::SvgDocument svg(count * panel + (count + 1) * margin, panel + 2 * margin + 20,
                          {{"font-family", "sans-serif"}});
  for (std::size_t k = 0; k < panels.size(); ++k) {
    const double ox = margin + static_cast<double>(k) * (panel + margin);
    const double oy = margin + 20 + panel;
    char title[160];
    std::snprintf(title, sizeof title, "%s %s: ATE %.2f m / %.1f deg", dataset.c_str(), panels[k].title, panels[k].ateM,
                  panels[k].ateDeg);
    svg.addText("text", {{"x", ox}, {"y", margin}, {"font-size", 14}}, title);
    std::string path;
    for (const auto& c : cells[k]) {
      const double x = ox + (static_cast<double>(c.first) * cell - minX) * scale;
      const double y = oy - (static_cast<double>(c.second) * cell - minY) * scale;
      path += "M" + report::svgNumber(x) + " " + report::svgNumber(y) + "h1";
    }
    svg.add("path", {{"d", path}, {"stroke", "black"}, {"stroke-width", 1}});
    report::SvgPoints line;
    for (const Pose2d& p : *panels[k].track) {
      line.add(ox + (p.x - minX) * scale, oy - (p.y - minY) * scale);
    }
    svg.add("polyline", {{"fill", "none"}, {"stroke", "#d62728"}, {"stroke-width", 1}, {"points", line.str()}});
  }
  return svg.str();
}

}  // namespace loops
}  // namespace agv
