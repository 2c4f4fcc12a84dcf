#include "vehicle_calibration.hpp"

#include <cmath>
#include <cstdio>
#include <limits>
#include <utility>

#include "agv/drivers/linux/socketcan_drive_control.hpp"

namespace agv::vehicle {

namespace {

namespace canopen = drivers::canopen;

/// The CiA 402 drives on SocketCAN.
class SocketCanDrives final : public VehicleDrives {
 public:
  explicit SocketCanDrives(const VehicleConfig& c) : name_(c.canInterface), drives_(configOf(c, name_)) {}

  hal::DriveControl& control() noexcept override { return drives_; }

  void bringUp(Timestamp now) noexcept override {
    if (!opened_) {
      opened_ = true;
      static_cast<void>(drives_.open(now));  // a failed open is retried by cycle()
    }
    const canopen::DriveControllerState s = drives_.controller().state();
    startRefused_ = false;
    if (s != canopen::DriveControllerState::Enabled && s != canopen::DriveControllerState::BringingUp) {
      startRefused_ = drives_.start(now) != Status::Ok;  // NotInitialized: the bus is not open
    }
  }

  Status health(const char*& why) const noexcept override {
    if (startRefused_ && drives_.controller().state() == canopen::DriveControllerState::Idle) {
      why = "the drives' CAN interface cannot be opened";
      return Status::DeviceFault;
    }
    return drivesHealth(drives_.controller(), why);
  }

  void quickStop() noexcept override { drives_.quickStop(canopen::SafeStopReason::PlcStop); }

  void release() noexcept override {
    releasePending_ = true;
    releaseSince_ = Timestamp{};
  }

  std::uint32_t faultCode() const noexcept override { return drivesFaultCode(drives_.controller()); }

  void cycle(Timestamp now) noexcept override {
    if (releasePending_) {
      serveRelease(now);
    }
    if (opened_) {
      static_cast<void>(drives_.cycle(now));
    }
  }

 private:
  static drivers::SocketCanDriveControlConfig configOf(const VehicleConfig& c, const std::string& name) {
    drivers::SocketCanDriveControlConfig d;
    d.interfaceName = name.c_str();  // copied by the constructor
    d.drives = c.drives;
    return d;
  }

  /// The controller releases only at a standstill it has seen in a recent TPDO: until then
  /// (a late TPDO in a loaded cycle) the zero set-point is held; after `kReleaseWait` without one
  /// the release is given up and the set-point watchdog quick-stops as before.
  void serveRelease(Timestamp now) noexcept {
    if (releaseSince_.ns == 0) {
      releaseSince_ = now;
    }
    if (drives_.controller().state() != canopen::DriveControllerState::Enabled || drives_.release() == Status::Ok ||
        now - releaseSince_ > kReleaseWait) {
      releasePending_ = false;
      return;
    }
    static_cast<void>(drives_.stop());
  }

  static constexpr Duration kReleaseWait = Duration::fromMilliseconds(1000);
  std::string name_;
  drivers::SocketCanDriveControl drives_;
  bool releasePending_ = false;
  Timestamp releaseSince_{};
  bool opened_ = false;
  bool startRefused_ = false;  // the last bring-up could not start (no bus)
};

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

}  // namespace

Status drivesHealth(const canopen::Cia402DriveController& c, const char*& why) noexcept {
  switch (c.state()) {
    case canopen::DriveControllerState::Enabled:
      why = "enabled";
      return Status::Ok;
    case canopen::DriveControllerState::Idle:
    case canopen::DriveControllerState::BringingUp:
      why = "coming up";
      return Status::NotInitialized;
    case canopen::DriveControllerState::Released:
      why = "released after the last routine";
      return Status::NotInitialized;
    case canopen::DriveControllerState::SafeStop:
      why = canopen::toString(c.safeStopReason());
      return c.safeStopReason() == canopen::SafeStopReason::DriveHeartbeatLost ? Status::Timeout : Status::DeviceFault;
    case canopen::DriveControllerState::Failed:
      why = "the drives' bring-up failed";
      return Status::DeviceFault;
  }
  why = "?";
  return Status::DeviceFault;
}

std::uint32_t drivesFaultCode(const canopen::Cia402DriveController& c) noexcept {
  // The code of an axis in fault now: an axis keeps its last error code after a reset, and one
  // whose heartbeat was lost has no code of its own.
  for (const canopen::Cia402Axis* a : {&c.traction(), &c.steering()}) {
    if (a->phase() == canopen::AxisPhase::Faulted && !a->heartbeatLost() && a->errorCode() != 0U) {
      return a->errorCode();
    }
  }
  return 0U;
}

std::unique_ptr<VehicleDrives> makeSocketCanDrives(const VehicleConfig& config) {
  return std::make_unique<SocketCanDrives>(config);
}

struct VehicleCalibrationRoutine::Impl {
  /// Forwards the samples to the pipeline and gives them to the routine.
  struct EncoderTap final : hal::EncoderSource {
    Impl* m = nullptr;
    Status read(hal::EncoderSample& out) noexcept override {
      const Status s = m->encoders.read(out);
      if (s == Status::Ok && m->session) {
        m->session->onEncoderSample(out);
      }
      return s;
    }
    Status health() const noexcept override { return m->encoders.health(); }
  };
  /// Forwards the sweeps to the pipeline and gives them to the routine.
  struct LaserTap final : hal::LaserSource {
    Impl* m = nullptr;
    Status read(hal::LaserMeasurement& out) noexcept override {
      const Status s = m->laser.read(out);
      if (s == Status::Ok && m->session) {
        m->session->onSweep(out);
      }
      return s;
    }
    Status health() const noexcept override { return m->laser.health(); }
  };
  /// Takes Calibrate (and sees Stop) before the pipeline; adds the progress to every report.
  struct PlcTap final : hal::PlcLink {
    Impl* m = nullptr;
    Status publish(const hal::PoseReport& report) noexcept override {
      hal::PoseReport r = report;
      m->fill(r.health);
      return m->plc.publish(r);
    }
    Status readCommand(hal::PlcCommand& out) noexcept override {
      for (;;) {
        const Status s = m->plc.readCommand(out);
        if (s != Status::Ok || !m->enabled()) {
          return s;
        }
        if (out.kind == hal::PlcCommandKind::Calibrate) {
          m->calibrateRequested = true;  // handled by step(), after the pipeline's cycle
          m->commandRefused = false;
          continue;  // not the pipeline's
        }
        m->commandRefused = false;
        if (out.kind == hal::PlcCommandKind::Stop) {
          m->stopRequested = true;
          m->session->requestStop(out.stamp);  // quick stop in this very cycle
          m->pending = false;
        }
        return s;
      }
    }
  };

