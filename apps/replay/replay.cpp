#include "replay.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <sstream>
#include <utility>

#include <Eigen/QR>

#include "agv/core/angle.hpp"
#include "agv/falko/falko_detector.hpp"
#include "agv/mapping/corner_mapper.hpp"
#include "agv/mapping/surface_mapper.hpp"
#include "agv/report/svg.hpp"
#include "agv/scan/laser_scan.hpp"

namespace agv {
namespace replay {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = 180.0 / kPi;

std::string fmt(const char* f, double a, double b = 0.0, double c = 0.0, double d = 0.0) {
  char buf[256];
  std::snprintf(buf, sizeof buf, f, a, b, c, d);
  return buf;
}

report::Json statsJson(const ErrorStats& s, double scale) {
  return report::Json{{"count", s.count},
                      {"mean", s.mean * scale},
                      {"median", s.median * scale},
                      {"rms", s.rms * scale},
                      {"max", s.max * scale}};
}

// Clusters the keypoints of every scan, placed in the world with the corrected poses
// (`mapping::CornerMapper`), and freezes the clusters seen often enough into `map` as surveyed
// corners.
std::size_t buildStaticMap(const datasets::CarmenLog& log, std::size_t n, const ReplayOptions& options,
                           LandmarkMap& map) {
  mapping::CornerMapper mapper(options.staticClusterRadius);
  FalkoDetector detector(options.falko);
  auto scan = std::make_unique<LaserScan>();
  auto kps = std::make_unique<FalkoKeypoints>();
  for (std::size_t i = 0; i < n; ++i) {
    (void)log.scans[i].toLaserScan(*scan);
    if (detector.detect(*scan, *kps) != Status::Ok) {
      continue;
    }
    const Pose2d laser = log.scans[i].robotPose.compose(options.laserMounting);
    for (const FalkoKeypoint& k : *kps) {
      if (std::hypot(k.x, k.y) > static_cast<float>(options.localizer.laser.rangeMax)) {
        continue;
      }
      mapper.add(laser.transformPoint(Eigen::Vector2d(static_cast<double>(k.x), static_cast<double>(k.y))));
    }
  }
  mapping::CornerFreezeParams freeze;
  freeze.minSightings = options.staticMinCount;
  freeze.sigma = options.staticSigma;
  freeze.inlierRadius = options.staticInlierRadius;
  freeze.minInlierFraction = options.staticMinInlierFraction;
  freeze.maxScatter = options.staticMaxScatter;
  return mapper.freeze(freeze, map).frozen;
}

/// Scan points of the mapping run (scans [0, n)) placed with the corrected poses, as the surfaces
/// of `field` (`mapping::SurfaceMapper`). False with `error` when there are none or the area does
/// not fit the field's capacity.
bool buildField(const datasets::CarmenLog& log, std::size_t n, const ReplayOptions& options, LikelihoodFieldBase& field,
                std::string& error) {
  const double rangeMax = options.localizer.laser.rangeMax;
  mapping::SurfaceMapper mapper(options.field.resolution);
  auto scan = std::make_unique<LaserScan>();
  for (std::size_t i = 0; i < n; ++i) {
    (void)log.scans[i].toLaserScan(*scan);
    const Pose2d laser = log.scans[i].robotPose.compose(options.laserMounting);
    mapper.beginScan();
    for (std::size_t b = 0; b < scan->size(); ++b) {
      if (!scan->isValid(b) || static_cast<double>(scan->ranges[b]) > rangeMax) {
        continue;
      }
      const double a = static_cast<double>(scan->angle(b));
      const double r = static_cast<double>(scan->ranges[b]);
      mapper.add(laser.transformPoint(Eigen::Vector2d(r * std::cos(a), r * std::sin(a))), laser.translation());
    }
  }
  return mapper.build(options.field, options.fieldMinScans, field, error) == Status::Ok;
}

/// Cells of the replay's likelihood field: 8 M (8 MB), a 140 m x 140 m area at 5 cm.
constexpr std::size_t kReplayFieldCells = std::size_t{8} << 20U;

}  // namespace

ReplayOptions fr079Defaults() {
  ReplayOptions o;
  // Unicycle odometry noise from the raw odometry's own drift on this log (data README, median
  // relative error over 1 m of path: 0.063 m and 2.8 deg): a random walk reaching those one-sigma
  // figures after 1 m, and 0.1 rad^2 per radian turned (0.3 rad = 18 deg sigma after a full turn;
  // the Pioneer's heading error is dominated by turning on the spot).
  o.odometryNoise.translationVariancePerMetre = 0.063 * 0.063;
  o.odometryNoise.rotationVariancePerMetre = (2.8 / kDeg) * (2.8 / kDeg);
  o.odometryNoise.rotationVariancePerRadian = 0.01;
  LaserModel& l = o.localizer.laser;
  l.mounting = o.laserMounting;
  l.rangeMin = 0.1;
  l.rangeMax = 20.0;
  l.angleMin = -kPi / 2.0;
  l.angleMax = kPi / 2.0;
  l.rangeSigma = 0.01;                            // SICK LMS 200: ~1 cm
  l.bearingSigma = 0.5 / kDeg / std::sqrt(12.0);  // 0.5 deg beam spacing, uniform
  l.kindSigma[1] = 0.03;                          // real corners: clutter, partial views
  // The interlock limits of LocalizerParams are an industrial vehicle's (10 cm, 2 deg). The
  // Pioneer's odometry drifts 6 cm and 3 deg per metre (median), so dead reckoning through a
  // stretch without corners crosses them within metres; a bad cycle then stops the map updates
  // and the dynamic map can never catch up. Relaxed to 1 m / 0.5 rad for the replay.
  o.localizer.health.maxPositionSigma = 1.0;
  o.localizer.health.maxHeadingSigma = 0.5;
  // Each fused match's pose no better than its inliers fit (ScanMatchParams::fitScatter): the
  // maps here are built from the corrected poses of a SLAM run, whose own error moves whole
  // surfaces by centimetres, and the logs' rooms change between traversals. Measured over the
  // four corrected logs x seven splits (docs/localization.md, "Fit scatter"); 1.0 was measured too.
  o.localizer.scanMatch.fitScatter = 0.5;
  // A match that overrules the filter (the re-synchronisation) needs half as much support again
  // as one the filter agrees with: fr079's rooms that changed since the mapping run leave twins
  // that fit at 4 cm with 30-40 inliers (docs/localization.md, "Laser odometry: the wider retry").
  o.localizer.scanMatch.resyncMinInliers = 45;
  // The matched/expected check runs with the library defaults; each scan's ranges go to
  // `correct`, so corners hidden behind walls, doors and people are not expected.
  o.map.initialHits = 3;  // a corner seen once survives two missed re-detections
  return o;
}

namespace {

/// Non-negative least squares y = X c over every subset of X's columns (X has at most 3: the
/// subsets are few): the subset fit with all coefficients >= 0 and the smallest residual.
Eigen::Vector3d fitNonNegative(const std::vector<Eigen::Vector3d>& rows, const std::vector<double>& y, int columns) {
  Eigen::Vector3d best = Eigen::Vector3d::Zero();
  double bestCost = std::numeric_limits<double>::infinity();
  for (int mask = 1; mask < (1 << columns); ++mask) {
    std::vector<int> cols;
    for (int c = 0; c < columns; ++c) {
      if ((mask & (1 << c)) != 0) {
        cols.push_back(c);
      }
    }
    Eigen::MatrixXd X(static_cast<Eigen::Index>(rows.size()), static_cast<Eigen::Index>(cols.size()));
    Eigen::VectorXd Y(static_cast<Eigen::Index>(rows.size()));
    for (std::size_t i = 0; i < rows.size(); ++i) {
      for (std::size_t k = 0; k < cols.size(); ++k) {
        X(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(k)) = rows[i](cols[k]);
      }
      Y(static_cast<Eigen::Index>(i)) = y[i];
    }
    const Eigen::VectorXd c = X.colPivHouseholderQr().solve(Y);
    if ((c.array() < 0.0).any() || !c.allFinite()) {
      continue;
    }
    const double cost = (X * c - Y).squaredNorm();
    if (cost < bestCost) {
      bestCost = cost;
      best.setZero();
      for (std::size_t k = 0; k < cols.size(); ++k) {
        best(cols[k]) = c(static_cast<Eigen::Index>(k));
      }
    }
  }
  return best;
}

}  // namespace

UnicycleNoiseParams fitOdometryNoise(const datasets::CarmenLog& log, const std::vector<Pose2d>& inc, std::size_t begin,
                                     std::size_t end, const UnicycleNoiseParams& fallback, std::size_t& steps) {
  std::vector<Eigen::Vector3d> heading;   // [1, |turn|, d] -> e_theta^2
  std::vector<Eigen::Vector3d> position;  // [1, d, 0] -> (e_x^2 + e_y^2) / 2
  std::vector<double> yHeading;
  std::vector<double> yPosition;
  for (std::size_t i = std::max<std::size_t>(begin, 1); i < end && i < inc.size(); ++i) {
    const Pose2d& u = inc[i];
    if (std::hypot(u.x, u.y) < 1e-6 && std::fabs(u.theta) < 1e-6) {
      continue;  // no odometry for this step
    }
    // The regressors from the corrected step: the odometry's own turn carries its error, and a
    // noisy regressor would bias the fit low.
    const Pose2d t = between(log.scans[i - 1].robotPose, log.scans[i].robotPose);
    const double d = std::hypot(t.x, t.y);
    const double turn = std::fabs(normalizeAngle(t.theta));
    const Pose2d e = between(u, t);
    const double eth = normalizeAngle(e.theta);
    if (std::hypot(e.x, e.y) > 1.0 || std::fabs(eth) > 0.5) {
      continue;
    }
    heading.emplace_back(1.0, turn, d);
    yHeading.push_back(eth * eth);
    position.emplace_back(1.0, d, 0.0);
    yPosition.push_back(0.5 * (e.x * e.x + e.y * e.y));
  }
  steps = heading.size();
  if (steps < 20) {
    steps = 0;
    return fallback;
  }
  // The intercepts are the per-step scatter of the corrected poses themselves (a SLAM estimate
  // jitters by centimetres from scan to scan whatever the motion): fitted, then left out.
  const Eigen::Vector3d h = fitNonNegative(heading, yHeading, 3);
  const Eigen::Vector3d p = fitNonNegative(position, yPosition, 2);
  UnicycleNoiseParams n = fallback;
  n.translationVariancePerMetre = p(1);
  n.rotationVariancePerRadian = h(1);
  n.rotationVariancePerMetre = h(2);
  // Nor can the fit resolve an odometry error below that scatter: a model whose variance at the
  // mean step falls below the intercept is raised to it (a fit with no slope left, the odometry's
  // error hidden in the ground truth's jitter, would make the filter trust every step exactly).
  double meanDistance = 0.0;
  double meanTurn = 0.0;
  for (const Eigen::Vector3d& row : heading) {
    meanTurn += row(1) / static_cast<double>(heading.size());
    meanDistance += row(2) / static_cast<double>(heading.size());
  }
  if (meanDistance > 0.0 && p(1) * meanDistance < p(0)) {
    n.translationVariancePerMetre = p(0) / meanDistance;
  }
  const double headingAtMean = h(1) * meanTurn + h(2) * meanDistance;
  if (headingAtMean < h(0) && headingAtMean > 0.0) {
    n.rotationVariancePerRadian *= h(0) / headingAtMean;
    n.rotationVariancePerMetre *= h(0) / headingAtMean;
  } else if (headingAtMean < h(0) && meanTurn > 0.0) {
    n.rotationVariancePerRadian = h(0) / meanTurn;
  }
  return n;
}

namespace {

/// The ground truth (corrected poses), the raw odometry chained from `inc` and the path length of
/// scans [start, n).
void recordTracks(const datasets::CarmenLog& log, std::size_t start, std::size_t n, const std::vector<Pose2d>& inc,
                  ReplayResult& r) {
  r.truth.clear();
  r.odometry.clear();
  r.localizer.clear();
  for (std::size_t i = start; i < n; ++i) {
    r.truth.push_back(log.scans[i].robotPose);
    r.odometry.push_back(i == start ? r.truth[0] : r.odometry.back().compose(inc[i]));
  }
  r.pathLength = 0.0;
  for (std::size_t i = 1; i < r.truth.size(); ++i) {
    r.pathLength += std::hypot(r.truth[i].x - r.truth[i - 1].x, r.truth[i].y - r.truth[i - 1].y);
  }
}

/// The localizer, its map and the corner detector stepped through the scans of one replay, with
/// what the result tallies across scans; the large objects live on the heap.
class ScanReplay {
 public:
  ScanReplay(const datasets::CarmenLog& log, const ReplayOptions& options, const std::vector<Pose2d>& inc,
             ReplayResult& r)
      : log_(log), options_(options), inc_(inc), r_(r), lp_(options.localizer) {
    lp_.laser.mounting = options.laserMounting;
    localizer_ = std::make_unique<Localizer>(lp_);
    FieldRelocalizerParams rp = options.relocalizer;
    rp.match = lp_.scanMatch;
    relocalizer_ = std::make_unique<FieldRelocalizer>(rp);
    map_ = std::make_unique<LandmarkMap>(options.map);
    detector_ = std::make_unique<FalkoDetector>(options.falko);
    p0_(0, 0) = p0_(1, 1) = options.initialSigmaXY * options.initialSigmaXY;
    p0_(2, 2) = options.initialSigmaTheta * options.initialSigmaTheta;
  }
  ScanReplay(const ScanReplay&) = delete;
  ScanReplay& operator=(const ScanReplay&) = delete;
  ~ScanReplay() { closeTrace(); }

