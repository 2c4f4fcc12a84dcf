#include "agv/falko/falko_detector.hpp"

#include <cmath>
#include <limits>

#include "agv/core/angle.hpp"
#include "falko_math.hpp"

namespace agv {

namespace {

constexpr std::size_t kMaxGridSectors = 64;

/// A line through (mx, my) with unit direction (dx, dy).
struct Line {
  float mx = 0.0F;
  float my = 0.0F;
  float dx = 1.0F;
  float dy = 0.0F;
};

/// Least-squares line through points (total least squares): centroid and unit direction.
struct LineAcc {
  float n = 0.0F;
  float sx = 0.0F;
  float sy = 0.0F;
  float sxx = 0.0F;
  float sxy = 0.0F;
  float syy = 0.0F;
  void add(float x, float y) noexcept {
    n += 1.0F;
    sx += x;
    sy += y;
    sxx += x * x;
    sxy += x * y;
    syy += y * y;
  }
  void remove(float x, float y) noexcept {
    n -= 1.0F;
    sx -= x;
    sy -= y;
    sxx -= x * x;
    sxy -= x * y;
    syy -= y * y;
  }
  void subtract(const LineAcc& o) noexcept {
    n -= o.n;
    sx -= o.sx;
    sy -= o.sy;
    sxx -= o.sxx;
    sxy -= o.sxy;
    syy -= o.syy;
  }
  /// Sum of squared orthogonal distances to the best line (n * smallest covariance eigenvalue).
  float residual() const noexcept {
    if (n < 2.0F) {
      return 0.0F;
    }
    const float mx = sx / n;
    const float my = sy / n;
    const float cxx = sxx / n - mx * mx;
    const float cyy = syy / n - my * my;
    const float cxy = sxy / n - mx * my;
    const float h = 0.5F * (cxx - cyy);
    const float lmin = 0.5F * (cxx + cyy) - std::sqrt(h * h + cxy * cxy);
    return n * (lmin > 0.0F ? lmin : 0.0F);
  }
  /// Centroid (mx, my) and unit direction (dx, dy); false when fewer than 2 points or isotropic.
  bool fit(Line& line) const noexcept {
    if (n < 2.0F) {
      return false;
    }
    float& mx = line.mx;
    float& my = line.my;
    float& dx = line.dx;
    float& dy = line.dy;
    mx = sx / n;
    my = sy / n;
    const float cxx = sxx / n - mx * mx;
    const float cyy = syy / n - my * my;
    const float cxy = sxy / n - mx * my;
    // Major axis angle phi: tan(2 phi) = 2 cxy / (cxx - cyy); direction from the half-angle
    // formulas, no trigonometric call.
    const float a = cxx - cyy;
    const float b = 2.0F * cxy;
    const float h = std::sqrt(a * a + b * b);
    if (!(h > 1.0e-12F)) {
      return false;
    }
    const float cos2 = a / h;
    dx = std::sqrt(0.5F * (1.0F + cos2));
    dy = std::copysign(std::sqrt(0.5F * (1.0F - cos2 > 0.0F ? 1.0F - cos2 : 0.0F)), b);
    return true;
  }
};

/// Intersection of two lines; false when they are nearly parallel (less than 3 deg apart).
bool intersect(const Line& a, const Line& b, float& cx, float& cy) noexcept {
  const float den = a.dx * b.dy - a.dy * b.dx;  // sin of the angle between the lines
  if (std::fabs(den) < 0.05F) {
    return false;
  }
  const float t = ((b.mx - a.mx) * b.dy - (b.my - a.my) * b.dx) / den;
  cx = a.mx + t * a.dx;
  cy = a.my + t * a.dy;
  return std::isfinite(cx) && std::isfinite(cy);
}

}  // namespace

FalkoDetector::FalkoDetector(const FalkoParams& params) noexcept : params_(params) {}

bool FalkoDetector::paramsValid() const noexcept {
  const FalkoParams& p = params_;
  const bool finite = std::isfinite(p.neighA) && std::isfinite(p.neighB) && std::isfinite(p.beta) &&
                      std::isfinite(p.maxScore) && std::isfinite(p.nmsRadius) && std::isfinite(p.subbeamMaxShift) &&
                      std::isfinite(p.refineRadiusFactor) && std::isfinite(p.refineInlierDistance) &&
                      std::isfinite(p.minCornerResidualRatio) &&
                      std::isfinite(p.minExtractionRange) && std::isfinite(p.maxRadiusRangeRatio) &&
                      !std::isnan(p.maxExtractionRange);
  return finite && p.neighA > 0.0F && p.neighB >= 0.0F && p.beta > 0.0F && p.minSidePoints >= 1 &&
         p.gridSectors >= 4 && p.gridSectors <= kMaxGridSectors && p.maxScore >= 0.0F && p.nmsRadius >= 0.0F &&
         p.subbeamMaxShift >= 0.0F && p.refineRadiusFactor >= 1.0F && p.refineInlierDistance > 0.0F &&
         p.minCornerResidualRatio >= 0.0F && p.maxRadiusRangeRatio > 0.0F && p.maxRadiusRangeRatio < 1.0F;
}

Status FalkoDetector::detect(const LaserScan& scan, IVector<FalkoKeypoint>& out) noexcept {
  out.clear();
  const Status st = points_.assign(scan);
  if (!isOk(st)) {
    candidateCount_ = 0;
    return st;
  }
  return detect(points_, out);
}

bool FalkoDetector::gather(const ScanPoints& pts, std::size_t i, float radius, Side& left, Side& right) noexcept {
  const std::size_t n = pts.size();
  const float cx = pts.x(i);
  const float cy = pts.y(i);
  const float r2 = radius * radius;
  const std::size_t kmax = pts.maxOffset(pts.range(i), radius);
  left = Side{};
  right = Side{};
  for (std::size_t k = 1; k <= kmax; ++k) {
    const std::size_t j = pts.offsetIndex(i, -static_cast<std::ptrdiff_t>(k));
    if (j >= n) {
      break;
    }
    if (!pts.valid(j)) {
      continue;
    }
    const float dx = pts.x(j) - cx;
    const float dy = pts.y(j) - cy;
    if (dx * dx + dy * dy <= r2) {
      leftX_[left.count] = dx;
      leftY_[left.count] = dy;
      ++left.count;
      left.sumX += dx;
      left.sumY += dy;
    }
  }
  if (left.count < params_.minSidePoints) {
    return false;  // early rejection: the other side is not needed
  }
  for (std::size_t k = 1; k <= kmax; ++k) {
    const std::size_t j = pts.offsetIndex(i, static_cast<std::ptrdiff_t>(k));
    if (j >= n) {
      break;
    }
    if (!pts.valid(j)) {
      continue;
    }
    const float dx = pts.x(j) - cx;
    const float dy = pts.y(j) - cy;
    if (dx * dx + dy * dy <= r2) {
      rightX_[right.count] = dx;
      rightY_[right.count] = dy;
      ++right.count;
      right.sumX += dx;
      right.sumY += dy;
    }
  }
  return right.count >= params_.minSidePoints;
}

float FalkoDetector::scoreOf(const Side& left, const Side& right, float c, float s) const noexcept {
  const auto bins = static_cast<unsigned>(params_.gridSectors);
  const float binsPerRadian = static_cast<float>(bins) / kTwoPi<float>;
  const unsigned half = bins / 2U;
  float total = 0.0F;
  float pairs = 0.0F;
  for (int side = 0; side < 2; ++side) {
    const Side& sd = side == 0 ? left : right;
    const float* px = side == 0 ? leftX_.data() : rightX_.data();
    const float* py = side == 0 ? leftY_.data() : rightY_.data();
    std::array<std::uint32_t, kMaxGridSectors> hist{};
    std::array<unsigned, kMaxGridSectors> used{};
    unsigned usedCount = 0;
    for (std::size_t k = 0; k < sd.count; ++k) {
      // Bearing of the neighbour seen from the candidate, relative to the corner orientation.
      const float u = px[k] * c + py[k] * s;
      const float v = py[k] * c - px[k] * s;
      const unsigned b = falko_detail::sectorOf(v, u, binsPerRadian, bins);
      if (hist[b]++ == 0U) {
        used[usedCount++] = b;
      }
    }
    // Sum over point pairs of the circular sector distance = sum over pairs of occupied sectors.
    std::uint64_t sum = 0;
    for (unsigned a = 0; a < usedCount; ++a) {
      for (unsigned b = a + 1U; b < usedCount; ++b) {
        const unsigned d0 = used[a] > used[b] ? used[a] - used[b] : used[b] - used[a];
        const unsigned d = d0 > half ? bins - d0 : d0;
        sum += static_cast<std::uint64_t>(hist[used[a]]) * hist[used[b]] * d;
      }
    }
    const auto cnt = static_cast<float>(sd.count);
    total += static_cast<float>(sum);
    pairs += 0.5F * cnt * (cnt - 1.0F);
  }
  return pairs > 0.0F ? total / pairs : 0.0F;
}

bool FalkoDetector::refine(const ScanPoints& pts, std::size_t i, const Side& left, const Side& right,
                           FalkoKeypoint& kp) noexcept {
  const std::size_t n = pts.size();
  const float mxAbs = pts.x(i);
  const float myAbs = pts.y(i);
  const float maxShift2 = params_.subbeamMaxShift * params_.subbeamMaxShift;
  Line lineL;
  Line lineR;
  float cx = 0.0F;
  float cy = 0.0F;
  // Pass 1: the best two-line split of the points within refineRadiusFactor * r of the candidate,
  // in beam order: every split point s (excluded from both lines: it is the one nearest the
  // corner) with at least minSidePoints + 1 points on each side is tried, and the one with the
  // least total squared orthogonal residual wins. Incremental sums make it linear in the window.
  // The side buffers are reused for the window (the side sums stay in `left` / `right`).
  const float reach = params_.refineRadiusFactor * kp.radius;
  const float reach2 = reach * reach;
  bool ok = false;
  {
    float* wx = leftX_.data();
    float* wy = leftY_.data();
    std::size_t m = 0;
    const auto kmax = static_cast<std::ptrdiff_t>(pts.maxOffset(pts.range(i), reach));
    LineAcc total;
    for (std::ptrdiff_t k = -kmax; k <= kmax; ++k) {
      const std::size_t j = pts.offsetIndex(i, k);
      if (j >= n || !pts.valid(j)) {
        continue;
      }
      const float qx = pts.x(j) - mxAbs;
      const float qy = pts.y(j) - myAbs;
      if (qx * qx + qy * qy <= reach2) {
        wx[m] = qx;
        wy[m] = qy;
        ++m;
        total.add(qx, qy);
      }
    }
    const std::size_t minSide = params_.minSidePoints + 1;
    LineAcc before;  // points [0, q)
    float bestCost = std::numeric_limits<float>::infinity();
    LineAcc bestL;
    LineAcc bestR;
    for (std::size_t q = 0; q < m; ++q) {
      if (q >= minSide && m - q - 1 >= minSide) {
        LineAcc after = total;
        after.subtract(before);
        after.remove(wx[q], wy[q]);
        const float cost = before.residual() + after.residual();
        if (cost < bestCost) {
          bestCost = cost;
          bestL = before;
          bestR = after;
        }
      }
      before.add(wx[q], wy[q]);
    }
    // One line explaining the window almost as well as two: a noisy straight wall, not a corner.
    if (bestCost < std::numeric_limits<float>::infinity() &&
        total.residual() <= params_.minCornerResidualRatio * bestCost) {
      return false;
    }
    ok = bestCost < std::numeric_limits<float>::infinity() && bestL.fit(lineL) && bestR.fit(lineR) &&
         intersect(lineL, lineR, cx, cy);
    if (ok && cx * cx + cy * cy > maxShift2) {
      // The two walls meet farther than subbeamMaxShift away: this candidate sees a corner
      // elsewhere (e.g. beside an acute corner), whose own candidates will report it.
      return false;
    }
  }
  if (ok) {
    // Passes 2 and 3: the neighbourhood holds few points per side at long range, and the
    // candidate beam may lie a beam or two off the corner. Re-split the points of a wider disc at
    // the bearing of the estimated corner, keep those close to their side's line and not within
    // 1.5 beam spacings of the corner, and fit again.
    const float gap = 1.5F * pts.range(i) * pts.angleIncrement();
    const float gap2 = gap * gap;
    const float tol = params_.refineInlierDistance;
    for (int pass = 0; pass < 2; ++pass) {
      const float ccx = mxAbs + cx;
      const float ccy = myAbs + cy;
      const std::size_t kmax = pts.maxOffset(pts.range(i), reach + std::sqrt(cx * cx + cy * cy));
      LineAcc l;
      LineAcc r;
      for (std::ptrdiff_t k = -static_cast<std::ptrdiff_t>(kmax); k <= static_cast<std::ptrdiff_t>(kmax); ++k) {
        const std::size_t j = pts.offsetIndex(i, k);
        if (j >= n || !pts.valid(j)) {
          continue;
        }
        const float qx = pts.x(j) - mxAbs;
        const float qy = pts.y(j) - myAbs;
        const float ex = qx - cx;
        const float ey = qy - cy;
        const float e2 = ex * ex + ey * ey;
        if (e2 > reach2 || e2 < gap2) {
          continue;
        }
        // Sign of cross(corner, point) in the sensor frame: negative = clockwise = earlier beam.
        const bool isLeft = ccx * pts.y(j) - ccy * pts.x(j) < 0.0F;
        const Line& ln = isLeft ? lineL : lineR;
        const float dist = std::fabs(ln.dx * (qy - ln.my) - ln.dy * (qx - ln.mx));
        if (dist > tol) {
          continue;
        }
        (isLeft ? l : r).add(qx, qy);
      }
      Line nl;
      Line nr;
      float c2x = 0.0F;
      float c2y = 0.0F;
      const auto minPts = static_cast<float>(params_.minSidePoints);
      if (!(l.n >= minPts && r.n >= minPts && l.fit(nl) && r.fit(nr) && intersect(nl, nr, c2x, c2y) &&
            c2x * c2x + c2y * c2y <= maxShift2)) {
        break;
      }
      cx = c2x;
      cy = c2y;
      lineL = nl;
      lineR = nr;
    }
  } else {
    cx = 0.0F;
    cy = 0.0F;
  }
  kp.refined = ok;
  kp.x = mxAbs + cx;
  kp.y = myAbs + cy;
  // Orientation: mean direction from the corner to the centroids of its two sides. Refined
  // corners use the centroids of the points of each fitted wall, as unit vectors: the bisector
  // of the corner, independent of how much of each wall the sensor sees. Unrefined ones use the
  // neighbourhood sides as they are.
  float ox = 0.0F;
  float oy = 0.0F;
  if (ok) {
    const float lx = lineL.mx - cx;
    const float ly = lineL.my - cy;
    const float rx = lineR.mx - cx;
    const float ry = lineR.my - cy;
    const float ln = std::sqrt(lx * lx + ly * ly);
    const float rn = std::sqrt(rx * rx + ry * ry);
    if (ln > 0.0F && rn > 0.0F) {
      ox = lx / ln + rx / rn;
      oy = ly / ln + ry / rn;
    }
  }
  if (ox == 0.0F && oy == 0.0F) {
    ox = left.sumX / static_cast<float>(left.count) + right.sumX / static_cast<float>(right.count) - 2.0F * cx;
    oy = left.sumY / static_cast<float>(left.count) + right.sumY / static_cast<float>(right.count) - 2.0F * cy;
  }
  kp.orientation = std::atan2(oy, ox);
  return true;
}

Status FalkoDetector::detect(const ScanPoints& pts, IVector<FalkoKeypoint>& out) noexcept {
  out.clear();
  candidateCount_ = 0;
  if (!paramsValid()) {
    return Status::InvalidArgument;
  }
  const std::size_t n = pts.size();
  const FalkoParams& p = params_;
  const float invBeta = 1.0F / p.beta;
  std::size_t candidates = 0;

  // 1. Candidates: side split, triangle test, score.
  for (std::size_t i = 0; i < n; ++i) {
    if (!pts.valid(i)) {
      continue;
    }
    const float rho = pts.range(i);
    if (rho < p.minExtractionRange || rho > p.maxExtractionRange) {
      continue;
    }
    float radius = p.neighA * std::exp(p.neighB * rho);
    const float maxRadius = p.maxRadiusRangeRatio * rho;
    if (radius > maxRadius) {
      radius = maxRadius;
    }
    Side left;
    Side right;
    if (!gather(pts, i, radius, left, right)) {
      continue;
    }
    // Triangle first neighbour (front) / candidate (origin) / last neighbour (back).
    const float fx = leftX_[left.count - 1];
    const float fy = leftY_[left.count - 1];
    const float bx = rightX_[right.count - 1];
    const float by = rightY_[right.count - 1];
    const float minLen = radius * invBeta;
    const float base2 = (bx - fx) * (bx - fx) + (by - fy) * (by - fy);
    if (base2 < minLen * minLen) {
      continue;
    }
    const float cross = fx * by - fy * bx;  // = base * height
    if (cross * cross < base2 * minLen * minLen) {
      continue;
    }
    const float ox = left.sumX / static_cast<float>(left.count) + right.sumX / static_cast<float>(right.count);
    const float oy = left.sumY / static_cast<float>(left.count) + right.sumY / static_cast<float>(right.count);
    const float on = std::sqrt(ox * ox + oy * oy);
    if (!(on > 1.0e-6F * radius)) {
      continue;
    }
    const float score = scoreOf(left, right, ox / on, oy / on);
    if (score > p.maxScore) {
      continue;
    }
    // Refined here while the neighbourhood is in the buffers: suppression compares refined
    // corners, so that candidates a few beams apart that describe one corner compete.
    FalkoKeypoint& kp = cands_[candidates++];
    kp = FalkoKeypoint{};
    kp.beamIndex = static_cast<std::uint32_t>(i);
    kp.radius = radius;
    kp.score = score;
    if (!refine(pts, i, left, right, kp)) {
      --candidates;
    }
  }
  candidateCount_ = candidates;

  // 2. Non-maxima suppression on the refined corners: a candidate survives when no better one lies
  //    within nmsRadius. Better = refined over unrefined, then lower score, then lower beam index.
  //    Candidates are in beam order and lie within subbeamMaxShift of their beam point, so only
  //    candidates within a bounded beam offset need to be looked at.
  Status result = Status::Ok;
  const float nms2 = p.nmsRadius * p.nmsRadius;
  const float wide2 = (p.nmsRadius + p.subbeamMaxShift) * (p.nmsRadius + p.subbeamMaxShift);
  auto better = [](const FalkoKeypoint& a, const FalkoKeypoint& b) {
    if (a.refined != b.refined) {
      return a.refined;
    }
    if (a.score != b.score) {
      return a.score < b.score;
    }
    return a.beamIndex < b.beamIndex;
  };
  const auto nb = static_cast<std::ptrdiff_t>(n);
  for (std::size_t c = 0; c < candidates; ++c) {
    const FalkoKeypoint& kp = cands_[c];
    const std::size_t i = kp.beamIndex;
    const auto kmax = static_cast<std::ptrdiff_t>(
        pts.maxOffset(pts.range(i), p.nmsRadius + 2.0F * p.subbeamMaxShift));
    bool best = true;
    for (int dir = -1; dir <= 1 && best; dir += 2) {
      for (std::size_t step = 1; step < candidates; ++step) {
        // Neighbouring candidate in beam order, circular on wrapping scans.
        std::size_t d = 0;
        if (dir < 0) {
          if (step > c && !pts.wraps()) {
            break;
          }
          d = (c + candidates - (step % candidates)) % candidates;
        } else {
          if (c + step >= candidates && !pts.wraps()) {
            break;
          }
          d = (c + step) % candidates;
        }
        const FalkoKeypoint& other = cands_[d];
        std::ptrdiff_t off = dir * (static_cast<std::ptrdiff_t>(other.beamIndex) - static_cast<std::ptrdiff_t>(i));
        if (off < 0) {
          off += nb;  // wrapped around the seam
        }
        if (off > kmax) {
          break;
        }
        const float dx = other.x - kp.x;
        const float dy = other.y - kp.y;
        // An unrefined candidate is a beam point up to subbeamMaxShift away from the corner it
        // sees: a refined corner suppresses it within the enlarged radius.
        const float lim2 = (other.refined && !kp.refined) ? wide2 : nms2;
        if (dx * dx + dy * dy <= lim2 && better(other, kp)) {
          best = false;
          break;
        }
      }
    }
    if (best && !isOk(out.push_back(kp))) {
      result = Status::CapacityExceeded;
    }
  }
  return result;
}

}  // namespace agv
