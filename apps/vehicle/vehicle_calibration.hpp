#pragma once
/// @file vehicle_calibration.hpp
/// The calibration routine inside `agvnav-vehicle`: taps between the navigation pipeline and the
/// real devices, so that the one routine (`calibration::CalibrationSession` around the stepwise
/// `CalibrationRun`) sees the encoder samples and sweeps the pipeline reads, takes the PLC's
/// `Calibrate` and `Stop`, and publishes its progress in every report (registers 44-49, mode
/// `Calibrating` while it runs). On success the new calibration file is written atomically and
/// reloaded into the pipeline (`Pipeline::recalibrate`).
///
/// Allocates in the constructor and when a run starts or ends (see calibration_session.hpp); the
/// taps and `step()` while collecting do not. Not thread-safe (the vehicle's one loop).

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "agv/calibration/calibration_session.hpp"
#include "agv/hal/encoder_source.hpp"
#include "agv/hal/laser_source.hpp"
#include "agv/hal/plc_link.hpp"
#include "agv/nav/pipeline.hpp"
#include "vehicle_config.hpp"

namespace agv::vehicle {

/// The drives as the vehicle owns them: the `hal::DriveControl` plus bring-up, quick stop and
/// health, which are not in the HAL (the SocketCAN CiA 402 controller on the vehicle, a simulated
/// drive in the tests).
class VehicleDrives {
 public:
  virtual ~VehicleDrives() = default;
  virtual hal::DriveControl& control() noexcept = 0;
  /// Brings the drives up when they are not enabled (idempotent while coming up).
  virtual void bringUp(Timestamp now) noexcept = 0;
  /// `Ok` when enabled; `NotInitialized` while coming up; else why they are not usable
  /// (`DeviceFault` a fault or failed bring-up, `Timeout` a heartbeat lost) with `why` in words.
  virtual Status health(const char*& why) const noexcept = 0;
  /// Traction quick stop now (the PLC's Stop, an abort).
  virtual void quickStop() noexcept = 0;
  /// The routine is done and the vehicle stands: hand the drives back in order (CiA 402 disable
  /// operation), not by the set-point watchdog's quick stop. The CiA 402 drives do it in a later
  /// `cycle()` once a recent TPDO shows the standstill (zero set-point held meanwhile, for at most
  /// 1 s; then the watchdog's quick stop ends it as before).
  virtual void release() noexcept = 0;
  /// The fault or error code of the drive that stopped (0: none known).
  virtual std::uint32_t faultCode() const noexcept = 0;
  /// One control cycle (SocketCAN: frames in, controller polled, frames out).
  virtual void cycle(Timestamp now) noexcept = 0;
};

/// The CiA 402 drive controller's state as the routine sees it: `Ok` enabled; `NotInitialized`
/// idle, coming up or released after a routine; `Timeout` quick-stopped for a lost drive heartbeat; `DeviceFault` any
/// other safe stop (drive fault, bus-off, PLC Stop, stale set-point) or a failed bring-up; `why` names it.
Status drivesHealth(const drivers::canopen::Cia402DriveController& controller, const char*& why) noexcept;
/// The error code (0x603F / EMCY) of the traction drive if it is in fault, else of the steering
/// drive if it is (0: none in fault, only a lost heartbeat, or the code not known yet).
std::uint32_t drivesFaultCode(const drivers::canopen::Cia402DriveController& controller) noexcept;

/// The drives on SocketCAN (`drivers::SocketCanDriveControl`, the interface of `config`).
std::unique_ptr<VehicleDrives> makeSocketCanDrives(const VehicleConfig& config);

/// See the file comment.
class VehicleCalibrationRoutine {
 public:
  /// `drives` may be null (no `drives.enabled`): Calibrate is then left to the pipeline, which
  /// refuses it (health bit 8, `unsupported`), as without `calibration.area`. The devices must
  /// outlive this object. `log` gets one line per event (may be empty).
  VehicleCalibrationRoutine(const VehicleConfig& config, const VehicleCalibration& current,
                            hal::EncoderSource& encoders, hal::LaserSource& laser, hal::PlcLink& plc,
                            VehicleDrives* drives, std::function<void(const std::string&)> log);
  ~VehicleCalibrationRoutine();
  VehicleCalibrationRoutine(const VehicleCalibrationRoutine&) = delete;
  VehicleCalibrationRoutine& operator=(const VehicleCalibrationRoutine&) = delete;

  /// The devices to give the pipeline (`nav::PipelineDevices`): they forward to the real ones.
  hal::EncoderSource& encoders() noexcept;
  hal::LaserSource& laser() noexcept;
  hal::PlcLink& plc() noexcept;

  /// The pipeline whose pose starts the plan and which reloads the new calibration.
  void attach(nav::Pipeline& pipeline) noexcept;

  /// Call after each pipeline cycle. Every 10 ms (the drive controller's cycle) it checks the
  /// drives (a fault or heartbeat loss during a run aborts it), steps the run, and cycles the drives.
  /// True in the call where a new calibration was written and reloaded (`calibration()`).
  bool step(Timestamp now);

  /// Whether Calibrate is handled here (drives enabled and `calibration.area` set).
  bool enabled() const noexcept;
  bool running() const noexcept;
  const calibration::SessionProgress& progress() const noexcept;
  const calibration::CalibrationSession* session() const noexcept;
  /// The calibration in use (the file's at start, then each one written).
  const VehicleCalibration& calibration() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace agv::vehicle