  /// The static map and field (when asked), the localizer at the corrected pose of scan `start`
  /// (the first after the mapping run), the trace file.
  bool begin(std::size_t start, std::size_t n, std::string& error) {
    start_ = start;
    r_.staticMap = options_.staticMapFromTruth || start > 0;
    if (options_.staticMapFromTruth) {
      r_.staticCorners = buildStaticMap(log_, n, options_, *map_);
    } else if (start > 0) {
      r_.staticCorners = buildStaticMap(log_, start, options_, *map_);
      if (options_.scanMatching) {
        field_ = std::make_unique<LikelihoodField<kReplayFieldCells>>();
        if (!buildField(log_, start, options_, *field_, error)) {
          return false;
        }
        r_.fieldSurfaceCells = field_->surfacePoints();
        if (options_.mapChanges) {
          if (options_.changes.validate() != Status::Ok) {
            error = "invalid map change parameters";
            return false;
          }
          changes_ = std::make_unique<HallSurfaceMap>(changeMapParams(options_.surface, options_.changes));
          changeDetector_ = std::make_unique<MapChangeDetector>(options_.changes);
          r_.mapChanges = true;
        }
        if (options_.surfaceFallback) {
          fallback_ = std::make_unique<HallSurfaceMap>(options_.surface);
          if (fallback_->params().validate() != Status::Ok) {
            error = "invalid surface map parameters";
            return false;
          }
          r_.surfaceFallback = true;
        }
        r_.fieldWidth = static_cast<double>(field_->width()) * options_.field.resolution;
        r_.fieldHeight = static_cast<double>(field_->height()) * options_.field.resolution;
      }
    } else if (options_.surfaceMap) {
      surface_ = std::make_unique<HallSurfaceMap>(options_.surface);
      if (surface_->params().validate() != Status::Ok) {
        error = "invalid surface map parameters";
        return false;
      }
      lp_.scanMatch = surfaceMapMatching(lp_.scanMatch);
      localizer_ = std::make_unique<Localizer>(lp_);
      r_.surfaceMap = true;
    }
    last_ = Timestamp::fromSeconds(log_.scans[start].timestamp);
    if (options_.coldStart) {
      // No pose: the first scans search the whole field (`coldStartScan`).
      localized_ = false;
      reloc_ = RelocState::Searching;
      r_.coldStart = true;
    } else if (localizer_->reset(last_, r_.truth[0], p0_) != Status::Ok) {
      error = "localizer refused the initial pose";
      return false;
    }
    trace_ = options_.tracePath.empty() ? nullptr : std::fopen(options_.tracePath.c_str(), "w");
    if (trace_ != nullptr) {
      std::fputs(
          "scan,keypoints,used,expected,unmatched,gate,inserted,deleted,flags,sigma_xy,sigma_theta,err_xy,err_theta,"
          "map,match,match_inliers,match_rms,match_d2,correction,heading_correction,match_err_xy,match_err_theta,"
          "window,hypothesis,hypothesis_checked,on_map,lost,true_x,true_y,true_theta,est_x,est_y,est_theta,reloc,"
          "reloc_err_xy,reloc_err_theta,reloc_inliers,reloc_points,reloc_rms,reloc_truth_in_region,reloc_truth_fits,"
          "fallback,fallback_inliers,fallback_rms,fallback_d2,fallback_window,fallback_err_xy,fallback_err_theta\n",
          trace_);
    }
    return true;
  }

