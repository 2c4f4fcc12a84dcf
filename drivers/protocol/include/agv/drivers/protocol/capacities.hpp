#pragma once
/// @file capacities.hpp
/// Compile-time capacities of the device drivers (the algorithms' are in agv/core/capacities.hpp).
/// Override per product with a compile definition of the macro, for the library and the vehicle
/// code alike (e.g. -DAGV_MAX_LASER_TELEGRAM_BYTES=65536).

#include <cstddef>

#ifndef AGV_MAX_CAN_FILTERS
#define AGV_MAX_CAN_FILTERS 16
#endif
#ifndef AGV_MAX_LASER_TELEGRAM_BYTES
#define AGV_MAX_LASER_TELEGRAM_BYTES 32768
#endif

namespace agv::drivers {

/// Receive filters of one CAN socket (one per node and object class leaves ample room).
inline constexpr std::size_t kMaxCanFilters = AGV_MAX_CAN_FILTERS;
/// Bytes of one laser telegram (framing included) a driver buffers: a CoLa A LMDscandata of
/// 1141 beams with RSSI is ~12 KB, a NAV350 reply with 1440 beams and 64 reflectors ~8 KB.
inline constexpr std::size_t kMaxLaserTelegramBytes = AGV_MAX_LASER_TELEGRAM_BYTES;

static_assert(kMaxCanFilters >= 1, "a CAN socket needs at least one filter");
static_assert(kMaxLaserTelegramBytes >= 64, "a laser telegram buffer needs at least 64 bytes");

}  // namespace agv::drivers
