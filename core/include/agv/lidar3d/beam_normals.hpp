#pragma once
/// @file beam_normals.hpp
/// Surface normals from the beam arrangement of a multi-beam lidar (Muhammad 2012, ch. 5): no
/// neighbour search, the neighbours of a return are given by the scan pattern.
///
/// At cell (l, f) of a range image with the point p, take the same laser `firingStep` firings
/// before and after (columns f -+ firingStep, circular: a revolution has no seam) and the lasers
/// `laserStep` rows below and above (rows l -+ laserStep: elevation order, not hardware id order).
/// The normal is the unit cross product of the two differences,
///   n = (p[l][f+k] - p[l][f-k]) x (p[l+j][f] - p[l-j][f]) / |...|,
/// turned towards the sensor (n . p <= 0), so a floor seen from above has n.z = +1, a ceiling -1
/// and a wall 0.
///
/// Skip rule (documented reason counted per skipped point, see NormalSkip):
/// - `OutOfRange`: the point is invalid or its range is outside [minRange, maxRange] (3..50 m:
///   below 3 m the vehicle and the beam footprint dominate, beyond 50 m the neighbours are metres
///   apart and the returns sparse);
/// - `MissingNeighbour`: one of the four neighbours is outside the image (rows) or has no return;
/// - `NeighbourTooFar`: one of the four neighbours is farther from p than maxNeighbourRatio * |p|
///   (a depth jump: the neighbour lies on another surface; 0.25 keeps a floor seen at 12 m by
///   HDL-64E lasers two steps apart, 1.1 m, and drops grazing far floor and object edges);
/// - `Degenerate`: the two differences are (anti)parallel within minSine (sin of their angle), so
///   their cross product has no direction.
///
/// Precision: float. Work: O(1) per point (4 cell reads, one cross product, one sqrt).

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>

#include "agv/lidar3d/range_image.hpp"

namespace agv {

/// Neighbourhood and acceptance of a beam-arrangement normal.
struct BeamNormalParams {
  std::size_t firingStep = 5;       ///< same laser, this many firings before and after (thesis: 5)
  std::size_t laserStep = 2;        ///< lasers this many rows below and above in elevation (thesis: 2)
  float minRange = 3.0F;            ///< [m] points nearer are skipped (thesis: 3)
  float maxRange = 50.0F;           ///< [m] points farther are skipped (thesis: 50)
  float maxNeighbourRatio = 0.25F;  ///< a neighbour farther than this times |p| from p: skipped
  float minSine = 0.1F;             ///< sin of the angle between the two differences, at least (~5.7 deg)
};

/// True when `p` lies in its domain: steps >= 1, 0 <= minRange < maxRange finite,
/// maxNeighbourRatio > 0 finite, minSine in [0, 1).
bool isValid(const BeamNormalParams& p) noexcept;

/// Why no normal was computed at a point.
enum class NormalSkip : std::uint8_t {
  None = 0,          ///< a normal was computed
  OutOfRange,        ///< no return, or range outside [minRange, maxRange]
  MissingNeighbour,  ///< a neighbour outside the rows or without return
  NeighbourTooFar,   ///< a neighbour on another surface (depth jump)
  Degenerate,        ///< the two differences are parallel
};

/// The normal at (row, column) of `image` (unit, towards the sensor) in `normal`; returns why it
/// was skipped (None when computed; `normal` unchanged otherwise). Precondition: row < rows(),
/// column < columns(), isValid(params), columns() > 2 * firingStep.
NormalSkip beamNormal(const RangeImageBase& image, std::size_t row, std::size_t column, const BeamNormalParams& params,
                      Eigen::Vector3f& normal) noexcept;

}  // namespace agv
