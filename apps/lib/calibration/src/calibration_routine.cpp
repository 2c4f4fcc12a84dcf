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

/// Keypoint detection state (the detector holds large buffers: one per routine, on the heap).
struct KeypointTools {
  FalkoDetector detector;
  FalkoDescriber describer;
  FalkoKeypoints keypoints;
  BscDescriptors bsc;
  CghDescriptors cgh;
};

/// The data collection of one run: drives the plan's segments on the vehicle, feeds the encoder samples to the
/// segment builder (one drive record per segment) and observes with the laser at every standstill (one
/// observation before the first segment and one after each).
class DataCollection {
 public:
  DataCollection(CalibrationVehicle& vehicle, const RoutineOptions& options)
      : vehicle_(vehicle),
        drive_(vehicle.drive()),
        encoders_(vehicle.encoders()),
        laser_(vehicle.laser()),
        options_(options),
        t0_(vehicle.now()) {
    if (options.egomotion == EgomotionSource::Keypoints) {
      tools_ = std::make_unique<KeypointTools>();
    }
  }

  /// Drives `plan`, counting in `out`; false with `out.status` and `out.message` (the drive stopped) on a
  /// fault. `out.seconds` is the duration either way.
  bool run(const CalibrationPlan& plan, const std::function<void(const RoutineProgress&)>& progress,
           CalibrationOutcome& out) {
    if (!settle(lastSteer_)) {
      return fail(out, Status::Timeout, "the vehicle did not come to standstill");
    }
    observe();
    const int total = static_cast<int>(plan.segments.size());
    for (const PlannedSegment& seg : plan.segments) {
      if (!driveSegment(seg, out)) {
        return false;
      }
      observe();
      if (progress) {
        RoutineProgress p;
        p.segment = out.segmentsDriven;
        p.total = total;
        p.elapsed = (vehicle_.now() - t0_).seconds();
        p.remaining = p.elapsed / p.segment * (total - p.segment);
        progress(p);
      }
    }
    out.seconds = (vehicle_.now() - t0_).seconds();
    return true;
  }

  const std::vector<DriveRecord>& drives() const noexcept { return drives_; }
  const std::vector<Observation>& observations() const noexcept { return observations_; }

 private:
  static constexpr int kGuardSteps = 100000;  // bound on control periods per wait (2000 s at 20 ms)

  /// Steers at rest, then drives until the nominal odometry says the rotation is reached (minus the braking
  /// distance), stops and waits for standstill; false after `fail` on a fault.
  bool driveSegment(const PlannedSegment& seg, CalibrationOutcome& out) {
    if (drive_.command(hal::DriveCommand{vehicle_.now(), 0.0, seg.steering}) != Status::Ok) {
      return fail(out, Status::InvalidArgument, "steering set-point refused by the drive");
    }
    if (!settle(seg.steering)) {
      return fail(out, Status::Timeout, "the steering did not reach its set-point");
    }
    const std::int64_t startTicks = lastTicks_;
    const double braking = options_.speed * options_.speed / (2.0 * options_.deceleration);
    drives_.push_back(DriveRecord{});
    ++out.segmentsDriven;
    if (drive_.command(hal::DriveCommand{vehicle_.now(), seg.direction * options_.speed, seg.steering}) != Status::Ok) {
      return fail(out, Status::InvalidArgument, "speed set-point refused by the drive");
    }
    bool reached = false;
    for (int guard = 0; guard < kGuardSteps && !reached; ++guard) {
      pump();
      const double travelled = std::fabs(static_cast<double>(lastTicks_ - startTicks) * options_.nominal.driveScale);
      reached = travelled >= seg.wheelTravel - braking;
    }
    static_cast<void>(drive_.stop());
    if (!reached) {
      return fail(out, Status::Timeout, "the segment's travel was not reached (drive or encoder fault)");
    }
    // The builder closes a segment after its standstill time; the settle time is longer.
    if (!settle(seg.steering)) {
      return fail(out, Status::Timeout, "the vehicle did not come to standstill");
    }
    return true;
  }

