#pragma once
/// @file places.hpp
/// agvnav-lidar-places: a sequence of multi-beam revolutions (KITTI or NCLT velodyne `.bin`) run
/// or VLP-16 raw packets) through the normal-histogram signatures, key-signatures and loop detection of agv/lidar3d,
/// with precision / recall against ground-truth positions and yaw errors where poses exist.

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "agv/core/pose2.hpp"
#include "agv/lidar3d/normal_signature.hpp"
#include "agv/lidar3d/orientation_signature.hpp"
#include "agv/lidar3d/place_database.hpp"
#include "agv/report/json.hpp"

namespace agv::places {

/// Kitti / Nclt: one revolution per `.bin` of points. Vlp16Packets: recordings of raw VLP-16 UDP
/// payloads (1206 bytes each, concatenated: the einride recording), decoded by
/// agv::drivers::velodyne, cut into revolutions by its RevolutionAssembler, points by a
/// calibration file (`calibrationPath`). Vlp16Bag: the same from the VelodyneScan messages of a
/// ROS 2 bag (`*.db3`, rosbag2's sqlite3 storage: the nebula recording), messages in time order.
enum class Format { Kitti, Nclt, Vlp16Packets, Vlp16Bag };

/// The formats of raw VLP-16 packets (decoder, assembler, calibration file).
constexpr bool isPacketFormat(Format f) noexcept {
  return f == Format::Vlp16Packets || f == Format::Vlp16Bag;
}

/// The simulated route (drivers/sim multibeam_world.hpp) instead of files.
struct SimRouteOptions {
  std::string sensor;       ///< "" (no simulation), "hdl64" or "vlp16"
  std::string calibration;  ///< hdl64: factory calibration YAML (elevations, azimuth offsets)
  double width = 120.0;     ///< [m] the yard's road rectangle
  double height = 80.0;     ///< [m]
  double step = 1.0;        ///< [m] between revolutions
  double back = 0.5;        ///< fraction of the lap driven back in the opposite direction
  double again = 0.3;       ///< fraction of the lap driven again in the first direction
  double lateral = 1.0;     ///< [m] lateral offset of the repeated passes (sinusoidal)
  std::uint64_t seed = 1;   ///< world and noise
  /// vlp16: each revolution encoded as VLP-16 packets and run through the decoder, the revolution
  /// assembler and buildFromFirings (the packet path against the simulator's truth).
  bool packets = false;
};

/// One sensor's threshold set on the simulated yard (docs/lidar-places.md, "Adopted: one set per
/// sensor"): what `--sim hdl64|vlp16` uses for each of these options the command line does not give.
struct SensorSet {
  float chiSquareThreshold = 3.0e-4F;  ///< T_chi2
  float sorensenThreshold = 0.035F;    ///< T_Sor
  std::size_t laserStep = 2;           ///< normals: lasers above / below
  float maxLoopTranslation = 4.5F;     ///< [m] geometric verification radius (the 5-m truth radius less 0.5 m)
  float minAlignedFraction = 0.6F;     ///< geometric verification: inlier share
};

/// The set of a simulated sensor ("hdl64": the library's T_chi2 / T_Sor and laser step; "vlp16": T_chi2
/// 9e-4, T_Sor 0.105, laser step 1; both with the verification at 4.5 m / 0.6). False for another name.
bool simulatedSensorSet(const std::string& sensor, SensorSet& set);

/// What to run and how.
struct PlacesOptions {
  Format format = Format::Kitti;
  std::vector<std::string> files;  ///< revolutions in driving order
  SimRouteOptions sim{};
  std::string calibrationPath;  ///< packet formats: db.xml or velodyne_pointcloud YAML (16 lasers)
  std::string posesPath;        ///< KITTI poses (frame = the file name's number); empty: no truth
  double radius = 5.0;          ///< [m] a loop is true when the two positions are this close
  std::size_t columns = 0;      ///< range-image columns (0: 2000 for KITTI, 1024 for NCLT)
  PlaceParams place{};
  NormalSignatureParams signature{};
  OrientationParams orientation{};
  /// The precision / recall curve: the database rerun with T_chi2 and T_Sor both multiplied by
  /// each factor (T_key and m kept).
  std::vector<float> curveScale = {0.25F, 0.5F, 1.0F, 1.5F, 2.0F, 3.0F, 4.0F, 6.0F, 8.0F};
};

/// One revolution's outcome.
struct ScanResult {
  std::string file;
  long frame = -1;  ///< number in the file name (KITTI frame), -1 when none
  std::size_t points = 0;
  std::uint32_t normals = 0;
  std::uint32_t collisions = 0;  ///< returns that fell on an occupied cell of the range image
  Status status = Status::Ok;    ///< of the signature (a failed scan is not added)
  PlaceUpdate update{};
  bool hasTruth = false;
  bool truePositiveCandidate = false;  ///< an eligible key was within the radius (a loop to find)
  bool loopTrue = false;               ///< the detected loop's positions are within the radius
  double loopDistance = 0.0;           ///< [m] between the two positions of the detected loop
  bool hasYawError = false;
  double yawTruth = 0.0;             ///< [rad]
  double yawError = 0.0;             ///< [rad] estimate - truth (the alignment's yaw when there is one)
  double signatureYawError = 0.0;    ///< [rad] the orientation signature's yaw - truth
  bool hasTranslationError = false;  ///< the loop has an alignment and truth
  Eigen::Vector2d translationTruth = Eigen::Vector2d::Zero();  ///< [m] this position in the key's frame
  double translationError = 0.0;                               ///< [m] |alignment (x, y) - truth|
  double signatureSum = 0.0;  ///< sum of the normal signature's bins (1 when normalised, 0 when empty)
  bool hasStepYaw = false;    ///< relative yaw to the previous revolution (both orientations valid)
  double stepYaw = 0.0;       ///< [rad] counter-clockwise, this revolution w.r.t. the previous one
  float stepYawRelativeCost = 0.0F;
};

/// What the packet path decoded (packet formats).
struct PacketStats {
  std::size_t files = 0;
  std::size_t messages = 0;        ///< Vlp16Bag: VelodyneScan messages read
  std::size_t packets = 0;         ///< packets read
  std::size_t refusedPackets = 0;  ///< refused by the decoder (truncated, another product, ...)
  std::size_t skippedBlocks = 0;   ///< blocks skipped (bad id / azimuth)
  std::size_t records = 0;         ///< returns decoded
  std::size_t revolutions = 0;     ///< revolutions cut by the assembler
  std::size_t incomplete = 0;      ///< of them begun mid-turn (a file's first): not run
  std::size_t refusedRecords = 0;  ///< records beyond the assembler's storage
  std::size_t firingReturns = 0;   ///< returns handed to the range images
};

/// One point of the precision / recall curve.
struct PrPoint {
  float chiSquareThreshold = 0.0F;
  float sorensenThreshold = 0.0F;
  std::size_t detected = 0;
  std::size_t truePositives = 0;
  std::size_t positives = 0;  ///< scans with a true eligible key
  double precision = 0.0;     ///< 1 when nothing was detected
  double recall = 0.0;        ///< 1 when there is nothing to find
};

/// The run.
struct PlacesResult {
  std::vector<ScanResult> scans;
  std::vector<NormalSignature> signatures;         ///< per scan (empty on failure)
  std::vector<OrientationSignature> orientations;  ///< per scan (empty on failure)
  std::size_t keys = 0;
  PrPoint summary{};  ///< at the chosen T_chi2
  std::vector<PrPoint> curve;
  std::vector<Pose2d> truth;  ///< per scan when poses were given: position on the ground, yaw
  double yawErrorMaxDeg = 0.0;
  double yawErrorMeanAbsDeg = 0.0;
  std::size_t yawCount = 0;
  /// |yaw error| statistics of the loops [deg], all / same direction / opposite direction (|yaw
  /// truth| > 90 deg): median, 90 %, max, share within 1 deg.
  struct YawStats {
    std::size_t count = 0;
    double median = 0.0;
    double p90 = 0.0;
    double max = 0.0;
    double within1 = 0.0;
  };
  YawStats yawAll{};
  YawStats yawSame{};
  YawStats yawOpposite{};
  YawStats signatureYawAll{};           ///< the same for the orientation signature's (coarse) yaw
  std::size_t translationCount = 0;     ///< loops with an alignment and truth
  double translationErrorMedian = 0.0;  ///< [m]
  double translationErrorMax = 0.0;     ///< [m]
  PacketStats packets{};
  std::size_t stepYawCount = 0;  ///< consecutive revolutions with a relative yaw
  double stepYawMaxAbsDeg = 0.0;
  double stepYawMeanAbsDeg = 0.0;
  double seconds = 0.0;  ///< wall time of the run (reading / simulating included)
};

/// Runs the sequence. False with `error` on a file that cannot be read or bad options.
bool runPlaces(const PlacesOptions& options, PlacesResult& result, std::string& error);

/// The JSON document of a run.
report::Json placesJson(const PlacesOptions& options, const PlacesResult& result);

/// The SVG of a run: the key signatures, and the trajectory with its loops when poses exist.
std::string placesSvg(const PlacesResult& result);

}  // namespace agv::places
