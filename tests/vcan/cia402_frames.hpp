#pragma once
/// @file cia402_frames.hpp
/// Reading the frames a vcan VM test records on the vehicle's bus (docs/drives.md): little-endian
/// fields of a CAN payload and the CiA 402 quick-stop command to the traction drive (node 1).

#include <cstdint>

#include "agv/drivers/protocol/can_frame.hpp"

namespace agv::test {

/// The traction drive's RPDO (controlword + target velocity), node 1.
constexpr std::uint32_t kTractionRpdo = 0x201;

/// The little-endian 16-bit field of `f` at byte `at` (at + 1 < 8).
inline std::uint16_t u16(const drivers::CanFrame& f, unsigned at) {
  return static_cast<std::uint16_t>(f.data[at] | (f.data[at + 1] << 8U));
}

/// The little-endian signed 32-bit field of `f` at byte `at` (at + 3 < 8).
inline std::int32_t i32(const drivers::CanFrame& f, unsigned at) {
  std::uint32_t v = 0;
  for (unsigned i = 0; i < 4U; ++i) {
    v |= static_cast<std::uint32_t>(f.data[at + i]) << (8U * i);
  }
  return static_cast<std::int32_t>(v);
}

/// A data frame to the traction drive whose controlword is Quick stop (0x0002).
inline bool isQuickStop(const drivers::CanFrame& f) {
  return !f.error && f.id == kTractionRpdo && f.dlc == 6 && u16(f, 0) == 0x0002;
}

}  // namespace agv::test