  /// Scan `i`: prediction to its stamp (after the first), its corners, the correction, the tally.
  bool replayScan(std::size_t i, std::string& error) {
    Timestamp stamp = Timestamp::fromSeconds(log_.scans[i].timestamp);
    if (!localized_) {
      coldStartScan(i, stamp);
      return true;
    }
    if (i > start_ && !predictTo(i, stamp, error)) {
      return false;
    }
    (void)log_.scans[i].toLaserScan(*scan_);
    detectCorners(stamp);
    r_.keypoints += obs_->points.size();
    const LocalizerHealth& h = correct();
    tally(h);
    if (surface_ && mayExtendSurfaceMap(h)) {
      const SurfaceInsert in = surface_->insert(*surfacePoints_, h.scanPose.compose(lp_.laser.mounting));
      r_.surfaceAdded += in.added;
    }
    if (fallback_) {
      r_.fallbackAttempts += h.fallbackMatch.attempted ? 1U : 0U;
      r_.fallbackFused += h.fallbackMatch.fused ? 1U : 0U;
      if (h.scanMatch.resynced) {
        clearFallback();  // its surfaces were placed with the estimate the resync overruled
      } else if (mayExtendFallbackMap(h)) {
        r_.fallbackPieces += fallback_->insert(*fallbackPoints_, h.scanPose.compose(lp_.laser.mounting)).added;
      }
    }
    if (changes_ && h.scanMatch.fused && !h.scanMatch.softGated && !h.scanMatch.resynced) {
      const Pose2d sensor = h.scanMatch.pose.compose(lp_.laser.mounting);
      if (changeDetector_->select(*allPoints_, sensor, *field_, *changedPoints_) == Status::Ok &&
          !changedPoints_->empty()) {
        r_.changePieces += changes_->insert(*changedPoints_, sensor).added;
      }
    }
    if (h.scanMatch.resynced) {
      ++r_.matchResyncs;
      r_.resyncWrong += isWrongRestart(h.scanMatch.pose, log_.scans[i].robotPose) ? 1U : 0U;
    }
    if (h.lost) {
      ++r_.lostEvents;
      if (options_.resetWhenLost) {
        // Keep the estimate and its covariance (re-opening it would only grow it, cycle after
        // cycle). A dynamic map that no longer matches the pose is dropped and rebuilt from here:
        // without a surveyed map there is nothing else to return to.
        (void)localizer_->reset(stamp, localizer_->pose(), localizer_->covariance());
        if (map_->mode() == MapMode::Dynamic) {
          r_.mapInserted += map_->counters().inserted;  // clear() resets the counters
          r_.mapDeleted += map_->counters().deleted;
          map_->clear();  // the mode stays
          ++r_.mapRestarts;
        }
      }
    }
    if (field_ && options_.fieldRelocalization && options_.resetWhenLost) {
      relocalize(i, stamp, h);
    }
    r_.localizer.push_back(localizer_->pose());
    if (field_) {
      tallyOnMap(i);
    }
    writeTrace(i, h);
    return true;
  }

  void closeTrace() {
    if (trace_ != nullptr) {
      std::fclose(trace_);
      trace_ = nullptr;
    }
  }

  /// The mean test ratio and the map's figures into the result.
  void finish() {
    r_.meanTestRatio = ratioCount_ > 0 ? ratioSum_ / static_cast<double>(ratioCount_) : 0.0;
    r_.mapSize = map_->size();
    r_.mapInserted += map_->counters().inserted;  // plus those of the maps dropped on restarts
    r_.mapDeleted += map_->counters().deleted;
  }

 private:
  /// Predicts to `stamp` (strictly increasing: a repeated logger time is nudged by 1 us) with the
  /// odometry increment of scan `i` (or the ground truth's, as a diagnostic).
  bool predictTo(std::size_t i, Timestamp& stamp, std::string& error) {
    if (!(last_ < stamp)) {
      stamp = last_ + Duration::fromNanoseconds(1000);
    }
    const Pose2d delta =
        options_.truthOdometry ? between(log_.scans[i - 1].robotPose, log_.scans[i].robotPose) : inc_[i];
    const Status st = localizer_->predict(unicycleIncrement(stamp, delta, options_.odometryNoise));
    if (st != Status::Ok) {
      error = std::string("prediction refused at scan ") + std::to_string(i) + ": " + toString(st);
      return false;
    }
    last_ = stamp;
    return true;
  }

  /// Scan `i` of a cold start before its first restart: no pose to predict or correct; the
  /// whole-field search, or the confirmation of its candidate, which restarts the localizer.
  void coldStartScan(std::size_t i, Timestamp& stamp) {
    if (i > start_ && !(last_ < stamp)) {
      stamp = last_ + Duration::fromNanoseconds(1000);  // as predictTo: strictly increasing
    }
    last_ = stamp;
    (void)log_.scans[i].toLaserScan(*scan_);
    obs_->points.clear();
    LocalizerHealth none{};
    none.lost = true;  // no pose yet (the trace's `lost` column)
    relocalize(i, stamp, none);
    r_.localizer.push_back(localized_ ? localizer_->pose() : Pose2d{});  // left out until the restart
    tallyOnMap(i);
    none.lost = !localized_;
    writeTrace(i, none);
  }