  Impl(const VehicleConfig& c, const VehicleCalibration& current, hal::EncoderSource& e, hal::LaserSource& l,
       hal::PlcLink& p, VehicleDrives* d, std::function<void(const std::string&)> lg)
      : config(c), calibration(current), encoders(e), laser(l), plc(p), drives(d), log(std::move(lg)) {
    encoderTap.m = this;
    laserTap.m = this;
    plcTap.m = this;
    if (drives != nullptr && config.calibrationAreaSet) {
      calibration::SessionConfig sc;
      sc.plan = config.calibrationPlan;
      sc.plan.wheelbase = current.params.wheelbase;
      sc.plan.steeringLimit = std::fmin(config.drives.steering.maxAngle, deg2rad(89.0));
      sc.routine.nominal = current.params;
      sc.routine.nominalLaser = current.laserPose;
      sc.routine.speed = config.calibrationSpeed;
      sc.routine.deceleration = config.drives.traction.acceleration;
      sc.routine.egomotion = config.calibrationEgomotion;
      sc.routine.controlPeriod = Duration::fromMilliseconds(10);  // the drive controller's cycle
      sc.calibrationFile = config.calibrationFile;
      calibration::DriveHooks hooks;
      hooks.quickStop = [this] { drives->quickStop(); };
      hooks.faultCode = [this] { return drives->faultCode(); };
      hooks.release = [this] { drives->release(); };
      session = std::make_unique<calibration::CalibrationSession>(drives->control(), hooks, sc, log);
      period = sc.routine.controlPeriod;
    }
  }

  bool enabled() const noexcept { return session != nullptr; }

  void fill(hal::NavHealth& h) const noexcept {
    if (!session) {
      return;
    }
    const calibration::SessionProgress& p = session->progress();
    h.calibration.state = static_cast<std::uint8_t>(p.state);
    h.calibration.phase = static_cast<std::uint8_t>(p.phase);
    h.calibration.segment = p.segment;
    h.calibration.total = p.total;
    h.calibration.lastRefusal = p.lastRefusal;
    h.calibration.driveFault = p.driveFault;
    if (session->running() || pending) {
      h.mode = hal::NavMode::Calibrating;
    }
    h.bits = hal::withBit(h.bits, hal::HealthBit::CommandRejected, commandRefused);
  }

  void refuse(Status why, const std::string& message, std::uint16_t driveFault = 0) {
    commandRefused = true;
    session->reportRefusal(why, message, driveFault);
  }

  /// A Calibrate waiting for the drives: started when they are enabled, refused when they fail.
  void servePending(Timestamp now) {
    const char* why = "";
    const Status h = drives->health(why);
    if (h == Status::Ok) {
      pending = false;
      if (session->begin(now) != Status::Ok) {
        commandRefused = true;
      }
    } else if (h != Status::NotInitialized || now - pendingSince > Duration::fromSeconds(5.0)) {
      pending = false;
      const std::uint32_t code = h == Status::DeviceFault ? drives->faultCode() : 0U;
      char detail[64] = "";
      if (code != 0U) {
        std::snprintf(detail, sizeof detail, ", drive fault code 0x%04X", static_cast<unsigned>(code));
      }
      refuse(h == Status::NotInitialized ? Status::Timeout : h,
             std::string("calibrate refused: the drives are not enabled (") + why + detail + ")",
             static_cast<std::uint16_t>(code & 0xFFFFU));
    }
  }

