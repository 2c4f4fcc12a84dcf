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

}  // namespace

Status planCalibration(const PlanRequest& r, CalibrationPlan& plan, std::string& error) {
  plan = CalibrationPlan{};
  plan.request = r;
  error.clear();
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
  const int n = r.segmentsPerPhase;
  for (int k = 0; k < n; ++k) {
    const double a =
        n == 1 ? r.minSteering
               : r.minSteering + (r.maxSteering - r.minSteering) * static_cast<double>(k) / static_cast<double>(n - 1);
    const double radius = r.wheelbase / std::tan(a);
    for (int side : {1, -1}) {
      // The forward arc and the backward one retracing it sweep the same ground: sample the arc
      // (<= 2 deg steps) and test the logical point and the vehicle's front against the area.
      const int steps = static_cast<int>(std::ceil(r.rotation / deg2rad(2.0)));
      for (int i = 0; i <= steps; ++i) {
        const double t = r.rotation * static_cast<double>(i) / static_cast<double>(steps);
        const Pose2d local{radius * std::sin(t), side * radius * (1.0 - std::cos(t)), side * t};
        const Pose2d p = r.start.compose(local);
        const Eigen::Vector2d front = p.transformPoint(Eigen::Vector2d(r.frontOverhang, 0.0));
        for (const Eigen::Vector2d& q : {Eigen::Vector2d(p.x, p.y), front}) {
          if (!inside(r.area, q.x(), q.y(), r.clearance)) {
            error = format(
                "the %s circle at %.1f deg steering (radius %.2f m) leaves the free area at (%.2f, %.2f) "
                "(clearance %.2f m): enlarge the area, move the start, raise the minimum steering or lower beta",
                side > 0 ? "left" : "right", rad2deg(a), radius, q.x(), q.y(), r.clearance);
            plan.segments.clear();
            return Status::OutOfRange;
          }
        }
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

}  // namespace

CalibrationOutcome runCalibrationRoutine(CalibrationVehicle& vehicle, const CalibrationPlan& plan,
                                         const RoutineOptions& options,
                                         const std::function<void(const RoutineProgress&)>& progress) {
  CalibrationOutcome out;
  hal::DriveControl& drive = vehicle.drive();
  hal::EncoderSource& encoders = vehicle.encoders();
  hal::LaserSource& laser = vehicle.laser();
  const TricycleParams& nominal = options.nominal;
  const Timestamp t0 = vehicle.now();
  CalibSegmentBuilder builder;
  std::vector<DriveRecord> drives;
  std::vector<Observation> observations;  // one per standstill
  std::int64_t lastTicks = 0;
  double lastSteer = 0.0;
  std::unique_ptr<KeypointTools> tools;
  if (options.egomotion == EgomotionSource::Keypoints) {
    tools = std::make_unique<KeypointTools>();
  }
  static hal::LaserMeasurement scan;  // large: kept out of the stack

  // Lets one control period pass and feeds the encoder samples to the builder.
  auto pump = [&]() {
    vehicle.wait(options.controlPeriod);
    hal::EncoderSample s;
    while (encoders.read(s) == Status::Ok) {
      lastTicks = s.driveTicks;
      lastSteer = s.steeringAngle;
      SegmentEvent ev = SegmentEvent::None;
      if (builder.addSample(s.stamp, s.driveTicks, s.steeringAngle, &ev) != Status::Ok) {
        continue;
      }
      if (ev == SegmentEvent::None || drives.empty()) {
        continue;
      }
      drives.back().closed = ev == SegmentEvent::Closed;
      drives.back().segment = builder.lastSegment();
    }
  };
  const int guardSteps = 100000;  // bound on control periods per wait (2000 s at 20 ms)
  // Waits at rest for the settle time and until the steering encoder reads the set-point.
  auto settle = [&](double steerSet) {
    const Timestamp until = vehicle.now() + options.settle;
    for (int guard = 0; guard < guardSteps; ++guard) {
      if (vehicle.now() >= until && drive.isStandstill() && std::fabs(lastSteer - steerSet) < deg2rad(0.1)) {
        return true;
      }
      pump();
    }
    return false;
  };
  // Takes the first sweep that starts after the vehicle settled.
  auto observe = [&]() {
    const Timestamp settled = vehicle.now();
    Observation obs;
    bool got = false;
    for (int guard = 0; guard < 500 && !got; ++guard) {
      while (laser.read(scan) == Status::Ok) {
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
      if (tools && tools->detector.detect(scan.scan, tools->keypoints) == Status::Ok &&
          tools->describer.describe(tools->detector.points(), tools->keypoints, tools->bsc, tools->cgh) == Status::Ok) {
        obs.keypoints.assign(tools->keypoints.begin(), tools->keypoints.end());
        obs.bsc.assign(tools->bsc.begin(), tools->bsc.end());
      }
    }
    observations.push_back(std::move(obs));
  };
  auto fail = [&](Status s, const std::string& message) {
    static_cast<void>(drive.stop());
    out.status = s;
    out.message = message;
    out.seconds = (vehicle.now() - t0).seconds();
    return out;
  };

  if (!settle(lastSteer)) {
    return fail(Status::Timeout, "the vehicle did not come to standstill");
  }
  observe();
  const int total = static_cast<int>(plan.segments.size());
  for (const PlannedSegment& seg : plan.segments) {
    // Steer at rest, then drive until the nominal odometry says the rotation is reached (minus the
    // braking distance), stop and observe.
    if (drive.command(hal::DriveCommand{vehicle.now(), 0.0, seg.steering}) != Status::Ok) {
      return fail(Status::InvalidArgument, "steering set-point refused by the drive");
    }
    if (!settle(seg.steering)) {
      return fail(Status::Timeout, "the steering did not reach its set-point");
    }
    const std::int64_t startTicks = lastTicks;
    const double braking = options.speed * options.speed / (2.0 * options.deceleration);
    drives.push_back(DriveRecord{});
    ++out.segmentsDriven;
    if (drive.command(hal::DriveCommand{vehicle.now(), seg.direction * options.speed, seg.steering}) != Status::Ok) {
      return fail(Status::InvalidArgument, "speed set-point refused by the drive");
    }
    bool reached = false;
    for (int guard = 0; guard < guardSteps && !reached; ++guard) {
      pump();
      const double travelled = std::fabs(static_cast<double>(lastTicks - startTicks) * nominal.driveScale);
      reached = travelled >= seg.wheelTravel - braking;
    }
    static_cast<void>(drive.stop());
    if (!reached) {
      return fail(Status::Timeout, "the segment's travel was not reached (drive or encoder fault)");
    }
    // The builder closes a segment after its standstill time; the settle time is longer.
    if (!settle(seg.steering)) {
      return fail(Status::Timeout, "the vehicle did not come to standstill");
    }
    observe();
    if (progress) {
      RoutineProgress p;
      p.segment = out.segmentsDriven;
      p.total = total;
      p.elapsed = (vehicle.now() - t0).seconds();
      p.remaining = p.elapsed / p.segment * (total - p.segment);
      progress(p);
    }
  }
  out.seconds = (vehicle.now() - t0).seconds();

  // Egomotion of every closed segment, the guess predicted by `params` and `laserPose`; segments
  // whose alignment fails stay out. Two passes: the nominal guess can be off by metres at far
  // reflectors on the long low-steering arcs, so the segments that fail with it are aligned again
  // from the first solve's estimate.
  std::vector<int> aligned(drives.size(), 0);
  std::vector<CalibSegment> segments;
  std::vector<double> rms(drives.size(), 0.0);
  std::vector<double> matches(drives.size(), 0.0);
  CalibrationOptions calibOptions;
  calibOptions.nominal = nominal;
  auto alignAll = [&](const TricycleParams& params, const Pose2d& laserPose) {
    for (std::size_t i = 0; i < drives.size(); ++i) {
      const Observation& a = observations[i];
      const Observation& b = observations[i + 1];
      if (!drives[i].closed || aligned[i] != 0 || !a.valid || !b.valid) {
        continue;
      }
      const Pose2d guess = predictedEgomotion(toCalibSegment(drives[i].segment, Pose2d{}), params, laserPose);
      Pose2d motion;
      Status s = Status::NotInitialized;
      if (options.egomotion == EgomotionSource::Reflectors) {
        ReflectorAlignment al;
        ReflectorAlignmentOptions ao;
        ao.associationGate = options.reflectorGate;
        s = alignReflectors(Span<const Eigen::Vector2d>(a.reflectors.data(), a.reflectors.size()),
                            Span<const Eigen::Vector2d>(b.reflectors.data(), b.reflectors.size()), guess, ao, al);
        motion = al.motion;
        rms[i] = al.rms;
        matches[i] = static_cast<double>(al.matches);
      } else {
        KeypointAlignment al;
        KeypointAlignmentOptions ko;
        ko.guessTranslationGate = options.keypointGuessTranslation;
        ko.guessRotationGate = options.keypointGuessRotation;
        const KeypointScanView va{{a.keypoints.data(), a.keypoints.size()}, {a.bsc.data(), a.bsc.size()}, {}};
        const KeypointScanView vb{{b.keypoints.data(), b.keypoints.size()}, {b.bsc.data(), b.bsc.size()}, {}};
        s = alignKeypoints(va, vb, guess, ko, al);
        motion = al.motion;
        rms[i] = al.rms;
        matches[i] = static_cast<double>(al.inliers);
      }
      if (s == Status::Ok) {
        aligned[i] = 1;
        segments.push_back(toCalibSegment(drives[i].segment, motion));
      }
    }
  };
  const auto span = [&]() { return Span<const CalibSegment>(segments.data(), segments.size()); };
  alignAll(nominal, options.nominalLaser);
  out.status = calibrateAtc(span(), calibOptions, out.result);
  if (out.status == Status::Ok && segments.size() < drives.size()) {
    const std::size_t before = segments.size();
    alignAll(out.result.params, out.result.laserPose);
    if (segments.size() > before) {
      out.status = calibrateAtc(span(), calibOptions, out.result);
    }
  }
  out.stcStatus = calibrateStc(span(), calibOptions, out.stc);
  if (out.status == Status::Ok) {
    out.refinedStatus = refineCalibration(span(), out.result.params, out.result.laserPose,
                                          options.refinementFor(options.egomotion), out.refined);
  }
  out.segmentsUsed = static_cast<int>(segments.size());
  double rmsSum = 0.0;
  double matchSum = 0.0;
  for (std::size_t i = 0; i < drives.size(); ++i) {
    if (aligned[i] == 0) {
      ++out.segmentsRejected;
    } else {
      rmsSum += rms[i];
      matchSum += matches[i];
    }
  }
  out.meanAlignmentRms = segments.empty() ? 0.0 : rmsSum / static_cast<double>(segments.size());
  out.meanMatches = segments.empty() ? 0.0 : matchSum / static_cast<double>(segments.size());
  if (out.status != Status::Ok) {
    out.message = std::string(toString(out.status));
    if (out.result.report.failed != CalibCondition::None) {
      out.message += std::string(" (") + toString(out.result.report.failed) + ")";
    }
  }
  return out;
}

}  // namespace agv::calibration