  /// Lets one control period pass and feeds the encoder samples to the builder.
  void pump() {
    vehicle_.wait(options_.controlPeriod);
    hal::EncoderSample s;
    while (encoders_.read(s) == Status::Ok) {
      lastTicks_ = s.driveTicks;
      lastSteer_ = s.steeringAngle;
      SegmentEvent ev = SegmentEvent::None;
      if (builder_.addSample(s.stamp, s.driveTicks, s.steeringAngle, &ev) != Status::Ok) {
        continue;
      }
      if (ev == SegmentEvent::None || drives_.empty()) {
        continue;
      }
      drives_.back().closed = ev == SegmentEvent::Closed;
      drives_.back().segment = builder_.lastSegment();
    }
  }

  /// Waits at rest for the settle time and until the steering encoder reads the set-point.
  bool settle(double steerSet) {
    const Timestamp until = vehicle_.now() + options_.settle;
    for (int guard = 0; guard < kGuardSteps; ++guard) {
      if (vehicle_.now() >= until && drive_.isStandstill() && std::fabs(lastSteer_ - steerSet) < deg2rad(0.1)) {
        return true;
      }
      pump();
    }
    return false;
  }

  /// Takes the first sweep that starts after the vehicle settled (invalid when none comes).
  void observe() {
    static hal::LaserMeasurement scan;  // large: kept out of the stack
    const Timestamp settled = vehicle_.now();
    Observation obs;
    bool got = false;
    for (int guard = 0; guard < 500 && !got; ++guard) {
      while (laser_.read(scan) == Status::Ok) {
        got = got || scan.scan.stamp >= settled;
        if (got) {
          break;
        }
      }
      if (!got) {
        pump();
      }
    }
    if (got) {
      obs.valid = true;
      for (const hal::ReflectorObservation& o : scan.reflectors) {
        obs.reflectors.emplace_back(static_cast<double>(o.x), static_cast<double>(o.y));
      }
      KeypointTools* t = tools_.get();
      if (t != nullptr && t->detector.detect(scan.scan, t->keypoints) == Status::Ok &&
          t->describer.describe(t->detector.points(), t->keypoints, t->bsc, t->cgh) == Status::Ok) {
        obs.keypoints.assign(t->keypoints.begin(), t->keypoints.end());
        obs.bsc.assign(t->bsc.begin(), t->bsc.end());
      }
    }
    observations_.push_back(std::move(obs));
  }

  /// Stops the drive and records the failure in `out`; always false.
  bool fail(CalibrationOutcome& out, Status s, const char* message) {
    static_cast<void>(drive_.stop());
    out.status = s;
    out.message = message;
    out.seconds = (vehicle_.now() - t0_).seconds();
    return false;
  }

  CalibrationVehicle& vehicle_;
  hal::DriveControl& drive_;
  hal::EncoderSource& encoders_;
  hal::LaserSource& laser_;
  const RoutineOptions& options_;
  const Timestamp t0_;
  CalibSegmentBuilder builder_;
  std::vector<DriveRecord> drives_;
  std::vector<Observation> observations_;  // one per standstill
  std::int64_t lastTicks_ = 0;
  double lastSteer_ = 0.0;
  std::unique_ptr<KeypointTools> tools_;
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
void alignAll(const DataCollection& data, const RoutineOptions& options, const TricycleParams& params,
              const Pose2d& laserPose, Alignments& al) {
  const std::vector<DriveRecord>& drives = data.drives();
  const std::vector<Observation>& observations = data.observations();
  for (std::size_t i = 0; i < drives.size(); ++i) {
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
void solve(const DataCollection& data, const RoutineOptions& options, Alignments& al, CalibrationOutcome& out) {
  CalibrationOptions calibOptions;
  calibOptions.nominal = options.nominal;
  alignAll(data, options, options.nominal, options.nominalLaser, al);
  out.status = calibrateAtc(al.span(), calibOptions, out.result);
  if (out.status == Status::Ok && al.segments.size() < data.drives().size()) {
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

CalibrationOutcome runCalibrationRoutine(CalibrationVehicle& vehicle, const CalibrationPlan& plan,
                                         const RoutineOptions& options,
                                         const std::function<void(const RoutineProgress&)>& progress) {
  CalibrationOutcome out;
  DataCollection data(vehicle, options);
  if (!data.run(plan, progress, out)) {
    return out;
  }
  Alignments al(data.drives().size());
  solve(data, options, al, out);
  summarize(al, out);
  return out;
}

}  // namespace agv::calibration
