#pragma once
/// @file velodyne_packet.hpp
/// Decoder of Velodyne VLP-16, HDL-32E and HDL-64E (S2) data packets into per-firing records, and
/// a revolution assembler that cuts at the azimuth wrap. Portable and heap-free (docs/velodyne.md).
///
/// Packet (the 1206-byte UDP payload, little-endian): 12 blocks of 100 bytes, each `uint16` block
/// id (0xEEFF; HDL-64E lower block 0xDDFF), `uint16` azimuth [0.01 deg, 0..35999], 32 channel
/// records of `uint16` distance [raw counts, 0 = no return] + `uint8` intensity; then `uint32`
/// timestamp [us past the hour] at byte 1200 and two factory bytes: return mode (0x37 strongest,
/// 0x38 last, 0x39 dual) and product id (0x21 HDL-32E, 0x22 VLP-16). The HDL-64E S2 sends status
/// bytes there instead: its return mode comes from the configuration.
///
/// - VLP-16: a block holds two firing sequences of lasers 0-15; the azimuth of each laser is
///   interpolated between this block's azimuth and the next (velodyne_pointcloud's `unpack_vlp16`:
///   phi = phi_block + dphi * (laser * 2.304 us + sequence * 55.296 us) / 110.592 us, rounded to
///   0.01 deg and wrapped to [0, 36000); dphi of the last block = the previous step). Time within
///   the packet: block * 110.592 + sequence * 55.296 + laser * 2.304 us.
/// - HDL-32E: one firing of lasers 0-31 per block, the block's azimuth for all (velodyne_pointcloud's
///   `unpack`); time block * 46.08 + laser * 1.152 us.
/// - HDL-64E: upper blocks (0xEEFF) hold lasers 0-31, lower blocks (0xDDFF) lasers 32-63; the
///   block's azimuth for all lasers (`unpack`). Time: 0 (the S2 firing timing is not implemented).
/// - Dual return (VLP-16, HDL-32E): blocks come in pairs with the same azimuth, the even one holds
///   the last return, the odd one the strongest (or the second strongest when it is the last);
///   records of the odd block have `secondReturn` set and share the timing of the even block; the
///   VLP-16's azimuth step is then taken between pairs.
///
/// Refused input is counted in `VelodyneCounters` and never crashes or stops the decoder: a packet
/// of the wrong size (truncated, oversized) or of another product is refused whole; a block with a
/// wrong id or an azimuth >= 36000 is skipped (its records are not emitted), the rest of the packet
/// is decoded.

#include <cstddef>
#include <cstdint>

#include "agv/core/span.hpp"
#include "agv/core/status.hpp"
#include "agv/lidar3d/laser_intrinsics.hpp"
#include "agv/lidar3d/range_image.hpp"

