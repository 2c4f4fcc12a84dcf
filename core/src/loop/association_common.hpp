#pragma once
/// @file association_common.hpp
/// Private helpers shared by the loop-closure point associations: input checks, the rigid fit of
/// pairs and the one-to-one nearest-neighbour re-association.

#include <Eigen/Core>
#include <cstddef>

#include "agv/core/fixed_vector.hpp"
#include "agv/core/pose2.hpp"
#include "agv/core/span.hpp"
#include "agv/core/split_mix64.hpp"
#include "agv/core/status.hpp"
#include "agv/loop/point_association.hpp"

namespace agv::detail {

/// EmptyInput when a set is empty, CapacityExceeded above kMaxLoopPoints, NonFiniteInput for a
/// NaN or infinite coordinate, else Ok.
Status checkPointSets(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second) noexcept;

/// InvalidArgument when a candidate indexes outside its set, EmptyInput when there is none,
/// CapacityExceeded above CandidatePairs' capacity.
Status checkCandidates(Span<const PointPair> candidates, std::size_t nFirst, std::size_t nSecond) noexcept;

/// The checks every matcher's `match` starts with, in order: `InvalidArgument` when the
/// parameters are not valid (`paramsValid` false), then `checkPointSets`, then, when `candidates`
/// is given, `checkCandidates`.
Status checkMatchInput(bool paramsValid, Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second,
                       const Span<const PointPair>* candidates = nullptr) noexcept;

/// Fills out.transform (fitRigid2d over the pairs, identity below 3 pairs) and out.rms.
void fitPairs(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second, PointAssociation& out) noexcept;

/// One-to-one association under `motion`: each second point to its nearest first point within
/// `gate` [m]; when two claim the same first point the nearer keeps it. O(n m). Returns the count.
std::size_t associateNearest(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second,
                             const Pose2d& motion, float gate, IVector<PointPair>& out) noexcept;

/// Re-associates under out.transform within `gate` and refits, `passes` times (keeps the previous
/// answer if a pass would leave fewer than 3 pairs).
void refine(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second, float gate, int passes,
            PointAssociation& out) noexcept;

}  // namespace agv::detail
