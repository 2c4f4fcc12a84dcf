#include "agv/drivers/protocol/velodyne/velodyne_encoder.hpp"

namespace agv::drivers::velodyne {

namespace {
constexpr std::uint16_t kNoReturn[kChannelsPerBlock] = {};

void put16(std::uint8_t* p, std::uint16_t v) noexcept {
  p[0] = static_cast<std::uint8_t>(v & 0xFFU);
  p[1] = static_cast<std::uint8_t>(v >> 8U);
}
}  // namespace

VelodyneEncoder::VelodyneEncoder(Model model) noexcept : model_(model) {}

void VelodyneEncoder::writeBlock(std::size_t block, std::uint16_t id, std::uint16_t azimuth,
                                 const std::uint16_t* distances) noexcept {
  std::uint8_t* b = packet_ + block * kBlockBytes;
  put16(b, id);
  put16(b + 2, azimuth);
  for (std::size_t c = 0; c < kChannelsPerBlock; ++c) {
    put16(b + 4 + 3 * c, distances[c]);
    b[4 + 3 * c + 2] = 0;
  }
}

void VelodyneEncoder::finishPacket() noexcept {
  for (std::size_t i = kBlocksPerPacket * kBlockBytes; i < kPacketBytes; ++i) {
    packet_[i] = 0;
  }
  if (model_ == Model::Hdl32e) {
    packet_[1204] = static_cast<std::uint8_t>(ReturnMode::Strongest);
    packet_[1205] = kProductHdl32e;
  }
  block_ = 0;
  ++packets_;
}

Status VelodyneEncoder::add(std::uint16_t azimuth, Span<const std::uint16_t> distances, bool& packetReady) noexcept {
  packetReady = false;
  if (model_ == Model::Vlp16) {
    return Status::Unsupported;
  }
  if (azimuth >= kAzimuthTurn || distances.size() != laserCount(model_)) {
    return Status::InvalidArgument;
  }
  writeBlock(block_++, kUpperBlockId, azimuth, distances.data());
  if (model_ == Model::Hdl64e) {
    writeBlock(block_++, kLowerBlockId, azimuth, distances.data() + kChannelsPerBlock);
  }
  lastAzimuth_ = azimuth;
  if (block_ == kBlocksPerPacket) {
    finishPacket();
    packetReady = true;
  }
  return Status::Ok;
}

Status VelodyneEncoder::flush(bool& packetReady) noexcept {
  packetReady = false;
  if (model_ == Model::Vlp16) {
    return Status::Unsupported;
  }
  if (block_ == 0) {
    return Status::Ok;
  }
  while (block_ < kBlocksPerPacket) {  // bounded: at most 11 blocks
    writeBlock(block_, (model_ == Model::Hdl64e && block_ % 2U == 1U) ? kLowerBlockId : kUpperBlockId, lastAzimuth_,
               kNoReturn);
    ++block_;
  }
  finishPacket();
  packetReady = true;
  return Status::Ok;
}

}  // namespace agv::drivers::velodyne
