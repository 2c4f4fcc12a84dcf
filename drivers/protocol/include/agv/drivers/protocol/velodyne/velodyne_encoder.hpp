#pragma once
/// @file velodyne_encoder.hpp
/// Encoder of HDL-32E and HDL-64E (S2) data packets from firings: the inverse of `VelodyneDecoder`
/// for single-return packets (a simulated sensor's output, a recording of simulated scans).
/// Portable and heap-free (docs/velodyne.md).
///
/// One firing = the head azimuth and one raw distance per laser. HDL-32E: one block (0xEEFF,
/// lasers 0-31) per firing, 12 firings per packet, factory bytes 0x37 (strongest) / 0x21. HDL-64E:
/// an upper (0xEEFF, lasers 0-31) and a lower block (0xDDFF, lasers 32-63) with the same azimuth
/// per firing, 6 firings per packet; bytes 1200-1205 (timestamp / status) are zero. Intensity is
/// written as 0. The VLP-16 is not encoded: its decoder interpolates every laser's azimuth between
/// blocks, so a list of firings at arbitrary azimuths has no exact packet form.

#include <cstddef>
#include <cstdint>

#include "agv/core/span.hpp"
#include "agv/core/status.hpp"
#include "agv/drivers/protocol/velodyne/velodyne_packet.hpp"

namespace agv::drivers::velodyne {

class VelodyneEncoder {
 public:
  /// An encoder for `model` (Vlp16: every call returns Unsupported).
  explicit VelodyneEncoder(Model model) noexcept;

  /// Adds one firing: head azimuth [0.01 deg] and `distances[l]` the raw count of laser l (0 = no
  /// return; exactly laserCount(model) entries). `packetReady` is set when this firing completed a
  /// packet: `packet()` then holds it until the next call. InvalidArgument (wrong entry count,
  /// azimuth >= 36000), Unsupported (VLP-16); nothing is added then.
  Status add(std::uint16_t azimuth, Span<const std::uint16_t> distances, bool& packetReady) noexcept;

  /// Completes a partly filled packet (its remaining firings repeat the last azimuth with no
  /// return, which the decoder skips): `packetReady` is set when there was one.
  Status flush(bool& packetReady) noexcept;

  /// The last completed packet (kPacketBytes).
  Span<const std::uint8_t> packet() const noexcept { return Span<const std::uint8_t>(packet_, kPacketBytes); }

  /// Packets completed so far.
  std::uint32_t packets() const noexcept { return packets_; }

 private:
  void writeBlock(std::size_t block, std::uint16_t id, std::uint16_t azimuth, const std::uint16_t* distances) noexcept;
  void finishPacket() noexcept;

  Model model_;
  std::uint8_t packet_[kPacketBytes]{};
  std::size_t block_ = 0;  ///< next block of the packet being filled
  std::uint16_t lastAzimuth_ = 0;
  std::uint32_t packets_ = 0;
};

}  // namespace agv::drivers::velodyne
