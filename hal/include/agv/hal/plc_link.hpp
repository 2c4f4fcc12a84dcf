#pragma once
/// @file plc_link.hpp
/// Device interface: the link to the vehicle PLC (Modbus TCP on a real vehicle).

#include "agv/core/status.hpp"
#include "agv/hal/plc_messages.hpp"

namespace agv::hal {

/// Publishes the navigation's output to the PLC and reads the PLC's commands.
class PlcLink {
 public:
  /// Sends one pose report. `Ok`, or `Timeout`/`DeviceFault` when the PLC did not take it (the
  /// caller keeps running and publishes the next report; nothing is queued).
  virtual Status publish(const PoseReport& report) noexcept = 0;
  /// Takes the oldest unread command: `Ok` with `out` filled, `NotFound` when there is none,
  /// or a link error.
  virtual Status readCommand(PlcCommand& out) noexcept = 0;

 protected:
  PlcLink() = default;
  PlcLink(const PlcLink&) = default;
  PlcLink& operator=(const PlcLink&) = default;
  ~PlcLink() = default;
};

}  // namespace agv::hal
