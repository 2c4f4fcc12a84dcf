#include "agv/calibration/calibration_routine.hpp"

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>

#include "agv/calib/keypoint_alignment.hpp"
#include "agv/calib/reflector_alignment.hpp"
#include "agv/calib/segment_builder.hpp"
#include "agv/core/span.hpp"
#include "agv/falko/falko_descriptors.hpp"
#include "agv/falko/falko_detector.hpp"
#include "agv/hal/laser_measurement.hpp"

namespace agv::calibration {

const char* phaseName(Phase phase) noexcept {
  switch (phase) {
    case Phase::ForwardLeft:
      return "forward left";
    case Phase::ForwardRight:
      return "forward right";
    case Phase::BackwardLeft:
      return "backward left";
    case Phase::BackwardRight:
      return "backward right";
  }
  return "?";
}

namespace {

template <typename... Args>
std::string format(const char* fmt, Args... args) {
  char buf[320];
  std::snprintf(buf, sizeof buf, fmt, args...);
  return buf;
}

bool inside(const FreeArea& area, double x, double y, double margin) noexcept {
  return x >= area.xMin + margin && x <= area.xMax - margin && y >= area.yMin + margin && y <= area.yMax - margin;
}

/// Ok, or InvalidArgument with `error` when a field of the request is out of its domain.
Status checkRequest(const PlanRequest& r, std::string& error) {
  const double right = deg2rad(90.0);
  if (!(r.wheelbase > 0.0) || !std::isfinite(r.wheelbase)) {
    error = "wheelbase must be a positive length";
    return Status::InvalidArgument;
  }
  if (!(r.steeringLimit > 0.0) || !(r.steeringLimit < right)) {
    error = "steering limit must be in (0, 90) deg";
    return Status::InvalidArgument;
  }
  if (!(r.minSteering > 0.0) || !(r.minSteering <= r.maxSteering) || !(r.maxSteering <= r.steeringLimit)) {
    error = format("steering range %.1f..%.1f deg must satisfy 0 < min <= max <= limit (%.1f deg)",
                   rad2deg(r.minSteering), rad2deg(r.maxSteering), rad2deg(r.steeringLimit));
    return Status::InvalidArgument;
  }
  if (r.segmentsPerPhase < 1 || 4 * static_cast<std::size_t>(r.segmentsPerPhase) > kMaxCalibSegments) {
    error = format("segments per phase must be in 1..%zu", kMaxCalibSegments / 4);
    return Status::InvalidArgument;
  }
  if (r.segmentsPerPhase > 1 && !(r.maxSteering > r.minSteering)) {
    error = "several segments per phase need a steering range (max > min)";
    return Status::InvalidArgument;
  }
  if (!(r.rotation > 0.0) || !(r.rotation < kTwoPi<double>)) {
    error = "beta (segment rotation) must be in (0, 360) deg: a full circle hides the laser's rotation";
    return Status::InvalidArgument;
  }
  return Status::Ok;
}

/// Ok, or InvalidArgument with `error` when the free area, clearances or start are unusable.
Status checkArea(const PlanRequest& r, std::string& error) {
  if (!(r.area.xMax > r.area.xMin) || !(r.area.yMax > r.area.yMin) || !std::isfinite(r.area.xMin) ||
      !std::isfinite(r.area.xMax) || !std::isfinite(r.area.yMin) || !std::isfinite(r.area.yMax)) {
    error = "free area must be a rectangle xmin < xmax, ymin < ymax";
    return Status::InvalidArgument;
  }
  if (!(r.clearance >= 0.0) || !(r.frontOverhang >= 0.0) || !r.start.isFinite()) {
    error = "clearance, front overhang and start must be finite (lengths >= 0)";
    return Status::InvalidArgument;
  }
  if (!inside(r.area, r.start.x, r.start.y, r.clearance)) {
    error = format("start (%.2f, %.2f) is not inside the free area (with %.2f m clearance)", r.start.x, r.start.y,
                   r.clearance);
    return Status::InvalidArgument;
  }
  return Status::Ok;
}

/// True when the circle at steering `a` to `side` (+1 left, -1 right) stays in the free area; else false with
/// `error` naming where it leaves. The forward arc and the backward one retracing it sweep the same ground: the
/// arc is sampled (<= 2 deg steps) and the logical point and the vehicle's front tested against the area.
bool arcInside(const PlanRequest& r, double a, int side, std::string& error) {
  const double radius = r.wheelbase / std::tan(a);
  const int steps = static_cast<int>(std::ceil(r.rotation / deg2rad(2.0)));
  for (int i = 0; i <= steps; ++i) {
    const double t = r.rotation * static_cast<double>(i) / static_cast<double>(steps);
    const Pose2d local{radius * std::sin(t), side * radius * (1.0 - std::cos(t)), side * t};
    const Pose2d p = r.start.compose(local);
    const Eigen::Vector2d front = p.transformPoint(Eigen::Vector2d(r.frontOverhang, 0.0));
    for (const Eigen::Vector2d& q : {Eigen::Vector2d(p.x, p.y), front}) {
      if (!inside(r.area, q.x(), q.y(), r.clearance)) {
        error = format(
            "the %s circle at %.1f deg steering (radius %.2f m) leaves the free area at (%.2f, %.2f) (clearance %.2f "
            "m): enlarge the area, move the start, raise the minimum steering or lower beta",
            side > 0 ? "left" : "right", rad2deg(a), radius, q.x(), q.y(), r.clearance);
        return false;
      }
    }
  }
  return true;
}

}  // namespace

Status planCalibration(const PlanRequest& r, CalibrationPlan& plan, std::string& error) {
  plan = CalibrationPlan{};
  plan.request = r;
  error.clear();
  Status s = checkRequest(r, error);
  if (s == Status::Ok) {
    s = checkArea(r, error);
  }
  if (s != Status::Ok) {
    return s;
  }
  const int n = r.segmentsPerPhase;
  for (int k = 0; k < n; ++k) {
    const double a =
        n == 1 ? r.minSteering
               : r.minSteering + (r.maxSteering - r.minSteering) * static_cast<double>(k) / static_cast<double>(n - 1);
    for (int side : {1, -1}) {
      if (!arcInside(r, a, side, error)) {
        plan.segments.clear();
        return Status::OutOfRange;
      }
      const double travel = r.rotation * r.wheelbase / std::sin(a);
      const double steer = side * a;
      plan.segments.push_back(PlannedSegment{steer, 1, travel, side > 0 ? Phase::ForwardLeft : Phase::ForwardRight});
      plan.segments.push_back(PlannedSegment{steer, -1, travel, side > 0 ? Phase::BackwardLeft : Phase::BackwardRight});
    }
  }
  return Status::Ok;
}

namespace {

/// What the laser saw at one standstill.
struct Observation {
  bool valid = false;
  std::vector<Eigen::Vector2d> reflectors;
  std::vector<FalkoKeypoint> keypoints;
  std::vector<BscDescriptor> bsc;
};

struct DriveRecord {
  bool closed = false;
  BuiltSegment segment;
};

/// What the collection gathered: one drive record per segment driven, one observation per
/// standstill (before the first segment and after each); `observed` of `observations` are filled
/// (the rest is reserved storage).
struct CollectedData {
  std::vector<DriveRecord> drives;
  std::vector<Observation> observations;
  std::size_t observed = 0;
};

/// Keypoint detection state (the detector holds large buffers: one per routine, on the heap).
struct KeypointTools {
  FalkoDetector detector;
  FalkoDescriber describer;
  FalkoKeypoints keypoints;
  BscDescriptors bsc;
  CghDescriptors cgh;
};

/// Per drive: whether its egomotion was aligned, with the alignment's residual and match count; the aligned
/// segments in the order they were aligned.
struct Alignments {
  explicit Alignments(std::size_t drives) : aligned(drives, 0), rms(drives, 0.0), matches(drives, 0.0) {}
  std::vector<int> aligned;
  std::vector<CalibSegment> segments;
  std::vector<double> rms;
  std::vector<double> matches;
  Span<const CalibSegment> span() const { return Span<const CalibSegment>(segments.data(), segments.size()); }
};

/// The laser's motion from observation `a` to `b` around `guess`, by reflectors or keypoints as `options` say;
/// `rms` and `matches` describe the alignment whatever its status.
Status alignPair(const Observation& a, const Observation& b, const Pose2d& guess, const RoutineOptions& options,
                 Pose2d& motion, double& rms, double& matches) {
  if (options.egomotion == EgomotionSource::Reflectors) {
    ReflectorAlignment al;
    ReflectorAlignmentOptions ao;
    ao.associationGate = options.reflectorGate;
    const Status s =
        alignReflectors(Span<const Eigen::Vector2d>(a.reflectors.data(), a.reflectors.size()),
                        Span<const Eigen::Vector2d>(b.reflectors.data(), b.reflectors.size()), guess, ao, al);
    motion = al.motion;
    rms = al.rms;
    matches = static_cast<double>(al.matches);
    return s;
  }
  KeypointAlignment al;
  KeypointAlignmentOptions ko;
  ko.guessTranslationGate = options.keypointGuessTranslation;
  ko.guessRotationGate = options.keypointGuessRotation;
  const KeypointScanView va{{a.keypoints.data(), a.keypoints.size()}, {a.bsc.data(), a.bsc.size()}, {}};
  const KeypointScanView vb{{b.keypoints.data(), b.keypoints.size()}, {b.bsc.data(), b.bsc.size()}, {}};
  const Status s = alignKeypoints(va, vb, guess, ko, al);
  motion = al.motion;
  rms = al.rms;
  matches = static_cast<double>(al.inliers);
  return s;
}

/// Aligns every closed, not yet aligned segment with both observations valid, the guess predicted by `params`
/// and `laserPose`; the segments whose alignment fails stay out.
void alignAll(const CollectedData& data, const RoutineOptions& options, const TricycleParams& params,
              const Pose2d& laserPose, Alignments& al) {
  const std::vector<DriveRecord>& drives = data.drives;
  const std::vector<Observation>& observations = data.observations;
  for (std::size_t i = 0; i < drives.size() && i + 1 < data.observed; ++i) {
    const Observation& a = observations[i];
    const Observation& b = observations[i + 1];
    if (!drives[i].closed || al.aligned[i] != 0 || !a.valid || !b.valid) {
      continue;
    }
    const Pose2d guess = predictedEgomotion(toCalibSegment(drives[i].segment, Pose2d{}), params, laserPose);
    Pose2d motion;
    if (alignPair(a, b, guess, options, motion, al.rms[i], al.matches[i]) == Status::Ok) {
      al.aligned[i] = 1;
      al.segments.push_back(toCalibSegment(drives[i].segment, motion));
    }
  }
}

/// Egomotion of the segments, then the ATC and STC closed forms and the joint refinement. Two alignment passes:
/// the nominal guess can be off by metres at far reflectors on the long low-steering arcs, so the segments that
/// fail with it are aligned again from the first solve's estimate.
void solve(const CollectedData& data, const RoutineOptions& options, Alignments& al, CalibrationOutcome& out) {
  CalibrationOptions calibOptions;
  calibOptions.nominal = options.nominal;
  alignAll(data, options, options.nominal, options.nominalLaser, al);
  out.status = calibrateAtc(al.span(), calibOptions, out.result);
  if (out.status == Status::Ok && al.segments.size() < data.drives.size()) {
    const std::size_t before = al.segments.size();
    alignAll(data, options, out.result.params, out.result.laserPose, al);
    if (al.segments.size() > before) {
      out.status = calibrateAtc(al.span(), calibOptions, out.result);
    }
  }
  out.stcStatus = calibrateStc(al.span(), calibOptions, out.stc);
  if (out.status == Status::Ok) {
    out.refinedStatus = refineCalibration(al.span(), out.result.params, out.result.laserPose,
                                          options.refinementFor(options.egomotion), out.refined);
  }
}

/// Segments used and rejected, mean alignment figures, the failure in words.
void summarize(const Alignments& al, CalibrationOutcome& out) {
  out.segmentsUsed = static_cast<int>(al.segments.size());
  double rmsSum = 0.0;
  double matchSum = 0.0;
  for (std::size_t i = 0; i < al.aligned.size(); ++i) {
    if (al.aligned[i] == 0) {
      ++out.segmentsRejected;
    } else {
      rmsSum += al.rms[i];
      matchSum += al.matches[i];
    }
  }
  const double used = static_cast<double>(al.segments.size());
  out.meanAlignmentRms = al.segments.empty() ? 0.0 : rmsSum / used;
  out.meanMatches = al.segments.empty() ? 0.0 : matchSum / used;
  if (out.status != Status::Ok) {
    out.message = std::string(toString(out.status));
    if (out.result.report.failed != CalibCondition::None) {
      out.message += std::string(" (") + toString(out.result.report.failed) + ")";
    }
  }
}

}  // namespace

double refinementVarianceFactor(const CalibrationOutcome& r) noexcept {
  const double dof = 3.0 * r.segmentsUsed - static_cast<double>(kCalibParamCount);
  return dof > 0.0 ? std::fmax(1.0, r.refined.finalCost / dof) : 1.0;
}

VehicleCalibration calibrationToWrite(const CalibrationOutcome& r) noexcept {
  const bool refined = r.refinedStatus == Status::Ok;
  VehicleCalibration cal;
  cal.params = refined ? r.refined.params : r.result.params;
  cal.laserPose = refined ? r.refined.laserPose : r.result.laserPose;
  if (refined) {
    const double factor = refinementVarianceFactor(r);
    const auto sd = [&](int i) { return std::sqrt(factor * r.refined.covariance(i, i)); };
    cal.sigmas = CalibrationSigmas{sd(kParamDriveScale), sd(kParamOffsetForward), sd(kParamOffsetBackward),
                                   sd(kParamLaserX),     sd(kParamLaserY),        sd(kParamLaserTheta)};
  }
  return cal;
}

const char* routineStateName(RoutineState state) noexcept {
  switch (state) {
    case RoutineState::Idle:
      return "idle";
    case RoutineState::Settling:
      return "settling";
    case RoutineState::Steering:
      return "steering";
    case RoutineState::Driving:
      return "driving";
    case RoutineState::Stopping:
      return "stopping";
    case RoutineState::Observing:
      return "observing";
    case RoutineState::Solving:
      return "solving";
    case RoutineState::Done:
      return "done";
    case RoutineState::Aborted:
      return "aborted";
  }
  return "?";
}

struct CalibrationRun::Impl {
  Impl(hal::DriveControl& d, const RoutineOptions& o) : drive(d), options(o) {
    if (options.egomotion == EgomotionSource::Keypoints) {
      tools = std::make_unique<KeypointTools>();
    }
  }

