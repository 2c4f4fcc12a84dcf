#pragma once
/// @file correspondence_graph.hpp
/// Point association by the Correspondence Graph: vertices are candidate pairs (a point of the
/// first set, a point of the second), two vertices are joined when their pairs could both be right
/// under one rigid motion, |d(a_i, a_k) - d(b_j, b_l)| < epsilon with i != k and j != l; the
/// association is a maximum clique of that graph, and the transform its rigid fit.
///
/// Maximum clique: exact branch and bound over bit sets with the greedy-colouring bound of Tomita's
/// MCQ in the bit-parallel form of San Segundo's BBMC, vertices ordered by non-increasing degree,
/// iterative (explicit per-depth frames, no recursion). Maximum clique is NP-hard: the worst case
/// is exponential in the vertex count V (O(3^(V/3)) nodes for Moon-Moser graphs), so the search is
/// bounded by a node budget: at most `maxNodes` colourings of O(V * V / 64) word operations each,
/// plus O(V^2) to build the graph. When the budget is hit the best clique found so far is returned
/// with Status::NotConverged and `budgetHit`. A clique holds each point at most once, so its size
/// is at most min(n_first, n_second) <= kMaxLoopPoints, which bounds the depth.
///
/// Distance compatibility cannot tell a set from its mirror image: a clique is a rigid match or a
/// reflected one; the reflected one shows as a large `rms` of the fit.
///
/// Memory: 96 kB with the default capacities (V = 256: adjacency 8 kB, per-depth colour lists
/// 50 kB, distance tables 32 kB): make the matcher static or a member, not a stack object.

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>

#include "agv/core/capacities.hpp"
#include "agv/core/span.hpp"
#include "agv/core/status.hpp"
#include "agv/loop/point_association.hpp"

namespace agv {

/// Settings of the correspondence-graph association.
struct CorrespondenceGraphParams {
  /// [m] largest difference between the two distances of compatible pairs (thesis: 0.10 m; a few
  /// times the keypoint position noise).
  float epsilon = 0.10F;
  /// Branch-and-bound nodes (greedy colourings) allowed per call. With the default 1e5 and V = 256
  /// the worst case is about 1e5 * 256 * 4 word operations.
  std::uint32_t maxNodes = 100000;
  /// Fewest associated pairs accepted (at least 3: two pairs are compatible with some motion
  /// whenever their distances agree).
  std::size_t minPairs = 3;
};

/// True when epsilon is finite and > 0, maxNodes >= 1 and minPairs >= 3.
bool isValid(const CorrespondenceGraphParams& p) noexcept;

/// Correspondence-graph matcher with its working storage.
class CorrespondenceGraphMatcher {
 public:
  explicit CorrespondenceGraphMatcher(const CorrespondenceGraphParams& params = CorrespondenceGraphParams{}) noexcept;

  /// Associates `second` with `first` [m], every (first, second) combination a vertex.
  /// Returns Ok; InvalidArgument for parameters out of their domain; EmptyInput when a set is
  /// empty; CapacityExceeded when a set exceeds kMaxLoopPoints or the combinations kMaxCgVertices
  /// (filter them: the overload below); NonFiniteInput for a NaN or infinite coordinate;
  /// NotEnoughData when the maximum clique has fewer than minPairs pairs (out holds it, transform
  /// identity below 3); NotConverged when the node budget was hit (out holds the best clique found,
  /// fitted when it has 3 pairs or more).
  Status match(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second, PointAssociation& out) noexcept;

  /// The same with the vertices given: candidate pairs (e.g. those whose descriptors are close).
  /// InvalidArgument also when a candidate indexes outside its set; CapacityExceeded above
  /// kMaxCgVertices candidates.
  Status match(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second, Span<const PointPair> candidates,
               PointAssociation& out) noexcept;

  const CorrespondenceGraphParams& params() const noexcept { return params_; }
  /// Replaces the parameters (checked at the next match: InvalidArgument when out of their domain).
  /// Use it instead of assigning a new matcher: a temporary of this size does not fit a small stack.
  void setParams(const CorrespondenceGraphParams& params) noexcept { params_ = params; }
  /// Vertices and edges of the last graph built (for the docs' figures and the tests).
  std::size_t lastVertices() const noexcept { return vertices_; }
  std::size_t lastEdges() const noexcept { return edges_; }

 private:
  static constexpr std::size_t kWords = kMaxCgVertices / 64;
  static constexpr std::size_t kDepth = kMaxLoopPoints + 1;
  using Bits = std::array<std::uint64_t, kWords>;

  Status run(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second, std::size_t nVertices,
             PointAssociation& out) noexcept;
  void buildGraph(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second) noexcept;
  std::size_t colour(std::size_t depth) noexcept;
  std::uint32_t maxClique(std::size_t& bestSize, bool& budgetHit) noexcept;

  CorrespondenceGraphParams params_;
  std::size_t vertices_ = 0;
  std::size_t edges_ = 0;
  std::size_t words_ = 0;
  std::array<PointPair, kMaxCgVertices> pair_{};   ///< vertex (in search order) -> pair
  std::array<PointPair, kMaxCgVertices> given_{};  ///< vertices as given, before ordering
  std::array<std::uint16_t, kMaxCgVertices> degree_{};
  std::array<Bits, kMaxCgVertices> adj_{};
  std::array<std::array<float, kMaxLoopPoints>, kMaxLoopPoints> distFirst_{};
  std::array<std::array<float, kMaxLoopPoints>, kMaxLoopPoints> distSecond_{};
  std::array<Bits, kDepth> cand_{};                                        ///< P at each depth
  std::array<std::array<std::uint16_t, kMaxCgVertices>, kDepth> order_{};  ///< colour-sorted P
  std::array<std::array<std::uint8_t, kMaxCgVertices>, kDepth> colour_{};  ///< its colours (capped)
  std::array<std::uint16_t, kDepth> count_{};
  std::array<std::uint16_t, kDepth> pos_{};
  std::array<std::uint16_t, kDepth> clique_{};
  std::array<std::uint16_t, kDepth> best_{};
};

}  // namespace agv