  bool step(Timestamp now) {
    if (!session) {
      return false;
    }
    if (calibrateRequested) {
      calibrateRequested = false;
      if (session->running() || pending) {
        refuse(Status::Rejected, "calibrate refused: the routine is already running");
      } else {
        // The plan is checked before the drives are brought up: a refusal moves nothing.
        const Pose2d start =
            pipeline != nullptr && pipeline->localizing() ? pipeline->localizer().pose() : Pose2d{kNaN, kNaN, kNaN};
        if (session->prepare(start) != Status::Ok) {
          commandRefused = true;
        } else {
          pending = true;
          pendingSince = now;
          drives->bringUp(now);
        }
      }
    }
    if (now < next) {
      return false;
    }
    next = now + period;
    if (pending) {
      servePending(now);
    }
    bool wrote = false;
    if (session->running()) {
      const char* why = "";
      const Status h = drives->health(why);
      if (h != Status::Ok) {
        char reason[160];
        const std::uint32_t code = drives->faultCode();
        if (code != 0U) {
          std::snprintf(reason, sizeof reason, "the drives stopped (%s, drive fault code 0x%04X)", why,
                        static_cast<unsigned>(code));
        } else {
          std::snprintf(reason, sizeof reason, "the drives stopped (%s)", why);
        }
        session->abortOnFault(h, reason, now, static_cast<std::uint16_t>(code & 0xFFFFU));
      } else {
        wrote = session->step(now);
      }
    } else if (!pending) {
      // A drive fault seen before its code (0x603F read by SDO after the abort): the register gets it.
      session->noteDriveFault(static_cast<std::uint16_t>(drives->faultCode() & 0xFFFFU));
    }
    drives->cycle(now);
    if (wrote) {
      calibration = session->lastCalibration();
      if (pipeline != nullptr && pipeline->recalibrate(calibration.params, calibration.laserPose) != Status::Ok &&
          log) {
        log("the new calibration was written but the navigation refused to reload it (restart to use it)");
      }
    }
    return wrote;
  }

  const VehicleConfig& config;
  VehicleCalibration calibration;
  hal::EncoderSource& encoders;
  hal::LaserSource& laser;
  hal::PlcLink& plc;
  VehicleDrives* drives;
  std::function<void(const std::string&)> log;
  std::unique_ptr<calibration::CalibrationSession> session;
  nav::Pipeline* pipeline = nullptr;
  EncoderTap encoderTap;
  LaserTap laserTap;
  PlcTap plcTap;
  Duration period = Duration::fromMilliseconds(20);
  Timestamp next{};
  Timestamp pendingSince{};
  bool calibrateRequested = false;
  bool stopRequested = false;
  bool pending = false;
  bool commandRefused = false;
};

VehicleCalibrationRoutine::VehicleCalibrationRoutine(const VehicleConfig& config, const VehicleCalibration& current,
                                                     hal::EncoderSource& encoders, hal::LaserSource& laser,
                                                     hal::PlcLink& plc, VehicleDrives* drives,
                                                     std::function<void(const std::string&)> log)
    : impl_(std::make_unique<Impl>(config, current, encoders, laser, plc, drives, std::move(log))) {}

VehicleCalibrationRoutine::~VehicleCalibrationRoutine() = default;

hal::EncoderSource& VehicleCalibrationRoutine::encoders() noexcept {
  return impl_->encoderTap;
}

hal::LaserSource& VehicleCalibrationRoutine::laser() noexcept {
  return impl_->laserTap;
}

hal::PlcLink& VehicleCalibrationRoutine::plc() noexcept {
  return impl_->plcTap;
}

void VehicleCalibrationRoutine::attach(nav::Pipeline& pipeline) noexcept {
  impl_->pipeline = &pipeline;
}

bool VehicleCalibrationRoutine::step(Timestamp now) {
  return impl_->step(now);
}

bool VehicleCalibrationRoutine::enabled() const noexcept {
  return impl_->enabled();
}

bool VehicleCalibrationRoutine::running() const noexcept {
  return impl_->session && (impl_->session->running() || impl_->pending);
}

const calibration::SessionProgress& VehicleCalibrationRoutine::progress() const noexcept {
  static const calibration::SessionProgress none{};
  return impl_->session ? impl_->session->progress() : none;
}

const calibration::CalibrationSession* VehicleCalibrationRoutine::session() const noexcept {
  return impl_->session.get();
}

const VehicleCalibration& VehicleCalibrationRoutine::calibration() const noexcept {
  return impl_->calibration;
}

}  // namespace agv::vehicle
