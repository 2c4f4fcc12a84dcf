#pragma once
/// @file beam_lookup.hpp
/// Which beams of a range scan look in a given direction, and how far they saw: the lookup the
/// localizer's occlusion test needs ("is a landmark predicted at bearing b and range r in the
/// line of sight, or did the scan hit something nearer?").
///
/// Precision: the bearing arithmetic is double (the beam index of a bearing must not shift by
/// float rounding of `bearing - angleMin` near a beam boundary); ranges stay the scan's float.

#include "agv/core/result.hpp"
#include "agv/core/status.hpp"
#include "agv/scan/laser_scan.hpp"

namespace agv {

/// `Ok` when beams can be looked up by bearing in `scan`: at least one beam, finite `angleMin`,
/// finite `angleIncrement` in (0, pi/8], and at most one revolution of beams
/// (`size() * angleIncrement <= 2 pi + angleIncrement / 2`). Otherwise `EmptyInput`,
/// `NonFiniteInput` or `InvalidArgument`. Range values are not checked (invalid beams are normal).
Status checkBeamGeometry(const LaserScan& scan) noexcept;

/// The farthest *valid* range (`LaserScan::isValid`) among the beams nearest to `bearing` [rad,
/// laser frame, any finite value]: the two beams whose angles bracket it; across the seam from the
/// last beam to the first when the scan covers a full revolution; the end beam alone when the
/// bearing lies within half a beam outside either end. The farthest of the two, because a point
/// between two beams is in the line of sight if either of them passes it (the nearer one may hit
/// the surface that ends at the point).
///
/// `OutOfRange`: the bearing is not covered by the scan. `NotFound`: the nearest beams carry no
/// valid range (NaN, inf, no return, below rangeMin). `NonFiniteInput` for a non-finite bearing;
/// the errors of `checkBeamGeometry` for an unusable scan.
Result<double> farthestReturnNear(const LaserScan& scan, double bearing) noexcept;

/// Valid scan points near a point on each side of its bearing (see `sideSupport`).
struct SideSupport {
  std::size_t before = 0;  ///< among the beams at smaller angles (clockwise of the bearing)
  std::size_t after = 0;   ///< among the beams at larger angles
};

/// Counts the valid scan points lying within `radius` [m] of the laser-frame point at (`range`,
/// `bearing`), separately on each side of the bearing, up to `maxPerSide` each: whether the
/// surfaces that form a corner at that point are seen on both sides (a corner whose one face is
/// turned away or hidden shows points on one side only). Walks outward from the bracketing beams
/// over at most asin(radius / range) + one beam per side (across the seam of a full revolution),
/// so the work is bounded by the beams in that angle and by the scan size.
/// Errors as `farthestReturnNear`; `InvalidArgument` for a non-positive or non-finite range or radius.
Result<SideSupport> sideSupport(const LaserScan& scan, double range, double bearing, double radius,
                                std::size_t maxPerSide) noexcept;

}  // namespace agv
