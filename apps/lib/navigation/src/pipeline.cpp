#include "agv/nav/pipeline.hpp"

#include <cmath>
#include <cstdio>
#include <initializer_list>

#include "agv/core/fixed_vector.hpp"
#include "agv/falko/falko_detector.hpp"
#include "agv/localization/map_changes.hpp"
#include "agv/localization/sweep_motion.hpp"
#include "agv/loop/global_localizer.hpp"

namespace agv::nav {
namespace {
/// The localizer's parameters: the configured ones, with the surface map's matching settings when
/// the sweeps are matched against it.
LocalizerParams localizerParams(const PipelineParams& p) noexcept {
  LocalizerParams l = p.localizer;
  if (p.observations.surfaceMap) {
    l.scanMatch = surfaceMapMatching(l.scanMatch);
  }
  return l;
}
}  // namespace

Status PipelineParams::validate() const noexcept {
  for (const Status s :
       {kinematics.validate(), odometryNoise.validate(), localizer.validate(), agv::validate(falko),
        observations.surfaceMap || observations.mapChanges || observations.surfaceFallback ? surface.validate()
                                                                                           : Status::Ok,
        observations.mapChanges ? changes.validate() : Status::Ok}) {
    if (s != Status::Ok) {
      return s;
    }
  }
  if (!std::isfinite(setPosePositionStdDev) || !std::isfinite(setPoseHeadingStdDev)) {
    return Status::NonFiniteInput;
  }
  if (setPosePositionStdDev < 0.0 || setPoseHeadingStdDev < 0.0 || publishPeriod.ns < 0 || maxSamplesPerCycle == 0 ||
      maxCommandsPerCycle == 0) {
    return Status::InvalidArgument;
  }
  const RelocalizationParams& r = relocalization;
  if (!std::isfinite(r.positionStdDev) || !std::isfinite(r.headingStdDev)) {
    return Status::NonFiniteInput;
  }
  GlobalLocalizerParams search = r.search;
  search.laserMount = localizer.laser.mounting;
  if (!isValid(search) || !(r.positionStdDev > 0.0) || !(r.headingStdDev > 0.0) || r.relocalizedHold.ns < 0 ||
      r.confirm.scansToConfirm == 0) {
    return Status::InvalidArgument;
  }
  if (!std::isfinite(r.fieldRegionRadius)) {
    return Status::NonFiniteInput;
  }
  if (r.fieldPosesPerSweep == 0 || r.fieldConfirmSweeps == 0 || r.fieldRegionRadius < 0.0) {
    return Status::InvalidArgument;
  }
  return r.field.validate();
}

const char* toString(PipelineState state) noexcept {
  switch (state) {
    case PipelineState::Unconfigured:
      return "unconfigured";
    case PipelineState::Inactive:
      return "inactive";
    case PipelineState::Active:
      return "active";
    case PipelineState::Fault:
      return "fault";
  }
  return "?";
}

struct Pipeline::Impl {
  Impl(const PipelineParams& p, LandmarkMap& m, const PipelineDevices& d)
      : params(p),
        map(m),
        encoders(d.encoders),
        laser(d.laser),
        plc(d.plc),
        clock(d.clock),
        odometry(p.kinematics, p.odometryNoise),
        localizer(std::make_unique<Localizer>(localizerParams(p))),
        detector(std::make_unique<FalkoDetector>(p.falko)),
        keypoints(std::make_unique<FalkoKeypoints>()),
        observations(std::make_unique<ScanObservations>()),
        measurement(std::make_unique<hal::LaserMeasurement>()),
        corners(std::make_unique<FixedVector<Pose2d::Vector2, kMaxCorners>>()) {
    GlobalLocalizerParams search = p.relocalization.search;
    search.laserMount = p.localizer.laser.mounting;
    globalLocalizer = std::make_unique<GlobalLocalizer>(search);
    confirmer = std::make_unique<RelocConfirmer>(p.relocalization.confirm);
    if (p.observations.surfaceMap || p.observations.surfaceFallback) {
      surface = std::make_unique<HallSurfaceMap>(p.surface);
      fallbackPoints = std::make_unique<MatchPoints>();
    }
    if (p.observations.mapChanges) {
      changes = std::make_unique<HallSurfaceMap>(changeMapParams(p.surface, p.changes));
      changeDetector = std::make_unique<MapChangeDetector>(p.changes);
      changePoints = std::make_unique<MatchPoints>();
      unchangedPoints = std::make_unique<MatchPoints>();
    }
  }

  /// Drops the surface map (when there is one): a new pose may not fit the surfaces placed with
  /// the old one.
  void clearSurfaces() noexcept {
    if (surface) {
      surface->clear();
    }
  }

