#pragma once
/// @file velodyne_recording.hpp
/// Reader of a recording of raw Velodyne UDP payloads concatenated without any header (the
/// einride VLP-16 `recording.bin`: 1000 payloads of 1206 bytes; docs/velodyne.md). Host code.

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace agv::datasets {

/// A recording's bytes: `packets` payloads of `packetBytes` each, back to back.
struct PacketRecording {
  std::vector<std::uint8_t> bytes;
  std::size_t packetBytes = 0;
  std::size_t packets = 0;
  /// The bytes of payload `k` (k < packets).
  const std::uint8_t* packet(std::size_t k) const noexcept { return bytes.data() + k * packetBytes; }
};

/// Reads `path` as concatenated payloads of `packetBytes` (1206 for Velodyne data packets). False
/// with `error` when the file cannot be opened, is empty, or its size is not a multiple of
/// `packetBytes` (another container: pcap, a ROS bag, a KITTI .bin).
bool readPacketRecording(const std::string& path, std::size_t packetBytes, PacketRecording& out, std::string& error);

}  // namespace agv::datasets
