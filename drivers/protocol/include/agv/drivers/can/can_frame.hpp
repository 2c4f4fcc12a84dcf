#pragma once
/// @file can_frame.hpp
/// One classic CAN 2.0 frame, independent of any OS API (the SocketCAN transport converts from
/// `struct can_frame`, the simulator builds them directly).

#include <cstdint>

#include "agv/core/timestamp.hpp"

namespace agv::drivers {

struct CanFrame {
  /// Flag bits of `flags`.
  static constexpr std::uint8_t kExtended = 1U << 0U;  ///< 29-bit identifier
  static constexpr std::uint8_t kRemote = 1U << 1U;    ///< remote transmission request
  static constexpr std::uint8_t kError = 1U << 2U;     ///< error frame reported by the controller

  std::uint32_t id = 0;       ///< identifier without flag bits (11 or 29 bits)
  std::uint8_t dlc = 0;       ///< data length 0..8
  std::uint8_t flags = 0;     ///< OR of kExtended, kRemote, kError
  std::uint8_t data[8] = {};  ///< payload; bytes past dlc are 0
  Timestamp stamp;            ///< receive time on the vehicle clock (kernel time stamp when available)

  bool extended() const noexcept { return (flags & kExtended) != 0U; }
  bool remote() const noexcept { return (flags & kRemote) != 0U; }
  bool error() const noexcept { return (flags & kError) != 0U; }
};

}  // namespace agv::drivers