  // Stages of one cycle, in order.
  void readEncoders() noexcept;
  void readCommands() noexcept;
  void applySetPose() noexcept;
  void readSweep() noexcept;
  void observe(const SweepCompensation& sweep) noexcept;
  /// Relocalization on this sweep's observations (while searching): confirm the candidate, or
  /// search for one; restart the localizer when confirmed.
  void relocalize() noexcept;
  /// The same with a likelihood field: advance the field search, or confirm its candidate.
  void relocalizeOnField() noexcept;
  /// Restarts the localizer at `pose` (at the sweep whose dead reckoning is `dr`), carried to the
  /// newest sample.
  void restartAt(const Pose2d& pose, const Result<Pose2d>& dr, Timestamp ref) noexcept;
  void startSearch() noexcept;
  void watchDevices() noexcept;
  void publishIfDue() noexcept;
  Result<Pose2d> poseAt(Timestamp t) const noexcept;  // Pipeline::poseAt

  void publish(Timestamp now) noexcept;
  std::uint16_t healthBits() const noexcept;
  Status lastStatus() const noexcept;
  hal::NavMode mode() const noexcept;
  void log(const char* line) const noexcept {
    if (logSink != nullptr) {
      logSink(logContext, line);
    }
  }
  void resetTracking() noexcept;
  void logRefused(hal::PlcCommandKind kind) const noexcept {
    char line[160];
    (void)std::snprintf(line, sizeof line,
                        "PLC command %u (%s) refused: the navigation cycle does not drive the vehicle; health bit 8 "
                        "stays set until the next command",
                        static_cast<unsigned>(kind), kind == hal::PlcCommandKind::Calibrate ? "calibrate" : "none");
    log(line);
  }

  PipelineParams params;
  LandmarkMap& map;
  hal::EncoderSource& encoders;
  hal::LaserSource& laser;
  hal::PlcLink& plc;
  const hal::Clock& clock;

  TricycleOdometry odometry;
  /// Dead reckoning of the odometry increments, for the motion within a sweep (its origin is
  /// arbitrary: only the motion between two instants is used).
  Pose2d deadReckoning{};
  std::unique_ptr<MotionHistory> motion = std::make_unique<MotionHistory>();
  std::unique_ptr<Localizer> localizer;
  std::unique_ptr<FalkoDetector> detector;
  std::unique_ptr<FalkoKeypoints> keypoints;
  std::unique_ptr<ScanObservations> observations;
  std::unique_ptr<hal::LaserMeasurement> measurement;
  std::unique_ptr<FixedVector<Pose2d::Vector2, kMaxCorners>> corners;
  const LikelihoodFieldBase* field = nullptr;
  std::unique_ptr<MatchPoints> matchPoints = std::make_unique<MatchPoints>();
  std::unique_ptr<HallSurfaceMap> surface;      // with observations.surfaceMap or surfaceFallback
  std::unique_ptr<MatchPoints> fallbackPoints;  // the sweep's points within the surface map's range
  /// With observations.mapChanges: the surfaces the mapping run did not see, placed by the fused
  /// matches (kept across set-poses: they are in the field's frame, not the filter's), and the
  /// scratch of the sweep's points on them and of those left to match.
  std::unique_ptr<HallSurfaceMap> changes;
  std::unique_ptr<MapChangeDetector> changeDetector;
  std::unique_ptr<MatchPoints> changePoints;
  std::unique_ptr<MatchPoints> unchangedPoints;
  std::unique_ptr<GlobalLocalizer> globalLocalizer;
  std::unique_ptr<RelocConfirmer> confirmer;
  bool searching = false;
  bool lastSearchAmbiguous = false;
  bool haveSearchPose = false;
  Pose2d searchDeadReckoning{};        // dead reckoning at the previous searched sweep
  bool searchWithoutOdometry = false;  // the previous searched sweep came before any encoder sample
  Timestamp searchStamp{};             // ... its reference instant
  bool everRelocalized = false;
  Timestamp relocalizedAt{};
  /// With a likelihood field: the field search (allocated when the first field is set), its stage,
  /// the dead reckoning at the sweep its candidate refers to, the candidate and its confirmations.
  enum class FieldStage : std::uint8_t { Idle, Searching, Confirming };
  std::unique_ptr<FieldRelocalizer> fieldReloc;
  FieldStage fieldStage = FieldStage::Idle;
  Pose2d fieldAnchor{};
  bool fieldHaveAnchor = false;
  Pose2d fieldCandidate{};
  FieldConfirmation fieldConfirmation{};  // the candidate's confirming sweeps and their motion
  RelocRegion fieldRegion{};

