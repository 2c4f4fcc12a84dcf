#include "vehicle_loop.hpp"

#include <cmath>
#include <cstdio>

#include "agv/falko/falko_detector.hpp"
#include "agv/localization/landmark_map_io.hpp"
#include "agv/localization/localizer.hpp"
#include "agv/localization/odometry.hpp"
#include "agv/localization/sweep_motion.hpp"

namespace agv::vehicle {
namespace {

constexpr double kPi = 3.14159265358979323846;
// Encoder samples handled per cycle at most (the rest wait in the socket for the next cycle).
constexpr int kMaxSamplesPerCycle = 32;

/// Field of view of the model [rad], centred on the laser's x axis.
double fieldOfView(drivers::SickLaserModel m) {
  switch (m) {
    case drivers::SickLaserModel::Lms5xx:
      return 190.0 * kPi / 180.0;
    case drivers::SickLaserModel::Nav350:
      return 2.0 * kPi;
    case drivers::SickLaserModel::Lms1xx:
    case drivers::SickLaserModel::Tim:
      break;
  }
  return 270.0 * kPi / 180.0;
}

std::string calibrationErrorText(Status s, const CalibrationFileReport& r) {
  const char* why = toString(s);
  switch (s) {
    case Status::EmptyInput:
      why = "no 'agvnav-calibration 1' header";
      break;
    case Status::Malformed:
      why = "malformed line (header, unknown key, bad number or field count)";
      break;
    case Status::InvalidArgument:
      why = "given twice";
      break;
    case Status::OutOfRange:
      why = "value or sigma out of range";
      break;
    case Status::NotFound:
      why = "missing";
      break;
    default:
      break;
  }
  return r.key != nullptr ? std::string(r.key) + ": " + why : std::string(why);
}

std::string mapErrorText(Status s) {
  switch (s) {
    case Status::EmptyInput:
      return "no 'agvnav-landmarks 1' header";
    case Status::Malformed:
      return "malformed line (header, kind, number or field count)";
    case Status::OutOfRange:
      return "coordinate beyond 1e6 m, negative sigma or id 0";
    case Status::InvalidArgument:
      return "duplicate landmark id";
    case Status::CapacityExceeded:
      return "more landmarks than the map holds (kMaxLandmarks)";
    default:
      return toString(s);
  }
}

}  // namespace

bool loadVehicleFiles(const VehicleConfig& config, VehicleFiles& files, ConfigError& error) {
  std::string text;
  if (!readTextFile(config.calibrationFile, text)) {
    error = ConfigError{config.calibrationFile, "calibration.file", "cannot read the calibration file"};
    return false;
  }
  CalibrationFileReport crep;
  const Status cs = parseCalibrationFile(Span<const char>(text.data(), text.size()), files.calibration, &crep);
  if (cs != Status::Ok) {
    error = ConfigError{config.calibrationFile + (crep.errorLine > 0 ? ":" + std::to_string(crep.errorLine) : ""),
                        "calibration.file", "refused: " + calibrationErrorText(cs, crep)};
    return false;
  }
  if (!readTextFile(config.mapFile, text)) {
    error = ConfigError{config.mapFile, "map.file", "cannot read the map file"};
    return false;
  }
  LandmarkMapParams mp;
  mp.mode = config.mapMode;
  files.map = std::make_unique<LandmarkMap>(mp);
  LandmarkMapParseReport mrep;
  const Status ms = parseLandmarkMap(Span<const char>(text.data(), text.size()), *files.map, &mrep);
  if (ms != Status::Ok) {
    error = ConfigError{config.mapFile + (mrep.errorLine > 0 ? ":" + std::to_string(mrep.errorLine) : ""), "map.file",
                        "refused: " + mapErrorText(ms)};
    return false;
  }
  return true;
}

drivers::CanopenEncoderSourceConfig encoderSourceConfig(const VehicleConfig& config) {
  drivers::CanopenEncoderSourceConfig c = config.can;
  c.interfaceName = config.canInterface.c_str();
  return c;
}

struct VehicleLoop::Impl {
  Impl(const VehicleConfig& c, VehicleFiles&& f, const VehicleDevices& d)
      : config(c),
        calibration(f.calibration),
        map(std::move(f.map)),
        encoders(d.encoders),
        laser(d.laser),
        plc(d.plc),
        odometry(calibration.params, TricycleNoiseParams{}),
        localizer(std::make_unique<Localizer>(localizerParams(config, calibration))),
        detector(std::make_unique<FalkoDetector>()),
        keypoints(std::make_unique<FalkoKeypoints>()),
        observations(std::make_unique<ScanObservations>()),
        measurement(std::make_unique<hal::LaserMeasurement>()) {}

