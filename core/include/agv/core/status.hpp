#pragma once
/// @file status.hpp
/// Failure reasons as values: the core never throws; a function that can fail returns a `Status`
/// or a `Result<T>` (see result.hpp) naming why.

#include <cstdint>

namespace agv {

/// Why an operation did not succeed. `Ok` is the only success value.
///
/// One enum for the whole library so that a status can travel from any module to the PLC link
/// and the logs unchanged. Append new reasons at the end: the numeric values are published on
/// the PLC link and must stay stable.
// (clang-format 14 misreads an attribute on an enum: formatting is fenced off here.)
// clang-format off
enum class [[nodiscard]] Status : std::uint8_t {
  Ok = 0,
  InvalidArgument,   ///< a parameter is out of its documented domain
  NonFiniteInput,    ///< NaN or infinity where a finite number is required
  EmptyInput,        ///< no data where some is required
  CapacityExceeded,  ///< fixed-capacity storage is full; the item was refused (and counted)
  NotEnoughData,     ///< fewer samples/segments/points than the method needs
  Unobservable,      ///< the data cannot determine the unknowns (e.g. one steering angle only)
  IllConditioned,    ///< observable in principle, but too poorly conditioned to trust
  NotConverged,      ///< an iterative method hit its iteration bound
  NotFound,          ///< a looked-up item does not exist
  OutOfRange,        ///< an index or value lies outside the valid range
  Timeout,           ///< a deadline passed (e.g. heartbeat)
  Truncated,         ///< a message or buffer ended early
  Malformed,         ///< a message or buffer does not follow its format
  Unsupported,       ///< a valid request this build or device does not support
  NotInitialized,    ///< used before the required set-up
  Rejected,          ///< a measurement failed a consistency test (e.g. Mahalanobis gate)
  Lost,              ///< the localizer no longer trusts its pose
  DeviceFault,       ///< a device reported a fault (EMCY, bus-off, ...)
};
// clang-format on

/// Number of enumerators in `Status` (keep equal to the last value + 1).
inline constexpr std::uint8_t kStatusCount = static_cast<std::uint8_t>(Status::DeviceFault) + 1U;

/// Short, stable, human-readable name of a status (e.g. "capacity exceeded"). Never null.
const char* toString(Status status) noexcept;

/// True when `status` is `Status::Ok`.
constexpr bool isOk(Status status) noexcept {
  return status == Status::Ok;
}

}  // namespace agv
