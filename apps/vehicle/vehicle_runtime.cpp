#include "vehicle_runtime.hpp"

#include <cstdio>
#include <ctime>

#include "agv/drivers/linux/modbus_plc_link.hpp"
#include "agv/drivers/linux/monotonic_clock.hpp"

namespace agv::vehicle {
namespace {

void sleepFor(Duration d) {
  if (d.ns <= 0) {
    return;
  }
  timespec t{};
  t.tv_sec = static_cast<time_t>(d.ns / 1000000000LL);
  t.tv_nsec = static_cast<long>(d.ns % 1000000000LL);
  (void)nanosleep(&t, nullptr);  // a signal ends it early: the loop then sees the stop flag
}

}  // namespace

struct VehicleRuntime::Impl {
  Impl(const VehicleConfig& c, VehicleFiles&& f)
      : config(c),
        encoders(encoderSourceConfig(config)),
        laser(config.laser),
        modbus(config.modbus),
        navigation(config, std::move(f), nav::PipelineDevices{encoders, laser, modbus, clock}) {}

  VehicleConfig config;
  drivers::CanopenEncoderSource encoders;
  drivers::SickLaserSource laser;
  drivers::ModbusPlcLink modbus;
  drivers::MonotonicClock clock;
  VehicleNavigation navigation;
};

VehicleRuntime::VehicleRuntime(const VehicleConfig& config, VehicleFiles&& files)
    : impl_(std::make_unique<Impl>(config, std::move(files))) {
  const VehicleCalibration& cal = impl_->navigation.calibration();
  drivers::plc::PlcCalibration pc;
  pc.driveScale = cal.params.driveScale;
  pc.steerOffsetForward = cal.params.steerOffsetForward;
  pc.steerOffsetBackward = cal.params.steerOffsetBackward;
  pc.laserMount = cal.laserPose;
  pc.wheelbase = cal.params.wheelbase;
  impl_->modbus.setCalibration(pc);
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
  (void)impl_->navigation.pipeline().cycle();
}

const nav::PipelineCounters& VehicleRuntime::counters() const noexcept {
  return impl_->navigation.pipeline().counters();
}

std::uint16_t VehicleRuntime::healthBits() const noexcept {
  return impl_->navigation.pipeline().healthBits();
}

void VehicleRuntime::run(const volatile std::sig_atomic_t& stop) {
  const Duration period = impl_->config.cyclePeriod;
  while (stop == 0) {
    (void)impl_->navigation.pipeline().cycle();
    sleepFor(period);
  }
  (void)impl_->navigation.pipeline().deactivate();  // one last report: idle
  impl_->encoders.close();
}

}  // namespace agv::vehicle
