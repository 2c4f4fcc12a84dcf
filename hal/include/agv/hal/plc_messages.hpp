#pragma once
/// @file plc_messages.hpp
/// Messages exchanged with the vehicle PLC: what the navigation publishes and what it is told.

#include <Eigen/Core>
#include <cstdint>

#include "agv/core/pose2.hpp"
#include "agv/core/status.hpp"
#include "agv/core/timestamp.hpp"

namespace agv::hal {

/// Operating mode of the navigation, as published to the PLC.
enum class NavMode : std::uint8_t {
  Idle = 0,         ///< not localizing (after start-up or a stop command)
  Localizing = 1,   ///< pose is tracked and published
  Calibrating = 2,  ///< the calibration routine drives the vehicle
  Lost = 3,         ///< the localizer does not trust its pose; the PLC must stop the vehicle
};

/// Health bits of a pose report (`NavHealth::bits`), published as they are in the PLC link's status
/// block (register 2 of the Modbus map). The navigation pipeline sets the device and state bits;
/// the PLC link ORs in what only it knows (`PlcHeartbeatLost`, and `CommandRejected` for a write it
/// refused itself).
enum class HealthBit : std::uint16_t {
  LaserOk = 1U << 0U,           ///< sweeps arriving in time
  EncodersOk = 1U << 1U,        ///< encoder samples arriving in time, heartbeats ok
  MapLoaded = 1U << 2U,         ///< the landmark map holds at least one landmark
  CalibrationValid = 1U << 3U,  ///< the navigation runs with a checked calibration
  LaserTimeout = 1U << 4U,      ///< the laser has been silent longer than its deadline
  EncoderTimeout = 1U << 5U,    ///< CANopen heartbeat or PDO timeout
  DeviceFault = 1U << 6U,       ///< a device reported a fault (EMCY, bus-off, error replies)
  PlcHeartbeatLost = 1U << 7U,  ///< the PLC's heartbeat register stopped changing (set by the link)
  CommandRejected = 1U << 8U,   ///< the last PLC command or write was refused
  Searching = 1U << 9U,         ///< relocalizing: searching the map for the pose (no set-pose, or lost)
  Relocalized = 1U << 10U,      ///< the pose was found by relocalization (held for a while after it)
  Ambiguous = 1U << 11U,        ///< the last search found several poses the map cannot tell apart
};

/// `bits` with `bit` set when `on`.
constexpr std::uint16_t withBit(std::uint16_t bits, HealthBit bit, bool on) noexcept {
  return on ? static_cast<std::uint16_t>(bits | static_cast<std::uint16_t>(bit)) : bits;
}
/// True when `bit` is set in `bits`.
constexpr bool hasBit(std::uint16_t bits, HealthBit bit) noexcept {
  return (bits & static_cast<std::uint16_t>(bit)) != 0U;
}

/// Progress of the on-vehicle calibration routine, as the PLC reads it (registers 44-48 of the
/// Modbus map). All zero when no routine ever ran.
struct CalibrationProgress {
  std::uint8_t state = 0;  ///< `calibration::RoutineState` value: 0 idle .. 7 done, 8 aborted
  std::uint8_t phase =
      0;  ///< `calibration::Phase` of `segment`: 0 forward left, 1 forward right, 2 backward left, 3 backward right
  std::uint16_t segment = 0;        ///< segment being driven, 1-based (0: none)
  std::uint16_t total = 0;          ///< segments of the plan (0: none)
  Status lastRefusal = Status::Ok;  ///< why the last Calibrate was refused or the last run aborted or failed
  /// The CiA 402 error code (0x603F, or the EMCY's) of the drive fault behind `lastRefusal`: the
  /// drive that stopped the last run or refused to come up for it (0: none, or not a drive fault).
  std::uint16_t driveFault = 0;
};

/// Health of the localization: enough for a PLC to decide whether to trust the pose.
struct NavHealth {
  NavMode mode = NavMode::Idle;
  std::uint16_t bits = 0;               ///< OR of `HealthBit`
  Status lastStatus = Status::Ok;       ///< last non-Ok status of the pipeline (Ok when none)
  std::uint16_t matchedLandmarks = 0;   ///< landmarks used by the last correction
  std::uint16_t visibleReflectors = 0;  ///< reflectors reported by the laser in the last scan
  float scanAge = 0.0F;                 ///< [s] age of the last laser correction at publication time
  /// Per observation kind of the last correction (the localizer's `SourceHealth`): how many were
  /// fused and how many rejected, so an operator sees which kind is being gated out.
  std::uint16_t reflectorsFused = 0;
  std::uint16_t reflectorsRejected = 0;
  std::uint16_t cornersFused = 0;
  std::uint16_t cornersRejected = 0;
  /// The calibration routine (filled by the program that runs it; zero otherwise).
  CalibrationProgress calibration;
};

/// Pose of the vehicle's logical point in the map frame, with its uncertainty.
struct PoseReport {
  Timestamp stamp;                                       ///< time the pose refers to (vehicle monotonic clock)
  Pose2d pose;                                           ///< [m, m, rad] map frame
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  ///< of (x, y, theta) [m^2, m^2 rad, rad^2]
  NavHealth health;
};

/// What the PLC asks the navigation to do.
enum class PlcCommandKind : std::uint8_t {
  None = 0,       ///< no new command
  Localize = 1,   ///< start localizing from `initialPose`
  Calibrate = 2,  ///< run the on-vehicle calibration routine
  Stop = 3,       ///< stop localizing / abort the routine
};

/// One command from the PLC.
struct PlcCommand {
  Timestamp stamp;  ///< when it was received
  PlcCommandKind kind = PlcCommandKind::None;
  Pose2d initialPose;  ///< for Localize: start pose of the logical point, map frame
};

}  // namespace agv::hal
