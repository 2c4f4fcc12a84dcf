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

}  // namespace agv