  /// Field relocalization of scan `i` (see `ReplayOptions::fieldRelocalization`): a search when
  /// the localizer has just been declared lost (or the last candidate was not confirmed), the
  /// confirmation of a pending candidate otherwise.
  void relocalize(std::size_t i, Timestamp stamp, const LocalizerHealth& h) {
    if (reloc_ == RelocState::Searching && h.scanMatch.fused && !h.lost) {
      reloc_ = RelocState::Idle;  // the tracking found the map again by itself
    }
    if (reloc_ == RelocState::Idle && !h.lost) {
      return;
    }
    scanToMatchPoints(*scan_, *points_);
    const Pose2d& mount = lp_.laser.mounting;
    if (reloc_ == RelocState::Confirming) {
      const Pose2d carried = candidate_.compose(inc_[i]);
      // The window the carry may be off by: its covariance under the odometry noise model.
      const Eigen::Matrix3d carry = unicycleIncrement(stamp, inc_[i], options_.odometryNoise).covariance;
      Pose2d refined;
      if (relocalizer_->confirm(*points_, mount, carried, *field_, carry, refined)) {
        candidate_ = refined;
        traceRelocLabel_ = "confirming";
        traceReloc_.pose = refined;
        confirmation_.add(inc_[i]);
        if (confirmation_.complete(options_.relocConfirmations, options_.relocalizer)) {
          Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
          // The candidate's fit over the confirmations, loosely: the tracking refines it.
          cov(0, 0) = cov(1, 1) = options_.relocConfirmDistance() * options_.relocConfirmDistance() / 4.0;
          cov(2, 2) = options_.relocConfirmAngle() * options_.relocConfirmAngle() / 4.0;
          if (localizer_->reset(stamp, candidate_, cov) == Status::Ok) {
            clearFallback();
            ++r_.relocConfirmed;
            const Pose2d& t = log_.scans[i].robotPose;
            const bool wrong = isWrongRestart(candidate_, t);
            r_.relocWrong += wrong ? 1U : 0U;
            traceRelocLabel_ = "confirmed";
            if (!localized_) {
              localized_ = true;
              r_.coldStartFound = true;
              r_.coldStartScans = i - start_;
              r_.coldStartWrong = wrong;
            }
          }
          reloc_ = RelocState::Idle;
        }
        return;
      }
      ++r_.relocUnconfirmed;
      traceRelocLabel_ = "unconfirmed";  // then a new search: the label below overrides it
      reloc_ = RelocState::Searching;
    }
    const auto t0 = std::chrono::steady_clock::now();
    RelocRegion region;
    if (options_.relocRadius > 0.0 && localized_) {  // a cold start has no estimate: the whole field
      region.x = localizer_->pose().x;
      region.y = localizer_->pose().y;
      const Eigen::Matrix3d& P = localizer_->covariance();
      const double sigma = std::sqrt(std::max(P(0, 0), P(1, 1)));
      region.radius = std::max(options_.relocRadius, 3.0 * sigma);
    }
    const FieldRelocResult f = relocalizer_->localize(*points_, mount, *field_, region);
    r_.relocSeconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ++r_.relocSearches;
    r_.relocAmbiguous += f.outcome == FieldRelocOutcome::Ambiguous ? 1U : 0U;
    r_.relocWeak += f.outcome == FieldRelocOutcome::WeakSupport ? 1U : 0U;
    traceReloc_ = f;
    traceRelocLabel_ = f.outcome == FieldRelocOutcome::Found         ? "found"
                       : f.outcome == FieldRelocOutcome::WeakSupport ? "weak"
                       : f.outcome == FieldRelocOutcome::Ambiguous   ? "ambiguous"
                                                                     : "none";
    if (trace_ != nullptr) {
      // For the trace: whether the true pose lay inside the searched region and whether the
      // relocalizer would accept it there (its confirmation from the true pose: the fit it demands).
      const Pose2d& t = log_.scans[i].robotPose;
      Pose2d refined;
      traceTruthInRegion_ = region.radius <= 0.0 || std::hypot(t.x - region.x, t.y - region.y) <= region.radius;
      traceTruthFits_ = relocalizer_->confirm(*points_, mount, t, *field_, refined);
    }
    if (f.outcome == FieldRelocOutcome::Found) {
      ++r_.relocFound;
      candidate_ = f.pose;
      confirmation_.restart();
      reloc_ = RelocState::Confirming;
    } else {
      reloc_ = RelocState::Searching;
    }
  }

  /// A restart of the filter (relocalization, resync) at `pose` that the corrected pose `truth`
  /// says is wrong: more than 0.3 m or 5 deg off (the tracking cannot pull it back).
  static bool isWrongRestart(const Pose2d& pose, const Pose2d& truth) {
    return std::hypot(pose.x - truth.x, pose.y - truth.y) > 0.3 ||
           std::fabs(normalizeAngle(pose.theta - truth.theta)) > deg2rad(5.0);
  }

  /// Drops the fallback surface map (when there is one) at a restart of the filter.
  void clearFallback() {
    if (fallback_) {
      fallback_->clear();
      ++r_.fallbackClears;
    }
  }

  /// The localizer's correction of the current scan: against the mapping run's field, the surface
  /// map of the earlier scans (with the beams it takes: within its range), or the corners alone.
  const LocalizerHealth& correct() {
    if (field_ && (changes_ || fallback_)) {
      // All valid beams, less those on the changes since the mapping run (seen from the prior).
      scanToMatchPoints(*scan_, *allPoints_);
      const MatchPoints* toMatch = allPoints_.get();
      if (changes_) {
        std::size_t dropped = 0;
        (void)changeDetector_->keepUnchanged(*allPoints_, localizer_->pose().compose(lp_.laser.mounting), *field_,
                                             changes_->field(), *keptPoints_, dropped);
        r_.changedPointsDropped += dropped;
        toMatch = keptPoints_.get();
      }
      if (!fallback_) {
        return localizer_->correct(*obs_, *scan_, *toMatch, *map_, *field_);
      }
      fallback_->takenBeams(*scan_, *fallbackPoints_);
      return localizer_->correct(*obs_, *scan_, *toMatch, *map_, *field_, *fallbackPoints_, fallback_->field());
    }
    if (field_) {
      return localizer_->correct(*obs_, *scan_, *map_, *field_);
    }
    if (!surface_) {
      return localizer_->correct(*obs_, *scan_, *map_);
    }
    surface_->takenBeams(*scan_, *surfacePoints_);
    return surface_->field().built() ? localizer_->correct(*obs_, *scan_, *surfacePoints_, *map_, surface_->field())
                                     : localizer_->correct(*obs_, *scan_, *map_);
  }

  /// Scan `i`'s entry of `ReplayResult::onMap` (the current scan at its corrected pose).
  void tallyOnMap(std::size_t i) {
    const bool on = onMap(log_.scans[i].robotPose);
    r_.onMap.push_back(on);
    r_.onMapScans += on ? 1U : 0U;
  }

  /// Whether the current scan is on the map at the vehicle pose `truth` (`ReplayResult::onMap`).
  bool onMap(const Pose2d& truth) const {
    const ScanMatchParams& mp = lp_.scanMatch;
    const Pose2d laser = truth.compose(lp_.laser.mounting);
    std::size_t points = 0;
    std::size_t inliers = 0;
    Eigen::Vector2d last(1e300, 1e300);
    for (std::size_t b = 0; b < scan_->size(); ++b) {
      if (!scan_->isValid(b)) {
        continue;
      }
      const double a = static_cast<double>(scan_->angle(b));
      const double r = static_cast<double>(scan_->ranges[b]);
      const Eigen::Vector2d w = laser.transformPoint(Eigen::Vector2d(r * std::cos(a), r * std::sin(a)));
      if ((w - last).norm() < mp.pointSpacing) {
        continue;
      }
      last = w;
      ++points;
      const FieldSample f = field_->sample(w.x(), w.y());
      inliers += f.inside && std::fabs(f.distance) < mp.inlierDistance ? 1U : 0U;
    }
    return points > 0 && static_cast<double>(inliers) >= options_.onMapFraction * static_cast<double>(points);
  }

  /// The FALKO corners of the current scan as the observations at `stamp`.
  void detectCorners(Timestamp stamp) {
    obs_->stamp = stamp;
    obs_->kindsDetected = landmarkKindBit(LandmarkKind::Corner);
    obs_->points.clear();
    if (detector_->detect(*scan_, *kps_) == Status::Ok) {
      for (const FalkoKeypoint& k : *kps_) {
        (void)obs_->points.push_back(
            PointObservation{static_cast<double>(k.x), static_cast<double>(k.y), LandmarkKind::Corner});
      }
    }
  }

