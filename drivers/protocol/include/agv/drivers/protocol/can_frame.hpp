#pragma once
/// @file can_frame.hpp
/// One classic CAN frame as the drivers exchange it: plain data, no OS types.

#include <cstdint>

#include "agv/core/timestamp.hpp"

namespace agv::drivers {

/// A classic CAN 2.0 frame (at most 8 data bytes), a remote request, or a bus error report.
///
/// `id` is the bare identifier: 11 bits for a standard frame, 29 bits when `extended`. For an
/// error report (`error` true) `id` holds the error class bits and `data` their details, as
/// SocketCAN defines them (linux/can/error.h). `stamp` is the receive time on the vehicle's
/// monotonic clock (zero for a frame built to be sent). Bytes past `dlc` are unspecified.
struct CanFrame {
  std::uint32_t id = 0;
  std::uint8_t dlc = 0;
  std::uint8_t data[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  bool extended = false;
  bool rtr = false;
  bool error = false;
  agv::Timestamp stamp{};
};

}  // namespace agv::drivers
