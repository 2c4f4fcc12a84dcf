#pragma once
/// @file cola_a_scan.hpp
/// Decoder of the SICK CoLa A (ASCII) scan telegram `sRA LMDscandata` / `sSN LMDscandata` of the
/// LMS1xx, LMS5xx and TiM families into an `agv::LaserScan` in SI units. Heap-free.
///
/// Field order (space separated, numbers in hexadecimal; see docs/drivers.md for the full table):
/// command type, command, version, device number, serial number, device status (2), telegram
/// counter, scan counter, time since start-up [us], time of transmission [us], digital inputs (2),
/// digital outputs (2), reserved, scan frequency [1/100 Hz], measurement frequency [100 Hz],
/// encoder count + (position, speed) per encoder, 16-bit channel count + channels, 8-bit channel
/// count + channels, then optional blocks (position, name, comment, time, event) that are ignored.
/// A channel is: content name ("DIST1", "RSSI1", ...), scale factor (IEEE-754 float as 8 hex
/// digits), scale offset (same), start angle (int32, 1/10000 deg), angular step (uint16, 1/10000
/// deg), value count (uint16), values. Distance [mm] = value * scale factor + scale offset; the
/// scale factor is always applied (LMS5xx sends 2.0 in some resolutions).

#include <cstddef>
#include <cstdint>

#include "agv/core/span.hpp"
#include "agv/core/status.hpp"
#include "agv/core/timestamp.hpp"
#include "agv/scan/laser_scan.hpp"

namespace agv::drivers::sick {

/// How raw SICK values map onto the sensor frame; defaults suit the LMS1xx/5xx/TiM.
struct ColaAScanConfig {
  /// [rad] added to the device angle. SICK counts 0 deg along the device's y axis (cable side
  /// opposite), so -pi/2 puts 0 rad straight ahead (x forward, y left).
  double angleOffset = -1.5707963267948966;
  float rangeMin = 0.05F;  ///< [m] readings below are invalid (LMS1xx 0.5, TiM 0.05)
  float rangeMax = 80.0F;  ///< [m] readings at or above are invalid (LMS5xx 80, LMS1xx 20)
};

/// Header fields of a decoded telegram, for diagnostics and time stamping.
struct ColaAScanInfo {
  std::uint32_t serialNumber = 0;
  std::uint16_t deviceStatus = 0;  ///< first device-status word (0 = ok)
  std::uint16_t telegramCounter = 0;
  std::uint16_t scanCounter = 0;
  std::uint32_t timeSinceStartupUs = 0;    ///< device clock at the scan [us]
  std::uint32_t timeOfTransmissionUs = 0;  ///< device clock at transmission [us]
  double scanFrequency = 0.0;              ///< [Hz]
  double scaleFactor = 0.0;                ///< DIST1 scale factor as sent
  double scaleOffset = 0.0;                ///< DIST1 scale offset as sent [mm]
  std::uint16_t beamCount = 0;             ///< DIST1 value count as sent (may exceed kMaxScanBeams)
  std::uint32_t noReturnBeams = 0;         ///< raw 0 values (no echo), stored as +inf
};

/// Decodes one CoLa A telegram (the text between STX and ETX, as `TelegramFramer` delivers it).
///
/// `receivedAt` is the vehicle time the telegram was received; the scan stamp is
/// `receivedAt - (timeOfTransmission - timeSinceStartup)` when that device-side latency lies in
/// [0, 1 s), else `receivedAt`. The sweep duration follows from the scan frequency and the
/// angular span. Readings: metres, raw 0 (no echo) becomes +inf (invalid).
///
/// Returns Ok; Malformed (not an LMDscandata telegram, bad number, bad float, no DIST1 channel,
/// zero or non-finite scale factor, zero angular step); OutOfRange (an implausible channel header:
/// scale outside [1e-3, 100], offset beyond +-10 m, step beyond 5 deg, start beyond +-360 deg, beams
/// spanning more than a turn); Truncated (fields missing);
/// CapacityExceeded (more than kMaxScanBeams values: the first ones are kept, the rest counted as
/// refused in `scan.ranges`). On error other than CapacityExceeded `scan` is left empty.
Status parseColaAScan(Span<const std::uint8_t> telegram, const ColaAScanConfig& config, Timestamp receivedAt,
                      LaserScan& scan, ColaAScanInfo* info = nullptr) noexcept;

}  // namespace agv::drivers::sick

namespace agv::drivers::sick {

/// Device-side values of a simulated LMDscandata telegram.
struct ColaAScanEncodeParams {
  double angleOffset = -1.5707963267948966;  ///< [rad] the same offset the decoder's config uses
  double scanFrequency = 50.0;               ///< [Hz]
  float scaleFactor = 1.0F;                  ///< device scale factor (LMS5xx: 2.0 in some resolutions)
  std::uint32_t serialNumber = 0x1234567U;
  std::uint16_t telegramCounter = 0;
  std::uint16_t scanCounter = 0;
  std::uint32_t timeSinceStartupUs = 0;
  std::uint32_t timeOfTransmissionUs = 0;
};

/// The inverse of `parseColaAScan`, for the simulator: writes a complete `sSN LMDscandata`
/// telegram (STX ... ETX) of `scan` into `out` and returns its length, 0 if `out` is too small
/// (at most 160 + 5 x beams bytes are needed). Invalid readings are sent as 0 (no echo); ranges
/// are rounded to the device resolution (scale factor, in mm) and clamped to 0xFFFF counts.
std::size_t encodeColaAScan(const LaserScan& scan, const ColaAScanEncodeParams& params,
                            Span<std::uint8_t> out) noexcept;

}  // namespace agv::drivers::sick