  /// One cycle's health summed into the result.
  void tally(const LocalizerHealth& h) {
    r_.used += h.used;
    r_.fixCycles += hasFlag(h.flags, LocalizerFlag::NoFix) ? 0U : 1U;
    r_.noFixCycles += hasFlag(h.flags, LocalizerFlag::NoFix) ? 1U : 0U;
    r_.lostCycles += h.lost ? 1U : 0U;
    if (h.scanMatch.attempted) {
      ++r_.matchAttempts;
      r_.matchFused += h.scanMatch.fused ? 1U : 0U;
      r_.matchGated += !h.scanMatch.fused && h.scanMatch.status == Status::Rejected ? 1U : 0U;
      r_.matchRefused += !h.scanMatch.fused && h.scanMatch.status != Status::Rejected ? 1U : 0U;
    }
    r_.rejectedGate += h.rejectedGate;
    r_.rejectedAmbiguous += h.rejectedAmbiguous;
    r_.rejectedDuplicate += h.rejectedDuplicate;
    r_.rejectedUpdate += h.rejectedUpdate;
    r_.rejectedField += h.rejectedField;
    r_.badCycles += hasFlag(h.flags, LocalizerFlag::BadCycle) ? 1U : 0U;
    r_.fieldContradicted += hasFlag(h.flags, LocalizerFlag::FieldContradicted) ? 1U : 0U;
    r_.expected += h.expectedInView;
    r_.occluded += h.occluded + h.noReturn;
    if (h.used > 0) {
      ratioSum_ += h.meanTestRatio;
      ++ratioCount_;
    }
  }

  /// The CSV line of scan `i` (when tracing).
  void writeTrace(std::size_t i, const LocalizerHealth& h) {
    if (trace_ == nullptr) {
      return;
    }
    const Pose2d& e = r_.localizer.back();
    const Pose2d& t = log_.scans[i].robotPose;
    std::fprintf(trace_,
                 "%zu,%zu,%u,%u,%u,%u,%u,%u,%#x,%.4f,%.4f,%.4f,%.4f,%zu,%s,%u,%.4f,%.2f,%.4f,%.5f,%.4f,%.4f,%.2f,%u,%d",
                 i, obs_->points.size(), unsigned{h.used}, unsigned{h.expectedInView}, unsigned{h.unmatched},
                 unsigned{h.rejectedGate}, unsigned{h.inserted}, unsigned{h.deleted}, h.flags, h.positionSigma,
                 h.headingSigma, std::hypot(e.x - t.x, e.y - t.y), normalizeAngle(e.theta - t.theta), map_->size(),
                 h.scanMatch.attempted ? toString(h.scanMatch.status) : "-", unsigned{h.scanMatch.inliers},
                 h.scanMatch.rmsResidual, h.scanMatch.mahalanobis2, h.correction, h.headingCorrection,
                 std::hypot(h.scanMatch.pose.x - t.x, h.scanMatch.pose.y - t.y),
                 normalizeAngle(h.scanMatch.pose.theta - t.theta), h.scanMatch.window,
                 unsigned{h.scanMatch.consecutiveGated}, h.scanMatch.hypothesisChecked ? 1 : 0);
    // Appended columns (the ones above keep their order): whether the scan is on the map at its
    // true pose, the poses, and this scan's field relocalization (its best refined match).
    const FieldRelocResult& f = traceReloc_;
    std::fprintf(trace_, ",%d,%d,%.4f,%.4f,%.5f,%.4f,%.4f,%.5f,%s,%.4f,%.4f,%u,%u,%.4f,%d,%d",
                 !r_.onMap.empty() && r_.onMap.back() ? 1 : 0, h.lost ? 1 : 0, t.x, t.y, t.theta, e.x, e.y, e.theta,
                 traceRelocLabel_, std::hypot(f.pose.x - t.x, f.pose.y - t.y), normalizeAngle(f.pose.theta - t.theta),
                 unsigned{f.inliers}, unsigned{f.points}, f.rmsResidual, traceTruthInRegion_ ? 1 : 0,
                 traceTruthFits_ ? 1 : 0);
    // The fallback's match (`surfaceFallback`): "fused", the matcher's status, or "-".
    const ScanMatchHealth& b = h.fallbackMatch;
    std::fprintf(trace_, ",%s,%u,%.4f,%.2f,%.3f,%.4f,%.5f\n",
                 b.fused ? "fused" : (b.attempted ? toString(b.status) : "-"), unsigned{b.inliers}, b.rmsResidual,
                 b.mahalanobis2, b.window, std::hypot(b.pose.x - t.x, b.pose.y - t.y),
                 normalizeAngle(b.pose.theta - t.theta));
    traceRelocLabel_ = "-";
    traceTruthInRegion_ = false;
    traceTruthFits_ = false;
    traceReloc_ = FieldRelocResult{};
  }

