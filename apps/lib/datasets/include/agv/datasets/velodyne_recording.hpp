#pragma once
/// @file velodyne_recording.hpp
/// Readers of recordings of raw Velodyne UDP payloads (docs/velodyne.md). Host code.
/// - concatenated payloads without any header (the einride VLP-16 `recording.bin`: 1000 payloads of
///   1206 bytes);
/// - a ROS 2 bag (rosbag2, sqlite3 storage) of `velodyne_msgs/msg/VelodyneScan` messages (the nebula
///   VLP-16 bag), CDR little-endian: the payloads of every message in the bag's time order.

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

/// One VelodyneScan message of a bag.
struct VelodyneScanMessage {
  std::int64_t bagTimeNs = 0;  ///< the bag's receive time (messages.timestamp)
  std::int32_t stampSec = 0;   ///< header.stamp
  std::uint32_t stampNanosec = 0;
  std::string frameId;          ///< header.frame_id
  std::size_t firstPacket = 0;  ///< index of its first payload in `VelodyneScanBag::packets`
  std::size_t packetCount = 0;  ///< its payloads
};

/// The VelodyneScan messages of a ROS 2 bag: their payloads back to back (1206 bytes each, the
/// messages in time order, each message's packets in its order) and where each message begins.
struct VelodyneScanBag {
  std::string topic;  ///< the one topic of type velodyne_msgs/msg/VelodyneScan
  std::vector<VelodyneScanMessage> messages;
  PacketRecording packets;
};

/// Reads the `velodyne_msgs/msg/VelodyneScan` messages of a rosbag2 sqlite3 file (`*.db3`). The CDR
/// layout (little-endian, alignment relative to the 4-byte encapsulation header): header.stamp
/// (int32 sec, uint32 nanosec), header.frame_id (uint32 length with the NUL, bytes), a uint32
/// packet count, per packet stamp (int32, uint32; 4-aligned) and a uint8[1206] payload. False with
/// `error` when the file is not an SQLite rosbag2 file, holds no or several VelodyneScan topics, a
/// message is big-endian CDR or shorter than its packet count says, or the reader was built without
/// SQLite (libsqlite3-dev).
bool readVelodyneScanBag(const std::string& path, VelodyneScanBag& out, std::string& error);

}  // namespace agv::datasets