namespace agv::drivers::velodyne {

/// Bytes of one data packet (UDP payload).
inline constexpr std::size_t kPacketBytes = 1206;
/// Blocks per packet and channel records per block.
inline constexpr std::size_t kBlocksPerPacket = 12;
inline constexpr std::size_t kChannelsPerBlock = 32;
/// Records one packet yields at most (every channel of every block).
inline constexpr std::size_t kMaxRecordsPerPacket = kBlocksPerPacket * kChannelsPerBlock;
/// One turn in the packets' azimuth unit (0.01 deg).
inline constexpr std::uint16_t kAzimuthTurn = 36000;
/// Bytes of one block, and the block ids (upper: every model; lower: HDL-64E lasers 32-63).
inline constexpr std::size_t kBlockBytes = 100;
inline constexpr std::uint16_t kUpperBlockId = 0xEEFF;
inline constexpr std::uint16_t kLowerBlockId = 0xDDFF;
/// Product ids of factory byte 1205.
inline constexpr std::uint8_t kProductHdl32e = 0x21;
inline constexpr std::uint8_t kProductVlp16 = 0x22;

enum class Model : std::uint8_t { Vlp16, Hdl32e, Hdl64e };

/// Return mode of a packet (factory byte 1204; HDL-64E: from the configuration).
enum class ReturnMode : std::uint8_t { Strongest = 0x37, Last = 0x38, Dual = 0x39 };

/// Number of lasers of a model (16, 32, 64).
std::size_t laserCount(Model model) noexcept;

struct VelodyneConfig {
  Model model = Model::Vlp16;
  /// HDL-64E only (its packets carry no return-mode byte).
  ReturnMode hdl64ReturnMode = ReturnMode::Strongest;
  /// Refuse VLP-16 / HDL-32E packets whose product byte names another product (a second sensor
  /// on the same port). Off: the byte is ignored.
  bool checkProductId = true;
  /// Emit records with distance 0 (no return). Off: they are skipped and counted in noReturn.
  bool keepNoReturn = false;
};

/// One return of one laser firing.
struct FiringRecord {
  std::uint32_t timeNs = 0;       ///< time of the firing after the packet's first firing [ns]
  std::uint16_t azimuth = 0;      ///< head angle phi [0.01 deg], [0, 36000) (VLP-16 interpolated)
  std::uint16_t distance = 0;     ///< raw range [counts of the distance resolution, 2 mm]; 0 = none
  std::uint8_t laser = 0;         ///< hardware laser id (the calibration file's laser_id)
  std::uint8_t intensity = 0;     ///< raw reflectivity
  std::uint8_t block = 0;         ///< block of the packet (0..11)
  std::uint8_t secondReturn = 0;  ///< 1 = the odd block of a dual-return pair (strongest / 2nd)
};

/// Header fields of the last decoded packet.
struct PacketInfo {
  std::uint32_t timestampUs = 0;  ///< device time of the packet's first firing [us past the hour]
  ReturnMode returnMode = ReturnMode::Strongest;
  std::uint8_t productId = 0;  ///< factory byte 1205 as sent (HDL-64E: status value)
};

/// What the decoder has refused and skipped since construction (or resetCounters()).
struct VelodyneCounters {
  std::uint32_t packets = 0;       ///< packets decoded (possibly with skipped blocks)
  std::uint32_t truncated = 0;     ///< refused: fewer than 1206 bytes
  std::uint32_t oversized = 0;     ///< refused: more than 1206 bytes
  std::uint32_t wrongProduct = 0;  ///< refused: product id / return mode byte not this model's
  std::uint32_t badBlockId = 0;    ///< blocks skipped: id not 0xEEFF (HDL-64E: nor 0xDDFF)
  std::uint32_t badAzimuth = 0;    ///< blocks skipped: azimuth >= 36000
  std::uint32_t noReturn = 0;      ///< records with distance 0 (skipped unless keepNoReturn)
  std::uint32_t outputFull = 0;    ///< records refused because the output span was full
  std::uint32_t refusedPackets() const noexcept { return truncated + oversized + wrongProduct; }
};

/// Decodes packets of one sensor. Holds no packet state between calls except the counters.
class VelodyneDecoder {
 public:
  explicit VelodyneDecoder(const VelodyneConfig& config) noexcept : config_(config) {}

  /// Decodes one packet into `out` (room for kMaxRecordsPerPacket is always enough) and returns
  /// how many records were written in `written`. Ok; Truncated / Malformed (oversized) /
  /// Unsupported (another product or an unknown return mode) with nothing written; Malformed
  /// when at least one block was skipped (the others are written); CapacityExceeded when `out`
  /// was too small (the first records are written, the rest counted). Slots of `out` past
  /// `written` are scratch: the decoder may overwrite them (a skipped no-return record).
  Status decode(Span<const std::uint8_t> packet, Span<FiringRecord> out, std::size_t& written,
                PacketInfo* info = nullptr) noexcept;

  const VelodyneCounters& counters() const noexcept { return counters_; }
  void resetCounters() noexcept { counters_ = VelodyneCounters{}; }
  const VelodyneConfig& config() const noexcept { return config_; }

