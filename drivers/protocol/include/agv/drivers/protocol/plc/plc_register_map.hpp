#pragma once
/// @file plc_register_map.hpp
/// The PLC link's Modbus register map (docs/plc-link.md is the user's copy of this table):
/// what the vehicle publishes (read-only for the PLC) and the few command registers the PLC may
/// write, each whitelisted and bounds-checked. Portable and heap-free: the Modbus transports
/// (libmodbus server or client, drivers/linux) only move the registers.
///
/// Holding registers, 0-based addresses (add the configured base). 32-bit values take two
/// registers in the configured `WordOrder`; "f32" = IEEE-754 float, SI units.
///
///   Status block (read-only)                 Command block (PLC-writable)
///   0      heartbeat counter u16 (+1/cycle)   100   command code u16 (PlcCommandCode, <= 3)
///   1      navigation mode u16 (hal::NavMode) 101   command sequence u16 (any; a change = new command)
///   2      health bits u16 (PlcHealthBit)      102-3 set-pose x f32 [m], |x| <= maxAbsPosition
///   3      last status code u16 (agv::Status)  104-5 set-pose y f32 [m], |y| <= maxAbsPosition
///   4-5    pose x f32 [m]                      106-7 set-pose theta f32 [rad], [-pi, pi]
///   6-7    pose y f32 [m]                      108   PLC heartbeat u16 (any)
///   8-9    pose theta f32 [rad] (-pi, pi]
///   10-21  covariance f32: xx, xy, xtheta, yy, ytheta, thetatheta [m^2, m^2, m rad, m^2, m rad, rad^2]
///   22-23  pose time u32 [ms, vehicle clock modulo 2^32]
///   24     matched landmarks u16
///   25     reflectors visible in the last scan u16
///   26-27  drive scale s_w f32 [m/tick]
///   28-29  steering offset forward f32 [rad]
///   30-31  steering offset backward f32 [rad]
///   32-33  laser mounting x f32 [m]
///   34-35  laser mounting y f32 [m]
///   36-37  laser mounting theta f32 [rad]
///   38-39  wheelbase f32 [m]
///   40     reflectors fused in the last correction u16
///   41     reflectors rejected in the last correction u16 (gate, ambiguity, duplicate, update)
///   42     corners fused in the last correction u16
///   43     corners rejected in the last correction u16
///   44     calibration routine state u16 (calibration::RoutineState: 0 idle .. 7 done, 8 aborted)
///   45     calibration phase u16 (0 forward left, 1 forward right, 2 backward left, 3 backward right)
///   46     calibration segment being driven u16 (1-based, 0 none)
///   47     calibration segments of the plan u16
///   48     calibration last refusal u16 (agv::Status; 0 none)
///   49     calibration drive fault code u16 (CiA 402 error code 0x603F / EMCY of the drive
///          behind 48; 0 none)
///
/// Every other address in [0, 110) reads as 0 and is not writable; addresses >= 110 do not exist.

#include <array>
#include <cstddef>
#include <cstdint>

#include "agv/core/pose2.hpp"
#include "agv/core/result.hpp"
#include "agv/core/span.hpp"
#include "agv/core/status.hpp"
#include "agv/core/timestamp.hpp"
#include "agv/drivers/protocol/plc/word_order.hpp"
#include "agv/hal/plc_messages.hpp"

