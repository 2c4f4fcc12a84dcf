#include "vehicle_runtime.hpp"

#include <cstdio>
#include <ctime>

#include "agv/drivers/linux/modbus_plc_link.hpp"

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

/// The Modbus link as the loop's `hal::PlcLink`: every report goes out with the loop's health bits
/// (the status block carries them; `hal::PoseReport` does not).
class ModbusStatusLink final : public hal::PlcLink {
 public:
  explicit ModbusStatusLink(drivers::ModbusPlcLink& link) noexcept : link_(link) {}
  void healthFrom(const VehicleLoop& loop) noexcept { loop_ = &loop; }
  Status publish(const hal::PoseReport& report) noexcept override {
    if (loop_ != nullptr) {
      link_.setHealthBits(loop_->healthBits());
    }
    return link_.publish(report);
  }
  Status readCommand(hal::PlcCommand& out) noexcept override { return link_.readCommand(out); }

 private:
  drivers::ModbusPlcLink& link_;
  const VehicleLoop* loop_ = nullptr;
};

}  // namespace

struct VehicleRuntime::Impl {
  Impl(const VehicleConfig& c, VehicleFiles&& f)
      : config(c),
        encoders(encoderSourceConfig(config)),
        laser(config.laser),
        modbus(config.modbus),
        plc(modbus),
        loop(config, std::move(f), VehicleDevices{encoders, laser, plc}) {
    plc.healthFrom(loop);
  }

  VehicleConfig config;
  drivers::CanopenEncoderSource encoders;
  drivers::SickLaserSource laser;
  drivers::ModbusPlcLink modbus;
  ModbusStatusLink plc;
  VehicleLoop loop;
};

VehicleRuntime::VehicleRuntime(const VehicleConfig& config, VehicleFiles&& files)
    : impl_(std::make_unique<Impl>(config, std::move(files))) {
  const VehicleCalibration& cal = impl_->loop.calibration();
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
  impl_->loop.cycle();
}

const RuntimeCounters& VehicleRuntime::counters() const noexcept {
  return impl_->loop.counters();
}

std::uint16_t VehicleRuntime::healthBits() const noexcept {
  return impl_->loop.healthBits();
}

void VehicleRuntime::run(const volatile std::sig_atomic_t& stop) {
  const Duration period = impl_->config.cyclePeriod;
  while (stop == 0) {
    impl_->loop.cycle();
    sleepFor(period);
  }
  impl_->encoders.close();
}

}  // namespace agv::vehicle
