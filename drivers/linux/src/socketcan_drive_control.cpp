#include "agv/drivers/linux/socketcan_drive_control.hpp"

#include <cstring>

namespace agv::drivers {

SocketCanDriveControl::SocketCanDriveControl(const SocketCanDriveControlConfig& config) noexcept
    : config_(config), controller_(config.drives) {
  if (config.interfaceName != nullptr) {
    const std::size_t len = std::strlen(config.interfaceName);
    nameOk_ = len >= 1U && len < sizeof interfaceName_;
    if (nameOk_) {
      std::memcpy(interfaceName_, config.interfaceName, len + 1U);
    }
  }
  config_.interfaceName = interfaceName_;
  controller_.setEmergencySink(this);
}

SocketCanDriveControl::~SocketCanDriveControl() {
  // The controller's destructor (run after this body, the bus still open) sends its last quick stop
  // through send().
}

Status SocketCanDriveControl::open(Timestamp now) noexcept {
  if (!nameOk_ || controller_.validate() != Status::Ok || config_.maxFramesPerCycle == 0U ||
      config_.openRetryInterval.ns <= 0) {
    return Status::InvalidArgument;
  }
  SocketCanConfig can;
  can.interfaceName = interfaceName_;
  can.receiveErrorFrames = true;
  ++counters_.openAttempts;
  openStatus_ = bus_.open(can);
  nextOpen_ = now + config_.openRetryInterval;
  return openStatus_;
}

Status SocketCanDriveControl::start(Timestamp now) noexcept {
  if (openStatus_ != Status::Ok) {
    return Status::NotInitialized;
  }
  const Status s = controller_.start(now);
  flush();
  return s;
}

bool SocketCanDriveControl::send(const CanFrame& frame) noexcept {
  if (openStatus_ != Status::Ok) {
    ++counters_.sendFailures;
    return false;
  }
  if (bus_.send(frame) == Status::Ok) {
    ++counters_.framesSent;
    return true;
  }
  ++counters_.sendFailures;
  return false;
}

void SocketCanDriveControl::flush() noexcept {
  CanFrame frames[canopen::CanOutbox::kCapacity];
  const std::size_t n = controller_.takeFrames(Span<CanFrame>(frames));
  for (std::size_t i = 0; i < n; ++i) {
    (void)send(frames[i]);
  }
}

bool SocketCanDriveControl::busUsable() const noexcept {
  return openStatus_ == Status::Ok && bus_.health().link == CanLinkState::Up &&
         bus_.health().controller != CanControllerState::BusOff;
}

void SocketCanDriveControl::quickStop(canopen::SafeStopReason reason) noexcept {
  controller_.quickStop(reason);
  flush();
}

Status SocketCanDriveControl::release() noexcept {
  const Status s = controller_.release();
  flush();
  return s;
}

BusStateReports busStateReports(bool reportedOff, bool offSeen, bool usable) noexcept {
  BusStateReports r;
  r.off = !reportedOff && (offSeen || !usable);
  r.back = usable && (reportedOff || r.off);
  return r;
}

Status SocketCanDriveControl::cycle(Timestamp now) noexcept {
  if (openStatus_ != Status::Ok && now >= nextOpen_) {
    (void)open(now);
  }
  const std::uint64_t busOffsBefore = bus_.health().counters.busOffEvents;
  if (openStatus_ == Status::Ok) {
    for (std::uint32_t i = 0; i < config_.maxFramesPerCycle; ++i) {
      CanFrame f;
      if (bus_.receive(f, Duration{}) != Status::Ok) {
        break;  // nothing waiting, or the link is down (the bus reopens it on later calls)
      }
      if (f.error) {
        ++counters_.errorFrames;  // already decoded into busHealth()
        continue;
      }
      ++counters_.framesHandled;
      controller_.onFrame(f);
    }
    bus_.maintain();
  }
  const bool usable = busUsable();
  const BusStateReports reports =
      busStateReports(reportedOff_, bus_.health().counters.busOffEvents != busOffsBefore, usable);
  if (reports.off) {
    controller_.onBusState(true, now);
    reportedOff_ = true;
  }
  if (reports.back) {
    controller_.onBusState(false, now);
    reportedOff_ = false;
  }
  controller_.poll(now);
  flush();
  return usable ? Status::Ok : Status::DeviceFault;
}

}  // namespace agv::drivers