  const datasets::CarmenLog& log_;
  const ReplayOptions& options_;
  const std::vector<Pose2d>& inc_;
  ReplayResult& r_;
  LocalizerParams lp_;
  std::unique_ptr<Localizer> localizer_;
  std::unique_ptr<LandmarkMap> map_;
  std::unique_ptr<FalkoDetector> detector_;
  std::unique_ptr<LikelihoodField<kReplayFieldCells>> field_;
  std::unique_ptr<HallSurfaceMap> surface_;
  std::unique_ptr<HallSurfaceMap> fallback_;  // with surfaceFallback: the field's fallback
  std::unique_ptr<MatchPoints> fallbackPoints_ = std::make_unique<MatchPoints>();
  std::unique_ptr<MatchPoints> surfacePoints_ = std::make_unique<MatchPoints>();  // beams within its range
  std::size_t start_ = 0;
  std::unique_ptr<LaserScan> scan_ = std::make_unique<LaserScan>();
  std::unique_ptr<FalkoKeypoints> kps_ = std::make_unique<FalkoKeypoints>();
  std::unique_ptr<ScanObservations> obs_ = std::make_unique<ScanObservations>();
  enum class RelocState : std::uint8_t { Idle, Searching, Confirming };
  RelocState reloc_ = RelocState::Idle;
  FieldRelocResult traceReloc_{};      // this scan's search, for the trace
  const char* traceRelocLabel_ = "-";  // "-": no search this scan
  bool traceTruthInRegion_ = false;    // the search's region held the true position
  bool traceTruthFits_ = false;        // the relocalizer accepts the true pose (its confirmation)
  std::unique_ptr<FieldRelocalizer> relocalizer_;
  std::unique_ptr<MatchPoints> points_ = std::make_unique<MatchPoints>();
  // With `mapChanges`: the changes since the mapping run, and the scan's points (all, those kept
  // for the match, those on changes).
  std::unique_ptr<HallSurfaceMap> changes_;
  std::unique_ptr<MapChangeDetector> changeDetector_;
  std::unique_ptr<MatchPoints> allPoints_ = std::make_unique<MatchPoints>();
  std::unique_ptr<MatchPoints> keptPoints_ = std::make_unique<MatchPoints>();
  std::unique_ptr<MatchPoints> changedPoints_ = std::make_unique<MatchPoints>();
  Pose2d candidate_{};
  FieldConfirmation confirmation_;  // the pending candidate's confirming scans and their motion
  bool localized_ = true;           // false during a cold start until its first restart
  Eigen::Matrix3d p0_ = Eigen::Matrix3d::Zero();
  Timestamp last_;
  double ratioSum_ = 0.0;
  std::size_t ratioCount_ = 0;
  std::FILE* trace_ = nullptr;
};

}  // namespace

namespace {

/// `ReplayResult::onRoute` of the localized scans against the mapping run's scans [0, mapping).
void markRoute(const datasets::CarmenLog& log, std::size_t mapping, double distance, ReplayResult& r) {
  r.onRouteDistance = distance;
  r.onRoute.assign(r.truth.size(), false);
  r.onRouteScans = 0;
  for (std::size_t k = 0; k < r.truth.size(); ++k) {
    const Eigen::Vector2d p = r.truth[k].translation();
    for (std::size_t m = 0; m < mapping; ++m) {
      if ((log.scans[m].robotPose.translation() - p).norm() <= distance) {
        r.onRoute[k] = true;
        ++r.onRouteScans;
        break;
      }
    }
  }
}

/// The laser odometry's steps of scans [0, n) (`ReplayOptions::scanOdometry`): `ScanOdometry`
/// from the first corrected pose over the wheel steps `inc`; its figures into `r`.
void laserOdometrySteps(const datasets::CarmenLog& log, std::size_t start, std::size_t n, const ReplayOptions& options,
                        const std::vector<Pose2d>& inc, std::vector<Pose2d>& steps, ReplayResult& r) {
  SurfaceMapParams surface;  // the default map, moved as the replay's surface maps are
  surface.recentreByShift = options.surface.recentreByShift;
  surface.gridOffsetX = options.surface.gridOffsetX;
  surface.gridOffsetY = options.surface.gridOffsetY;
  mapping::ScanOdometry odometry(options.laserMounting, ScanMatchParams{}, surface, options.scanOdometryRetry);
  auto scan = std::make_unique<LaserScan>();
  std::vector<Pose2d> track(n);
  steps.assign(n, Pose2d{});
  for (std::size_t i = 0; i < n; ++i) {
    (void)log.scans[i].toLaserScan(*scan);
    if (i == 0) {
      odometry.start(*scan, log.scans[0].robotPose);
      track[0] = odometry.pose();
      continue;
    }
    track[i] = odometry.next(*scan, inc[i], options.scanOdometryWindow.covariance(inc[i]));
    steps[i] = between(track[i - 1], track[i]);
  }
  r.scanOdometry = true;
  r.scanOdometryMatched = odometry.matched();
  r.scanOdometryScans = odometry.scans();
  r.scanOdometryRetry = options.scanOdometryRetry;
  r.scanOdometryRetried = odometry.retried();
  std::vector<Pose2d> truth;
  std::vector<Pose2d> localized;
  for (std::size_t i = start; i < n; ++i) {
    truth.push_back(log.scans[i].robotPose);
    localized.push_back(track[i]);
  }
  r.scanOdometryRelative = datasets::relativeError(truth, localized, options.segmentLength);
}

/// With a cold start: the trajectories and the on-map mask of scans [start, n) cut to those from
/// the first restart on (none when there was none), the odometry chained from its corrected pose
/// (from where the vehicle first knew where it was, as the localizer); the time and path before.
void cutToColdStartFix(const datasets::CarmenLog& log, std::size_t start, std::size_t n, const std::vector<Pose2d>& inc,
                       ReplayResult& r) {
  if (!r.coldStartFound) {
    r.coldStartScans = r.truth.size();  // none localized
  }
  const std::size_t k = std::min(r.coldStartScans, r.truth.size());
  r.coldStartSeconds = log.scans[std::min(start + k, n - 1)].timestamp - log.scans[start].timestamp;
  r.coldStartPath = 0.0;
  for (std::size_t i = 1; i <= k && i < r.truth.size(); ++i) {
    r.coldStartPath += std::hypot(r.truth[i].x - r.truth[i - 1].x, r.truth[i].y - r.truth[i - 1].y);
  }
  const auto from = static_cast<std::ptrdiff_t>(k);
  std::vector<Pose2d> localized(r.localizer.begin() + from, r.localizer.end());
  std::vector<bool> onMap(r.onMap.begin() + std::min(from, static_cast<std::ptrdiff_t>(r.onMap.size())), r.onMap.end());
  recordTracks(log, start + k, n, inc, r);
  r.localizer = std::move(localized);
  r.onMap = std::move(onMap);
  r.onMapScans = static_cast<std::size_t>(std::count(r.onMap.begin(), r.onMap.end(), true));
}

}  // namespace

bool replayLog(const datasets::CarmenLog& log, const ReplayOptions& optionsIn, ReplayResult& r, std::string& error) {
  if (!datasets::checkCorrectedLog(log, error)) {
    return false;
  }
  ReplayOptions options = optionsIn;
  if (options.laserFromLog) {
    options.laserMounting.x = log.frontLaserOffset;
    r.laserXLine = log.frontLaserOffsetLine;
  }
  r.laserX = options.laserMounting.x;
  std::size_t n = log.scans.size();
  if (options.maxScans != 0) {
    n = std::min(n, options.maxScans);
  }
  if (n < 2) {
    error = "fewer than 2 scans";
    return false;
  }
  std::size_t start = 0;
  if (options.mapFraction != 0.0) {
    if (!(options.mapFraction > 0.0 && options.mapFraction < 1.0)) {
      error = "the mapping fraction must lie in (0, 1)";
      return false;
    }
    start = static_cast<std::size_t>(options.mapFraction * static_cast<double>(n));
    if (start < 1 || n - start < 2) {
      error = "the mapping run leaves fewer than 2 scans to localize";
      return false;
    }
  }
  if (options.coldStart && (start == 0 || !options.scanMatching || !options.fieldRelocalization)) {
    error = "a cold start needs a mapping run (--map-fraction) with its field and the field relocalization";
    return false;
  }
  r.mappingScans = start;
  r.scans = n - start;
  r.surfaceShift = options.surface.recentreByShift;
  r.gridOffsetX = options.surface.gridOffsetX;
  r.gridOffsetY = options.surface.gridOffsetY;
  r.fitScatter = options.localizer.scanMatch.fitScatter;
  r.duration = log.scans[n - 1].timestamp - log.scans[start].timestamp;
  std::vector<Pose2d> inc;
  r.zeroIncrements = datasets::odometryIncrements(log, n, inc);
  recordTracks(log, start, n, inc, r);

  // The prediction's steps: the wheels', or the laser odometry's.
  std::vector<Pose2d> steps;
  const bool laserSteps = options.scanOdometry && start > 0;  // map-less runs keep the wheels'
  if (laserSteps) {
    laserOdometrySteps(log, start, n, options, inc, steps, r);
  }
  const std::vector<Pose2d>& predict = laserSteps ? steps : inc;
  ReplayOptions used = options;
  if (start > 0 && options.fitOdometryNoise) {
    used.odometryNoise = fitOdometryNoise(log, predict, 1, start, options.odometryNoise, r.odometryNoiseSteps);
  }
  r.odometryNoise = used.odometryNoise;
  ScanReplay replay(log, used, predict, r);
  if (!replay.begin(start, n, error)) {
    return false;
  }
  const auto t0 = std::chrono::steady_clock::now();
  for (std::size_t i = start; i < n; ++i) {
    if (!replay.replayScan(i, error)) {
      return false;
    }
  }
  replay.closeTrace();
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  replay.finish();
  if (r.coldStart) {
    cutToColdStartFix(log, start, n, inc, r);
  }
  r.odometryRelative = datasets::relativeError(r.truth, r.odometry, options.segmentLength);
  r.localizerRelative = datasets::relativeError(r.truth, r.localizer, options.segmentLength);
  r.odometryAbsolute = datasets::absoluteError(r.truth, r.odometry);
  r.localizerAbsolute = datasets::absoluteError(r.truth, r.localizer);
  if (!r.onMap.empty()) {
    r.localizerOnMap = datasets::absoluteErrorOf(r.truth, r.localizer, r.onMap);
    r.odometryOnMap = datasets::absoluteErrorOf(r.truth, r.odometry, r.onMap);
    markRoute(log, start, options.onRouteDistance, r);
    r.localizerOnRoute = datasets::absoluteErrorOf(r.truth, r.localizer, r.onRoute);
    r.odometryOnRoute = datasets::absoluteErrorOf(r.truth, r.odometry, r.onRoute);
  }
  return true;
}

std::string resultText(const ReplayResult& r) {
  std::ostringstream o;
  o << r.log << ": " << r.scans << " scans, " << fmt("%.1f m of path, %.1f s", r.pathLength, r.duration) << ", "
    << r.zeroIncrements << " zero odometry increments; laser " << fmt("%.3f m", r.laserX)
    << " ahead of the robot centre ("
    << (r.laserXLine > 0 ? "log line " + std::to_string(r.laserXLine) : std::string("not in the log: 0 or --laser-x"))
    << ")\n";
  if (r.scanOdometry) {
    o << "laser odometry (the prediction's steps): " << r.scanOdometryMatched << " of " << r.scanOdometryScans
      << " scans matched; "
      << fmt("per metre over the localized scans %.4f m / %.2f deg (mean)\n", r.scanOdometryRelative.position.mean,
             r.scanOdometryRelative.heading.mean * kDeg);
  }
  o << "odometry noise model"
    << (r.odometryNoiseSteps > 0 ? " (fitted on " + std::to_string(r.odometryNoiseSteps) + " mapping-run steps)"
                                 : std::string(" (given)"))
    << fmt(": position %.4f m^2/m, heading %.5f rad^2/m + %.5f rad^2/rad\n",
           r.odometryNoise.translationVariancePerMetre, r.odometryNoise.rotationVariancePerMetre,
           r.odometryNoise.rotationVariancePerRadian);
  o << "relative error per metre of path (" << r.odometryRelative.position.count << " segments)\n";
  o << "                 position mean / median [m]   heading mean / median [deg]\n";
  o << fmt("  raw odometry   %.4f / %.4f              %.2f / %.2f\n", r.odometryRelative.position.mean,
           r.odometryRelative.position.median, r.odometryRelative.heading.mean * kDeg,
           r.odometryRelative.heading.median * kDeg);
  o << fmt("  localizer      %.4f / %.4f              %.2f / %.2f\n", r.localizerRelative.position.mean,
           r.localizerRelative.position.median, r.localizerRelative.heading.mean * kDeg,
           r.localizerRelative.heading.median * kDeg);
  o << "absolute trajectory error (start aligned)\n";
  o << "                 position rms / median / max [m]   heading rms / max [deg]\n";
  o << fmt("  raw odometry   %.3f / %.3f / %.3f", r.odometryAbsolute.position.rms, r.odometryAbsolute.position.median,
           r.odometryAbsolute.position.max)
    << fmt("               %.2f / %.2f\n", r.odometryAbsolute.heading.rms * kDeg,
           r.odometryAbsolute.heading.max * kDeg);
  o << fmt("  localizer      %.3f / %.3f / %.3f", r.localizerAbsolute.position.rms, r.localizerAbsolute.position.median,
           r.localizerAbsolute.position.max)
    << fmt("               %.2f / %.2f\n", r.localizerAbsolute.heading.rms * kDeg,
           r.localizerAbsolute.heading.max * kDeg);
  o << "localizer: " << r.keypoints << " keypoints, " << r.used << " used, " << r.fixCycles << " cycles with a fix, "
    << r.badCycles << " bad cycles (" << r.fieldContradicted << " contradicting the field), " << r.lostEvents
    << " lost events (" << r.mapRestarts << " map restarts); rejected gate " << r.rejectedGate << ", ambiguous "
    << r.rejectedAmbiguous << ", duplicate " << r.rejectedDuplicate << ", update " << r.rejectedUpdate << ", field "
    << r.rejectedField << fmt("; mean test ratio %.3f\n", r.meanTestRatio);
  o << "in view: " << r.expected << " landmark-cycles expected, " << r.occluded
    << " inside the view limits but hidden or without a return\n";
  if (r.mappingScans > 0) {
    o << "mapping run: the first " << r.mappingScans << " scans -> " << r.staticCorners << " static corners";
    if (r.fieldSurfaceCells > 0) {
      o << ", likelihood field " << fmt("%.1f m x %.1f m", r.fieldWidth, r.fieldHeight) << " with "
        << r.fieldSurfaceCells << " surface cells";
    }
    o << "; localized: the " << r.scans << " scans after it\n";
    if (!r.onMap.empty()) {
      o << "on the map (" << r.onMapScans << " of " << r.scans << " scans): localizer "
        << fmt("%.3f / %.3f / %.3f m rms / median / max, ", r.localizerOnMap.position.rms,
               r.localizerOnMap.position.median, r.localizerOnMap.position.max)
        << fmt("%.2f / %.2f deg rms / max", r.localizerOnMap.heading.rms * kDeg, r.localizerOnMap.heading.max * kDeg)
        << fmt("; odometry %.3f m rms, %.2f deg rms\n", r.odometryOnMap.position.rms,
               r.odometryOnMap.heading.rms * kDeg);
      o << "on the mapping run's route (" << r.onRouteScans << " of " << r.scans << " scans): localizer "
        << fmt("%.3f / %.3f / %.3f m rms / median / max, ", r.localizerOnRoute.position.rms,
               r.localizerOnRoute.position.median, r.localizerOnRoute.position.max)
        << fmt("%.2f / %.2f deg rms / max", r.localizerOnRoute.heading.rms * kDeg,
               r.localizerOnRoute.heading.max * kDeg)
        << fmt("; odometry %.3f m rms, %.2f deg rms\n", r.odometryOnRoute.position.rms,
               r.odometryOnRoute.heading.rms * kDeg);
    }
    o << "scan matching: " << r.matchAttempts << " attempts, " << r.matchFused << " fused, " << r.matchGated
      << " gated, " << r.matchRefused << " refused by the matcher, " << r.matchResyncs << " resyncs (" << r.resyncWrong
      << " wrong); " << r.noFixCycles << " cycles without a fix, " << r.lostCycles << " cycles lost\n";
    o << "field relocalization: " << r.relocSearches << " searches (" << fmt("%.2f s", r.relocSeconds) << "), "
      << r.relocFound << " found, " << r.relocAmbiguous << " ambiguous, " << r.relocWeak << " weak; "
      << r.relocConfirmed << " confirmed restarts (" << r.relocWrong << " wrong), " << r.relocUnconfirmed
      << " unconfirmed\n";
    if (r.coldStart) {
      o << "cold start (no pose given): "
        << (r.coldStartFound
                ? "first restart after " + std::to_string(r.coldStartScans) + " scans" +
                      fmt(" (%.1f s, %.1f m driven), ", r.coldStartSeconds, r.coldStartPath) +
                      (r.coldStartWrong ? "WRONG" : "right") + " (within 0.3 m / 5 deg); the figures above start there"
                : std::string("no pose found in ") + std::to_string(r.coldStartScans) + " scans")
        << "\n";
    }
    if (r.surfaceFallback) {
      o << "surface fallback (off the map): " << r.fallbackAttempts << " matches, " << r.fallbackFused << " fused, "
        << r.fallbackPieces << " surface pieces, " << r.fallbackClears << " clears at restarts\n";
    }
  }
  if (r.surfaceMap) {
    o << "surface map (the earlier scans' surfaces): " << r.surfaceAdded
      << " surface pieces; scan matching: " << r.matchAttempts << " attempts, " << r.matchFused << " fused, "
      << r.matchGated << " gated, " << r.matchRefused << " refused by the matcher\n";
  }
  o << (r.staticMap ? "static map (built from the corrected poses): " : "dynamic map: ") << r.mapSize
    << " landmarks at the end, " << r.mapInserted << " inserted, " << r.mapDeleted << " deleted; replay "
    << fmt("%.1f s\n", r.seconds);
  return o.str();
}

report::Json resultJson(const ReplayResult& r) {
  using report::Json;
  const auto errors = [](const ErrorStats& position, const ErrorStats& heading) {
    return Json{{"position_m", statsJson(position, 1.0)}, {"heading_deg", statsJson(heading, kDeg)}};
  };
  Json j = Json{
      {"log", r.log},
      {"scans", r.scans},
      {"path_length_m", r.pathLength},
      {"duration_s", r.duration},
      {"zero_increments", r.zeroIncrements},
      {"odometry_per_metre", errors(r.odometryRelative.position, r.odometryRelative.heading)},
      {"localizer_per_metre", errors(r.localizerRelative.position, r.localizerRelative.heading)},
      {"odometry_absolute", errors(r.odometryAbsolute.position, r.odometryAbsolute.heading)},
      {"localizer_absolute", errors(r.localizerAbsolute.position, r.localizerAbsolute.heading)},
      {"static_map", r.staticMap},
      {"mapping_run",
       {{"scans", r.mappingScans},
        {"static_corners", r.staticCorners},
        {"field_surface_cells", r.fieldSurfaceCells},
        {"field_width_m", r.fieldWidth},
        {"field_height_m", r.fieldHeight}}},
      {"on_map",
       {{"scans", r.onMapScans},
        {"localizer", errors(r.localizerOnMap.position, r.localizerOnMap.heading)},
        {"odometry", errors(r.odometryOnMap.position, r.odometryOnMap.heading)}}},
      {"on_route",
       {{"scans", r.onRouteScans},
        {"distance_m", r.onRouteDistance},
        {"localizer", errors(r.localizerOnRoute.position, r.localizerOnRoute.heading)},
        {"odometry", errors(r.odometryOnRoute.position, r.odometryOnRoute.heading)}}},
      {"scan_matching",
       {{"fit_scatter", r.fitScatter},
        {"attempts", r.matchAttempts},
        {"fused", r.matchFused},
        {"gated", r.matchGated},
        {"refused", r.matchRefused},
        {"resyncs", r.matchResyncs},
        {"resync_wrong", r.resyncWrong},
        {"map_changes",
         {{"enabled", r.mapChanges}, {"pieces", r.changePieces}, {"points_dropped", r.changedPointsDropped}}},
        {"surface_fallback",
         {{"enabled", r.surfaceFallback},
          {"attempts", r.fallbackAttempts},
          {"fused", r.fallbackFused},
          {"pieces", r.fallbackPieces},
          {"clears", r.fallbackClears}}}}},
      {"field_relocalization",
       {{"searches", r.relocSearches},
        {"found", r.relocFound},
        {"ambiguous", r.relocAmbiguous},
        {"weak", r.relocWeak},
        {"confirmed", r.relocConfirmed},
        {"wrong", r.relocWrong},
        {"unconfirmed", r.relocUnconfirmed},
        {"seconds", r.relocSeconds}}},
      {"cold_start",
       {{"enabled", r.coldStart},
        {"found", r.coldStartFound},
        {"scans_before_fix", r.coldStartScans},
        {"seconds_to_fix", r.coldStartSeconds},
        {"path_to_fix_m", r.coldStartPath},
        {"wrong", r.coldStartWrong}}},
      {"surface_map", {{"enabled", r.surfaceMap}, {"pieces", r.surfaceAdded}, {"recentre_by_shift", r.surfaceShift}}},
      {"scan_odometry",
       {{"enabled", r.scanOdometry},
        {"matched", r.scanOdometryMatched},
        {"scans", r.scanOdometryScans},
        {"per_metre", errors(r.scanOdometryRelative.position, r.scanOdometryRelative.heading)}}},
      {"laser_x_m", r.laserX},
      {"odometry_noise",
       {{"fitted_steps", r.odometryNoiseSteps},
        {"translation_variance_per_m", r.odometryNoise.translationVariancePerMetre},
        {"rotation_variance_per_m", r.odometryNoise.rotationVariancePerMetre},
        {"rotation_variance_per_rad", r.odometryNoise.rotationVariancePerRadian}}},
      {"localizer",
       {{"keypoints", r.keypoints},
        {"used", r.used},
        {"fix_cycles", r.fixCycles},
        {"bad_cycles", r.badCycles},
        {"field_contradicted", r.fieldContradicted},
        {"lost_events", r.lostEvents},
        {"lost_cycles", r.lostCycles},
        {"no_fix_cycles", r.noFixCycles},
        {"map_restarts", r.mapRestarts},
        {"rejected_gate", r.rejectedGate},
        {"rejected_ambiguous", r.rejectedAmbiguous},
        {"rejected_duplicate", r.rejectedDuplicate},
        {"rejected_update", r.rejectedUpdate},
        {"rejected_field", r.rejectedField},
        {"mean_test_ratio", r.meanTestRatio},
        {"map_size", r.mapSize},
        {"map_inserted", r.mapInserted},
        {"map_deleted", r.mapDeleted},
        {"expected_in_view", r.expected},
        {"occluded_or_no_return", r.occluded}}},
      {"replay_seconds", r.seconds}};
  // Appended (the keys above keep their order): the surface maps' grid, the laser odometry's retry.
  j["surface_map"]["grid_offset_m"] = Json::array({r.gridOffsetX, r.gridOffsetY});
  j["scan_odometry"]["retry"] = r.scanOdometryRetry;
  j["scan_odometry"]["retried"] = r.scanOdometryRetried;
  return j;
}

std::string trajectorySvg(const ReplayResult& r) {
  double minX = 1e300;
  double minY = 1e300;
  double maxX = -1e300;
  double maxY = -1e300;
  for (const auto* track : {&r.truth, &r.odometry, &r.localizer}) {
    for (const Pose2d& p : *track) {
      minX = std::min(minX, p.x);
      minY = std::min(minY, p.y);
      maxX = std::max(maxX, p.x);
      maxY = std::max(maxY, p.y);
    }
  }
  const double margin = 1.0;
  const double scale = 800.0 / std::max(1.0, std::max(maxX - minX, maxY - minY) + 2.0 * margin);
  const double w = (maxX - minX + 2.0 * margin) * scale;
  const double h = (maxY - minY + 2.0 * margin) * scale + 60.0;
  report::SvgDocument svg(w, h);
  const auto line = [&](const std::vector<Pose2d>& t, const char* colour) {
    report::SvgPoints pts;
    for (const Pose2d& p : t) {
      pts.add((p.x - minX + margin) * scale, (maxY - p.y + margin) * scale + 60.0);
    }
    svg.add("polyline", {{"fill", "none"}, {"stroke", colour}, {"stroke-width", "1"}, {"points", pts.str()}});
  };
  line(r.odometry, "#d62728");
  line(r.truth, "#000000");
  line(r.localizer, "#1f77b4");
  svg.addText("text", {{"x", "10"}, {"y", "18"}, {"font-family", "sans-serif"}, {"font-size", "13"}},
              r.log + " (" + std::to_string(r.scans) + " scans)");
  svg.open("text", {{"x", "10"}, {"y", "34"}, {"font-family", "sans-serif"}, {"font-size", "12"}});
  svg.addText("tspan", {{"fill", "#000000"}}, "corrected poses");
  svg.text(", ");
  svg.addText("tspan", {{"fill", "#d62728"}}, "raw odometry");
  svg.text(", ");
  svg.addText("tspan", {{"fill", "#1f77b4"}}, "localizer (dynamic FALKO map)");
  svg.close();
  svg.addText("text", {{"x", "10"}, {"y", "50"}, {"font-family", "sans-serif"}, {"font-size", "12"}},
              fmt("per metre (mean): odometry %.3f m / %.2f deg, localizer %.3f m / %.2f deg",
                  r.odometryRelative.position.mean, r.odometryRelative.heading.mean * kDeg,
                  r.localizerRelative.position.mean, r.localizerRelative.heading.mean * kDeg));
  svg.add("line", {{"x1", "10"},
                   {"y1", h - 10},
                   {"x2", 10 + 5.0 * scale},
                   {"y2", h - 10},
                   {"stroke", "black"},
                   {"stroke-width", "2"}});
  svg.addText("text", {{"x", "14"}, {"y", h - 14}, {"font-family", "sans-serif"}, {"font-size", "11"}}, "5 m");
  return svg.str();
}

}  // namespace replay
}  // namespace agv
