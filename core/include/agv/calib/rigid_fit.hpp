#pragma once
/// @file rigid_fit.hpp
/// Closed-form least-squares rigid 2D transform between paired point sets: the solver shared by
/// the reflector and the FALKO-keypoint egomotion.
///
/// Precision: double (see reflector_alignment.hpp: the calibration's noise floor is millimetres
/// over 10 m lever arms).

#include <Eigen/Core>
#include <cstdint>

#include "agv/core/pose2.hpp"
#include "agv/core/span.hpp"

namespace agv {

/// Marks a point of the second set that has no partner in the first set.
inline constexpr std::uint16_t kNoPair = 0xFFFF;

/// The rigid motion T minimising sum |first[pairOf[j]] - T(second[j])|^2 over every j with
/// pairOf[j] != kNoPair (pairOf has one entry per point of `second`; indices must lie in `first`):
/// centroids, then the rotation atan2(sum q x p, sum q . p) of the centred pairs and the
/// translation from the centroids. Identity when no pair is given; with one pair the rotation is 0.
/// O(n), no allocation.
Pose2d fitRigid2d(Span<const Eigen::Vector2d> first, Span<const Eigen::Vector2d> second,
                  Span<const std::uint16_t> pairOf) noexcept;

/// RMS distance [m] between first[pairOf[j]] and motion(second[j]) over the pairs (0 without pairs).
double rigidFitRms(Span<const Eigen::Vector2d> first, Span<const Eigen::Vector2d> second,
                   Span<const std::uint16_t> pairOf, const Pose2d& motion) noexcept;

}  // namespace agv
