#pragma once
/// @file calibration_session.hpp
/// The calibration routine as the vehicle runs it on the PLC's request (`agvnav-vehicle`): the
/// plan from the configured free area around the vehicle's pose (refused before any set-point
/// when it does not fit), the stepwise routine (`CalibrationRun`, one copy for every program),
/// the abort on a PLC Stop or a drive fault (quick stop, calibration file untouched), the progress
/// the PLC reads (docs/plc-link.md, registers 44-49) and, when the solve succeeds, the calibration
/// file written atomically with the old one kept as `<file>.bak`.
///
/// Application code (host): it allocates at construction, when a run starts (the plan and the
/// routine's reserved storage), for a log line and when the file is written; the per-cycle calls
/// while collecting do not.

#include <cstdint>
#include <functional>
#include <string>

#include "agv/calib/calibration_file.hpp"
#include "agv/calibration/calibration_routine.hpp"

namespace agv::calibration {

/// Test hook of `writeFileAtomically`: called after the temporary file is written and synced and
/// before it replaces the file; a non-Ok status is treated as a failure there (as a crash at that
/// point would leave it: the old file intact).
using BeforeRenameHook = std::function<Status()>;

/// Replaces `path` with `content` atomically: writes `<path>.tmp`, fsyncs it, copies the current
/// `path` (when it exists) to `<path>.bak` (itself through a synced temporary and a rename), renames
/// the temporary over `path` and fsyncs the folder. Ok; else the reason in `error` and a non-Ok
/// status (`DeviceFault` for a system call that failed), `path` unchanged and the temporary removed.
Status writeFileAtomically(const std::string& path, const std::string& content, std::string& error,
                           const BeforeRenameHook& beforeRename = {});

/// The calibration file `path` (`formatCalibrationFile`) written by `writeFileAtomically`.
Status writeCalibrationFile(const std::string& path, const VehicleCalibration& calibration, std::string& error,
                            const BeforeRenameHook& beforeRename = {});

/// What the PLC reads about the routine (registers 44-49).
struct SessionProgress {
  RoutineState state = RoutineState::Idle;  ///< of the current or last run
  Phase phase = Phase::ForwardLeft;         ///< phase of `segment`
  std::uint16_t segment = 0;                ///< 1-based segment being driven (0 none)
  std::uint16_t total = 0;                  ///< segments of the plan (0 none)
  /// Why the last Calibrate was refused, the last run aborted or its solve or file write failed;
  /// Ok after a run that wrote its file (and until then for a run in progress).
  Status lastRefusal = Status::Ok;
  /// The CiA 402 error code (0x603F / EMCY) of the drive fault behind `lastRefusal` (0: none, or
  /// the refusal is not a drive's fault, or the code is not known yet: see `noteDriveFault`).
  std::uint16_t driveFault = 0;
};

/// The drive beyond `hal::DriveControl`: what the owner of the concrete controller can do.
struct DriveHooks {
  /// Quick stop of the traction now (the PLC's Stop). May be empty (then `stop()` only).
  std::function<void()> quickStop;
  /// The drive's fault or error code when the drive refused a set-point (0: none): in the log and
  /// `SessionProgress::driveFault`.
  std::function<std::uint32_t()> faultCode;
  /// The run ended at standstill (done, solved or not): hand the drives back in order. May be
  /// empty (the drives are then left enabled with a zero set-point).
  std::function<void()> release;
};

/// Configuration of the vehicle's routine.
struct SessionConfig {
  PlanRequest plan;             ///< geometry, free area and shape; `start` is the pose at the request
  RoutineOptions routine;       ///< the routine's settings
  std::string calibrationFile;  ///< written on success (old one kept as `<file>.bak`)
};

/// One line of log (no newline); may be empty.
using SessionLog = std::function<void(const std::string&)>;

class CalibrationSession {
 public:
  /// `drive` must outlive the session.
  CalibrationSession(hal::DriveControl& drive, DriveHooks hooks, SessionConfig config, SessionLog log);

  /// The PLC's Calibrate with the vehicle at `start` (map frame): plans from the free area and
  /// starts the run. Refused with the reason in `progress().lastRefusal` and the log, before any
  /// set-point: `Rejected` while a run is in progress, `OutOfRange` when the plan does not fit,
  /// `InvalidArgument` for a bad plan request or `NotInitialized` when `start` is not finite (no
  /// pose known).
  Status requestCalibrate(const Pose2d& start, Timestamp now);
  /// The first half of `requestCalibrate`: plans from `start` and keeps the plan, with the same
  /// refusals, without starting (an owner that must bring its drives up first checks the plan
  /// before). `begin()` then starts it.
  Status prepare(const Pose2d& start);
  /// Starts the plan of the last successful `prepare()`: `NotInitialized` without one, `Rejected`
  /// while running.
  Status begin(Timestamp now);
  /// The PLC's Stop: quick stop (`DriveHooks::quickStop`, and `stop()`) and abort of a run in
  /// progress in this call: state `Aborted` with `lastRefusal` Ok (stopped on request, no fault),
  /// calibration file untouched. Nothing when no run is in progress.
  void requestStop(Timestamp now);
  /// A fault the owner saw (drive fault, heartbeat loss, bus-off): quick stop and abort with `why`;
  /// `driveFault` the drive's error code (0: none or not known) in `progress().driveFault`.
  void abortOnFault(Status why, const char* reason, Timestamp now, std::uint16_t driveFault = 0);

  /// A refusal decided by the owner (e.g. the drives did not come up): published as
  /// `progress().lastRefusal` (and `driveFault`, the error code of a drive in fault) and logged.
  void reportRefusal(Status why, const std::string& message, std::uint16_t driveFault = 0) {
    refuse(why, message, driveFault);
  }
  /// The error code of the drive fault that aborted the last run, known only after the abort (a
  /// drive that reports Fault in its statusword before its EMCY, or without one: the controller
  /// reads 0x603F by SDO afterwards). Taken only while the last run stands aborted for a
  /// `DeviceFault` whose code is not known yet; ignored otherwise (and 0 is ignored).
  void noteDriveFault(std::uint16_t code) noexcept;

  void onEncoderSample(const hal::EncoderSample& sample) noexcept;
  void onSweep(const hal::LaserMeasurement& sweep);

  /// One control cycle. True in the cycle where a run ended with its calibration file written:
  /// `lastCalibration()` then holds the values to reload into the localizer.
  bool step(Timestamp now);

  bool running() const noexcept;
  const SessionProgress& progress() const noexcept;
  const CalibrationRun& run() const noexcept { return run_; }
  const VehicleCalibration& lastCalibration() const noexcept { return written_; }
  /// The last refusal or abort in words (empty when none).
  const std::string& lastMessage() const noexcept { return message_; }

 private:
  void refuse(Status why, const std::string& message, std::uint16_t driveFault = 0);
  void finishRun();

  hal::DriveControl& drive_;
  DriveHooks hooks_;
  SessionConfig config_;
  SessionLog log_;
  CalibrationRun run_;
  CalibrationPlan plan_;
  bool prepared_ = false;
  SessionProgress progress_;
  VehicleCalibration written_;
  std::string message_;
};

}  // namespace agv::calibration