  bool running() const noexcept {
    return state != RoutineState::Idle && state != RoutineState::Done && state != RoutineState::Aborted;
  }

  /// Sends the set-point of this state; false (after `fail`) when the drive refuses it.
  bool send(Timestamp now, double speed, const char* what) {
    const Status s = drive.command(hal::DriveCommand{now, speed, steerSet});
    if (s == Status::Ok) {
      return true;
    }
    const std::string message = format("%s set-point refused by the drive (%s) in %s, segment %d of %d", what,
                                       toString(s), routineStateName(state), segment, total());
    fail(s == Status::DeviceFault ? Status::DeviceFault : Status::InvalidArgument, message.c_str(), now);
    return false;
  }

  /// Stops the drive and ends the run with `s` and `message`.
  void fail(Status s, const char* message, Timestamp now) {
    static_cast<void>(drive.stop());
    out.status = s;
    out.message = message;
    out.seconds = (now - t0).seconds();
    state = RoutineState::Aborted;
  }

  int total() const noexcept { return static_cast<int>(plan.segments.size()); }

  /// At rest, steering on `steerSet`, at least the settle time after entering the state.
  bool atRest(Timestamp now) const noexcept {
    return now >= restUntil && drive.isStandstill() && haveSample && std::fabs(lastSteer - steerSet) < deg2rad(0.1);
  }

