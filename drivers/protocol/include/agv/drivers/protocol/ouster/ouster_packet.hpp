#pragma once
/// @file ouster_packet.hpp
/// Decoder of Ouster OS-series lidar data packets (UDP port 7502) into the Velodyne decoder's
/// per-firing records (`agv::drivers::velodyne::FiringRecord`), so the revolution assembler, the
/// range image and the calibration serve both families; and Ouster's beam model for the points.
/// Portable and heap-free; errors are values (docs/ouster.md).
///
/// Packet layouts (little-endian; W = columns per frame, H = pixels per column, C = columns per
/// packet, all from the unit's JSON `data_format`):
/// - LEGACY (firmware < 2.2 default, no `udp_profile_lidar`): C columns of
///   [16-byte header: u64 timestamp ns @0, u16 measurement id @8, u16 frame id @10, u32 encoder
///   count @12] + H x 12-byte pixels [u32 range mm (low 20 bits) @0, u16 reflectivity @4,
///   u16 signal @6, u16 near-IR @8] + [u32 status @end, 0xFFFFFFFF = valid].
/// - RNG19_RFL8_SIG16_NIR16: 32-byte packet header [u16 packet type (1) @0, u16 frame id @2],
///   C columns of [12-byte header: u64 timestamp @0, u16 measurement id @8, u16 status @10
///   (bit 0 = valid)] + H x 12-byte pixels [u32 range mm (low 19 bits) @0, u8 reflectivity @4,
///   u16 signal @6, u16 near-IR @8], then a 32-byte footer.
/// - RNG19_RFL8_SIG16_NIR16_DUAL: as above with 16-byte pixels [range 19 bits @0, reflectivity u8
///   @3, range2 19 bits @4, reflectivity2 u8 @7, signal u16 @8, signal2 u16 @10, near-IR u16 @12].
/// - RNG15_RFL8_NIR8: as above with 4-byte pixels [u16: range low 15 bits x 8 mm @0,
///   u8 reflectivity @2, u8 near-IR / 16 @3].
///
/// Mapping onto `FiringRecord`: laser = pixel row (beam index 0..H-1), block = column within the
/// packet, azimuth = the column's measurement id m in 0.01 deg, round(36000 m / W) (increasing with
/// m, so the assembler's wrap is Ouster's frame boundary; `measurementId()` inverts it exactly for
/// W <= 2048), distance = range in the record's 2 mm counts (rounded; ranges above 131.07 m do not
/// fit and are skipped and counted), intensity = reflectivity (clipped to 255), timeNs = column
/// timestamp minus the packet's first column timestamp, secondReturn = 1 for a dual profile's
/// second return (emitted only when asked). Signal, near-IR and the exact range in mm go to an
/// optional parallel `PixelExtra` span.
///
/// Refused input is counted in `OusterCounters`: a packet of the wrong size (truncated, oversized)
/// or, non-legacy, with a packet type other than 1 is refused whole; a column with its status
/// invalid or a measurement id >= W is skipped (its pixels not emitted), the rest decoded.

#include <cstddef>
#include <cstdint>

#include "agv/core/span.hpp"
#include "agv/core/status.hpp"
#include "agv/drivers/protocol/velodyne/velodyne_packet.hpp"
#include "agv/lidar3d/range_image.hpp"

namespace agv::drivers::ouster {

using velodyne::FiringRecord;

enum class Profile : std::uint8_t { Legacy, Rng19Rfl8Sig16Nir16, Rng19Rfl8Sig16Nir16Dual, Rng15Rfl8Nir8 };

/// Capacities: the OS-series sends at most 128 pixels per column and 16 columns per packet.
inline constexpr std::size_t kMaxPixelsPerColumn = 128;
inline constexpr std::size_t kMaxColumnsPerPacket = 16;
inline constexpr std::size_t kMaxColumnsPerFrame = 2048;
/// Records one packet yields at most (two returns of every pixel of every column).
inline constexpr std::size_t kMaxRecordsPerPacket = kMaxPixelsPerColumn * kMaxColumnsPerPacket * 2;
/// Range the record's uint16 2 mm counts can carry [mm].
inline constexpr std::uint32_t kMaxRecordRangeMm = 65535U * 2U;

struct Format {
  Profile profile = Profile::Legacy;
  std::uint16_t columnsPerPacket = 16;
  std::uint16_t pixelsPerColumn = 32;
  std::uint16_t columnsPerFrame = 1024;
};

/// Ok, or InvalidArgument when a count is 0 or beyond the capacities.
Status validate(const Format& format) noexcept;
/// Bytes of one lidar data packet of `format` (0 when the format is invalid).
std::size_t packetBytes(const Format& format) noexcept;
/// Bytes of one pixel of the profile (12, 12, 16, 4).
std::size_t pixelBytes(Profile profile) noexcept;

struct OusterConfig {
  Format format{};
  /// Dual profile: also emit the second return (secondReturn = 1).
  bool emitSecondReturn = false;
  /// Emit pixels with range 0 (no return). Off: skipped and counted in noReturn.
  bool keepNoReturn = false;
};

struct ColumnHeader {
  std::uint64_t timestampNs = 0;
  std::uint16_t measurementId = 0;
  std::uint16_t frameId = 0;       ///< legacy: per column; otherwise the packet header's
  std::uint32_t encoderCount = 0;  ///< legacy only (0 otherwise)
  std::uint32_t status = 0;        ///< legacy: the 32-bit footer; otherwise the u16 status
  bool valid = false;
};

struct PacketInfo {
  std::uint16_t packetType = 0;  ///< non-legacy packet header (1 = lidar data); legacy: 0
  std::uint16_t frameId = 0;     ///< of the first column (legacy) or the packet header
  std::size_t columnCount = 0;
  ColumnHeader columns[kMaxColumnsPerPacket]{};
};

/// What a record's pixel carried beyond the record (same index as the record).
struct PixelExtra {
  std::uint32_t rangeMm = 0;
  std::uint16_t signal = 0;
  std::uint16_t nearIr = 0;
  std::uint16_t reflectivity = 0;
};

struct OusterCounters {
  std::uint32_t packets = 0;            ///< packets decoded (possibly with skipped columns)
  std::uint32_t truncated = 0;          ///< refused: shorter than the format's packet
  std::uint32_t oversized = 0;          ///< refused: longer than the format's packet
  std::uint32_t badPacketType = 0;      ///< refused: non-legacy packet type not 1
  std::uint32_t invalidColumns = 0;     ///< columns skipped: status not valid
  std::uint32_t badMeasurementId = 0;   ///< columns skipped: measurement id >= columns per frame
  std::uint32_t validColumns = 0;       ///< columns decoded
  std::uint32_t noReturn = 0;           ///< pixels with range 0 (skipped unless keepNoReturn)
  std::uint32_t beyondRecordRange = 0;  ///< pixels skipped: range > kMaxRecordRangeMm
  std::uint32_t outputFull = 0;         ///< records refused because the output span was full
  std::uint32_t refusedPackets() const noexcept { return truncated + oversized + badPacketType; }
};

class OusterDecoder {
 public:
  explicit OusterDecoder(const OusterConfig& config) noexcept : config_(config) {}