namespace agv::drivers::plc {

/// Bits of the health word (register 2); a set bit means the condition holds. The status block's health bits: the HAL's
/// (one definition, agv/hal/plc_messages.hpp).
using PlcHealthBit = hal::HealthBit;

/// Calibration values published read-only.
struct PlcCalibration {
  double driveScale = 0.0;           ///< s_w [m/tick]
  double steerOffsetForward = 0.0;   ///< [rad]
  double steerOffsetBackward = 0.0;  ///< [rad]
  Pose2d laserMount;                 ///< l = (lx, ly, ltheta) [m, m, rad]
  double wheelbase = 0.0;            ///< [m]
};

/// Everything the vehicle publishes each cycle.
struct PlcStatus {
  std::uint16_t heartbeat = 0;
  hal::NavMode mode = hal::NavMode::Idle;
  std::uint16_t health = 0;  ///< OR of PlcHealthBit
  Status lastStatus = Status::Ok;
  Pose2d pose;
  /// Covariance upper triangle: xx, xy, xtheta, yy, ytheta, thetatheta.
  std::array<double, 6> covariance{};
  Timestamp stamp;
  std::uint16_t matchedLandmarks = 0;
  std::uint16_t visibleReflectors = 0;
  /// Per observation kind of the last correction: fused / rejected (`hal::NavHealth::sources`).
  std::uint16_t reflectorsFused = 0;
  std::uint16_t reflectorsRejected = 0;
  std::uint16_t cornersFused = 0;
  std::uint16_t cornersRejected = 0;
  PlcCalibration calibration;
  hal::CalibrationProgress routine;  ///< the calibration routine's progress (registers 44-49)
};

/// PLC command codes (register 100), the same values as hal::PlcCommandKind.
enum class PlcCommandCode : std::uint16_t {
  None = 0,
  Localize = 1,   ///< (re)start localizing from the set-pose in registers 102..107
  Calibrate = 2,  ///< run the on-vehicle calibration routine
  Stop = 3,       ///< stop localizing / abort the routine
};

/// The decoded command block.
struct PlcCommand {
  PlcCommandCode code = PlcCommandCode::None;
  std::uint16_t sequence = 0;
  Pose2d pose;  ///< for Localize [m, m, rad]
  std::uint16_t plcHeartbeat = 0;
};

/// Configuration of the map (defaults documented in docs/plc-link.md).
struct PlcMapConfig {
  WordOrder wordOrder = WordOrder::ABCD;
  double maxAbsPosition = 10000.0;  ///< [m] bound of a set-pose coordinate
};

class PlcRegisterMap {
 public:
  static constexpr std::uint16_t kStatusBase = 0;
  static constexpr std::uint16_t kStatusCount = 50;
  static constexpr std::uint16_t kCommandBase = 100;
  static constexpr std::uint16_t kCommandCount = 9;
  /// Size of the register table (addresses 0 .. kRegisterCount-1).
  static constexpr std::uint16_t kRegisterCount = 110;

  explicit PlcRegisterMap(const PlcMapConfig& config = PlcMapConfig{}) noexcept : config_(config) {}
  const PlcMapConfig& config() const noexcept { return config_; }

  /// Writes the status block into `table[kStatusBase .. kStatusBase + kStatusCount)`.
  /// InvalidArgument if `table` has fewer than kStatusBase + kStatusCount registers. NaN/inf in
  /// the status are published as NaN (the PLC must treat them as invalid).
  Status encodeStatus(const PlcStatus& status, Span<std::uint16_t> table) const noexcept;

  /// Checks a PLC write of `values` at `address` against the whitelist and the bounds, given the
  /// current table (so that a write of part of the block is checked with the rest):
  /// Ok; OutOfRange (an address is not writable: illegal data address); Malformed (only one
  /// register of a 32-bit field written); InvalidArgument (a value out of bounds or not finite:
  /// illegal data value). Nothing is written here.
  Status checkWrite(std::uint16_t address, Span<const std::uint16_t> values,
                    Span<const std::uint16_t> table) const noexcept;

  /// Decodes and bounds-checks the command block of `table` (size >= kRegisterCount); used by the
  /// server after an accepted write and by the client after reading the PLC's registers.
  /// InvalidArgument for an out-of-bounds block, InvalidArgument for a short table.
  Result<PlcCommand> decodeCommand(Span<const std::uint16_t> table) const noexcept;

  /// Decodes a command block given on its own (`block` holds kCommandCount registers).
  Result<PlcCommand> decodeCommandBlock(const std::uint16_t* block) const noexcept;

 private:
  PlcMapConfig config_;
};

}  // namespace agv::drivers::plc