  void enter(RoutineState s, Timestamp now) noexcept {
    state = s;
    entered = now;
    restUntil = now + options.settle;
  }

  bool waitedTooLong(Timestamp now, Duration limit) const noexcept { return now - entered > limit; }

  /// After an observation: prepares the next segment, or the solve after the last.
  void afterObservation(Timestamp now) {
    ++data.observed;  // an observation without a sweep (observeLimit) stays invalid
    observationTaken = false;
    if (data.observed > 1) {
      ++completed;  // the first observation precedes the first segment
    }
    if (completed >= total()) {
      out.seconds = (now - t0).seconds();
      enter(RoutineState::Solving, now);
      return;
    }
    segment = completed + 1;
    steerSet = plan.segments[static_cast<std::size_t>(completed)].steering;
    enter(RoutineState::Steering, now);
    static_cast<void>(send(now, 0.0, "steering"));
  }

  void stepCollecting(Timestamp now) {
    const PlannedSegment& seg = plan.segments[static_cast<std::size_t>(segment > 0 ? segment - 1 : 0)];
    switch (state) {
      case RoutineState::Settling:
      case RoutineState::Stopping:
        if (!send(now, 0.0, "standstill")) {
          return;
        }
        if (atRest(now)) {
          settledAt = now;
          enter(RoutineState::Observing, now);
        } else if (waitedTooLong(now, options.waitLimit)) {
          fail(Status::Timeout, "the vehicle did not come to standstill", now);
        }
        return;
      case RoutineState::Steering:
        if (!send(now, 0.0, "steering")) {
          return;
        }
        if (atRest(now)) {
          startTicks = lastTicks;
          data.drives.push_back(DriveRecord{});
          ++out.segmentsDriven;
          enter(RoutineState::Driving, now);
          static_cast<void>(send(now, seg.direction * options.speed, "speed"));
        } else if (waitedTooLong(now, options.waitLimit)) {
          fail(Status::Timeout, "the steering did not reach its set-point", now);
        }
        return;
      case RoutineState::Driving: {
        const double braking = options.speed * options.speed / (2.0 * options.deceleration);
        const double travelled = std::fabs(static_cast<double>(lastTicks - startTicks) * options.nominal.driveScale);
        if (travelled >= seg.wheelTravel - braking) {
          enter(RoutineState::Stopping, now);
          static_cast<void>(send(now, 0.0, "standstill"));
        } else if (waitedTooLong(now, options.waitLimit)) {
          fail(Status::Timeout, "the segment's travel was not reached (drive or encoder fault)", now);
        } else {
          static_cast<void>(send(now, seg.direction * options.speed, "speed"));
        }
        return;
      }
      case RoutineState::Observing:
        if (!send(now, 0.0, "standstill")) {
          return;
        }
        if (observationTaken || waitedTooLong(now, options.observeLimit)) {
          afterObservation(now);
        }
        return;
      default:
        return;
    }
  }

