#include "calibration_routine.hpp"

#include <cmath>
#include <vector>

#include "agv/calib/reflector_alignment.hpp"
#include "agv/calib/segment_builder.hpp"
#include "agv/core/span.hpp"
#include "agv/sim/sim_laser.hpp"
#include "agv/sim/sim_vehicle.hpp"

namespace agv::hil {

namespace {

struct DriveRecord {
  bool closed = false;
  BuiltSegment segment;
};

}  // namespace

CalibrationOutcome runCalibration(const sim::RayCaster& caster, const ScenarioConfig& config,
                                  const CalibrationPlan& plan) {
  CalibrationOutcome out;
  sim::SimVehicle vehicle(config.vehicle, config.seed * 7919U + 17U);
  sim::SimLaser laser(caster, config.laser, config.seed * 104729U + 3U);
  hal::DriveControl& drive = vehicle;
  sim::CanEncoderSource canEncoders(vehicle, config.can);  // encoder samples only through CAN frames
  hal::EncoderSource& encoders = canEncoders;
  const TricycleParams& nominal = config.nominal.kinematics;

  Timestamp t{};
  vehicle.reset(plan.home, t);
  CalibSegmentBuilder builder;
  std::vector<DriveRecord> drives;
  std::vector<std::vector<Eigen::Vector2d>> observations;  // one per standstill
  std::int64_t lastTicks = 0;
  double lastSteer = 0.0;
  const Duration step = config.controlPeriod;

  // Advances the simulation by one control period and feeds the encoder samples to the builder.
  auto pump = [&]() {
    t = t + step;
    vehicle.advanceTo(t);
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
  // Waits at rest for the settle time and until the steering encoder reads the set-point.
  auto settle = [&](double steerSet) {
    const Timestamp until = t + plan.settle;
    for (int guard = 0; guard < 100000; ++guard) {
      if (t >= until && drive.isStandstill() && std::fabs(lastSteer - steerSet) < deg2rad(0.1)) {
        break;
      }
      pump();
    }
  };
  static hal::LaserMeasurement scan;
  auto observe = [&]() {
    std::vector<Eigen::Vector2d> pts;
    if (laser.scan(vehicle.trueLaserPose(), t, scan) == Status::Ok) {
      for (const hal::ReflectorObservation& o : scan.reflectors) {
        pts.emplace_back(static_cast<double>(o.x), static_cast<double>(o.y));
      }
    }
    observations.push_back(std::move(pts));
  };

  settle(lastSteer);
  observe();
  for (int k = 0; k < plan.steeringCount; ++k) {
    for (int sign : {1, -1}) {
      const double steer = sign * deg2rad(plan.steeringDeg[k]);
      for (int dir : {1, -1}) {
        // Steer at rest, then drive until the nominal odometry says the rotation is reached
        // (minus the braking distance), stop and observe.
        if (drive.command(hal::DriveCommand{t, 0.0, steer}) != Status::Ok) {
          out.status = Status::InvalidArgument;
          out.message = "steering set-point refused";
          return out;
        }
        settle(steer);
        const std::int64_t startTicks = lastTicks;
        const double wheelTravel = plan.rotation * nominal.wheelbase / std::fabs(std::sin(steer));
        const double braking = plan.speed * plan.speed / (2.0 * config.vehicle.acceleration);
        drives.push_back(DriveRecord{});
        ++out.segmentsDriven;
        static_cast<void>(drive.command(hal::DriveCommand{t, dir * plan.speed, steer}));
        for (int guard = 0; guard < 100000; ++guard) {
          pump();
          const double travelled = std::fabs(static_cast<double>(lastTicks - startTicks) * nominal.driveScale);
          if (travelled >= wheelTravel - braking) {
            break;
          }
        }
        static_cast<void>(drive.stop());
        settle(steer);
        // The builder closes a segment after its standstill time; settle() is longer.
        observe();
      }
    }
  }
  out.simSeconds = t.seconds();
  out.can = canEncoders.counters();

  // Egomotion of every closed segment by reflector alignment, the guess predicted by `params`
  // and `laserPose`; segments whose alignment fails stay out. Two passes: the nominal guess can be
  // off by metres at far reflectors on the long low-steering arcs, so the segments that fail with
  // it are aligned again from the first solve's estimate.
  std::vector<int> aligned(drives.size(), 0);
  std::vector<CalibSegment> segments;
  std::vector<double> rms(drives.size(), 0.0);
  CalibrationOptions options;
  options.nominal = nominal;
  auto alignAll = [&](const TricycleParams& params, const Pose2d& laserPose) {
    for (std::size_t i = 0; i < drives.size(); ++i) {
      if (!drives[i].closed || aligned[i] != 0) {
        continue;
      }
      const std::vector<Eigen::Vector2d>& a = observations[i];
      const std::vector<Eigen::Vector2d>& b = observations[i + 1];
      const Pose2d guess = predictedEgomotion(toCalibSegment(drives[i].segment, Pose2d{}), params, laserPose);
      ReflectorAlignment al;
      ReflectorAlignmentOptions ao;
      ao.associationGate = 1.0;  // below half the smallest reflector spacing of the built-in warehouse
      if (alignReflectors(Span<const Eigen::Vector2d>(a.data(), a.size()),
                          Span<const Eigen::Vector2d>(b.data(), b.size()), guess, ao, al) == Status::Ok) {
        aligned[i] = 1;
        rms[i] = al.rms;
        segments.push_back(toCalibSegment(drives[i].segment, al.motion));
      }
    }
  };
  alignAll(nominal, config.nominal.laserMount);
  out.status = calibrateAtc(Span<const CalibSegment>(segments.data(), segments.size()), options, out.result);
  if (out.status == Status::Ok && static_cast<int>(segments.size()) < static_cast<int>(drives.size())) {
    const std::size_t before = segments.size();
    alignAll(out.result.params, out.result.laserPose);
    if (segments.size() > before) {
      out.status = calibrateAtc(Span<const CalibSegment>(segments.data(), segments.size()), options, out.result);
    }
  }
  out.segmentsUsed = static_cast<int>(segments.size());
  double rmsSum = 0.0;
  for (std::size_t i = 0; i < drives.size(); ++i) {
    rmsSum += rms[i];
    if (aligned[i] == 0) {
      ++out.segmentsRejected;
    }
  }
  out.meanAlignmentRms = segments.empty() ? 0.0 : rmsSum / static_cast<double>(segments.size());
  if (out.status != Status::Ok) {
    out.message = std::string(toString(out.status));
    if (out.result.report.failed != CalibCondition::None) {
      out.message += std::string(" (") + toString(out.result.report.failed) + ")";
    }
  }
  return out;
}

}  // namespace agv::hil
