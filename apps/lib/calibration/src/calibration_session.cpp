#include "agv/calibration/calibration_session.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <utility>
#include <vector>

namespace agv::calibration {

namespace {

/// `what` and the errno text in `error`; DeviceFault.
Status systemError(std::string& error, const std::string& what) {
  error = what + ": " + std::strerror(errno);
  return Status::DeviceFault;
}

/// Writes `content` into a new `tmp` (truncated) and fsyncs it; removes it on failure.
Status writeSynced(const std::string& tmp, const std::string& content, std::string& error) {
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    return systemError(error, "cannot create " + tmp);
  }
  std::size_t done = 0;
  while (done < content.size()) {
    const ssize_t n = ::write(fd, content.data() + done, content.size() - done);
    if (n < 0 && errno == EINTR) {
      continue;
    }
    if (n <= 0) {
      const Status s = systemError(error, "cannot write " + tmp);
      ::close(fd);
      ::unlink(tmp.c_str());
      return s;
    }
    done += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0) {
    const Status s = systemError(error, "cannot sync " + tmp);
    ::close(fd);
    ::unlink(tmp.c_str());
    return s;
  }
  if (::close(fd) != 0) {
    const Status s = systemError(error, "cannot close " + tmp);
    ::unlink(tmp.c_str());
    return s;
  }
  return Status::Ok;
}

/// The whole content of `path` in `out`: Ok, NotFound when it does not exist, DeviceFault.
Status readAll(const std::string& path, std::string& out, std::string& error) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    if (errno == ENOENT) {
      return Status::NotFound;
    }
    return systemError(error, "cannot read " + path);
  }
  out.clear();
  char buf[4096];
  for (;;) {
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n < 0 && errno == EINTR) {
      continue;
    }
    if (n < 0) {
      const Status s = systemError(error, "cannot read " + path);
      ::close(fd);
      return s;
    }
    if (n == 0) {
      break;
    }
    out.append(buf, static_cast<std::size_t>(n));
  }
  ::close(fd);
  return Status::Ok;
}

/// fsync of the folder holding `path` (makes the renames durable); errors are not fatal.
void syncFolder(const std::string& path) {
  const std::size_t slash = path.rfind('/');
  const std::string dir = slash == std::string::npos ? "." : (slash == 0 ? "/" : path.substr(0, slash));
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd >= 0) {
    static_cast<void>(::fsync(fd));
    ::close(fd);
  }
}

}  // namespace

Status writeFileAtomically(const std::string& path, const std::string& content, std::string& error,
                           const BeforeRenameHook& beforeRename) {
  error.clear();
  const std::string tmp = path + ".tmp";
  Status s = writeSynced(tmp, content, error);
  if (s != Status::Ok) {
    return s;
  }
  std::string old;
  s = readAll(path, old, error);
  if (s == Status::Ok) {
    const std::string bak = path + ".bak";
    const std::string bakTmp = bak + ".tmp";
    s = writeSynced(bakTmp, old, error);
    if (s == Status::Ok && ::rename(bakTmp.c_str(), bak.c_str()) != 0) {
      s = systemError(error, "cannot rename " + bakTmp + " to " + bak);
      ::unlink(bakTmp.c_str());
    }
  } else if (s == Status::NotFound) {
    s = Status::Ok;  // first file: nothing to back up
  }
  if (s == Status::Ok && beforeRename) {
    s = beforeRename();
    if (s != Status::Ok) {
      error = std::string("failed before replacing ") + path + " (" + toString(s) + ")";
    }
  }
  if (s == Status::Ok && ::rename(tmp.c_str(), path.c_str()) != 0) {
    s = systemError(error, "cannot rename " + tmp + " to " + path);
  }
  if (s != Status::Ok) {
    ::unlink(tmp.c_str());
    return s;
  }
  syncFolder(path);
  return Status::Ok;
}

Status writeCalibrationFile(const std::string& path, const VehicleCalibration& calibration, std::string& error,
                            const BeforeRenameHook& beforeRename) {
  std::vector<char> text(4096);
  const Result<std::size_t> n = formatCalibrationFile(calibration, Span<char>(text.data(), text.size()));
  if (!n.ok()) {
    error = std::string("cannot format the calibration (") + toString(n.status()) + ")";
    return n.status();
  }
  return writeFileAtomically(path, std::string(text.data(), n.value()), error, beforeRename);
}

CalibrationSession::CalibrationSession(hal::DriveControl& drive, DriveHooks hooks, SessionConfig config, SessionLog log)
    : drive_(drive),
      hooks_(std::move(hooks)),
      config_(std::move(config)),
      log_(std::move(log)),
      run_(drive, config_.routine) {
  message_.reserve(512);
}

void CalibrationSession::refuse(Status why, const std::string& message, std::uint16_t driveFault) {
  progress_.lastRefusal = why;
  progress_.driveFault = driveFault;
  message_ = message;
  if (log_) {
    log_(message);
  }
}

Status CalibrationSession::requestCalibrate(const Pose2d& start, Timestamp now) {
  const Status s = prepare(start);
  return s == Status::Ok ? begin(now) : s;
}

