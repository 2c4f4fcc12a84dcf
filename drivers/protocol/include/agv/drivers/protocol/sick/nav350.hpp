#pragma once
/// @file nav350.hpp
/// SICK NAV350 binary CoLa (CoLa B) `sMN mNPOSGetData` request and the decoder of its reply
/// `sAN mNPOSGetData`: pose, reflector list and optional scan, in SI units. Heap-free.
///
/// Reply payload (big-endian; the framer has removed 02020202, the length and the checksum):
/// "sAN mNPOSGetData " then version u16, error code u8, wait u8, mask u8,
/// pose valid u16 [x i32 mm, y i32 mm, phi u32 mdeg, optional valid u16 [output mode u8,
/// timestamp u32 ms, mean deviation i32 mm, navigation mode u8, info state u32, used reflectors u8]],
/// landmark valid u16 [filter u8, count u16, per reflector: cartesian valid u16 [x i32 mm, y i32 mm],
/// polar valid u16 [distance u32 mm, angle u32 mdeg], optional valid u16 [local id u16, global id
/// u16, type u8, subtype u16, quality u16, timestamp u32 ms, size u16 mm, hit count u16, mean echo
/// u16, start index u16, end index u16]],
/// scan channel count u16 (0..2), per channel: 5-char name ("DIST1" | "ANGL1"), scale factor f32,
/// scale offset f32, start angle i32 mdeg, angular step u16 mdeg, timestamp u32 ms, count u16,
/// values u32 each; remission valid u16 ["RSSI1", f32, f32, i32, u16, u32, count u16, u16 each].
/// See docs/drivers.md.

#include <cstddef>
#include <cstdint>

#include "agv/core/capacities.hpp"
#include "agv/core/fixed_vector.hpp"
#include "agv/core/pose2.hpp"
#include "agv/core/span.hpp"
#include "agv/core/status.hpp"
#include "agv/core/timestamp.hpp"
#include "agv/scan/laser_scan.hpp"

namespace agv::drivers::sick {

/// What the NAV350 should return with the pose (the request's "mask").
enum class Nav350Mask : std::uint8_t {
  Pose = 0,                ///< pose only
  PoseReflectors = 1,      ///< pose + reflectors
  PoseReflectorsScan = 2,  ///< pose + reflectors + scan
};

/// Payload of the request `sMN mNPOSGetData <wait> <mask>` (binary CoLa). Wrap it with
/// `encodeColaB`. wait = 1: the device answers after its next scan, 0: at once (last pose).
/// Returns the payload length, 0 if `out` is too small (needs 19 bytes).
std::size_t encodeNav350PoseRequest(bool waitForNextScan, Nav350Mask mask, Span<std::uint8_t> out) noexcept;

/// Frames a binary CoLa payload: 02 02 02 02, length (u32 BE), payload, XOR checksum. Returns the
/// telegram length, 0 if `out` is too small (needs payload + 9 bytes).
std::size_t encodeColaB(Span<const std::uint8_t> payload, Span<std::uint8_t> out) noexcept;

/// One reflector as the NAV350 reports it (SI units).
struct Nav350Reflector {
  bool hasCartesian = false;
  double x = 0.0;  ///< [m] cartesian position as reported (world frame in navigation mode)
  double y = 0.0;  ///< [m]
  bool hasPolar = false;
  double range = 0.0;    ///< [m] from the sensor
  double bearing = 0.0;  ///< [rad] in the sensor frame (device angle + angleOffset), in (-pi, pi]
  bool hasDetails = false;
  std::uint16_t localId = 0;
  std::uint16_t globalId = 0;
  std::uint8_t type = 0;
  std::uint16_t subType = 0;
  std::uint16_t quality = 0;
  std::uint32_t timestampMs = 0;  ///< device clock [ms]
  double size = 0.0;              ///< [m]
  std::uint16_t hitCount = 0;
  std::uint16_t meanEcho = 0;
  std::uint16_t startIndex = 0;
  std::uint16_t endIndex = 0;
};

/// Decoded `sAN mNPOSGetData` reply.
struct Nav350PoseReply {
  std::uint16_t version = 0;
  std::uint8_t errorCode =
      0;  ///< 0 ok, 1 wrong mode, 2 aborted, 3 invalid data, 4 no position, 5 timeout, 6 busy, 7 general
  std::uint8_t wait = 0;
  std::uint8_t mask = 0;

