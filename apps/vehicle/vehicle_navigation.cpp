#include "vehicle_navigation.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "agv/localization/landmark_map_io.hpp"
#include "agv/report/text_file.hpp"

namespace agv::vehicle {
namespace {

constexpr double kPi = 3.14159265358979323846;

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
      why = "no 'agvnav-calibration 2' header";
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
  if (r.detail != nullptr) {
    why = r.detail;
  }
  return r.key != nullptr ? std::string(r.key) + ": " + why : std::string(why);
}

std::string mapErrorText(Status s, const LandmarkMapParseReport& r) {
  if (r.detail != nullptr) {
    return r.detail;
  }
  switch (s) {
    case Status::EmptyInput:
      return "no 'agvnav-landmarks 2' header";
    case Status::Malformed:
      return "malformed line (kind, number or field count)";
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

/// The warning for a file of format version 1, which has no `end` line.
std::string versionOneWarning(const std::string& path, const char* key, const char* header, std::size_t records) {
  return path + ": " + key + ": format version 1 has no 'end' line: a file cut short at a line end cannot be told " +
         "from a complete one. Once its " + std::to_string(records) +
         " records are checked, make it version 2: " + "header '" + header + " 2' and a last line 'end " +
         std::to_string(records) + "'";
}

}  // namespace

bool loadVehicleFiles(const VehicleConfig& config, VehicleFiles& files, ConfigError& error) {
  std::string text;
  std::string why;
  if (!report::readTextFile(config.calibrationFile, text, why)) {
    error = ConfigError{config.calibrationFile, "calibration.file", "refused: " + why};
    return false;
  }
  CalibrationFileReport crep;
  const Status cs = parseCalibrationFile(Span<const char>(text.data(), text.size()), files.calibration, &crep);
  if (cs != Status::Ok) {
    error = ConfigError{config.calibrationFile + (crep.errorLine > 0 ? ":" + std::to_string(crep.errorLine) : ""),
                        "calibration.file", "refused: " + calibrationErrorText(cs, crep)};
    return false;
  }
  files.warnings.clear();
  if (crep.version < kCalibrationFileFormatVersion) {
    files.warnings.push_back(
        versionOneWarning(config.calibrationFile, "calibration.file", "agvnav-calibration", crep.records));
  }
  if (!report::readTextFile(config.mapFile, text, why)) {
    error = ConfigError{config.mapFile, "map.file", "refused: " + why};
    return false;
  }
  LandmarkMapParams mp;
  mp.mode = config.mapMode;
  files.map = std::make_unique<LandmarkMap>(mp);
  LandmarkMapParseReport mrep;
  const Status ms = parseLandmarkMap(Span<const char>(text.data(), text.size()), *files.map, &mrep);
  if (ms != Status::Ok) {
    error = ConfigError{config.mapFile + (mrep.errorLine > 0 ? ":" + std::to_string(mrep.errorLine) : ""), "map.file",
                        "refused: " + mapErrorText(ms, mrep)};
    return false;
  }
  if (mrep.version < kLandmarkMapFormatVersion) {
    files.warnings.push_back(versionOneWarning(config.mapFile, "map.file", "agvnav-landmarks", mrep.records));
  }
  return true;
}

drivers::CanopenEncoderSourceConfig encoderSourceConfig(const VehicleConfig& config) {
  drivers::CanopenEncoderSourceConfig c = config.can;
  c.interfaceName = config.canInterface.c_str();
  return c;
}

nav::PipelineParams pipelineParams(const VehicleConfig& c, const VehicleCalibration& cal) {
  nav::PipelineParams p;
  p.kinematics = cal.params;
  LaserModel& laser = p.localizer.laser;
  laser.mounting = cal.laserPose;
  const bool nav = c.laser.model == drivers::SickLaserModel::Nav350;
  laser.rangeMin = std::max(0.3, static_cast<double>(nav ? c.laser.nav.rangeMin : c.laser.scan.rangeMin));
  laser.rangeMax = static_cast<double>(nav ? c.laser.nav.rangeMax : c.laser.scan.rangeMax);
  const double fov = fieldOfView(c.laser.model);
  laser.angleMin = fov >= 2.0 * kPi ? -kPi : -0.5 * fov;
  laser.angleMax = fov >= 2.0 * kPi ? kPi : 0.5 * fov;
  p.observations.reflectors = true;  // used when the laser reports them (NAV350)
  p.observations.corners = c.useCorners;
  p.observations.surfaceMap = c.useSurfaceMap;
  p.relocalization.enabled = c.relocalize;
  p.publishPeriod = c.publishPeriod;
  p.calibrationValid = true;  // the program refuses to start without a checked calibration file
  return p;
}

void logToStderr(void* /*context*/, const char* line) {
  std::fprintf(stderr, "agvnav-vehicle: %s\n", line);
}

VehicleNavigation::VehicleNavigation(const VehicleConfig& config, VehicleFiles&& files,
                                     const nav::PipelineDevices& devices)
    : calibration_(files.calibration),
      map_(std::move(files.map)),
      pipeline_(std::make_unique<nav::Pipeline>(pipelineParams(config, calibration_), *map_, devices)) {
  pipeline_->setLogSink(&logToStderr, nullptr);
  status_ = pipeline_->configure();
  if (status_ == Status::Ok && config.haveInitialPose) {
    status_ = pipeline_->setPose(config.initialPose);
  }
  if (status_ == Status::Ok) {
    status_ = pipeline_->activate();
  }
  if (status_ != Status::Ok) {
    std::fprintf(stderr, "agvnav-vehicle: navigation pipeline refused its configuration: %s\n", toString(status_));
  }
}

}  // namespace agv::vehicle
