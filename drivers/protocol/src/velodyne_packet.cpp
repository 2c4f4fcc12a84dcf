#include "agv/drivers/protocol/velodyne/velodyne_packet.hpp"

#include <algorithm>
#include <cmath>

namespace agv::drivers::velodyne {

namespace {
// Firing timing [ns] (VLP-16 and HDL-32E user manuals; velodyne_pointcloud's constants).
constexpr std::uint32_t kVlp16LaserNs = 2304;
constexpr std::uint32_t kVlp16SequenceNs = 55296;
constexpr std::uint32_t kVlp16BlockNs = 110592;
constexpr std::uint32_t kHdl32LaserNs = 1152;
constexpr std::uint32_t kHdl32BlockNs = 46080;
constexpr std::uint16_t kHalfTurn = kAzimuthTurn / 2;

std::uint16_t le16(const std::uint8_t* p) noexcept {
  return static_cast<std::uint16_t>(p[0] | (static_cast<unsigned>(p[1]) << 8U));
}

bool validReturnMode(std::uint8_t b) noexcept {
  return b == static_cast<std::uint8_t>(ReturnMode::Strongest) || b == static_cast<std::uint8_t>(ReturnMode::Last) ||
         b == static_cast<std::uint8_t>(ReturnMode::Dual);
}

// Writes the records of one block's 32 channels to `out` from `written` on, in channel order:
// distance and intensity from the packet, the rest by `fill(channel, record)`. Records with
// distance 0 are counted in noReturn and kept only with `keepNoReturn`. Returns true when `out`
// ran full (the records that did not fit counted in outputFull). With room for the whole block the
// loop is branch-free: every record is stored at the next free slot, which advances only for the
// records kept (a skipped record's slot is overwritten by the next one or left past `written`).
template <typename Fill>
bool emitBlock(const std::uint8_t* blk, const Fill& fill, bool keepNoReturn, Span<FiringRecord> out,
               std::size_t& written, VelodyneCounters& counters) noexcept {
  const std::uint8_t* rec = blk + 4;
  if (out.size() - written >= kChannelsPerBlock) {
    FiringRecord* dst = out.data() + written;
    std::size_t kept = 0;
    std::uint32_t zeros = 0;
    for (std::size_t c = 0; c < kChannelsPerBlock; ++c, rec += 3) {
      FiringRecord r;
      r.distance = le16(rec);
      r.intensity = rec[2];
      fill(c, r);
      dst[kept] = r;
      const bool zero = r.distance == 0U;
      zeros += zero ? 1U : 0U;
      kept += (keepNoReturn || !zero) ? 1U : 0U;
    }
    counters.noReturn += zeros;
    written += kept;
    return false;
  }
  bool full = false;
  for (std::size_t c = 0; c < kChannelsPerBlock; ++c, rec += 3) {
    FiringRecord r;
    r.distance = le16(rec);
    r.intensity = rec[2];
    fill(c, r);
    if (r.distance == 0U) {
      ++counters.noReturn;
      if (!keepNoReturn) {
        continue;
      }
    }
    if (written >= out.size()) {
      ++counters.outputFull;
      full = true;
      continue;
    }
    out[written++] = r;
  }
  return full;
}
}  // namespace

std::size_t laserCount(Model model) noexcept {
  switch (model) {
    case Model::Vlp16:
      return 16;
    case Model::Hdl32e:
      return 32;
    case Model::Hdl64e:
      return 64;
  }
  return 0;
}

Status VelodyneDecoder::decode(Span<const std::uint8_t> packet, Span<FiringRecord> out, std::size_t& written,
                               PacketInfo* info) noexcept {
  written = 0;
  if (packet.size() < kPacketBytes) {
    ++counters_.truncated;
    return Status::Truncated;
  }
  if (packet.size() > kPacketBytes) {
    ++counters_.oversized;
    return Status::Malformed;
  }
  const std::uint8_t* p = packet.data();
  PacketInfo pi;
  pi.timestampUs = static_cast<std::uint32_t>(le16(p + 1200)) | (static_cast<std::uint32_t>(le16(p + 1202)) << 16U);
  pi.productId = p[1205];
  if (config_.model == Model::Hdl64e) {
    pi.returnMode = config_.hdl64ReturnMode;
  } else {
    const std::uint8_t wanted = config_.model == Model::Vlp16 ? kProductVlp16 : kProductHdl32e;
    if (!validReturnMode(p[1204]) || (config_.checkProductId && p[1205] != wanted)) {
      ++counters_.wrongProduct;
      return Status::Unsupported;
    }
    pi.returnMode = static_cast<ReturnMode>(p[1204]);
  }
  if (info != nullptr) {
    *info = pi;
  }
  ++counters_.packets;

  const bool dual = pi.returnMode == ReturnMode::Dual && config_.model != Model::Hdl64e;
  const std::size_t stride = dual ? 2U : 1U;  // blocks between two firings of the head
  bool skipped = false;
  bool full = false;
  float lastStep = -1.0F;  // VLP-16: the previous block step [0.01 deg]; < 0 = none yet

  for (std::size_t b = 0; b < kBlocksPerPacket; ++b) {
    const std::uint8_t* blk = p + b * kBlockBytes;
    const std::uint16_t id = le16(blk);
    const std::uint16_t az = le16(blk + 2);
    const bool lower = id == kLowerBlockId && config_.model == Model::Hdl64e;
    if (id != kUpperBlockId && !lower) {
      ++counters_.badBlockId;
      skipped = true;
      continue;
    }
    if (az >= kAzimuthTurn) {
      ++counters_.badAzimuth;
      skipped = true;
      continue;
    }
    const std::size_t firing = b / stride;  // index of the head firing within the packet
    const bool second = dual && (b % 2U) == 1U;

    // VLP-16: azimuth step to the next firing of the head (velodyne_pointcloud unpack_vlp16, with
    // the dual-return pairs of nebula): the next pair's azimuth, else the previous step, else the
    // step from the previous firing.
    float step = 0.0F;
    if (config_.model == Model::Vlp16) {
      const std::size_t next = (firing + 1U) * stride;
      const std::uint8_t* nb = p + next * kBlockBytes;
      const bool nextOk = next < kBlocksPerPacket && le16(nb) == kUpperBlockId && le16(nb + 2) < kAzimuthTurn;
      if (nextOk) {
        const int raw = static_cast<int>(le16(nb + 2)) - static_cast<int>(az);
        step = static_cast<float>((raw + kAzimuthTurn) % kAzimuthTurn);
        if (raw < 0 && lastStep > 0.0F) {
          step = lastStep;  // the next block wrapped: unpack_vlp16 keeps the previous step
        }
      } else if (lastStep >= 0.0F) {
        step = lastStep;
      } else if (firing > 0) {
        const std::uint8_t* pb = p + (firing - 1U) * stride * kBlockBytes;
        if (le16(pb) == kUpperBlockId && le16(pb + 2) < kAzimuthTurn) {
          step =
              static_cast<float>((static_cast<int>(az) - static_cast<int>(le16(pb + 2)) + kAzimuthTurn) % kAzimuthTurn);
        }
      }
      if (!second) {
        lastStep = step;
      }
    }

    // The model's switch is taken once per block; emitBlock writes the 32 records.
    const std::uint8_t blockIndex = static_cast<std::uint8_t>(b);
    const std::uint8_t secondFlag = second ? 1U : 0U;
    switch (config_.model) {
      case Model::Vlp16: {
        const std::uint32_t firingNs = static_cast<std::uint32_t>(firing) * kVlp16BlockNs;
        full |= emitBlock(
            blk,
            [&](std::size_t c, FiringRecord& r) noexcept {
              const std::uint32_t seq = static_cast<std::uint32_t>(c / 16U);
              const std::uint32_t laser = static_cast<std::uint32_t>(c % 16U);
              r.laser = static_cast<std::uint8_t>(laser);
              const std::uint32_t tIn = laser * kVlp16LaserNs + seq * kVlp16SequenceNs;
              r.timeNs = firingNs + tIn;
              const float f =
                  static_cast<float>(az) + step * static_cast<float>(tIn) / static_cast<float>(kVlp16BlockNs);
              r.azimuth = static_cast<std::uint16_t>(static_cast<long>(std::lround(f)) % kAzimuthTurn);
              r.block = blockIndex;
              r.secondReturn = secondFlag;
            },
            config_.keepNoReturn, out, written, counters_);
        break;
      }
      case Model::Hdl32e: {
        const std::uint32_t firingNs = static_cast<std::uint32_t>(firing) * kHdl32BlockNs;
        full |= emitBlock(
            blk,
            [&](std::size_t c, FiringRecord& r) noexcept {
              r.laser = static_cast<std::uint8_t>(c);
              r.timeNs = firingNs + static_cast<std::uint32_t>(c) * kHdl32LaserNs;
              r.azimuth = az;
              r.block = blockIndex;
              r.secondReturn = secondFlag;
            },
            config_.keepNoReturn, out, written, counters_);
        break;
      }
      case Model::Hdl64e: {
        const std::size_t laserBase = lower ? kChannelsPerBlock : 0U;
        full |= emitBlock(
            blk,
            [&](std::size_t c, FiringRecord& r) noexcept {
              r.laser = static_cast<std::uint8_t>(c + laserBase);
              r.timeNs = 0;
              r.azimuth = az;
              r.block = blockIndex;
              r.secondReturn = secondFlag;
            },
            config_.keepNoReturn, out, written, counters_);
        break;
      }
    }
  }
  if (full) {
    return Status::CapacityExceeded;
  }
  return skipped ? Status::Malformed : Status::Ok;
}

void RevolutionAssembler::reset() noexcept {
  pendingCount_ = 0;
  count_ = 0;
  refused_ = 0;
  pendingRefused_ = 0;
  packets_ = 0;
  revolutions_ = 0;
  lastAzimuth_ = -1;
  armed_ = true;
  done_ = false;
  started_ = false;
  info_ = RevolutionInfo{};
}

void RevolutionAssembler::store(const FiringRecord& r) noexcept {
  if (count_ < storage_.size()) {
    storage_[count_++] = r;
  } else {
    ++refused_;
  }
}

void RevolutionAssembler::startFromPending() noexcept {
  done_ = false;
  count_ = 0;
  refused_ = pendingRefused_;
  pendingRefused_ = 0;
  packets_ = pendingCount_ > 0 ? 1U : 0U;
  for (std::size_t i = 0; i < pendingCount_; ++i) {
    store(pending_[i]);
  }
  pendingCount_ = 0;
}

bool RevolutionAssembler::finish() noexcept {
  if (done_) {  // the last add() completed a revolution: its pending tail is the one to end
    startFromPending();
  }
  if (count_ == 0 && refused_ == 0) {
    return false;
  }
  close(false);
  started_ = false;
  armed_ = true;
  lastAzimuth_ = -1;
  return true;
}

void RevolutionAssembler::close(bool complete) noexcept {
  info_.records = count_;
  info_.refused = refused_;
  info_.packets = packets_;
  info_.complete = complete;
  done_ = true;
  ++revolutions_;
}

bool RevolutionAssembler::add(Span<const FiringRecord> records) noexcept {
  if (done_) {  // the previous call completed a revolution: start the next from its pending tail
    startFromPending();
  }
  const std::size_t n = records.size();
  const FiringRecord* const rec = records.data();
  // Up to the wrap: a wrap is where the azimuth falls by more than half a turn after the head
  // passed half a turn (the hysteresis keeps a record interpolated just past the cut from cutting
  // twice), i.e. below `limit` = the previous azimuth - half a turn while armed (-1 = no wrap
  // possible: not armed, or no previous record). The records before it are stored in one copy.
  bool armed = armed_;
  std::int32_t limit = armed && lastAzimuth_ >= 0 ? lastAzimuth_ - kHalfTurn : -1;
  std::size_t cut = 0;
  for (; cut < n; ++cut) {
    const std::int32_t az = rec[cut].azimuth;
    if (az < limit) {
      break;
    }
    armed = armed || az >= kHalfTurn;
    limit = armed ? az - kHalfTurn : -1;
  }
  const bool wrapped = cut < n;
  const std::size_t room = storage_.size() - count_;
  const std::size_t stored = cut < room ? cut : room;
  std::copy(rec, rec + stored, storage_.data() + count_);
  count_ += stored;
  refused_ += static_cast<std::uint32_t>(cut - stored);
  ++packets_;
  if (n > 0) {
    lastAzimuth_ = rec[n - 1].azimuth;
  }
  if (!wrapped) {
    armed_ = armed;
    return false;
  }
  // From the wrap on, records of the packet's second half-turn still belong to the old revolution
  // (a dual-return pair or an interpolated firing that straddles the cut); the others start the
  // next one.
  for (std::size_t i = cut; i < n; ++i) {
    const FiringRecord& r = rec[i];
    if (r.azimuth >= kHalfTurn) {
      store(r);
    } else if (pendingCount_ < kMaxRecordsPerPacket) {
      pending_[pendingCount_++] = r;
    } else {
      ++pendingRefused_;
    }
  }
  armed_ = false;
  close(started_);
  started_ = true;
  return true;
}

Status toFiringReturns(Span<const FiringRecord> records, const LaserIntrinsics& intrinsics, std::size_t columns,
                       Span<FiringReturn> out, std::size_t& written) noexcept {
  written = 0;
  if (columns == 0) {
    return Status::InvalidArgument;
  }
  Status st = Status::Ok;
  const std::size_t lasers = intrinsics.size();
  int cachedAz = -1;  // per firing (head azimuth): sin / cos of the head angle and the column
  float sinPhi = 0.0F;
  float cosPhi = 1.0F;
  std::uint32_t column = 0;
  FiringReturn* const dst = out.data();
  const std::size_t capacity = out.size();
  std::size_t count = 0;  // written once at the end: no store through the reference per point
  for (const FiringRecord& r : records) {
    if (r.secondReturn != 0U || r.distance == 0U) {
      continue;
    }
    if (r.laser >= lasers) {
      st = Status::OutOfRange;
      continue;
    }
    if (count >= capacity) {
      written = count;
      return Status::CapacityExceeded;
    }
    if (r.azimuth != cachedAz) {
      cachedAz = r.azimuth;
      const float phi = static_cast<float>(r.azimuth) * (3.14159265358979323846F / 18000.0F);
      sinPhi = std::sin(phi);
      cosPhi = std::cos(phi);
      column = static_cast<std::uint32_t>(static_cast<std::size_t>(r.azimuth) * columns / kAzimuthTurn);
    }
    FiringReturn& f = dst[count++];
    f.point = intrinsics.laserPoint(r.laser, r.distance, sinPhi, cosPhi);
    f.laser = r.laser;
    f.firing = column;
  }
  written = count;
  return st;
}

}  // namespace agv::drivers::velodyne