 private:
  VelodyneConfig config_;
  VelodyneCounters counters_{};
};

/// What one completed revolution holds.
struct RevolutionInfo {
  std::size_t records = 0;    ///< records stored (= revolution().size())
  std::uint32_t refused = 0;  ///< records that did not fit the storage (counted, not stored)
  std::uint32_t packets = 0;  ///< packets that contributed
  /// False for the first revolution after construction or reset(): it began mid-turn.
  bool complete = false;
};

/// Collects the records of consecutive packets into revolutions. A revolution ends where the
/// azimuth wraps (a record's azimuth lies more than half a turn below the previous record's);
/// the records from the wrap on start the next one. Storage is the caller's (a VLP-16 at 10 Hz
/// needs ~29 000 single-return records, an HDL-64E S2 ~ 134 000).
class RevolutionAssembler {
 public:
  explicit RevolutionAssembler(Span<FiringRecord> storage) noexcept : storage_(storage) {}

  /// Adds the records of one packet, in packet order (at most kMaxRecordsPerPacket after a wrap
  /// are carried over to the next revolution; more are refused and counted there). Returns true when a revolution was
  /// completed by this packet: `revolution()` and `info()` then describe it until the next add().
  /// Records beyond the storage are refused and counted in the revolution's info (never
  /// silently). Bounded: O(records).
  bool add(Span<const FiringRecord> records) noexcept;

  /// Ends the revolution in progress without a wrap (the end of a recording, or a sensor whose
  /// last frame is not followed by the next one: Ouster captures of one frame). Returns true when
  /// it held records: `revolution()` / `info()` then describe it (complete = false: no wrap closed
  /// it). The next add() starts a new revolution, itself marked incomplete.
  bool finish() noexcept;

  /// The last completed revolution (empty before the first).
  Span<const FiringRecord> revolution() const noexcept {
    return Span<const FiringRecord>(storage_.data(), done_ ? info_.records : 0);
  }
  const RevolutionInfo& info() const noexcept { return info_; }
  /// Revolutions completed since construction or reset().
  std::uint32_t revolutions() const noexcept { return revolutions_; }
  /// Forgets everything (the next revolution is marked incomplete).
  void reset() noexcept;

 private:
  void store(const FiringRecord& r) noexcept;
  void startFromPending() noexcept;
  void close(bool complete) noexcept;  ///< publishes the revolution in storage

  Span<FiringRecord> storage_;
  FiringRecord pending_[kMaxRecordsPerPacket]{};
  std::size_t pendingCount_ = 0;
  std::size_t count_ = 0;
  std::uint32_t refused_ = 0;
  std::uint32_t packets_ = 0;
  std::uint32_t revolutions_ = 0;
  std::int32_t lastAzimuth_ = -1;
  bool done_ = false;
  std::uint32_t pendingRefused_ = 0;
  bool armed_ = true;     ///< the head has passed half a turn since the last wrap
  bool started_ = false;  ///< a wrap has been seen: the current revolution began at the cut
  RevolutionInfo info_{};
};

/// The records of a revolution as the range image's input (`RangeImageBase::buildFromFirings`):
/// each return's point by the thesis' model (`LaserIntrinsics::laserPoint`, REP-103 frame), its
/// laser id, and as firing index the column of its head azimuth in `columns` equal steps (column 0
/// at phi = 0). Dual-return pairs: only the first return of each (secondReturn = 0) is used.
/// Ok; InvalidArgument (columns 0); OutOfRange when a laser id is beyond the table (skipped);
/// CapacityExceeded when `out` is full (the rest not written). `written` = returns written.
Status toFiringReturns(Span<const FiringRecord> records, const LaserIntrinsics& intrinsics, std::size_t columns,
                       Span<FiringReturn> out, std::size_t& written) noexcept;

}  // namespace agv::drivers::velodyne
