#include "vehicle_runtime.hpp"

#include <poll.h>
#include <pthread.h>
#include <signal.h>

#include <cstdio>
#include <ctime>

#include "agv/drivers/linux/modbus_plc_link.hpp"
#include "agv/drivers/linux/monotonic_clock.hpp"
#include "vehicle_calibration.hpp"

namespace agv::vehicle {
namespace {

using drivers::monotonicNow;

timespec toTimespec(Duration d) {
  timespec t{};
  if (d.ns > 0) {
    t.tv_sec = static_cast<time_t>(d.ns / 1000000000LL);
    t.tv_nsec = static_cast<long>(d.ns % 1000000000LL);
  }
  return t;
}

/// The laser as the loop runs it: no wait in `read()`. A connection attempt is started and then
/// completed by later cycles (non-blocking connect, given up after laser.connect_timeout, which the
/// TCP stream keeps as its connect timeout); commands are sent without waiting for room.
drivers::SickLaserSourceConfig laserSourceConfig(const VehicleConfig& c) {
  drivers::SickLaserSourceConfig l = c.laser;
  l.connectBudget = Duration{};
  return l;
}

constexpr int kMaxWaitFds = 16;  // CAN + laser + Modbus listener and its 8 connections, with room

}  // namespace

struct VehicleRuntime::Impl {
  Impl(const VehicleConfig& c, VehicleFiles&& f)
      : config(c),
        encoders(encoderSourceConfig(config)),
        laser(laserSourceConfig(config)),
        modbus(config.modbus),
        drives(config.drivesEnabled ? makeSocketCanDrives(config) : nullptr),
        routine(config, f.calibration, encoders, laser, modbus, drives.get(),
                [](const std::string& line) { std::fprintf(stderr, "agvnav-vehicle: %s\n", line.c_str()); }),
        navigation(config, std::move(f),
                   nav::PipelineDevices{routine.encoders(), routine.laser(), routine.plc(), clock}) {
    routine.attach(navigation.pipeline());
  }

  /// The calibration registers from `cal`.
  void publishCalibration(const VehicleCalibration& cal) {
    drivers::plc::PlcCalibration pc;
    pc.driveScale = cal.params.driveScale;
    pc.steerOffsetForward = cal.params.steerOffsetForward;
    pc.steerOffsetBackward = cal.params.steerOffsetBackward;
    pc.laserMount = cal.laserPose;
    pc.wheelbase = cal.params.wheelbase;
    modbus.setCalibration(pc);
  }

  /// One pipeline cycle and the calibration routine's step after it.
  void cycle() {
    (void)navigation.pipeline().cycle();
    if (routine.step(monotonicNow())) {
      publishCalibration(routine.calibration());
    }
  }

  VehicleConfig config;
  drivers::CanopenEncoderSource encoders;
  drivers::SickLaserSource laser;
  drivers::ModbusPlcLink modbus;
  drivers::MonotonicClock clock;
  std::unique_ptr<VehicleDrives> drives;  // drives.enabled only
  VehicleCalibrationRoutine routine;      // between the pipeline and the devices
  VehicleNavigation navigation;
  VehicleRuntime::LoopStats stats;

  /// The descriptors to wait on for input now.
  nfds_t collectFds(pollfd* fds) const noexcept {
    nfds_t n = 0;
    const int can = encoders.fileDescriptor();
    if (can >= 0) {
      fds[n++] = pollfd{can, POLLIN, 0};
    }
    const int las = laser.fileDescriptor();
    if (las >= 0) {
      fds[n++] = pollfd{las, POLLIN, 0};
    }
    int plc[kMaxWaitFds];
    const int k = modbus.inputDescriptors(plc, kMaxWaitFds - static_cast<int>(n));
    for (int i = 0; i < k; ++i) {
      fds[n++] = pollfd{plc[i], POLLIN, 0};
    }
    return n;
  }
};

VehicleRuntime::VehicleRuntime(const VehicleConfig& config, VehicleFiles&& files)
    : impl_(std::make_unique<Impl>(config, std::move(files))) {
  impl_->publishCalibration(impl_->navigation.calibration());
}

VehicleRuntime::~VehicleRuntime() = default;

bool VehicleRuntime::open(std::string& error) {
  Impl& m = *impl_;
  if (m.navigation.status() != Status::Ok) {
    error = std::string("navigation pipeline: configuration refused (") + toString(m.navigation.status()) + ")";
    return false;
  }
  const Status p = m.modbus.open();
  if (p != Status::Ok) {
    error = std::string("modbus: cannot set up the PLC link on ") + m.config.modbus.address + ":" +
            std::to_string(m.config.modbus.port) + " (" + toString(p) + ")";
    return false;
  }
  const Status e = m.encoders.open();
  if (e != Status::Ok) {
    std::fprintf(stderr, "agvnav-vehicle: CAN interface %s: %s; retrying every %.1f s (encoder fault reported)\n",
                 m.config.canInterface.c_str(), toString(e), m.config.can.openRetryInterval.seconds());
  }
  return true;
}

void VehicleRuntime::cycle() {
  impl_->cycle();
}

const nav::PipelineCounters& VehicleRuntime::counters() const noexcept {
  return impl_->navigation.pipeline().counters();
}

std::uint16_t VehicleRuntime::healthBits() const noexcept {
  return impl_->navigation.pipeline().healthBits();
}

const VehicleRuntime::LoopStats& VehicleRuntime::loopStats() const noexcept {
  return impl_->stats;
}

const drivers::PlcLinkCounters& VehicleRuntime::plcCounters() const noexcept {
  return impl_->modbus.counters();
}

void VehicleRuntime::run(const volatile std::sig_atomic_t& stop) {
  Impl& m = *impl_;
  const Duration period = m.config.cyclePeriod;
  // The wait's signal mask: the caller's, with SIGINT and SIGTERM deliverable.
  sigset_t waitMask;
  (void)pthread_sigmask(SIG_SETMASK, nullptr, &waitMask);
  (void)sigdelset(&waitMask, SIGINT);
  (void)sigdelset(&waitMask, SIGTERM);
  Timestamp deadline = monotonicNow() + period;
  bool wokeThisPeriod = false;
  while (stop == 0) {
    const Timestamp start = monotonicNow();
    m.cycle();
    // The PLC is answered every cycle, not only when a status is published (loop.publish_period).
    (void)m.modbus.service(monotonicNow());
    Timestamp now = monotonicNow();
    ++m.stats.cycles;
    if ((now - start).ns > m.stats.longestCycleNs) {
      m.stats.longestCycleNs = (now - start).ns;
    }
    if (now >= deadline) {  // this was the period's cycle: on to the next deadline
      deadline = deadline + period;
      if (deadline <= now) {  // the cycle overran a whole period: resynchronize, do not catch up
        ++m.stats.overruns;
        deadline = now + period;
      }
      wokeThisPeriod = false;
    }
    pollfd fds[kMaxWaitFds];
    const nfds_t n = wokeThisPeriod ? 0 : m.collectFds(fds);
    const timespec timeout = toTimespec(deadline - now);
    const int rc = ::ppoll(fds, n, &timeout, &waitMask);
    if (rc > 0) {
      wokeThisPeriod = true;
      ++m.stats.inputWakes;
    }
  }
  (void)impl_->navigation.pipeline().deactivate();  // one last report: idle
  impl_->encoders.close();
}

}  // namespace agv::vehicle