  /// Decodes one packet into `out` (kMaxRecordsPerPacket is always enough) and, when `extra` is
  /// not empty, the pixel extras at the same indices (it must then be at least as long as `out`).
  /// Ok; InvalidArgument (bad format or extra too short) / Truncated / Malformed (oversized) /
  /// Unsupported (packet type) with nothing written; Malformed when a column was skipped (the
  /// others written); CapacityExceeded when `out` was too small (the first records written).
  Status decode(Span<const std::uint8_t> packet, Span<FiringRecord> out, std::size_t& written,
                PacketInfo* info = nullptr, Span<PixelExtra> extra = Span<PixelExtra>()) noexcept;

  const OusterCounters& counters() const noexcept { return counters_; }
  void resetCounters() noexcept { counters_ = OusterCounters{}; }
  const OusterConfig& config() const noexcept { return config_; }

 private:
  OusterConfig config_;
  OusterCounters counters_{};
};

/// The record azimuth of measurement id m (0.01 deg) and back.
std::uint16_t columnAzimuth(std::uint16_t measurementId, std::uint16_t columnsPerFrame) noexcept;
std::uint16_t measurementId(std::uint16_t azimuth, std::uint16_t columnsPerFrame) noexcept;

/// One unit's beam intrinsics in SI (read at the edge from its JSON: apps/lib/datasets).
struct OusterIntrinsics {
  std::uint16_t beams = 0;
  std::uint16_t columnsPerFrame = 1024;
  float altitudeRad[kMaxPixelsPerColumn]{};        ///< beam_altitude_angles
  float azimuthRad[kMaxPixelsPerColumn]{};         ///< beam_azimuth_angles
  std::int16_t pixelShift[kMaxPixelsPerColumn]{};  ///< pixel_shift_by_row (staggering)
  float beamOriginM = 0.0F;                        ///< n = lidar_origin_to_beam_origin_mm / 1000
  float beamZOffsetM = 0.0F;  ///< beam_to_lidar_transform[2][3] / 1000 when the JSON has it, else 0
  /// lidar_to_sensor_transform, row-major 4x4, translation in m.
  float lidarToSensor[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
};

/// Ouster's beam model, lidar frame [m]: theta_e = 2 pi (1 - m / W), theta = theta_e - az_i,
/// phi = alt_i; x = (r - n) cos theta cos phi + n cos theta_e; y = (r - n) sin theta cos phi +
/// n sin theta_e; z = (r - n) sin phi + z_beam. With `sensorFrame` the point is then mapped by
/// lidar_to_sensor_transform. OutOfRange (laser >= beams), NotFound (distance 0), else Ok.
Status ousterPoint(const OusterIntrinsics& in, const FiringRecord& r, bool sensorFrame, float xyz[3]) noexcept;

/// The records as the range image's input: points in the sensor frame, laser = beam, firing =
/// the destaggered image column (m + pixel_shift_by_row[beam]) mod W. First returns only.
/// CapacityExceeded when `out` is full; OutOfRange when a beam is beyond the table (skipped).
/// The points are ousterPoint()'s (sensor frame) to float rounding; the sines and cosines are
/// taken once per beam and per column of the call, not per point.
Status toFiringReturns(Span<const FiringRecord> records, const OusterIntrinsics& intrinsics, Span<FiringReturn> out,
                       std::size_t& written) noexcept;

}  // namespace agv::drivers::ouster
