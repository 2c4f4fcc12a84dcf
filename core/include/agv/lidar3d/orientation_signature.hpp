#pragma once
/// @file orientation_signature.hpp
/// The orientation signature of one revolution (Muhammad 2012, ch. 5): 360 bins of 1 deg, each
/// the mean range of the returns of one beam (one row of the range image) whose azimuth falls in
/// it; and the relative yaw of two revolutions as the circular shift that minimises the sum of
/// absolute differences, refined below the bin width by a parabola through the cost at the best
/// shift and its two neighbours.
///
/// Which beam: the row whose mean elevation is nearest to `targetElevation` (default 0 rad, the
/// horizontal beam). A horizontal beam sees the walls, racks and facades around the vehicle at
/// their full distance, which change with the heading; a beam pointing down sees the floor at the
/// same range in every direction (no heading information) and one pointing up sees the sky or a
/// ceiling (few returns outdoors). Give `row` to force one.
///
/// Convention: the azimuth of a return is atan2(y, x) (counter-clockwise from +x, z up). When the
/// sensor of revolution b is turned by psi counter-clockwise relative to that of revolution a (same
/// place), a landmark at azimuth theta in a appears at theta - psi in b, so b[k] ~ a[k + psi];
/// `relativeYaw(a, b)` returns psi in (-pi, pi].
///
/// Empty bins (no return of that beam) hold 0 and take no part in the comparison: the cost of a
/// shift is the mean absolute difference over the bins valid in both (the SAD normalised by the
/// overlap, so shifts with different overlaps compare; with full signatures it is the SAD / 360).
///
/// Precision: float. Work: compute O(columns); relativeYaw 360 x 360 absolute differences.

#include <array>
#include <cstddef>
#include <cstdint>

#include "agv/core/result.hpp"
#include "agv/core/status.hpp"
#include "agv/lidar3d/range_image.hpp"

namespace agv {

/// Bins of the orientation signature (1 deg each).
inline constexpr std::size_t kOrientationBins = 360;

/// Beam choice and acceptance.
struct OrientationParams {
  /// Row of the range image to use; negative: the row whose mean elevation is nearest to
  /// targetElevation (among rows with at least one return).
  int row = -1;
  float targetElevation = 0.0F;  ///< [rad]
  float minRange = 0.5F;         ///< [m] returns nearer are left out (the vehicle itself)
  float maxRange = 120.0F;       ///< [m] returns farther are left out
  /// Fewer filled bins than this give NotEnoughData (a beam that sees nothing has no heading).
  std::size_t minFilledBins = 36;
  /// relativeYaw: fewer bins valid in both at the best shift than this give NotEnoughData.
  std::size_t minOverlap = 36;
};

/// The signature: mean range per 1-deg azimuth bin of one beam.
struct OrientationSignature {
  std::array<float, kOrientationBins> meanRange{};  ///< [m]; 0 = no return in the bin
  std::uint16_t filled = 0;                         ///< bins with a return
  std::uint16_t row = 0;                            ///< the range-image row it was taken from
  bool empty() const noexcept { return filled == 0; }
};

/// The row of `image` whose mean elevation (of its valid cells) is nearest to `targetElevation`
/// [rad]; EmptyInput when no row holds a return; NonFiniteInput for a NaN target.
Result<std::size_t> orientationRow(const RangeImageBase& image, float targetElevation) noexcept;

/// Computes the signature of one row of `image`. Ok; InvalidArgument (bad params, row beyond the
/// shape); EmptyInput (no return in the image); NotEnoughData (fewer than minFilledBins bins).
/// On failure `out` is empty.
Status computeOrientationSignature(const RangeImageBase& image, const OrientationParams& params,
                                   OrientationSignature& out) noexcept;

/// A relative yaw.
struct YawEstimate {
  float yaw = 0.0F;           ///< [rad] in (-pi, pi]: b is a turned by yaw (counter-clockwise)
  float cost = 0.0F;          ///< [m] mean absolute difference at the best integer shift
  std::uint16_t shift = 0;    ///< best integer shift [deg], 0..359
  std::uint16_t overlap = 0;  ///< bins valid in both at that shift
  float meanRange = 0.0F;     ///< [m] mean of the two signatures over those bins
  /// cost / meanRange: the mismatch relative to the scale of the scene (0 = identical).
  float relativeCost() const noexcept { return meanRange > 0.0F ? cost / meanRange : 0.0F; }
};

/// The relative yaw of b with respect to a (see the convention above). NotEnoughData when either
/// signature has fewer than minOverlap filled bins or no shift reaches minOverlap common bins.
Result<YawEstimate> relativeYaw(const OrientationSignature& a, const OrientationSignature& b,
                                std::size_t minOverlap = 36) noexcept;

}  // namespace agv