Status CalibrationSession::prepare(const Pose2d& start) {
  prepared_ = false;
  if (running()) {
    refuse(Status::Rejected, "calibrate refused: the routine is already running");
    return Status::Rejected;
  }
  if (!start.isFinite()) {
    refuse(Status::NotInitialized, "calibrate refused: the vehicle's pose is not known (localize first)");
    return Status::NotInitialized;
  }
  PlanRequest request = config_.plan;
  request.start = start;
  std::string error;
  const Status planned = planCalibration(request, plan_, error);
  if (planned != Status::Ok) {
    refuse(planned, "calibrate refused before any motion: " + error);
    return planned;
  }
  prepared_ = true;
  return Status::Ok;
}

Status CalibrationSession::begin(Timestamp now) {
  if (!prepared_) {
    return Status::NotInitialized;
  }
  if (running()) {
    refuse(Status::Rejected, "calibrate refused: the routine is already running");
    return Status::Rejected;
  }
  prepared_ = false;
  const Status started = run_.start(plan_, now);
  if (started != Status::Ok) {
    refuse(started, std::string("calibrate refused: the routine did not start (") + toString(started) + ")");
    return started;
  }
  progress_ = SessionProgress{};
  progress_.state = run_.state();
  progress_.total = static_cast<std::uint16_t>(run_.total());
  progress_.phase = run_.phase();
  message_.clear();
  if (log_) {
    const Pose2d& start = plan_.request.start;
    char line[200];
    std::snprintf(line, sizeof line, "calibration started: %d segments from (%.2f, %.2f, %.1f deg)", run_.total(),
                  start.x, start.y, rad2deg(start.theta));
    log_(line);
  }
  return Status::Ok;
}

void CalibrationSession::requestStop(Timestamp now) {
  if (!running()) {
    return;
  }
  if (hooks_.quickStop) {
    hooks_.quickStop();
  }
  run_.abort(Status::Ok, "stopped by the PLC", now);
  progress_.state = run_.state();
  progress_.lastRefusal = Status::Ok;
  progress_.driveFault = 0;
  message_ = "calibration aborted by the PLC's Stop (quick stop); calibration file untouched";
  if (log_) {
    log_(message_);
  }
}

void CalibrationSession::abortOnFault(Status why, const char* reason, Timestamp now, std::uint16_t driveFault) {
  if (!running()) {
    return;
  }
  if (hooks_.quickStop) {
    hooks_.quickStop();
  }
  run_.abort(why, reason, now);
  progress_.state = run_.state();
  refuse(why, std::string("calibration aborted: ") + reason + "; calibration file untouched", driveFault);
}

void CalibrationSession::noteDriveFault(std::uint16_t code) noexcept {
  if (code != 0U && !running() && progress_.state == RoutineState::Aborted &&
      progress_.lastRefusal == Status::DeviceFault && progress_.driveFault == 0U) {
    progress_.driveFault = code;
  }
}

void CalibrationSession::onEncoderSample(const hal::EncoderSample& sample) noexcept {
  run_.onEncoderSample(sample);
}

void CalibrationSession::onSweep(const hal::LaserMeasurement& sweep) {
  if (running()) {
    run_.onSweep(sweep);
  }
}

bool CalibrationSession::running() const noexcept {
  return !run_.finished();
}

const SessionProgress& CalibrationSession::progress() const noexcept {
  return progress_;
}

bool CalibrationSession::step(Timestamp now) {
  if (!running()) {
    return false;
  }
  const RoutineState s = run_.step(now);
  progress_.state = s;
  progress_.segment = static_cast<std::uint16_t>(run_.segment());
  progress_.phase = run_.phase();
  if (s == RoutineState::Aborted) {
    if (hooks_.quickStop) {
      hooks_.quickStop();
    }
    const CalibrationOutcome& o = run_.outcome();
    std::string reason = "calibration aborted: " + o.message;
    const std::uint32_t code = hooks_.faultCode ? hooks_.faultCode() : 0U;
    if (code != 0U) {
      char hex[32];
      std::snprintf(hex, sizeof hex, " (drive fault code 0x%04X)", static_cast<unsigned>(code));
      reason += hex;
    }
    refuse(o.status, reason + "; calibration file untouched", static_cast<std::uint16_t>(code & 0xFFFFU));
    return false;
  }
  if (s != RoutineState::Done) {
    return false;
  }
  if (hooks_.release) {
    hooks_.release();
  }
  const CalibrationOutcome& o = run_.outcome();
  if (o.status != Status::Ok) {
    refuse(o.status, "calibration failed: " + o.message + "; calibration file untouched");
    return false;
  }
  const VehicleCalibration cal = calibrationToWrite(o);
  std::string error;
  const Status w = writeCalibrationFile(config_.calibrationFile, cal, error);
  if (w != Status::Ok) {
    refuse(w, "calibration solved but not written: " + error + "; calibration file untouched");
    return false;
  }
  written_ = cal;
  progress_.lastRefusal = Status::Ok;
  progress_.driveFault = 0;
  message_.clear();
  if (log_) {
    char line[300];
    std::snprintf(line, sizeof line,
                  "calibration written to %s (old file kept as .bak): %d of %d segments used; s_w %.6e m/tick, "
                  "alpha_F %.4f deg, alpha_B %.4f deg, laser (%.4f m, %.4f m, %.4f deg)",
                  config_.calibrationFile.c_str(), o.segmentsUsed, o.segmentsDriven, cal.params.driveScale,
                  rad2deg(cal.params.steerOffsetForward), rad2deg(cal.params.steerOffsetBackward), cal.laserPose.x,
                  cal.laserPose.y, rad2deg(cal.laserPose.theta));
    log_(line);
  }
  return true;
}

}  // namespace agv::calibration