  static LocalizerParams localizerParams(const VehicleConfig& c, const VehicleCalibration& cal) {
    LocalizerParams p;
    p.laser.mounting = cal.laserPose;
    const bool nav = c.laser.model == drivers::SickLaserModel::Nav350;
    p.laser.rangeMin = std::max(0.3, static_cast<double>(nav ? c.laser.nav.rangeMin : c.laser.scan.rangeMin));
    p.laser.rangeMax = static_cast<double>(nav ? c.laser.nav.rangeMax : c.laser.scan.rangeMax);
    const double fov = fieldOfView(c.laser.model);
    p.laser.angleMin = fov >= 2.0 * kPi ? -kPi : -0.5 * fov;
    p.laser.angleMax = fov >= 2.0 * kPi ? kPi : 0.5 * fov;
    return p;
  }

  VehicleConfig config;
  VehicleCalibration calibration;
  std::unique_ptr<LandmarkMap> map;
  drivers::CanopenEncoderSource& encoders;
  drivers::SickLaserSource& laser;
  hal::PlcLink& plc;
  TricycleOdometry odometry;
  /// Dead reckoning of the odometry increments, for the motion within a sweep (its origin is
  /// arbitrary: only the motion between two instants of a sweep is used).
  Pose2d deadReckoning{};
  std::unique_ptr<MotionHistory> motion = std::make_unique<MotionHistory>();
  std::unique_ptr<Localizer> localizer;
  std::unique_ptr<FalkoDetector> detector;
  std::unique_ptr<FalkoKeypoints> keypoints;
  std::unique_ptr<ScanObservations> observations;
  std::unique_ptr<hal::LaserMeasurement> measurement;

