#pragma once
/// @file laser_intrinsics.hpp
/// Per-laser intrinsic calibration of a multi-beam lidar (Velodyne-class) and the thesis' point
/// model (Muhammad 2012; ../shared/DESIGN.md), which is velodyne_pointcloud's `RawData::unpack`
/// with the two-point distance correction off.
///
/// Per laser (thesis names; velodyne_pointcloud YAML names in brackets):
/// - D_corr [dist_correction] m: added to the measured range;
/// - V_o [vert_offset_correction] m, H_o [horiz_offset_correction] m: beam origin offsets;
/// - theta [vert_correction] rad: elevation of the laser, positive up;
/// - alpha [rot_correction] rad: azimuth offset of the laser, subtracted from the head angle.
///
/// Model, with phi the encoder (head) azimuth, clockwise seen from above from the Velodyne frame's
/// +y axis (forward), and D_ret = raw * distanceResolution:
///   D = D_ret + D_corr;  Pz = D sin(theta) + V_o cos(theta);  Dxy = D cos(theta) - V_o sin(theta);
///   beta = phi - alpha;  Px = Dxy sin(beta) - H_o cos(beta);  Py = Dxy cos(beta) + H_o sin(beta)
/// (Px, Py, Pz) is the Velodyne frame (x right, y forward, z up). `laserPoint` returns the sensor
/// frame of the rest of the library (REP-103, what `RangeImage` and KITTI use: x forward, y left,
/// z up): x = Py, y = -Px, z = Pz, exactly as velodyne_pointcloud publishes it.
///
/// Precision: the parameters are kept in double (the calibration estimates them; file values are
/// kept unrounded); points are computed in float from cached float sines and cosines of theta and
/// of beta (ranges <= 130 m: float resolution 8 um, as velodyne_pointcloud's float tables).
/// Heap-free; a table is ~6 KiB for kMaxLidarLasers = 128.

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>

#include "agv/core/capacities.hpp"
#include "agv/core/status.hpp"

namespace agv {

/// The five parameters of one laser in SI units (converted from cm / degrees at the file edge).
struct LaserParams {
  double distCorrection = 0.0;  ///< D_corr [m]
  double vertOffset = 0.0;      ///< V_o [m]
  double horizOffset = 0.0;     ///< H_o [m]
  double theta = 0.0;           ///< vertical correction = elevation [rad], positive up
  double alpha = 0.0;           ///< rotational correction = azimuth offset [rad]
};

/// The intrinsics of every laser of one sensor, indexed by hardware laser id (0 .. size()-1).
class LaserIntrinsics {
 public:
  /// An empty table (size 0) with distance resolution 2 mm per raw count.
  LaserIntrinsics() noexcept = default;

  /// Sets the number of lasers; every laser's parameters become zero. InvalidArgument for 0,
  /// CapacityExceeded beyond kMaxLidarLasers (the table is then left unchanged).
  Status reset(std::size_t lasers) noexcept;
  /// Sets laser `id`'s parameters. OutOfRange for id >= size(), NonFiniteInput for a NaN/inf
  /// parameter, InvalidArgument for |theta| or |alpha| > pi (radians expected, not degrees); the
  /// laser is unchanged on failure.
  Status set(std::size_t id, const LaserParams& params) noexcept;
  /// Metres per raw distance count (0.002 for the VLP-16, HDL-32E and HDL-64E S2). InvalidArgument
  /// unless finite and in (0, 0.1].
  Status setDistanceResolution(double metresPerCount) noexcept;

  std::size_t size() const noexcept { return size_; }
  double distanceResolution() const noexcept { return resolution_; }
  /// Parameters of laser `id`; precondition id < size().
  const LaserParams& params(std::size_t id) const noexcept { return lasers_[id].p; }

  /// The point of one return in the sensor frame (REP-103: x forward, y left, z up) by the thesis'
  /// model. `raw` is the packet's distance count (0 = no return: the result is then the model's
  /// point at D = D_corr and callers skip it), `azimuthCentiDeg` the head angle phi in 0.01 deg
  /// (may be fractional). Precondition: laser < size().
  Eigen::Vector3f laserPoint(std::size_t laser, std::uint16_t raw, float azimuthCentiDeg) const noexcept;
  /// The same with sin(phi) and cos(phi) given (one pair per firing serves every laser of it:
  /// beta = phi - alpha by the angle-difference identity, as velodyne_pointcloud's tables do).
  /// Defined inline below: the per-return inner loops (`toFiringReturns`) inline it.
  Eigen::Vector3f laserPoint(std::size_t laser, std::uint16_t raw, float sinPhi, float cosPhi) const noexcept;

 private:
  struct Laser {
    LaserParams p{};
    float distCorrection = 0.0F;
    float vertOffset = 0.0F;
    float horizOffset = 0.0F;
    float cosTheta = 1.0F;
    float sinTheta = 0.0F;
    float cosAlpha = 1.0F;
    float sinAlpha = 0.0F;
  };
  std::array<Laser, kMaxLidarLasers> lasers_{};
  std::size_t size_ = 0;
  double resolution_ = 0.002;
  float resolutionF_ = 0.002F;
};

inline Eigen::Vector3f LaserIntrinsics::laserPoint(std::size_t laser, std::uint16_t raw, float sinPhi,
                                                   float cosPhi) const noexcept {
  const Laser& l = lasers_[laser];
  const float d = static_cast<float>(raw) * resolutionF_ + l.distCorrection;  // D = D_ret + D_corr
  const float pz = d * l.sinTheta + l.vertOffset * l.cosTheta;
  const float dxy = d * l.cosTheta - l.vertOffset * l.sinTheta;
  const float sb = sinPhi * l.cosAlpha - cosPhi * l.sinAlpha;  // sin(beta), beta = phi - alpha
  const float cb = cosPhi * l.cosAlpha + sinPhi * l.sinAlpha;  // cos(beta)
  const float px = dxy * sb - l.horizOffset * cb;
  const float py = dxy * cb + l.horizOffset * sb;
  return {py, -px, pz};  // Velodyne frame (x right, y forward) -> REP-103 (x forward, y left)
}

}  // namespace agv
