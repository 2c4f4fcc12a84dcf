// Loop-closure benchmarks on the fr079 log (FLIRTLib, 1464 scans), FALKO keypoints with the thesis
// parameters:
//   BM_Glarot/fr079           one iteration = one scan's GLAROT signature searched against the
//                             database of all fr079 signatures for 10 candidates (k nearest by SL1).
//   BM_LoopAssociation/<m>    one iteration = one scan associated with its 10 GLAROT candidates
//                             (itself excluded) by m = cg (correspondence graph, all pairs), ah
//                             (affine Hough, thesis grid) or ransac; 10 association calls.
// Iterations cycle over every scan, so the reported time is the mean per scan (the unit of the
// thesis' Table 4.1: GLAROT 12.2 ms, CG 16.3 ms, AH 356.9 ms, RANSAC 49.4 ms on an i7-3630QM).
// Counters: ok = associations per scan that returned Ok; correct = those whose transform agrees
// with the ground truth within 0.5 m and 10 deg; refused_capacity = calls refused for size.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "agv/datasets/carmen_log.hpp"
#include "agv/falko/falko_detector.hpp"
#include "agv/loop/affine_hough.hpp"
#include "agv/loop/correspondence_graph.hpp"
#include "agv/loop/glarot_database.hpp"
#include "agv/loop/ransac_association.hpp"

namespace {

constexpr std::size_t kCandidates = 10;

struct LoopSet {
  std::vector<std::vector<Eigen::Vector2f>> points;  // keypoints per scan (sensor frame)
  std::vector<agv::Pose2d> truth;                    // ground-truth laser pose per scan
  std::unique_ptr<agv::GlarotDatabase<2048>> db;
  std::vector<agv::GlarotSignature> signatures;
  std::vector<std::vector<std::uint32_t>> candidates;  // 10 GLAROT candidates per scan, itself excluded
};

const LoopSet& fr079() {
  static LoopSet set;
  static bool loaded = false;
  if (loaded) {
    return set;
  }
  loaded = true;
  agv::datasets::CarmenLog log;
  std::string err;
  const std::string path = std::string(AGV_SHARED_DATA_DIR) + "/laser2d/fr079/fr079.log.gz";
  if (!agv::datasets::readCarmenLog(path, log, err)) {
    std::fprintf(stderr, "bench_loop: %s\n", err.c_str());
    std::abort();
  }
  auto detector = std::make_unique<agv::FalkoDetector>();
  auto keypoints = std::make_unique<agv::FalkoKeypoints>();
  auto scan = std::make_unique<agv::LaserScan>();
  set.db = std::make_unique<agv::GlarotDatabase<2048>>();
  for (const auto& s : log.scans) {
    if (!s.hasGroundTruth) {
      continue;
    }
    (void)s.toLaserScan(*scan);
    (void)detector->detect(*scan, *keypoints);
    std::vector<Eigen::Vector2f> pts;
    for (const agv::FalkoKeypoint& k : *keypoints) {
      if (pts.size() < agv::kMaxLoopPoints) {
        pts.emplace_back(k.x, k.y);
      }
    }
    agv::GlarotSignature sig;
    (void)agv::computeGlarot(agv::Span<const Eigen::Vector2f>(pts.data(), pts.size()), agv::GlarotParams{}, sig);
    (void)set.db->insert(sig, s.groundTruth);
    set.points.push_back(std::move(pts));
    set.truth.push_back(s.groundTruth);
    set.signatures.push_back(sig);
  }
  agv::GlarotCandidates found;
  for (std::size_t i = 0; i < set.signatures.size(); ++i) {
    agv::GlarotQuery q;
    q.k = kCandidates;
    q.excludeIndex = i;
    (void)set.db->query(set.signatures[i], q, found);
    std::vector<std::uint32_t> c;
    for (const agv::GlarotCandidate& x : found) {
      c.push_back(x.index);
    }
    set.candidates.push_back(std::move(c));
  }
  return set;
}

void BM_Glarot(benchmark::State& state) {
  const LoopSet& set = fr079();
  agv::GlarotCandidates found;
  agv::GlarotQuery q;
  q.k = kCandidates;
  std::size_t i = 0;
  for (auto _ : state) {
    const agv::Status st = set.db->query(set.signatures[i], q, found);
    benchmark::DoNotOptimize(st);
    benchmark::DoNotOptimize(found.data());
    i = i + 1 == set.signatures.size() ? 0 : i + 1;
  }
  state.counters["scans"] = static_cast<double>(set.signatures.size());
}

template <typename Matcher>
void runAssociation(benchmark::State& state) {
  const LoopSet& set = fr079();
  auto matcher = std::make_unique<Matcher>();
  auto out = std::make_unique<agv::PointAssociation>();
  const auto view = [&](std::size_t k) {
    return agv::Span<const Eigen::Vector2f>(set.points[k].data(), set.points[k].size());
  };
  // Outcome over one pass of every scan (not timed).
  double ok = 0.0;
  double correct = 0.0;
  double refused = 0.0;
  for (std::size_t i = 0; i < set.points.size(); ++i) {
    for (std::uint32_t c : set.candidates[i]) {
      const agv::Status st = matcher->match(view(c), view(i), *out);
      refused += st == agv::Status::CapacityExceeded ? 1.0 : 0.0;
      if (st == agv::Status::Ok) {
        ok += 1.0;
        const agv::Pose2d rel = agv::between(set.truth[c], set.truth[i]);
        const double dt = std::hypot(rel.x - out->transform.x, rel.y - out->transform.y);
        const double dr = std::fabs(agv::angleDiff(rel.theta, out->transform.theta));
        correct += (dt < 0.5 && dr < 0.17453292519943295) ? 1.0 : 0.0;
      }
    }
  }
  std::size_t i = 0;
  for (auto _ : state) {
    for (std::uint32_t c : set.candidates[i]) {
      const agv::Status st = matcher->match(view(c), view(i), *out);
      benchmark::DoNotOptimize(st);
      benchmark::DoNotOptimize(out->transform);
    }
    i = i + 1 == set.points.size() ? 0 : i + 1;
  }
  const double scans = static_cast<double>(set.points.size());
  state.counters["ok"] = ok / scans;
  state.counters["correct"] = correct / scans;
  state.counters["refused_capacity"] = refused / scans;
}

const int kRegistered = [] {
  benchmark::RegisterBenchmark("BM_Glarot/fr079", BM_Glarot)->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("BM_LoopAssociation/cg", runAssociation<agv::CorrespondenceGraphMatcher>)
      ->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("BM_LoopAssociation/ah", runAssociation<agv::AffineHoughMatcher>)
      ->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("BM_LoopAssociation/ransac", runAssociation<agv::RansacMatcher>)
      ->Unit(benchmark::kMicrosecond);
  return 0;
}();

}  // namespace
