#include "agv/loop/correspondence_graph.hpp"

#include <cmath>

#include "association_common.hpp"

namespace agv {
namespace {

constexpr std::uint8_t kColourCap = static_cast<std::uint8_t>(kMaxLoopPoints + 1);

inline void setBit(std::uint64_t* w, std::size_t i) noexcept {
  w[i >> 6U] |= std::uint64_t{1} << (i & 63U);
}
inline void clearBit(std::uint64_t* w, std::size_t i) noexcept {
  w[i >> 6U] &= ~(std::uint64_t{1} << (i & 63U));
}
/// Index of the lowest set bit of the first `words` words, or `words * 64` when none is set.
inline std::size_t lowestBit(const std::uint64_t* w, std::size_t words) noexcept {
  for (std::size_t k = 0; k < words; ++k) {
    if (w[k] != 0U) {
      return k * 64U + static_cast<std::size_t>(__builtin_ctzll(w[k]));
    }
  }
  return words * 64U;
}
inline bool anyBit(const std::uint64_t* w, std::size_t words) noexcept {
  for (std::size_t k = 0; k < words; ++k) {
    if (w[k] != 0U) {
      return true;
    }
  }
  return false;
}

}  // namespace

bool isValid(const CorrespondenceGraphParams& p) noexcept {
  return std::isfinite(p.epsilon) && p.epsilon > 0.0F && p.maxNodes >= 1 && p.minPairs >= 3;
}

CorrespondenceGraphMatcher::CorrespondenceGraphMatcher(const CorrespondenceGraphParams& params) noexcept
    : params_(params) {}

Status CorrespondenceGraphMatcher::match(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second,
                                         PointAssociation& out) noexcept {
  out = PointAssociation{};
  vertices_ = 0;
  edges_ = 0;
  const Status st = detail::checkMatchInput(isValid(params_), first, second);
  if (st != Status::Ok) {
    return st;
  }
  if (first.size() * second.size() > kMaxCgVertices) {
    return Status::CapacityExceeded;
  }
  std::size_t v = 0;
  for (std::size_t i = 0; i < first.size(); ++i) {
    for (std::size_t j = 0; j < second.size(); ++j) {
      given_[v++] = PointPair{static_cast<std::uint16_t>(i), static_cast<std::uint16_t>(j)};
    }
  }
  return run(first, second, v, out);
}

Status CorrespondenceGraphMatcher::match(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second,
                                         Span<const PointPair> candidates, PointAssociation& out) noexcept {
  out = PointAssociation{};
  vertices_ = 0;
  edges_ = 0;
  const Status st = detail::checkMatchInput(isValid(params_), first, second, &candidates);
  if (st != Status::Ok) {
    return st;
  }
  if (candidates.size() > kMaxCgVertices) {
    return Status::CapacityExceeded;
  }
  for (std::size_t v = 0; v < candidates.size(); ++v) {
    given_[v] = candidates[v];
  }
  return run(first, second, candidates.size(), out);
}

Status CorrespondenceGraphMatcher::run(Span<const Eigen::Vector2f> first, Span<const Eigen::Vector2f> second,
                                       std::size_t nVertices, PointAssociation& out) noexcept {
  vertices_ = nVertices;
  words_ = (nVertices + 63U) / 64U;
  buildGraph(first, second);
  std::size_t bestSize = 0;
  bool budgetHit = false;
  out.work = maxClique(bestSize, budgetHit);
  out.budgetHit = budgetHit;
  for (std::size_t k = 0; k < bestSize; ++k) {
    (void)out.pairs.push_back(pair_[best_[k]]);
  }
  detail::fitPairs(first, second, out);
  if (budgetHit) {
    return Status::NotConverged;
  }
  return bestSize >= params_.minPairs ? Status::Ok : Status::NotEnoughData;
}

void CorrespondenceGraphMatcher::buildGraph(Span<const Eigen::Vector2f> first,
                                            Span<const Eigen::Vector2f> second) noexcept {
  for (std::size_t i = 0; i < first.size(); ++i) {
    for (std::size_t k = 0; k < first.size(); ++k) {
      distFirst_[i][k] = (first[i] - first[k]).norm();
    }
  }
  for (std::size_t j = 0; j < second.size(); ++j) {
    for (std::size_t l = 0; l < second.size(); ++l) {
      distSecond_[j][l] = (second[j] - second[l]).norm();
    }
  }
  const float eps = params_.epsilon;
  const auto compatible = [&](const PointPair& a, const PointPair& b) noexcept {
    return a.first != b.first && a.second != b.second &&
           std::fabs(distFirst_[a.first][b.first] - distSecond_[a.second][b.second]) < eps;
  };
  const std::size_t n = vertices_;
  // Degrees, then the search order: non-increasing degree (counting sort, stable).
  for (std::size_t u = 0; u < n; ++u) {
    degree_[u] = 0;
  }
  std::size_t edges = 0;
  for (std::size_t u = 0; u < n; ++u) {
    for (std::size_t v = u + 1; v < n; ++v) {
      if (compatible(given_[u], given_[v])) {
        ++degree_[u];
        ++degree_[v];
        ++edges;
      }
    }
  }
  edges_ = edges;
  std::array<std::uint16_t, kMaxCgVertices + 1> start{};  // vertices with degree > d come first
  for (std::size_t u = 0; u < n; ++u) {
    ++start[kMaxCgVertices - 1U - degree_[u] + 1U];
  }
  for (std::size_t d = 1; d <= kMaxCgVertices; ++d) {
    start[d] = static_cast<std::uint16_t>(start[d] + start[d - 1]);
  }
  std::array<std::uint16_t, kMaxCgVertices> perm{};  // search index -> given index
  for (std::size_t u = 0; u < n; ++u) {
    perm[start[kMaxCgVertices - 1U - degree_[u]]++] = static_cast<std::uint16_t>(u);
  }
  for (std::size_t u = 0; u < n; ++u) {
    pair_[u] = given_[perm[u]];
    for (std::size_t w = 0; w < words_; ++w) {
      adj_[u][w] = 0U;
    }
  }
  for (std::size_t u = 0; u < n; ++u) {
    for (std::size_t v = u + 1; v < n; ++v) {
      if (compatible(pair_[u], pair_[v])) {
        setBit(adj_[u].data(), v);
        setBit(adj_[v].data(), u);
      }
    }
  }
}

std::size_t CorrespondenceGraphMatcher::colour(std::size_t depth) noexcept {
  // Greedy sequential colouring of P in bit order; the list comes out by non-decreasing colour.
  Bits q = cand_[depth];
  Bits r{};
  std::size_t k = 0;
  std::size_t col = 0;
  while (anyBit(q.data(), words_)) {  // at most |P| colours
    ++col;
    r = q;
    for (std::size_t v = lowestBit(r.data(), words_); v < words_ * 64U; v = lowestBit(r.data(), words_)) {
      clearBit(r.data(), v);
      clearBit(q.data(), v);
      for (std::size_t w = 0; w < words_; ++w) {
        r[w] &= ~adj_[v][w];
      }
      order_[depth][k] = static_cast<std::uint16_t>(v);
      colour_[depth][k] = col < kColourCap ? static_cast<std::uint8_t>(col) : kColourCap;
      ++k;
    }
  }
  count_[depth] = static_cast<std::uint16_t>(k);
  pos_[depth] = static_cast<std::uint16_t>(k);
  return k;
}

std::uint32_t CorrespondenceGraphMatcher::maxClique(std::size_t& bestSize, bool& budgetHit) noexcept {
  bestSize = 0;
  budgetHit = false;
  if (vertices_ == 0) {
    return 0;
  }
  for (std::size_t w = 0; w < words_; ++w) {
    cand_[0][w] = 0U;
  }
  for (std::size_t v = 0; v < vertices_; ++v) {
    setBit(cand_[0].data(), v);
  }
  std::uint32_t nodes = 1;
  (void)colour(0);
  std::size_t d = 0;
  // Every step either descends (one node of the budget), processes a list entry or ascends;
  // the lists are finite and the nodes bounded, so the loop ends.
  for (;;) {
    if (pos_[d] == 0) {  // level exhausted
      if (d == 0) {
        break;
      }
      --d;
      clearBit(cand_[d].data(), clique_[d]);
      continue;
    }
    const std::size_t idx = pos_[d] - 1U;
    if (d + colour_[d][idx] <= bestSize) {  // no clique through this level beats the best
      pos_[d] = 0;
      continue;
    }
    pos_[d] = static_cast<std::uint16_t>(idx);
    const std::uint16_t v = order_[d][idx];
    clique_[d] = v;
    Bits& next = cand_[d + 1U];
    bool any = false;
    for (std::size_t w = 0; w < words_; ++w) {
      next[w] = cand_[d][w] & adj_[v][w];
      any = any || next[w] != 0U;
    }
    if (!any || d + 2U >= kDepth) {  // a maximal clique (depth bound: cliques hold each point once)
      if (d + 1U > bestSize) {
        bestSize = d + 1U;
        for (std::size_t k = 0; k <= d; ++k) {
          best_[k] = clique_[k];
        }
      }
      clearBit(cand_[d].data(), v);
      continue;
    }
    if (nodes >= params_.maxNodes) {
      budgetHit = true;
      break;
    }
    ++nodes;
    ++d;
    (void)colour(d);
  }
  return nodes;
}

}  // namespace agv
