#include "agv/mapping/corner_mapper.hpp"

#include <algorithm>
#include <cmath>

namespace agv::mapping {

CornerMapper::CornerMapper(double mergeRadius) : radius_(mergeRadius > 0.0 ? mergeRadius : 0.2) {}

std::int64_t CornerMapper::cellOf(double v) const noexcept {
  return static_cast<std::int64_t>(std::floor(v / radius_));
}

std::uint64_t CornerMapper::cellKey(std::int64_t cx, std::int64_t cy) noexcept {
  // Cell indices may be negative: shifted as unsigned (a left shift of a negative signed value is
  // undefined).
  return (static_cast<std::uint64_t>(cx) << 32U) ^ (static_cast<std::uint64_t>(cy) & 0xffffffffULL);
}

std::size_t CornerMapper::nearest(const Eigen::Vector2d& w) const {
  std::size_t best = clusters_.size();
  double bestD = radius_;
  const std::int64_t cx = cellOf(w.x());
  const std::int64_t cy = cellOf(w.y());
  for (std::int64_t dx = -1; dx <= 1; ++dx) {
    for (std::int64_t dy = -1; dy <= 1; ++dy) {
      const auto it = grid_.find(cellKey(cx + dx, cy + dy));
      if (it == grid_.end()) {
        continue;
      }
      for (const std::size_t c : it->second) {
        const double n = static_cast<double>(clusters_[c].sightings.size());
        const double d = std::hypot(clusters_[c].sx / n - w.x(), clusters_[c].sy / n - w.y());
        if (d < bestD) {
          bestD = d;
          best = c;
        }
      }
    }
  }
  return best;
}

void CornerMapper::add(const Eigen::Vector2d& world) {
  if (!world.allFinite()) {
    return;
  }
  std::size_t best = nearest(world);
  if (best == clusters_.size()) {
    clusters_.emplace_back();
    grid_[cellKey(cellOf(world.x()), cellOf(world.y()))].push_back(best);
  }
  Cluster& c = clusters_[best];
  c.sx += world.x();
  c.sy += world.y();
  c.sightings.push_back(world);
  ++sightings_;
}

namespace {

double median(std::vector<double>& v) {
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  if (v.size() % 2 == 1) {
    return v[mid];
  }
  const double upper = v[mid];
  return 0.5 * (*std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid)) + upper);
}

}  // namespace

CornerFreezeStats CornerMapper::freeze(const CornerFreezeParams& params, LandmarkMap& frozen) const {
  frozen.clear();
  CornerFreezeStats stats;
  stats.clusters = clusters_.size();
  std::uint32_t id = 1;
  std::vector<double> xs;
  std::vector<double> ys;
  std::vector<char> inlier;
  for (const Cluster& c : clusters_) {
    const std::size_t n = c.sightings.size();
    inlier.assign(n, 1);
    // The inliers' sums, in sighting order (every sighting an inlier: the running sums themselves).
    double sx = c.sx;
    double sy = c.sy;
    std::size_t inliers = n;
    if (params.inlierRadius > 0.0 && n > 0) {
      xs.clear();
      ys.clear();
      for (const Eigen::Vector2d& s : c.sightings) {
        xs.push_back(s.x());
        ys.push_back(s.y());
      }
      const double medX = median(xs);
      const double medY = median(ys);
      sx = 0.0;
      sy = 0.0;
      inliers = 0;
      for (std::size_t k = 0; k < n; ++k) {
        const Eigen::Vector2d& s = c.sightings[k];
        inlier[k] = std::fabs(s.x() - medX) <= params.inlierRadius && std::fabs(s.y() - medY) <= params.inlierRadius;
        if (inlier[k] != 0) {
          sx += s.x();
          sy += s.y();
          ++inliers;
        }
      }
    }
    if (inliers < params.minSightings || inliers == 0) {
      ++stats.tooFew;
      continue;
    }
    if (static_cast<double>(inliers) < params.minInlierFraction * static_cast<double>(n)) {
      ++stats.viewDependent;
      continue;
    }
    const double mx = sx / static_cast<double>(inliers);
    const double my = sy / static_cast<double>(inliers);
    double ss = 0.0;
    for (std::size_t k = 0; k < n; ++k) {
      if (inlier[k] != 0) {
        const Eigen::Vector2d& s = c.sightings[k];
        ss += (s.x() - mx) * (s.x() - mx) + (s.y() - my) * (s.y() - my);
      }
    }
    const double scatter = std::sqrt(ss / static_cast<double>(inliers) / 2.0);
    if (scatter > params.maxScatter) {
      ++stats.scattered;
      continue;
    }
    const double sigma = params.sigma > 0.0 ? params.sigma : scatter;
    if (frozen.addSurveyed(LandmarkKind::Corner, mx, my, sigma, id).ok()) {
      ++id;
      ++stats.frozen;
    } else {
      ++stats.refusedByMap;
    }
  }
  frozen.setMode(MapMode::Static);
  return stats;
}

}  // namespace agv::mapping
