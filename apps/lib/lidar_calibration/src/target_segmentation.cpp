#include "agv/lidar_calibration/target_segmentation.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <random>
#include <unordered_map>

namespace agv::lidar_calibration {

Eigen::Matrix<double, 3, 2> planeAxes(const Eigen::Vector3d& n) {
  const Eigen::Vector3d a = std::fabs(n.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitX();
  Eigen::Matrix<double, 3, 2> b;
  b.col(0) = n.cross(a).normalized();
  b.col(1) = n.cross(b.col(0));
  return b;
}

Plane pcaPlane(const std::vector<Eigen::Vector3d>& points, const std::vector<std::size_t>* indices,
               double* meanSquared) {
  const std::size_t n = indices != nullptr ? indices->size() : points.size();
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < n; ++k) {
    mean += points[indices != nullptr ? (*indices)[k] : k];
  }
  mean /= static_cast<double>(std::max<std::size_t>(n, 1));
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (std::size_t k = 0; k < n; ++k) {
    const Eigen::Vector3d q = points[indices != nullptr ? (*indices)[k] : k] - mean;
    cov += q * q.transpose();
  }
  cov /= static_cast<double>(std::max<std::size_t>(n, 1));
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  Plane p;
  p.normal = es.eigenvectors().col(0);
  p.offset = p.normal.dot(mean);
  if (meanSquared != nullptr) {
    *meanSquared = std::max(0.0, es.eigenvalues()[0]);
  }
  return p;
}

namespace {

/// Two unit vectors spanning the plane.
void inPlaneAxes(const Eigen::Vector3d& n, Eigen::Vector3d& u, Eigen::Vector3d& v) {
  const Eigen::Matrix<double, 3, 2> b = planeAxes(n);
  u = b.col(0);
  v = b.col(1);
}

using CellKey = std::int64_t;
CellKey cellKey(std::int64_t i, std::int64_t j) {
  return i * 1000003LL + j;
}

/// The largest 8-connected region of `inliers` on the in-plane grid: its indices and cell set.
std::vector<std::size_t> largestRegion(const std::vector<Eigen::Vector3d>& points,
                                       const std::vector<std::size_t>& inliers, const Plane& plane, double cell,
                                       std::unordered_map<CellKey, int>& cellLabel, int& bestLabel) {
  Eigen::Vector3d u;
  Eigen::Vector3d v;
  inPlaneAxes(plane.normal, u, v);
  std::unordered_map<CellKey, std::vector<std::size_t>> cells;
  std::unordered_map<CellKey, std::pair<std::int64_t, std::int64_t>> coords;
  for (const std::size_t i : inliers) {
    const auto ci = static_cast<std::int64_t>(std::floor(points[i].dot(u) / cell));
    const auto cj = static_cast<std::int64_t>(std::floor(points[i].dot(v) / cell));
    cells[cellKey(ci, cj)].push_back(i);
    coords[cellKey(ci, cj)] = {ci, cj};
  }
  cellLabel.clear();
  int label = 0;
  std::vector<std::size_t> regionSize;
  for (const auto& entry : cells) {
    if (cellLabel.count(entry.first) != 0U) {
      continue;
    }
    std::vector<CellKey> stack{entry.first};
    cellLabel[entry.first] = label;
    std::size_t size = 0;
    while (!stack.empty()) {
      const CellKey k = stack.back();
      stack.pop_back();
      size += cells[k].size();
      const auto [ci, cj] = coords[k];
      for (std::int64_t di = -1; di <= 1; ++di) {
        for (std::int64_t dj = -1; dj <= 1; ++dj) {
          const CellKey nk = cellKey(ci + di, cj + dj);
          if (cells.count(nk) != 0U && cellLabel.count(nk) == 0U) {
            cellLabel[nk] = label;
            stack.push_back(nk);
          }
        }
      }
    }
    regionSize.push_back(size);
    ++label;
  }
  bestLabel = static_cast<int>(std::max_element(regionSize.begin(), regionSize.end()) - regionSize.begin());
  std::vector<std::size_t> out;
  for (const auto& entry : cells) {
    if (cellLabel[entry.first] == bestLabel) {
      out.insert(out.end(), entry.second.begin(), entry.second.end());
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

/// In-plane extents (larger first) of `points[indices]` along its principal in-plane axes (1st to
/// 99th percentile).
Eigen::Vector2d extents(const std::vector<Eigen::Vector3d>& points, const std::vector<std::size_t>& indices,
                        const Plane& plane) {
  Eigen::Vector3d u;
  Eigen::Vector3d v;
  inPlaneAxes(plane.normal, u, v);
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const std::size_t i : indices) {
    mean += Eigen::Vector2d(points[i].dot(u), points[i].dot(v));
  }
  mean /= static_cast<double>(indices.size());
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (const std::size_t i : indices) {
    const Eigen::Vector2d q = Eigen::Vector2d(points[i].dot(u), points[i].dot(v)) - mean;
    cov += q * q.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(cov);
  // Robust extents: 1st to 99th percentile along each axis (a thin strip of another surface that
  // touches the region, the floor along the target's foot, does not stretch it).
  Eigen::Vector2d e;
  for (int axis = 0; axis < 2; ++axis) {
    std::vector<double> q;
    q.reserve(indices.size());
    for (const std::size_t i : indices) {
      q.push_back(es.eigenvectors().col(axis).dot(Eigen::Vector2d(points[i].dot(u), points[i].dot(v)) - mean));
    }
    const auto lo = static_cast<std::ptrdiff_t>(q.size() / 100);
    const auto hi = static_cast<std::ptrdiff_t>(q.size() - 1 - q.size() / 100);
    std::nth_element(q.begin(), q.begin() + lo, q.end());
    const double a = q[static_cast<std::size_t>(lo)];
    std::nth_element(q.begin(), q.begin() + hi, q.end());
    e[axis] = q[static_cast<std::size_t>(hi)] - a;
  }
  return e[0] >= e[1] ? e : Eigen::Vector2d(e[1], e[0]);
}

/// The plane of `region` refit without its outliers (a RANSAC region also holds the points of
/// other surfaces within the RANSAC threshold): PCA of the points within the MAD threshold, a few times.
Plane robustPlane(const std::vector<Eigen::Vector3d>& points, const std::vector<std::size_t>& region, Plane fit,
                  const TargetSegmentationConfig& c) {
  for (int r = 0; r < c.refinements; ++r) {
    std::vector<double> dist;
    for (const std::size_t i : region) {
      dist.push_back(std::fabs(fit.normal.dot(points[i]) - fit.offset));
    }
    std::vector<double> sorted = dist;
    std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
    const double threshold = std::max(c.minThreshold, c.madFactor * 1.4826 * sorted[sorted.size() / 2]);
    std::vector<std::size_t> keep;
    for (std::size_t k = 0; k < region.size(); ++k) {
      if (dist[k] < threshold) {
        keep.push_back(region[k]);
      }
    }
    if (keep.size() < 3) {
      break;
    }
    fit = pcaPlane(points, &keep, nullptr);
  }
  return fit;
}

/// The best target region so far.
struct Candidate {
  std::vector<std::size_t> region;
  Plane plane;        ///< PCA plane of the region
  Plane ransacPlane;  ///< the hypothesis (its in-plane axes define the region's cells)
  std::unordered_map<CellKey, int> cellLabel;
  int label = 0;
  std::vector<std::size_t> pool;  ///< points not taken by the planes extracted before it
  std::size_t planeIndex = 0;     ///< its plane among the large planes found
};

/// PCA refit and re-selection of the points within the region's cells and a robust threshold.
/// Points on the line where the target meets another surface (the floor at its foot) lie in both
/// planes: points within `threshold` of one of the `others` (large planes found that are not the
/// target) are not the target's.
void refine(const std::vector<Eigen::Vector3d>& points, const TargetSegmentationConfig& c, const Candidate& cand,
            const std::vector<Plane>& others, TargetSegment& out) {
  Eigen::Vector3d u;
  Eigen::Vector3d v;
  inPlaneAxes(cand.ransacPlane.normal, u, v);
  std::vector<std::size_t> current = cand.region;
  Plane fit = cand.plane;
  for (int r = 0; r < c.refinements; ++r) {
    std::vector<double> dist;
    for (const std::size_t i : current) {
      dist.push_back(std::fabs(fit.normal.dot(points[i]) - fit.offset));
    }
    std::nth_element(dist.begin(), dist.begin() + static_cast<std::ptrdiff_t>(dist.size() / 2), dist.end());
    const double mad = dist[dist.size() / 2];
    const double threshold = std::max(c.minThreshold, c.madFactor * 1.4826 * mad);
    std::vector<std::size_t> next;
    for (const std::size_t i : cand.pool) {
      const auto ci = static_cast<std::int64_t>(std::floor(points[i].dot(u) / c.regionCell));
      const auto cj = static_cast<std::int64_t>(std::floor(points[i].dot(v) / c.regionCell));
      const auto it = cand.cellLabel.find(cellKey(ci, cj));
      if (it == cand.cellLabel.end() || it->second != cand.label ||
          std::fabs(fit.normal.dot(points[i]) - fit.offset) >= threshold) {
        continue;
      }
      bool onOther = false;
      for (const Plane& o : others) {
        const bool same = std::fabs(o.normal.dot(fit.normal)) > 0.98 &&
                          std::fabs(o.offset - o.normal.dot(fit.normal) * fit.offset) < 0.5;  // the target again
        onOther = onOther || (!same && std::fabs(o.normal.dot(points[i]) - o.offset) < threshold);
      }
      if (!onOther) {
        next.push_back(i);
      }
    }
    if (next.size() < c.minPoints) {
      break;
    }
    current = next;
    fit = pcaPlane(points, &current, nullptr);
  }
  double ms = 0.0;
  out.indices = current;
  out.plane = pcaPlane(points, &current, &ms);
  out.rms = std::sqrt(ms);
  out.extent = extents(points, current, out.plane);
}

}  // namespace

bool segmentTarget(const std::vector<Eigen::Vector3d>& points, const TargetSegmentationConfig& c, TargetSegment& out,
                   std::string& error) {
  out = TargetSegment{};
  if (points.empty()) {
    error = "empty scan (no point)";
    return false;
  }
  std::vector<std::size_t> remaining;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) {
      error = "point " + std::to_string(i) + " is not finite";
      return false;
    }
    if (points[i].norm() <= c.maxRange) {
      remaining.push_back(i);
    }
  }
  std::mt19937_64 rng(c.seed);
  std::vector<Candidate> candidates;  // regions of the target's size
  std::vector<Plane> planes;          // every large plane found
  const double large = std::max(c.targetWidth, c.targetHeight);
  const double small = std::min(c.targetWidth, c.targetHeight);
  std::string rejected;
  for (int planeNo = 0; planeNo < c.maxPlanes && remaining.size() >= c.minPoints; ++planeNo) {
    ++out.planesTried;
    // Hypotheses from 3 random points, scored on a sample.
    std::vector<std::size_t> sample;
    std::uniform_int_distribution<std::size_t> pick(0, remaining.size() - 1);
    const std::size_t sampleSize = std::min<std::size_t>(remaining.size(), static_cast<std::size_t>(c.sample));
    for (std::size_t k = 0; k < sampleSize; ++k) {
      sample.push_back(remaining[sampleSize == remaining.size() ? k : pick(rng)]);
    }
    Plane hypothesis;
    std::size_t bestScore = 0;
    for (int it = 0; it < c.iterations; ++it) {
      const Eigen::Vector3d& a = points[remaining[pick(rng)]];
      const Eigen::Vector3d& b = points[remaining[pick(rng)]];
      const Eigen::Vector3d& d = points[remaining[pick(rng)]];
      const Eigen::Vector3d n = (b - a).cross(d - a);
      if (n.norm() < 1e-9) {
        continue;
      }
      Plane p{n.normalized(), n.normalized().dot(a)};
      std::size_t score = 0;
      for (const std::size_t i : sample) {
        score += std::fabs(p.normal.dot(points[i]) - p.offset) < c.ransacThreshold ? 1U : 0U;
      }
      if (score > bestScore) {
        bestScore = score;
        hypothesis = p;
      }
    }
    if (bestScore == 0) {
      break;
    }
    std::vector<std::size_t> inliers;
    std::vector<std::size_t> outliers;
    for (const std::size_t i : remaining) {
      (std::fabs(hypothesis.normal.dot(points[i]) - hypothesis.offset) < c.ransacThreshold ? inliers : outliers)
          .push_back(i);
    }
    std::unordered_map<CellKey, int> cellLabel;
    int label = 0;
    const std::vector<std::size_t> region = largestRegion(points, inliers, hypothesis, c.regionCell, cellLabel, label);
    const Plane plane = region.size() >= 3 ? pcaPlane(points, &region, nullptr) : hypothesis;
    const Eigen::Vector2d e = region.size() >= 3 ? extents(points, region, plane) : Eigen::Vector2d::Zero();
    const bool fits = region.size() >= c.minPoints && e[0] <= c.candidateTolerance * large &&
                      e[1] <= c.candidateTolerance * small && e[0] >= c.minExtentFraction * large &&
                      e[1] >= c.minExtentFraction * small;
    if (region.size() >= c.minPoints) {
      planes.push_back(robustPlane(points, region, plane, c));
    }

    if (!fits) {
      rejected += (rejected.empty() ? "" : ", ") + std::to_string(region.size()) + " points " +
                  std::to_string(e[0]).substr(0, 5) + " x " + std::to_string(e[1]).substr(0, 5) + " m";
    } else {
      Candidate cand;
      cand.region = region;
      cand.plane = plane;
      cand.ransacPlane = hypothesis;
      cand.cellLabel = std::move(cellLabel);
      cand.label = label;
      cand.pool = remaining;
      cand.planeIndex = planes.size() - 1;
      candidates.push_back(std::move(cand));
    }
    remaining = outliers;  // look for the next plane
  }
  // The largest candidate that still fits once refined (planar within maxRms, the target's size) wins.
  std::sort(candidates.begin(), candidates.end(),
            [](const Candidate& x, const Candidate& y) { return x.region.size() > y.region.size(); });
  for (const Candidate& cand : candidates) {
    std::vector<Plane> others;  // the large planes that are not this candidate
    for (std::size_t k = 0; k < planes.size(); ++k) {
      if (k != cand.planeIndex) {
        others.push_back(planes[k]);
      }
    }
    TargetSegment seg;
    refine(points, c, cand, others, seg);
    const bool fits = seg.indices.size() >= c.minPoints && seg.rms <= c.maxRms &&
                      seg.extent[0] <= c.extentTolerance * large && seg.extent[1] <= c.extentTolerance * small &&
                      seg.extent[0] >= c.minExtentFraction * large && seg.extent[1] >= c.minExtentFraction * small;
    if (fits) {
      seg.planesTried = out.planesTried;
      out = std::move(seg);
      return true;
    }
    rejected += (rejected.empty() ? "" : ", ") + std::string("refined ") + std::to_string(seg.indices.size()) +
                " points " + std::to_string(seg.extent[0]).substr(0, 5) + " x " +
                std::to_string(seg.extent[1]).substr(0, 5) + " m rms " + std::to_string(seg.rms).substr(0, 5) + " m";
  }
  error = "no plane region of the target's size (" + std::to_string(c.targetWidth).substr(0, 4) + " x " +
          std::to_string(c.targetHeight).substr(0, 4) + " m) among " + std::to_string(out.planesTried) + " planes" +
          (rejected.empty() ? std::string() : " (rejected: " + rejected + ")");
  return false;
}

}  // namespace agv::lidar_calibration