  PipelineState state = PipelineState::Unconfigured;
  Status faultReason = Status::Ok;
  bool localizing = false;
  /// The last PLC command was one this pipeline does not carry out (Calibrate): published as
  /// `HealthBit::CommandRejected` until the next command it carries out.
  bool commandRefused = false;
  bool haveSample = false;
  hal::EncoderSample lastSample{};
  bool pendingSetPose = false;
  Pose2d pendingPose{};
  Status encoderHealth = Status::NotInitialized;
  Status laserHealth = Status::NotInitialized;
  Status loggedEncoder = Status::NotInitialized;
  Status loggedLaser = Status::NotInitialized;
  std::uint16_t visibleReflectors = 0;
  bool havePublished = false;
  Timestamp nextPublish{};
  std::uint16_t bits = 0;
  PipelineCounters counters{};
  CycleReport report{};
  PipelineLogSink logSink = nullptr;
  void* logContext = nullptr;
};

// --- 1. Encoders -> odometry -> prediction ---------------------------------------------------
void Pipeline::Impl::readEncoders() noexcept {
  for (std::uint32_t i = 0; i < params.maxSamplesPerCycle; ++i) {
    hal::EncoderSample s;
    report.encoderRead = encoders.read(s);
    if (report.encoderRead != Status::Ok) {
      break;
    }
    ++report.encoderSamples;
    ++counters.encoderSamples;
    const Result<OdometryIncrement> inc = odometry.step(TricycleSample{s.stamp, s.driveTicks, s.steeringAngle});
    if (inc.ok()) {
      deadReckoning = deadReckoning * inc.value().delta;
      if (localizing) {
        (void)localizer->predict(inc.value());
      }
    }
    (void)motion->add(s.stamp, deadReckoning);  // a refused stamp leaves the history as it was
    haveSample = true;
    lastSample = s;
  }
}

// --- 2. PLC commands ----------------------------------------------------------------------
void Pipeline::Impl::readCommands() noexcept {
  hal::PlcCommand cmd;
  for (std::uint32_t i = 0; i < params.maxCommandsPerCycle && plc.readCommand(cmd) == Status::Ok; ++i) {
    ++counters.commands;
    switch (cmd.kind) {
      case hal::PlcCommandKind::Localize:
        pendingSetPose = true;
        pendingPose = cmd.initialPose;
        commandRefused = false;
        break;
      case hal::PlcCommandKind::Stop:
        pendingSetPose = false;
        localizing = false;  // idle until the next Localize
        searching = false;
        commandRefused = false;
        break;
      case hal::PlcCommandKind::Calibrate:
      case hal::PlcCommandKind::None:
        // The calibration routine drives the vehicle, which the navigation cycle does not do:
        // refused visibly (health bit), localization goes on unchanged.
        ++counters.refusedCommands;
        commandRefused = true;
        logRefused(cmd.kind);
        break;
    }
  }
}

void Pipeline::Impl::applySetPose() noexcept {
  if (!pendingSetPose) {
    return;
  }
  pendingSetPose = false;
  const Timestamp t = haveSample ? lastSample.stamp : clock.now();
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  cov(0, 0) = cov(1, 1) = params.setPosePositionStdDev * params.setPosePositionStdDev;
  cov(2, 2) = params.setPoseHeadingStdDev * params.setPoseHeadingStdDev;
  if (localizer->reset(t, pendingPose, cov) != Status::Ok) {
    log("set-pose refused by the localizer (non-finite pose or covariance)");
    return;
  }
  localizing = true;
  searching = false;
  everRelocalized = false;
  clearSurfaces();
  ++counters.setPoses;
  // The odometry restarts at the newest sample: the set-pose holds at its instant.
  odometry.reset();
  if (haveSample) {
    (void)odometry.step(TricycleSample{lastSample.stamp, lastSample.driveTicks, lastSample.steeringAngle});
  }
}

// --- 3. Laser -> observations -> correction -------------------------------------------------
void Pipeline::Impl::readSweep() noexcept {
  hal::LaserMeasurement& meas = *measurement;
  report.laserRead = laser.read(meas);
  if (report.laserRead != Status::Ok) {
    return;
  }
  ++counters.sweeps;
  report.sweep = true;
  // Every point is moved to the sensor frame at the end of the sweep with the motion the odometry
  // saw during the sweep: per beam for the corners; for the reflectors at the instant the device
  // stamped, else at their bearing.
  const SweepCompensation sweep(*motion, meas.scan, params.localizer.laser.mounting);
  report.sweepReference = sweep.referenceStamp();
  observe(sweep);
  MatchPoints& points = *matchPoints;
  points.clear();
  // Without a mapping run's field the sweep is matched against the surface map, with only the
  // beams it takes (farther surfaces are not in it, and would count as off the map).
  const bool surfaceMatching = field == nullptr && surface;
  if (field != nullptr || params.observations.collectScanPoints || surface) {
    const double maxRange = surfaceMatching ? params.surface.maxRange : 1e300;
    for (std::size_t i = 0; i < meas.scan.size(); ++i) {
      if (meas.scan.isValid(i) && static_cast<double>(meas.scan.ranges[i]) <= maxRange) {
        const double a = static_cast<double>(meas.scan.angle(i));
        const double r = static_cast<double>(meas.scan.ranges[i]);
        const Pose2d::Vector2 p = sweep.atBeam(i, r * std::cos(a), r * std::sin(a));
        (void)points.push_back(MatchPoint{static_cast<float>(p.x()), static_cast<float>(p.y())});
      }
    }
  }
  if (localizing) {
    // The sweep's ranges let the localizer tell hidden landmarks from missed ones.
    const LikelihoodFieldBase* against = field;
    if (surfaceMatching && surface->field().built()) {
      against = &surface->field();
    }
    const MatchPoints* toMatch = matchPoints.get();
    const bool trackChanges = field != nullptr && changes;
    if (trackChanges && changes->field().built()) {
      // The points on surfaces that changed since the mapping run are left out of the match, seen
      // from the estimate at the sweep's reference instant.
      const Result<Pose2d> at = poseAt(sweep.referenceStamp());
      if (at.ok()) {
        std::size_t dropped = 0;
        (void)changeDetector->keepUnchanged(points, at.value().compose(params.localizer.laser.mounting), *field,
                                            changes->field(), *unchangedPoints, dropped);
        report.changedPointsDropped = static_cast<std::uint32_t>(dropped);
        toMatch = unchangedPoints.get();
      }
    }
    // With a field, the surface map (when kept) is its fallback, with the beams it takes.
    const bool fallback = field != nullptr && surface && params.observations.surfaceFallback;
    if (fallback) {
      fallbackPoints->clear();
      for (const MatchPoint& p : points) {
        if (std::hypot(static_cast<double>(p.x), static_cast<double>(p.y)) <= params.surface.maxRange) {
          (void)fallbackPoints->push_back(p);
        }
      }
    }
    const LocalizerHealth& h =
        against == nullptr ? localizer->correct(*observations, meas.scan, map)
        : fallback && surface->field().built()
            ? localizer->correct(*observations, meas.scan, *toMatch, map, *against, *fallbackPoints, surface->field())
            : localizer->correct(*observations, meas.scan, *toMatch, map, *against);
    if (surfaceMatching && mayExtendSurfaceMap(h)) {
      (void)surface->insert(*matchPoints, h.scanPose.compose(params.localizer.laser.mounting));
    }
    if (fallback) {
      report.fallbackMatched = h.fallbackMatch.attempted;
      report.fallbackFused = h.fallbackMatch.fused;
      if (h.scanMatch.resynced) {
        clearSurfaces();  // placed with the estimate the re-synchronisation overruled
      } else if (mayExtendFallbackMap(h)) {
        (void)surface->insert(*fallbackPoints, h.scanPose.compose(params.localizer.laser.mounting));
      }
    }
    if (trackChanges && h.scanMatch.fused && !h.scanMatch.softGated && !h.scanMatch.resynced) {
      // Placed by the match itself: in the field's frame, whatever the filter's prior said.
      const Pose2d sensor = h.scanMatch.pose.compose(params.localizer.laser.mounting);
      if (changeDetector->select(points, sensor, *field, *changePoints) == Status::Ok && !changePoints->empty()) {
        (void)changes->insert(*changePoints, sensor);
      }
    }
    ++counters.corrections;
    report.corrected = true;
    if (localizer->lost() && params.relocalization.enabled && !searching) {
      log("localizer lost: relocalization searches the map");
      startSearch();
    }
  }
  if (searching) {
    relocalize();
  }
}

void Pipeline::Impl::startSearch() noexcept {
  searching = true;
  haveSearchPose = false;
  searchWithoutOdometry = false;
  lastSearchAmbiguous = false;
  *confirmer = RelocConfirmer(params.relocalization.confirm);  // Idle: no candidate
  if (fieldReloc) {
    fieldReloc->cancel();
  }
  fieldStage = FieldStage::Idle;
  // Lost: around the last estimate when a radius is set; at start (nothing tracked): everywhere.
  const double radius = params.relocalization.fieldRegionRadius;
  fieldRegion =
      localizing && radius > 0.0 ? RelocRegion{localizer->pose().x, localizer->pose().y, radius} : RelocRegion{};
}

void Pipeline::Impl::restartAt(const Pose2d& pose, const Result<Pose2d>& dr, Timestamp ref) noexcept {
  // Restart at the newest sample: the confirmed pose carried there by dead reckoning.
  const Timestamp t = haveSample ? lastSample.stamp : ref;
  const Result<Pose2d> drNow = motion->at(t);
  const Pose2d now = drNow.ok() && dr.ok() ? pose * between(dr.value(), drNow.value()) : pose;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  cov(0, 0) = cov(1, 1) = params.relocalization.positionStdDev * params.relocalization.positionStdDev;
  cov(2, 2) = params.relocalization.headingStdDev * params.relocalization.headingStdDev;
  if (localizer->reset(t, now, cov) == Status::Ok) {
    localizing = true;
    searching = false;
    everRelocalized = true;
    clearSurfaces();
    relocalizedAt = t;
    report.relocalized = true;
    report.searching = false;
    ++counters.relocalizations;
    log("relocalized: the pose found on the map held over the confirmation sweeps");
  }
}

void Pipeline::Impl::relocalizeOnField() noexcept {
  report.searching = true;
  const RelocalizationParams& rp = params.relocalization;
  const Pose2d& mount = params.localizer.laser.mounting;
  const Timestamp ref = observations->stamp;
  const Result<Pose2d> dr = motion->at(ref);
  ++counters.searches;
  if (fieldStage != FieldStage::Idle && !fieldHaveAnchor && dr.ok()) {
    // The search began on a sweep before any odometry (the first after power-up): its candidate is
    // carried from the first sweep with odometry; the motion before that is not known (a standing
    // vehicle's is absorbed by the confirmation's match window).
    fieldAnchor = dr.value();
    fieldHaveAnchor = true;
  }
  if (fieldStage == FieldStage::Confirming) {
    if (!dr.ok() || !fieldHaveAnchor) {
      return;  // nothing to carry the candidate with yet
    }
    const Pose2d step = between(fieldAnchor, dr.value());
    const Pose2d carried = fieldCandidate * step;
    Pose2d refined;
    if (!fieldReloc->confirm(*matchPoints, mount, carried, *field, refined)) {
      ++counters.unconfirmed;
      fieldStage = FieldStage::Idle;  // this sweep starts a new search (below)
    } else {
      fieldCandidate = refined;
      fieldAnchor = dr.value();
      fieldConfirmation.add(step);
      if (fieldConfirmation.complete(rp.fieldConfirmSweeps, rp.field)) {
        fieldStage = FieldStage::Idle;
        restartAt(fieldCandidate, dr, ref);
      }
      return;
    }
  }
  if (fieldStage == FieldStage::Idle) {
    ++counters.fieldSearches;
    fieldHaveAnchor = dr.ok();
    fieldAnchor = dr.ok() ? dr.value() : Pose2d{};
    if (fieldReloc->start(*matchPoints, mount, *field, fieldRegion) != Status::Ok) {
      report.fieldSearchEnded = true;
      report.fieldSearchOutcome = fieldReloc->result().outcome;
      return;  // refused at once (no point, no free position...): the next sweep tries again
    }
    fieldStage = FieldStage::Searching;
  }
  if (!fieldReloc->advance(rp.fieldPosesPerSweep)) {
    return;
  }
  const FieldRelocResult& r = fieldReloc->result();
  report.searched = true;
  report.fieldSearchEnded = true;
  report.fieldSearchOutcome = r.outcome;
  lastSearchAmbiguous = r.outcome == FieldRelocOutcome::Ambiguous;
  counters.ambiguous += lastSearchAmbiguous ? 1U : 0U;
  if (r.outcome != FieldRelocOutcome::Found) {
    fieldStage = FieldStage::Idle;  // nothing: the next sweep starts a new search
    return;
  }
  ++counters.candidates;
  fieldCandidate = r.pose;  // at the search's sweep, carried from fieldAnchor
  fieldConfirmation.restart();
  fieldStage = FieldStage::Confirming;
}

void Pipeline::Impl::relocalize() noexcept {
  if (field != nullptr && fieldReloc) {
    relocalizeOnField();
    return;
  }
  report.searching = true;
  // The vehicle's motion since the previous searched sweep, by dead reckoning at the sweeps'
  // reference instants.
  // Before the first encoder sample (the first sweep after power-up) the search runs all the same;
  // the next sweep carries its candidate from the first sample on (the motion before it is not
  // known: the confirming sweeps' refits absorb a standing vehicle's). A candidate is never
  // confirmed without odometry: it waits for the first sample.
  const Timestamp ref = observations->stamp;
  const Result<Pose2d> dr = motion->at(ref);
  Pose2d moved{};
  if (dr.ok()) {
    if (haveSearchPose) {
      moved = between(searchDeadReckoning, dr.value());
    } else if (searchWithoutOdometry) {
      const Result<Pose2d> first = motion->at(searchStamp);  // the oldest pose held
      moved = first.ok() ? between(first.value(), dr.value()) : Pose2d{};
    }
    searchDeadReckoning = dr.value();
    haveSearchPose = true;
    searchWithoutOdometry = false;
  } else {
    if (confirmer->state() == RelocConfirmState::Pending) {
      return;  // nothing to carry the candidate with yet
    }
    haveSearchPose = false;
    searchWithoutOdometry = true;
    searchStamp = ref;
  }
  const Span<const PointObservation> obs(observations->points.data(), observations->points.size());
  const Pose2d& mount = params.localizer.laser.mounting;
  // Every sweep is searched, the confirming ones too: a candidate holds only while each sweep's
  // own search finds it again (a standing vehicle's sweeps differ in which poles the laser missed:
  // a wrong place that won one sweep's draw must win every one).
  RelocReport rr;
  (void)globalLocalizer->localize(map, obs, measurement->scan, rr);  // the sweep: negative evidence
  ++counters.searches;
  report.searched = true;
  report.searchOutcome = rr.outcome;
  lastSearchAmbiguous = rr.outcome == RelocOutcome::Ambiguous;
  counters.ambiguous += lastSearchAmbiguous ? 1U : 0U;
  if (confirmer->state() == RelocConfirmState::Pending) {
    RelocConfirmState st = confirmer->step(moved, map, obs, mount, &measurement->scan);
    if (st != RelocConfirmState::Rejected && !globalLocalizer->sameAnswer(rr, confirmer->pose())) {
      st = RelocConfirmState::Rejected;
      *confirmer = RelocConfirmer(params.relocalization.confirm);  // Idle: the candidate dropped
    }
    if (st == RelocConfirmState::Confirmed) {
      restartAt(confirmer->pose(), dr, ref);
      return;
    }
    if (st == RelocConfirmState::Pending) {
      return;
    }
    ++counters.unconfirmed;  // Rejected: this sweep's search result starts over
  }
  if (rr.outcome == RelocOutcome::Found) {
    ++counters.candidates;
    confirmer->start(rr, globalLocalizer->params(), map, obs, measurement->scan);
  }
}

void Pipeline::Impl::observe(const SweepCompensation& sweep) noexcept {
  const hal::LaserMeasurement& meas = *measurement;
  ScanObservations& obs = *observations;
  obs.points.clear();
  obs.stamp = sweep.referenceStamp();
  obs.kindsDetected = 0;
  visibleReflectors = meas.hasReflectors ? static_cast<std::uint16_t>(meas.reflectors.size()) : 0U;
  report.reflectors = visibleReflectors;
  if (params.observations.reflectors && meas.hasReflectors) {
    obs.kindsDetected |= landmarkKindBit(LandmarkKind::Reflector);
    for (std::size_t i = 0; i < meas.reflectors.size(); ++i) {
      const hal::ReflectorObservation& r = meas.reflectors[i];
      const auto x = static_cast<double>(r.x);
      const auto y = static_cast<double>(r.y);
      const Pose2d::Vector2 p = r.stamped ? sweep.atStamp(r.stamp, x, y) : sweep.atBearing(x, y);
      (void)obs.points.push_back(PointObservation{p.x(), p.y(), LandmarkKind::Reflector});  // full: counted
    }
  }
  corners->clear();
  const ObservationParams& o = params.observations;
  if (!(o.corners || o.detectCorners)) {
    return;
  }
  keypoints->clear();
  if (detector->detect(meas.scan, *keypoints) != Status::Ok) {
    return;
  }
  for (std::size_t i = 0; i < keypoints->size(); ++i) {
    const FalkoKeypoint& k = (*keypoints)[i];
    if (k.refined) {  // the apex of an unrefined keypoint is only the nearest beam point
      (void)corners->push_back(sweep.atBeam(k.beamIndex, static_cast<double>(k.x), static_cast<double>(k.y)));
    }
  }
  report.corners = static_cast<std::uint16_t>(corners->size());
  if (o.corners) {
    obs.kindsDetected |= landmarkKindBit(LandmarkKind::Corner);
    for (const Pose2d::Vector2& p : *corners) {
      (void)obs.points.push_back(PointObservation{p.x(), p.y(), LandmarkKind::Corner});
    }
  }
}

// --- Device state -----------------------------------------------------------------------
void Pipeline::Impl::watchDevices() noexcept {
  encoderHealth = encoders.health();
  laserHealth = laser.health();
  char line[96];
  if (encoderHealth != loggedEncoder) {
    (void)std::snprintf(line, sizeof line, "encoders: %s", toString(encoderHealth));
    log(line);
    loggedEncoder = encoderHealth;
  }
  if (laserHealth != loggedLaser) {
    (void)std::snprintf(line, sizeof line, "laser: %s", toString(laserHealth));
    log(line);
    loggedLaser = laserHealth;
  }
}

// --- 4. Publication -------------------------------------------------------------------------
std::uint16_t Pipeline::Impl::healthBits() const noexcept {
  using hal::HealthBit;
  std::uint16_t b = 0;
  b = hal::withBit(b, HealthBit::LaserOk, laserHealth == Status::Ok);
  b = hal::withBit(b, HealthBit::LaserTimeout, laserHealth == Status::Timeout);
  b = hal::withBit(b, HealthBit::EncodersOk, encoderHealth == Status::Ok);
  b = hal::withBit(b, HealthBit::EncoderTimeout, encoderHealth == Status::Timeout);
  b = hal::withBit(b, HealthBit::DeviceFault,
                   encoderHealth == Status::DeviceFault || laserHealth == Status::DeviceFault ||
                       report.laserRead == Status::DeviceFault || state == PipelineState::Fault);
  b = hal::withBit(b, HealthBit::MapLoaded, map.size() > 0U);
  b = hal::withBit(b, HealthBit::CalibrationValid, params.calibrationValid);
  b = hal::withBit(b, HealthBit::CommandRejected, commandRefused);
  b = hal::withBit(b, HealthBit::Searching, searching);
  b = hal::withBit(b, HealthBit::Ambiguous, searching && lastSearchAmbiguous);
  const Timestamp now = haveSample ? lastSample.stamp : Timestamp{};
  b = hal::withBit(b, HealthBit::Relocalized,
                   everRelocalized && localizing && !(relocalizedAt + params.relocalization.relocalizedHold < now));
  return b;
}

Status Pipeline::Impl::lastStatus() const noexcept {
  if (state == PipelineState::Fault) {
    return faultReason;
  }
  if (encoderHealth != Status::Ok && encoderHealth != Status::NotInitialized) {
    return encoderHealth;
  }
  if (laserHealth != Status::Ok && laserHealth != Status::NotInitialized) {
    return laserHealth;
  }
  if (localizing && localizer->health().status != Status::Ok) {
    return localizer->health().status;
  }
  return commandRefused ? Status::Unsupported : Status::Ok;
}

hal::NavMode Pipeline::Impl::mode() const noexcept {
  if (state == PipelineState::Fault) {
    return hal::NavMode::Lost;
  }
  if (!localizing) {
    return hal::NavMode::Idle;
  }
  // Without encoder samples the pose cannot follow the vehicle: published as lost (the PLC must
  // stop) until the encoders are back.
  const bool encodersFailed = encoderHealth == Status::Timeout || encoderHealth == Status::DeviceFault;
  return localizer->lost() || encodersFailed ? hal::NavMode::Lost : hal::NavMode::Localizing;
}

void Pipeline::Impl::publish(Timestamp now) noexcept {
  bits = healthBits();
  hal::PoseReport r;
  r.stamp = localizing ? localizer->stamp() : now;
  r.pose = localizer->pose();
  r.covariance = localizer->covariance();
  r.health.mode = mode();
  r.health.bits = bits;
  r.health.lastStatus = lastStatus();
  r.health.matchedLandmarks = localizer->health().used;
  r.health.visibleReflectors = visibleReflectors;
  const SourceHealth& refl = localizer->health().sources[static_cast<std::size_t>(LandmarkKind::Reflector)];
  const SourceHealth& corner = localizer->health().sources[static_cast<std::size_t>(LandmarkKind::Corner)];
  r.health.reflectorsFused = refl.fused;
  r.health.reflectorsRejected = refl.rejected;
  r.health.cornersFused = corner.fused;
  r.health.cornersRejected = corner.rejected;
  if (plc.publish(r) != Status::Ok) {
    ++counters.publishFailures;
  }
  ++counters.publications;
  report.published = true;
}

void Pipeline::Impl::publishIfDue() noexcept {
  const Timestamp now = clock.now();
  if (havePublished && now < nextPublish) {
    return;
  }
  const Duration period = params.publishPeriod;
  nextPublish = havePublished ? nextPublish + period : now + period;
  if (now - nextPublish > period) {
    nextPublish = now + period;  // late: no burst
  }
  havePublished = true;
  publish(now);
}

void Pipeline::Impl::resetTracking() noexcept {
  localizing = false;
  pendingSetPose = false;
  commandRefused = false;
  haveSample = false;
  odometry.reset();
  motion->clear();
  deadReckoning = Pose2d{};
  corners->clear();
  matchPoints->clear();
  clearSurfaces();
  visibleReflectors = 0;
  searching = false;
  lastSearchAmbiguous = false;
  everRelocalized = false;
  havePublished = false;
  counters = PipelineCounters{};
  report = CycleReport{};
}

// --- Public interface -------------------------------------------------------------------------
Pipeline::Pipeline(const PipelineParams& params, LandmarkMap& map, const PipelineDevices& devices)
    : impl_(std::make_unique<Impl>(params, map, devices)) {}

Pipeline::~Pipeline() = default;

Status Pipeline::configure() noexcept {
  Impl& m = *impl_;
  if (m.state == PipelineState::Active) {
    return Status::InvalidArgument;
  }
  const Status s = m.params.validate();
  if (s != Status::Ok) {
    return s;
  }
  m.resetTracking();
  m.faultReason = Status::Ok;
  m.state = PipelineState::Inactive;
  return Status::Ok;
}

Status Pipeline::activate() noexcept {
  Impl& m = *impl_;
  if (m.state != PipelineState::Inactive) {
    return Status::NotInitialized;
  }
  m.state = PipelineState::Active;
  if (m.params.relocalization.enabled && m.params.relocalization.atStart && !m.localizing) {
    m.startSearch();
  }
  return Status::Ok;
}

Status Pipeline::deactivate() noexcept {
  Impl& m = *impl_;
  if (m.state != PipelineState::Active) {
    return Status::NotInitialized;
  }
  m.localizing = false;
  m.pendingSetPose = false;
  m.searching = false;
  m.state = PipelineState::Inactive;
  m.publish(m.clock.now());
  return Status::Ok;
}

void Pipeline::fault(Status why) noexcept {
  Impl& m = *impl_;
  m.faultReason = why == Status::Ok ? Status::DeviceFault : why;
  m.state = PipelineState::Fault;
  m.localizing = false;
  m.pendingSetPose = false;
  m.searching = false;
  char line[96];
  (void)std::snprintf(line, sizeof line, "fault: %s; publishing lost until reconfigured", toString(m.faultReason));
  m.log(line);
}

PipelineState Pipeline::state() const noexcept {
  return impl_->state;
}

Status Pipeline::faultReason() const noexcept {
  return impl_->faultReason;
}

Status Pipeline::recalibrate(const TricycleParams& kinematics, const Pose2d& laserMounting) {
  Impl& m = *impl_;
  if (m.state != PipelineState::Active && m.state != PipelineState::Inactive) {
    return Status::NotInitialized;
  }
  PipelineParams p = m.params;
  p.kinematics = kinematics;
  p.localizer.laser.mounting = laserMounting;
  if (p.validate() != Status::Ok || !laserMounting.isFinite()) {
    return Status::InvalidArgument;
  }
  const bool wasLocalizing = m.localizing;
  const Pose2d pose = m.localizer->pose();
  m.params = p;
  m.odometry = TricycleOdometry(p.kinematics, p.odometryNoise);
  m.localizer = std::make_unique<Localizer>(localizerParams(p));
  GlobalLocalizerParams search = p.relocalization.search;
  search.laserMount = p.localizer.laser.mounting;
  m.globalLocalizer = std::make_unique<GlobalLocalizer>(search);
  m.localizing = false;
  if (wasLocalizing) {
    m.pendingSetPose = true;
    m.pendingPose = pose;
  }
  return Status::Ok;
}

Status Pipeline::setPose(const Pose2d& pose) noexcept {
  Impl& m = *impl_;
  if (m.state != PipelineState::Active && m.state != PipelineState::Inactive) {
    return Status::NotInitialized;
  }
  if (!pose.isFinite()) {
    return Status::NonFiniteInput;
  }
  m.pendingSetPose = true;
  m.pendingPose = pose;
  return Status::Ok;
}

Status Pipeline::cycle() noexcept {
  Impl& m = *impl_;
  m.report = CycleReport{};
  if (m.state == PipelineState::Fault) {
    m.publishIfDue();
    return m.faultReason;
  }
  if (m.state != PipelineState::Active) {
    return Status::NotInitialized;
  }
  ++m.counters.cycles;
  m.readEncoders();
  m.readCommands();
  m.applySetPose();
  m.readSweep();
  m.watchDevices();
  if (m.report.encoderRead == Status::InvalidArgument || m.report.laserRead == Status::InvalidArgument) {
    fault(Status::InvalidArgument);  // a device refusing its configuration never delivers
  }
  m.publishIfDue();
  return m.state == PipelineState::Active ? Status::Ok : m.faultReason;
}

bool Pipeline::searching() const noexcept {
  return impl_->searching;
}

bool Pipeline::localizing() const noexcept {
  return impl_->localizing;
}

const Localizer& Pipeline::localizer() const noexcept {
  return *impl_->localizer;
}

const LandmarkMap& Pipeline::map() const noexcept {
  return impl_->map;
}

const PipelineCounters& Pipeline::counters() const noexcept {
  return impl_->counters;
}

const CycleReport& Pipeline::lastCycle() const noexcept {
  return impl_->report;
}

std::uint16_t Pipeline::healthBits() const noexcept {
  return impl_->bits;
}

const hal::LaserMeasurement& Pipeline::lastMeasurement() const noexcept {
  return *impl_->measurement;
}

Span<const Pose2d::Vector2> Pipeline::sweepCorners() const noexcept {
  return Span<const Pose2d::Vector2>(impl_->corners->data(), impl_->corners->size());
}

Result<Pose2d> Pipeline::Impl::poseAt(Timestamp t) const noexcept {
  if (!localizing) {
    return Status::Lost;
  }
  const Result<Pose2d> from = motion->at(localizer->stamp());
  const Result<Pose2d> to = motion->at(t);
  if (!from.ok() || !to.ok()) {
    return Status::NotEnoughData;
  }
  return localizer->pose() * between(from.value(), to.value());
}

Result<Pose2d> Pipeline::poseAt(Timestamp t) const noexcept {
  return impl_->poseAt(t);
}

Span<const MatchPoint> Pipeline::sweepPoints() const noexcept {
  return Span<const MatchPoint>(impl_->matchPoints->data(), impl_->matchPoints->size());
}

const SurfaceMapBase* Pipeline::surfaceMap() const noexcept {
  return impl_->surface.get();
}

const SurfaceMapBase* Pipeline::mapChanges() const noexcept {
  return impl_->changes.get();
}

void Pipeline::setLikelihoodField(const LikelihoodFieldBase* field) {
  Impl& m = *impl_;
  m.field = field;
  if (field != nullptr && !m.fieldReloc) {
    m.fieldReloc = std::make_unique<FieldRelocalizer>(m.params.relocalization.field);
  }
  if (m.fieldReloc) {
    m.fieldReloc->cancel();  // it may hold the previous field
  }
  m.fieldStage = Impl::FieldStage::Idle;
}

void Pipeline::setLogSink(PipelineLogSink sink, void* context) noexcept {
  impl_->logSink = sink;
  impl_->logContext = context;
}

}  // namespace agv::nav