  void solveNow() {
    Alignments al(data.drives.size());
    solve(data, options, al, out);
    summarize(al, out);
    state = RoutineState::Done;
  }

  hal::DriveControl& drive;
  RoutineOptions options;
  CalibrationPlan plan;
  RoutineState state = RoutineState::Idle;
  int segment = 0;    // 1-based, 0 before the first
  int completed = 0;  // segments driven and observed
  double steerSet = 0.0;
  Timestamp t0{};
  Timestamp entered{};
  Timestamp restUntil{};
  Timestamp settledAt{};
  bool observationTaken = false;
  std::int64_t startTicks = 0;
  std::int64_t lastTicks = 0;
  double lastSteer = 0.0;
  bool haveSample = false;
  CalibSegmentBuilder builder;
  CollectedData data;
  std::unique_ptr<KeypointTools> tools;
  CalibrationOutcome out;
};

CalibrationRun::CalibrationRun(hal::DriveControl& drive, const RoutineOptions& options)
    : impl_(std::make_unique<Impl>(drive, options)) {}

CalibrationRun::~CalibrationRun() = default;

Status CalibrationRun::start(const CalibrationPlan& plan, Timestamp now) {
  Impl& m = *impl_;
  if (m.running()) {
    return Status::Rejected;
  }
  if (plan.segments.empty()) {
    return Status::InvalidArgument;
  }
  m.plan = plan;
  m.out = CalibrationOutcome{};
  m.builder.reset();
  m.data.drives.clear();
  m.data.drives.reserve(plan.segments.size());
  m.data.observations.resize(plan.segments.size() + 1);
  for (Observation& o : m.data.observations) {
    o = Observation{};
    o.reflectors.reserve(kMaxReflectors);
    if (m.tools) {
      o.keypoints.reserve(kMaxKeypoints);
      o.bsc.reserve(kMaxKeypoints);
    }
  }
  m.data.observed = 0;
  m.segment = 0;
  m.completed = 0;
  m.steerSet = 0.0;
  m.observationTaken = false;
  m.startTicks = m.lastTicks;
  m.t0 = now;
  m.enter(RoutineState::Settling, now);
  static_cast<void>(m.send(now, 0.0, "standstill"));
  return Status::Ok;
}

void CalibrationRun::onEncoderSample(const hal::EncoderSample& s) noexcept {
  Impl& m = *impl_;
  m.lastTicks = s.driveTicks;
  m.lastSteer = s.steeringAngle;
  m.haveSample = true;
  if (!m.running()) {
    return;
  }
  SegmentEvent ev = SegmentEvent::None;
  if (m.builder.addSample(s.stamp, s.driveTicks, s.steeringAngle, &ev) != Status::Ok) {
    return;
  }
  if (ev == SegmentEvent::None || m.data.drives.empty()) {
    return;
  }
  m.data.drives.back().closed = ev == SegmentEvent::Closed;
  m.data.drives.back().segment = m.builder.lastSegment();
}

void CalibrationRun::onSweep(const hal::LaserMeasurement& scan) {
  Impl& m = *impl_;
  if (m.state != RoutineState::Observing || m.observationTaken || scan.scan.stamp < m.settledAt ||
      m.data.observed >= m.data.observations.size()) {
    return;
  }
  m.observationTaken = true;
  Observation& obs = m.data.observations[m.data.observed];
  obs.valid = true;
  for (const hal::ReflectorObservation& o : scan.reflectors) {
    obs.reflectors.emplace_back(static_cast<double>(o.x), static_cast<double>(o.y));
  }
  KeypointTools* t = m.tools.get();
  if (t != nullptr && t->detector.detect(scan.scan, t->keypoints) == Status::Ok &&
      t->describer.describe(t->detector.points(), t->keypoints, t->bsc, t->cgh) == Status::Ok) {
    obs.keypoints.assign(t->keypoints.begin(), t->keypoints.end());
    obs.bsc.assign(t->bsc.begin(), t->bsc.end());
  }
}

RoutineState CalibrationRun::step(Timestamp now) {
  Impl& m = *impl_;
  if (m.state == RoutineState::Solving) {
    m.solveNow();
  } else if (m.running()) {
    m.stepCollecting(now);
  }
  return m.state;
}

void CalibrationRun::abort(Status why, const char* reason, Timestamp now) {
  Impl& m = *impl_;
  if (m.running()) {
    m.fail(why, reason, now);
  }
}

RoutineState CalibrationRun::state() const noexcept {
  return impl_->state;
}

bool CalibrationRun::finished() const noexcept {
  return !impl_->running();
}

int CalibrationRun::segment() const noexcept {
  return impl_->segment;
}

int CalibrationRun::segmentsCompleted() const noexcept {
  return impl_->completed;
}

int CalibrationRun::total() const noexcept {
  return impl_->total();
}

Phase CalibrationRun::phase() const noexcept {
  const Impl& m = *impl_;
  if (m.plan.segments.empty()) {
    return Phase::ForwardLeft;
  }
  return m.plan.segments[static_cast<std::size_t>(m.segment > 0 ? m.segment - 1 : 0)].phase;
}

Timestamp CalibrationRun::startTime() const noexcept {
  return impl_->t0;
}

const CalibrationOutcome& CalibrationRun::outcome() const noexcept {
  return impl_->out;
}

CalibrationOutcome runCalibrationRoutine(CalibrationVehicle& vehicle, const CalibrationPlan& plan,
                                         const RoutineOptions& options,
                                         const std::function<void(const RoutineProgress&)>& progress) {
  CalibrationRun run(vehicle.drive(), options);
  const Status started = run.start(plan, vehicle.now());
  if (started != Status::Ok) {
    CalibrationOutcome out;
    out.status = started;
    out.message = "the plan has no segment";
    return out;
  }
  auto scan = std::make_unique<hal::LaserMeasurement>();  // large: kept out of the stack
  hal::EncoderSource& encoders = vehicle.encoders();
  hal::LaserSource& laser = vehicle.laser();
  int reported = 0;
  while (!run.finished()) {
    if (run.state() == RoutineState::Solving) {
      static_cast<void>(run.step(vehicle.now()));
      continue;
    }
    vehicle.wait(options.controlPeriod);
    hal::EncoderSample s;
    while (encoders.read(s) == Status::Ok) {
      run.onEncoderSample(s);
    }
    const Timestamp now = vehicle.now();
    // The sweeps after the step: a standstill reached in this step takes a sweep that starts at
    // this very instant, and the next segment starts in the same instant (a second step).
    static_cast<void>(run.step(now));
    while (laser.read(*scan) == Status::Ok) {
      run.onSweep(*scan);
    }
    if (run.state() == RoutineState::Observing) {
      static_cast<void>(run.step(now));
    }
    if (progress && run.segmentsCompleted() > reported) {
      reported = run.segmentsCompleted();
      RoutineProgress p;
      p.segment = reported;
      p.total = run.total();
      p.elapsed = (vehicle.now() - run.startTime()).seconds();
      p.remaining = p.elapsed / p.segment * (p.total - p.segment);
      progress(p);
    }
  }
  return run.outcome();
}

}  // namespace agv::calibration
