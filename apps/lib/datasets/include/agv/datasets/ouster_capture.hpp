#pragma once
/// @file ouster_capture.hpp
/// Host-side readers for Ouster OS-series recordings (docs/ouster.md):
/// - the unit's metadata JSON (ouster-sdk / sensor `GET /api/v1/sensor/metadata` flat layout):
///   `data_format` {`udp_profile_lidar` (absent = LEGACY), `columns_per_packet`,
///   `pixels_per_column`, `columns_per_frame`, `pixel_shift_by_row`}, `beam_altitude_angles` and
///   `beam_azimuth_angles` [deg], `lidar_origin_to_beam_origin_mm`, `lidar_to_sensor_transform`
///   (row-major 4x4, translation in mm), optional `beam_to_lidar_transform`, `udp_port_lidar`;
///   converted here to the SI `OusterIntrinsics` (rad, m);
/// - classic libpcap files (magic a1b2c3d4 / a1b23c4d, either byte order; link type Ethernet, with
///   an optional 802.1Q tag; IPv4 UDP, unfragmented): the UDP payloads sent to one port. (libpcap is
///   not a dependency: the classic file format is 24 + 16 bytes of headers.)

#include <cstdint>
#include <string>
#include <vector>

#include "agv/drivers/protocol/ouster/ouster_packet.hpp"

namespace agv::datasets {

struct OusterMetadata {
  std::string prodLine;
  std::string profileName;  ///< as in the JSON ("LEGACY" when absent)
  std::string lidarMode;    ///< `lidar_mode`, e.g. "1024x10" (columns x frame rate [Hz]); may be empty
  drivers::ouster::Format format{};
  drivers::ouster::OusterIntrinsics intrinsics{};
  std::uint16_t udpPortLidar = 7502;
};

/// Parses the JSON text. False with `error` naming the field and the reason.
bool parseOusterMetadata(const std::string& text, OusterMetadata& out, std::string& error);
bool readOusterMetadata(const std::string& path, OusterMetadata& out, std::string& error);

struct PcapStats {
  std::uint32_t records = 0;    ///< pcap records read
  std::uint32_t matched = 0;    ///< UDP datagrams to the port (returned)
  std::uint32_t otherPort = 0;  ///< UDP to another port
  std::uint32_t notUdp = 0;     ///< not Ethernet/IPv4/UDP, or fragmented
  std::uint32_t truncated = 0;  ///< captured shorter than the headers / the UDP length says
};

/// UDP payloads to `port` in file order. False with `error` (unreadable file, bad magic, link type
/// not Ethernet, a record running past the end of the file).
bool readPcapUdp(const std::string& path, std::uint16_t port, std::vector<std::vector<std::uint8_t>>& payloads,
                 PcapStats& stats, std::string& error);

}  // namespace agv::datasets
