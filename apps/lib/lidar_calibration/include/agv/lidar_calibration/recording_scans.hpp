#pragma once
/// @file recording_scans.hpp
/// Calibration scans from recorded Velodyne data packets, and simulated scans written as such
/// recordings (host code; docs/lidar-calibration.md, "Real recordings").
///
/// A recording holds the packets of one placement of the sensor in front of the target, in one of
/// the containers the datasets readers know: classic pcap (UDP payloads to the data port), a ROS 2
/// bag of VelodyneScan messages (`.db3`), or bare 1206-byte payloads back to back. The packets go
/// through the protocol decoder and the revolution assembler; each revolution used becomes one
/// `CalibrationScan` of raw returns (laser, head angle phi, D_ret = count x the table's distance
/// resolution), which is what the calibration needs: the points are recomputed from them with every
/// new set of intrinsics.

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "agv/drivers/protocol/velodyne/velodyne_packet.hpp"
#include "agv/lidar3d/laser_intrinsics.hpp"
#include "agv/lidar_calibration/intrinsic_calibration.hpp"

namespace agv::lidar_calibration {

/// The sensor model of a table of `lasers` lasers (16: VLP-16, 32: HDL-32E, 64: HDL-64E). False
/// for any other count.
bool velodyneModelOf(std::size_t lasers, drivers::velodyne::Model& model) noexcept;

struct RecordingScanOptions {
  std::uint16_t port = 2368;       ///< pcap: UDP destination port of the data packets (Velodyne's default)
  std::size_t maxRevolutions = 1;  ///< revolutions used per recording, from the first whole one (0: all)
};

/// What reading one recording found.
struct RecordingStats {
  std::string container;           ///< "pcap", "rosbag2", "payloads"
  std::size_t packets = 0;         ///< payloads read
  std::size_t refusedPackets = 0;  ///< wrong size or product (decoder counters)
  std::size_t skippedBlocks = 0;   ///< wrong block id or azimuth
  std::size_t revolutions = 0;     ///< revolutions assembled (whole or not)
  std::size_t partial = 0;         ///< not used: begun mid-turn, or cut by the end of the recording
  std::size_t used = 0;            ///< revolutions returned as scans
  std::size_t returns = 0;         ///< returns in the scans returned
};

/// Appends the whole revolutions of the recording `path` (at most `options.maxRevolutions`) to
/// `out` as scans named "<file name>#rev<k>", for a sensor whose table is `intrinsics` (its laser count
/// gives the model, its resolution the range unit). A revolution is whole when a wrap of the
/// azimuth begins and ends it; the first revolution of a recording is also used when it begins
/// within 1 deg of azimuth 0 (a recording cut at the start of a turn, as `writeRecording` makes
/// them). Dual-return packets give their first returns only. False with `error` naming the file
/// for an unreadable or foreign file, a table of no Velodyne model, no packet of the model, or no
/// whole revolution.
bool readRecordingScans(const std::string& path, const LaserIntrinsics& intrinsics, const RecordingScanOptions& options,
                        std::vector<CalibrationScan>& out, RecordingStats& stats, std::string& error);

/// Writes `scan` (one revolution, returns grouped by firing: consecutive returns with the same
/// phi) as bare HDL-32E / HDL-64E data packets to `path`, followed by a repeat of its first packet
/// so that the reader sees the turn close. The head angle is rounded to the packets' 0.01 deg (the
/// largest rounding is returned in `maxAzimuthRounding` [rad]); the ranges must lie on the table's
/// distance grid (a simulation with quantisation). False with `error` for a VLP-16 table (not
/// encoded: velodyne_encoder.hpp), an off-grid or too long range, a laser twice in one firing, a
/// phi going backwards, or a write failure.
bool writeRecording(const std::string& path, const CalibrationScan& scan, const LaserIntrinsics& intrinsics,
                    double& maxAzimuthRounding, std::string& error);

}  // namespace agv::lidar_calibration