  bool active = false;  ///< localizing (reset from a set-pose, no Stop since)
  /// The last PLC command was one this program does not carry out (Calibrate): published as
  /// health bit 8 until the next command it carries out.
  bool commandRefused = false;
  bool haveSample = false;
  hal::EncoderSample lastSample{};
  bool pendingInitialPose = false;
  Pose2d pendingPose{};
  Status encoderStatus = Status::NotInitialized;
  Status laserStatus = Status::NotInitialized;
  Status lastFault = Status::Ok;
  std::uint16_t visibleReflectors = 0;
  Timestamp nextPublish{};
  Status lastLoggedEncoder = Status::Ok;
  Status lastLoggedLaser = Status::Ok;
  RuntimeCounters counters{};
  std::uint16_t healthBits = 0;
};

VehicleLoop::VehicleLoop(const VehicleConfig& config, VehicleFiles&& files, const VehicleDevices& devices)
    : impl_(std::make_unique<Impl>(config, std::move(files), devices)) {
  if (config.haveInitialPose) {
    impl_->pendingInitialPose = true;
    impl_->pendingPose = config.initialPose;
  }
}

VehicleLoop::~VehicleLoop() = default;

const RuntimeCounters& VehicleLoop::counters() const noexcept {
  return impl_->counters;
}

std::uint16_t VehicleLoop::healthBits() const noexcept {
  return impl_->healthBits;
}

const VehicleCalibration& VehicleLoop::calibration() const noexcept {
  return impl_->calibration;
}

void VehicleLoop::cycle() noexcept {
  Impl& m = *impl_;
  RuntimeCounters& counters = m.counters;
  ++counters.cycles;

  // Encoders -> odometry -> prediction.
  for (int i = 0; i < kMaxSamplesPerCycle; ++i) {
    hal::EncoderSample s;
    m.encoderStatus = m.encoders.read(s);
    if (m.encoderStatus != Status::Ok) {
      break;
    }
    ++counters.encoderSamples;
    const Result<OdometryIncrement> inc = m.odometry.step(TricycleSample{s.stamp, s.driveTicks, s.steeringAngle});
    if (inc.ok()) {
      m.deadReckoning = m.deadReckoning * inc.value().delta;
      if (m.active) {
        (void)m.localizer->predict(inc.value());
      }
    }
    (void)m.motion->add(s.stamp, m.deadReckoning);
    m.haveSample = true;
    m.lastSample = s;
  }
  const Status encHealth = m.encoders.health();

  // PLC commands.
  hal::PlcCommand cmd;
  while (m.plc.readCommand(cmd) == Status::Ok) {
    ++counters.commands;
    if (cmd.kind == hal::PlcCommandKind::Localize) {
      m.pendingInitialPose = true;
      m.pendingPose = cmd.initialPose;
      m.commandRefused = false;
    } else if (cmd.kind == hal::PlcCommandKind::Stop) {
      m.pendingInitialPose = false;
      m.active = false;  // idle until the next Localize command
      m.commandRefused = false;
    } else {
      // Calibrate: the routine drives the vehicle, which this program cannot do (no drive
      // command driver, docs/calibration.md). Refused visibly; localization goes on unchanged.
      ++counters.refusedCommands;
      m.commandRefused = true;
      std::fprintf(stderr,
                   "agvnav-vehicle: PLC command %u (calibrate) refused: this program does not drive the vehicle; "
                   "health bit 8 stays set until the next command\n",
                   static_cast<unsigned>(cmd.kind));
    }
  }
  if (m.pendingInitialPose) {
    const Timestamp t = m.haveSample ? m.lastSample.stamp : drivers::monotonicNow();
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    cov(0, 0) = cov(1, 1) = 0.05 * 0.05;
    cov(2, 2) = 0.02 * 0.02;
    if (m.localizer->reset(t, m.pendingPose, cov) == Status::Ok) {
      m.active = true;
      m.odometry.reset();
      if (m.haveSample) {
        (void)m.odometry.step(TricycleSample{m.lastSample.stamp, m.lastSample.driveTicks, m.lastSample.steeringAngle});
      }
    }
    m.pendingInitialPose = false;
  }

  // Laser -> observations -> correction.
  hal::LaserMeasurement& meas = *m.measurement;
  m.laserStatus = m.laser.read(meas);
  if (m.laserStatus == Status::Ok) {
    ++counters.sweeps;
    ScanObservations& obs = *m.observations;
    obs.points.clear();
    // Every point is moved to the sensor frame at the end of the sweep with the motion the
    // odometry saw during the sweep (per beam for the corners; for the reflectors at the time the
    // device stamped, the NAV350's, else per bearing).
    const SweepCompensation sweep(*m.motion, meas.scan, m.calibration.laserPose);
    obs.stamp = sweep.referenceStamp();
    obs.kindsDetected = 0;
    m.visibleReflectors = 0;
    if (meas.hasReflectors) {
      obs.kindsDetected |= landmarkKindBit(LandmarkKind::Reflector);
      m.visibleReflectors = static_cast<std::uint16_t>(meas.reflectors.size());
      for (std::size_t i = 0; i < meas.reflectors.size(); ++i) {
        const hal::ReflectorObservation& r = meas.reflectors[i];
        const auto x = static_cast<double>(r.x);
        const auto y = static_cast<double>(r.y);
        const Pose2d::Vector2 p = r.stamped ? sweep.atStamp(r.stamp, x, y) : sweep.atBearing(x, y);
        (void)obs.points.push_back(PointObservation{p.x(), p.y(), LandmarkKind::Reflector});
      }
    }
    if (m.config.useCorners) {
      m.keypoints->clear();
      if (m.detector->detect(meas.scan, *m.keypoints) == Status::Ok) {
        obs.kindsDetected |= landmarkKindBit(LandmarkKind::Corner);
        for (std::size_t i = 0; i < m.keypoints->size(); ++i) {
          const FalkoKeypoint& k = (*m.keypoints)[i];
          if (k.refined) {
            const Pose2d::Vector2 p = sweep.atBeam(k.beamIndex, static_cast<double>(k.x), static_cast<double>(k.y));
            (void)obs.points.push_back(PointObservation{p.x(), p.y(), LandmarkKind::Corner});
          }
        }
      }
    }
    if (m.active) {
      // The sweep's ranges let the localizer tell hidden landmarks from missed ones.
      (void)m.localizer->correct(obs, meas.scan, *m.map);
      ++counters.corrections;
    }
  }
  const Status laserHealth = m.laser.health();

  // Log changes of the devices' state (rare; not in the steady state).
  if (encHealth != m.lastLoggedEncoder) {
    std::fprintf(stderr, "agvnav-vehicle: encoders: %s\n", toString(encHealth));
    m.lastLoggedEncoder = encHealth;
  }
  if (laserHealth != m.lastLoggedLaser) {
    std::fprintf(stderr, "agvnav-vehicle: laser: %s\n", toString(laserHealth));
    m.lastLoggedLaser = laserHealth;
  }

  // Publication.
  const Timestamp now = drivers::monotonicNow();
  if (now < m.nextPublish) {
    return;
  }
  m.nextPublish = m.nextPublish + m.config.publishPeriod;
  if (now - m.nextPublish > m.config.publishPeriod) {
    m.nextPublish = now + m.config.publishPeriod;  // late: no burst
  }
  std::uint16_t bits = 0;
  auto set = [&bits](drivers::plc::PlcHealthBit b, bool on) {
    if (on) {
      bits = static_cast<std::uint16_t>(bits | static_cast<std::uint16_t>(b));
    }
  };
  set(drivers::plc::PlcHealthBit::LaserOk, laserHealth == Status::Ok);
  set(drivers::plc::PlcHealthBit::LaserTimeout, laserHealth == Status::Timeout);
  set(drivers::plc::PlcHealthBit::EncodersOk, encHealth == Status::Ok);
  set(drivers::plc::PlcHealthBit::EncoderTimeout, encHealth == Status::Timeout);
  set(drivers::plc::PlcHealthBit::DeviceFault,
      encHealth == Status::DeviceFault || m.laserStatus == Status::DeviceFault);
  set(drivers::plc::PlcHealthBit::MapLoaded, m.map->size() > 0U);
  set(drivers::plc::PlcHealthBit::CalibrationValid, true);  // the program refuses to start without one
  set(drivers::plc::PlcHealthBit::CommandRejected, m.commandRefused);
  m.healthBits = bits;  // read by the PLC link that carries them (VehicleDevices::plc)

  Status last = Status::Ok;
  if (encHealth != Status::Ok && encHealth != Status::NotInitialized) {
    last = encHealth;
  } else if (laserHealth != Status::Ok && laserHealth != Status::NotInitialized) {
    last = laserHealth;
  } else if (m.active && m.localizer->health().status != Status::Ok) {
    last = m.localizer->health().status;
  } else if (m.commandRefused) {
    last = Status::Unsupported;
  }
  hal::PoseReport r;
  r.stamp = m.active ? m.localizer->stamp() : now;
  r.pose = m.localizer->pose();
  r.covariance = m.localizer->covariance();
  // Without encoder samples the pose cannot follow the vehicle: it is published as lost (the PLC
  // must stop) until the encoders are back.
  const bool encodersFailed = encHealth == Status::Timeout || encHealth == Status::DeviceFault;
  r.health.mode = !m.active                                 ? hal::NavMode::Idle
                  : (m.localizer->lost() || encodersFailed) ? hal::NavMode::Lost
                                                            : hal::NavMode::Localizing;
  r.health.lastStatus = last;
  r.health.matchedLandmarks = m.localizer->health().used;
  r.health.visibleReflectors = m.visibleReflectors;
  (void)m.plc.publish(r);
  ++counters.publications;
}

}  // namespace agv::vehicle