  bool poseValid = false;
  Pose2d pose;  ///< vehicle/sensor pose in the NAV350's map frame [m, m, rad in (-pi, pi]]
  bool poseDetailsValid = false;
  std::uint8_t outputMode = 0;
  std::uint32_t poseTimestampMs = 0;  ///< device clock [ms]
  double meanDeviation = 0.0;         ///< [m]
  std::uint8_t navigationMode = 0;
  std::uint32_t infoState = 0;
  std::uint8_t usedReflectors = 0;

  bool landmarksValid = false;
  std::uint8_t landmarkFilter = 0;
  std::uint16_t reflectorCount = 0;  ///< as sent (may exceed kMaxReflectors; see reflectors.refusedCount())
  FixedVector<Nav350Reflector, kMaxReflectors> reflectors;

  bool scanValid = false;  ///< a DIST1 channel was present
  std::uint32_t scanTimestampMs = 0;
  LaserScan scan;  ///< DIST1 channel (ANGL1 and RSSI1 are checked and skipped)

  /// Set by the decoder, for `nav350VehicleTime`: when the reply was received (vehicle clock), and
  /// the newest device instant it carries (pose details, reflector details, scan channel).
  Timestamp receivedAt;
  bool hasDeviceTime = false;
  std::uint32_t newestDeviceMs = 0;
};

/// How far before the newest device instant of a reply another one may lie and still be mapped
/// to the vehicle clock: a NAV350 turns at 8 Hz (125 ms a turn); a second is a wrong clock.
inline constexpr std::uint32_t kNav350MaxSpanMs = 1000;

/// Sensor-frame conventions; defaults keep the device's own angles (0 = the NAV350's x axis).
struct Nav350Config {
  double angleOffset = 0.0;  ///< [rad] added to every device angle (scan and reflector bearings)
  float rangeMin = 0.5F;     ///< [m]
  float rangeMax = 250.0F;   ///< [m]
};

/// Decodes a reply payload (as `TelegramFramer` in CoLa B mode delivers it). `receivedAt` stamps
/// the scan. Returns Ok; Malformed (other telegram, more than 2 scan channels, unknown channel
/// name, bad scale); OutOfRange (an implausible scan channel header: scale outside [1e-3, 100],
/// offset beyond +-10 m, step beyond 5 deg, start beyond +-360 deg, more than a turn); Truncated (the payload ends
/// before its declared content); CapacityExceeded (more reflectors than kMaxReflectors or beams than kMaxScanBeams: the
/// first are kept, the rest counted as refused). A device error code is not a decoding error: check `errorCode`.
Status parseNav350PoseReply(Span<const std::uint8_t> payload, const Nav350Config& config, Timestamp receivedAt,
                            Nav350PoseReply& reply) noexcept;

/// The vehicle-clock time of the device instant `deviceMs` (e.g. a reflector's timestamp) of a
/// decoded reply: `receivedAt` minus how long before the reply's newest device instant it lies
/// (modulo 2^32 ms, so the device clock may wrap within the reply). The delay between that newest
/// instant and the reception is not known, so every time of a reply is late by it, by the same
/// amount; their differences keep the device's 1 ms. False, `out` unchanged, when the reply carries
/// no device time or `deviceMs` lies after the newest instant or more than `kNav350MaxSpanMs`
/// before it.
bool nav350VehicleTime(const Nav350PoseReply& reply, std::uint32_t deviceMs, Timestamp& out) noexcept;

/// The inverse of `parseNav350PoseReply`, for the simulator: writes the reply payload of `reply`
/// (pose if poseValid, with details if poseDetailsValid; reflectors if landmarksValid, each with
/// the parts it has; the scan as a DIST1 channel if scanValid) into `out`; frame it with
/// `encodeColaB`. Returns the payload length, 0 if `out` is too small. Values are rounded to the
/// device units (mm, mdeg); invalid readings are sent as 0.
std::size_t encodeNav350PoseReply(const Nav350PoseReply& reply, const Nav350Config& config,
                                  Span<std::uint8_t> out) noexcept;

}  // namespace agv::drivers::sick
