#include "agv/falko/falko_detector.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "agv/core/angle.hpp"
#include "falko_math.hpp"

namespace agv {

namespace {

constexpr std::size_t kMaxGridSectors = 64;
/// Interleaved copies of the score histogram (see scoreOf); FalkoDetector::hist_ holds them.
constexpr std::size_t kHistCopies = falko_detail::kFourWide ? 2 : 1;
static_assert(kHistCopies * kMaxGridSectors <= FalkoDetector::kHistSize, "score histogram buffer too small");
constexpr float kNotCandidate = std::numeric_limits<float>::infinity();

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
    const float inv = 1.0F / n;
    const float mx = sx * inv;
    const float my = sy * inv;
    const float cxx = sxx * inv - mx * mx;
    const float cyy = syy * inv - my * my;
    const float cxy = sxy * inv - mx * my;
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

bool isValid(const FalkoParams& p) noexcept {
  const bool finite = std::isfinite(p.neighA) && std::isfinite(p.neighB) && std::isfinite(p.beta) &&
                      std::isfinite(p.maxScore) && std::isfinite(p.nmsRadius) && std::isfinite(p.subbeamMaxShift) &&
                      std::isfinite(p.refineRadiusFactor) && std::isfinite(p.refineInlierDistance) &&
                      std::isfinite(p.minCornerResidualRatio) && std::isfinite(p.minExtractionRange) &&
                      std::isfinite(p.maxRadiusRangeRatio) && !std::isnan(p.maxExtractionRange);
  return finite && p.neighA > 0.0F && p.neighB >= 0.0F && p.beta > 0.0F && p.minSidePoints >= 1 && p.gridSectors >= 4 &&
         p.gridSectors <= kMaxGridSectors && p.maxScore >= 0.0F && p.nmsRadius >= 0.0F && p.subbeamMaxShift >= 0.0F &&
         p.refineRadiusFactor >= 1.0F && p.refineInlierDistance > 0.0F && p.minCornerResidualRatio >= 0.0F &&
         p.maxRadiusRangeRatio > 0.0F && p.maxRadiusRangeRatio < 1.0F;
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

namespace {
/// Offset k (in beams, 1..kmax) of the farthest point within `radius` of beam i on one side (dir
/// -1: earlier beams, +1: later), found by walking from the edge of the angular window inwards: on
/// a straight wall the window edge is about r away, so this usually stops after a few beams. The
/// point relative to beam i is written to (fx, fy). Returns 0 when the side is empty. No beam
/// beyond the returned offset (up to kmax) lies within the radius.
std::size_t farthestWithin(const ScanPoints& pts, std::size_t i, int dir, std::size_t kmax, float r2, float& fx,
                           float& fy) noexcept {
  const std::size_t n = pts.size();
  const float cx = pts.x(i);
  const float cy = pts.y(i);
  const float* xs = pts.xData();
  const float* ys = pts.yData();
  auto found = [&](std::size_t j) {
    fx = xs[j] - cx;
    fy = ys[j] - cy;
  };
  // The beams i + dir * k, k = kmax .. 1, as at most two plain index runs (farthest first).
  if (dir < 0) {
    if (kmax > i && pts.wraps()) {
      const std::size_t j = falko_detail::firstWithinAscending(xs, ys, n + i - kmax, n, cx, cy, r2);
      if (j < n) {
        found(j);
        return n + i - j;
      }
    }
    const std::size_t j = falko_detail::firstWithinAscending(xs, ys, kmax > i ? 0 : i - kmax, i, cx, cy, r2);
    if (j < i) {
      found(j);
      return i - j;
    }
    return 0;
  }
  if (i + kmax >= n && pts.wraps()) {
    const std::size_t end = i + kmax - n + 1;
    const std::size_t j = falko_detail::lastWithinDescending(xs, ys, 0, end, cx, cy, r2);
    if (j < end) {
      found(j);
      return n - i + j;
    }
  }
  const std::size_t end = (i + kmax < n ? i + kmax : n - 1) + 1;
  const std::size_t j = falko_detail::lastWithinDescending(xs, ys, i + 1, end, cx, cy, r2);
  if (j < end) {
    found(j);
    return j - i;
  }
  return 0;
}
}  // namespace

FalkoDetector::Side FalkoDetector::gatherSide(const ScanPoints& pts, std::size_t i, int dir, std::size_t k, float r2,
                                              float* xs, float* ys) noexcept {
  const float cx = pts.x(i);
  const float cy = pts.y(i);
  // Invalid readings are far away (ScanPoints::kFarAway): the radius test drops them.
  std::size_t count = 0;
  float sx = 0.0F;
  float sy = 0.0F;
  falko_detail::walkBeams(pts, i, dir, k, [&](std::size_t j) {
    const float dx = pts.x(j) - cx;
    const float dy = pts.y(j) - cy;
    if (dx * dx + dy * dy <= r2) {
      xs[count] = dx;
      ys[count] = dy;
      ++count;
      sx += dx;
      sy += dy;
    }
  });
  Side side;
  side.count = count;
  side.sumX = sx;
  side.sumY = sy;
  return side;
}

bool FalkoDetector::gather(const ScanPoints& pts, std::size_t i, float radius, std::size_t kLeft, std::size_t kRight,
                           Side& left, Side& right) noexcept {
  const float r2 = radius * radius;
  left = gatherSide(pts, i, -1, kLeft, r2, leftX_.data(), leftY_.data());
  if (left.count < params_.minSidePoints) {
    return false;  // early rejection: the other side is not needed
  }
  right = gatherSide(pts, i, 1, kRight, r2, rightX_.data(), rightY_.data());
  return right.count >= params_.minSidePoints;
}

float FalkoDetector::scoreOf(const Side& left, const Side& right, float c, float s) noexcept {
  const auto bins = static_cast<unsigned>(params_.gridSectors);
  const float binsPerRadian = static_cast<float>(bins) / kTwoPi<float>;
  const unsigned half = bins / 2U;
  const bool fast16 = bins == 16U;
  float total = 0.0F;
  float pairs = 0.0F;
  for (int side = 0; side < 2; ++side) {
    const Side& sd = side == 0 ? left : right;
    const float* px = side == 0 ? leftX_.data() : rightX_.data();
    const float* py = side == 0 ? leftY_.data() : rightY_.data();
    // Histogram of the sectors; hist_ is all zero between calls: only the occupied bins are
    // reset at the end. The points of one wall fall in one sector, so on out-of-order cores
    // (kHistCopies > 1) point k counts in copy k % kHistCopies, and the occupied sectors are
    // kept in two 32-bit masks: no increment waits for the previous one to reach memory. On
    // in-order cores (one copy) the first increment of a sector lists it, which is cheaper.
    std::uint32_t* h = hist_.data();
    std::array<unsigned, kMaxGridSectors> used;      // only [0, usedCount) is read
    std::array<std::uint32_t, kMaxGridSectors> cnt;  // count of sector used[a]
    unsigned usedCount = 0;
    std::uint32_t occupiedLo = 0;  // sectors 0..31
    std::uint32_t occupiedHi = 0;  // sectors 32..63
    auto count = [&](std::size_t k, unsigned b) {
      if constexpr (kHistCopies == 1) {
        if (h[b]++ == 0U) {
          used[usedCount++] = b;
        }
      } else {
        ++h[(k % kHistCopies) * kMaxGridSectors + b];
        occupiedLo |= b < 32U ? 1U << (b & 31U) : 0U;
        occupiedHi |= b < 32U ? 0U : 1U << (b & 31U);
      }
    };
    std::size_t k = 0;
    if (fast16 && falko_detail::kFourWide) {
      // Sectors of four neighbours at a time, branch-free (vector registers where available).
      for (; k + 4 <= sd.count; k += 4) {
        std::array<unsigned, 4> b4;
        for (std::size_t l = 0; l < 4; ++l) {
          const float u = px[k + l] * c + py[k + l] * s;
          const float v = py[k + l] * c - px[k + l] * s;
          b4[l] = falko_detail::sector16Branchless(u, v);
        }
        for (std::size_t l = 0; l < 4; ++l) {
          count(k + l, b4[l]);
        }
      }
    }
    for (; k < sd.count; ++k) {
      // Bearing of the neighbour seen from the candidate, relative to the corner orientation.
      const float u = px[k] * c + py[k] * s;
      const float v = py[k] * c - px[k] * s;
      count(k, fast16 ? falko_detail::sector16(u, v) : falko_detail::sectorOf(v, u, binsPerRadian, bins));
    }
    // Counts of the occupied sectors; the histogram is reset on the way.
    if constexpr (kHistCopies == 1) {
      for (unsigned a = 0; a < usedCount; ++a) {
        cnt[a] = h[used[a]];
        h[used[a]] = 0U;
      }
    } else {
      for (unsigned base = 0; base < 64U; base += 32U) {
        for (std::uint32_t m = base == 0U ? occupiedLo : occupiedHi; m != 0U; m &= m - 1U) {
          const unsigned b = base + falko_detail::lowestBitIndex(m);
          std::uint32_t sum = 0;
          for (std::size_t copy = 0; copy < kHistCopies; ++copy) {
            sum += h[copy * kMaxGridSectors + b];
            h[copy * kMaxGridSectors + b] = 0U;
          }
          used[usedCount] = b;
          cnt[usedCount] = sum;
          ++usedCount;
        }
      }
    }
    // Sum over point pairs of the circular sector distance = sum over pairs of occupied sectors.
    std::uint32_t sum = 0;
    for (unsigned a = 0; a < usedCount; ++a) {
      for (unsigned b = a + 1U; b < usedCount; ++b) {
        const unsigned d0 = used[a] > used[b] ? used[a] - used[b] : used[b] - used[a];
        const unsigned d = d0 > half ? bins - d0 : d0;
        sum += cnt[a] * cnt[b] * d;  // < 2048^2 * 32: fits
      }
    }
    const auto cntSide = static_cast<float>(sd.count);
    total += static_cast<float>(sum);
    pairs += 0.5F * cntSide * (cntSide - 1.0F);
  }
  return pairs > 0.0F ? total / pairs : 0.0F;
}

namespace {

/// The refinement window of one candidate (pass 1): the points within refineRadiusFactor * r of
/// it, relative to it, in beam order.
struct RefineWindow {
  std::size_t count = 0;     ///< points in the window
  std::size_t mLeft = 0;     ///< points before the candidate (the candidate is point mLeft)
  std::size_t qStart = 0;    ///< first point at most kSplit beams from the candidate
  std::size_t qEnd = 0;      ///< one past the last such point
  float splitReach2 = 0.0F;  ///< squared distance from the candidate within which a split may lie
};

/// A corner relative to the candidate point, and the two wall lines meeting there.
struct Corner {
  float x = 0.0F;
  float y = 0.0F;
  Line left;
  Line right;
};

/// What passes 2 and 3 keep of a window (candidate point in the sensor frame, distances squared).
struct RefitLimits {
  float mxAbs = 0.0F;
  float myAbs = 0.0F;
  float reach2 = 0.0F;     ///< window disc around the corner
  float gap2 = 0.0F;       ///< points this close to the corner are left out
  float tol = 0.0F;        ///< largest distance of a point to its side's line
  float minPts = 0.0F;     ///< least points per line
  float maxShift2 = 0.0F;  ///< farthest corner from the candidate point
};

/// Collects the window of candidate i in beam order into (wx, wy) (earlier beams farthest first).
/// Branch-free compaction: every beam is written, the count advances only for points within reach
/// (at most one write beyond the kept points, inside the buffer: the window never exceeds the
/// scan). The split point is the one nearest the corner, which lies within subbeamMaxShift of the
/// candidate: no point more than kSplit beams away can be that close, so [qStart, qEnd) holds the
/// only split points worth trying (farther splits could only be rejected).
RefineWindow collectWindow(const ScanPoints& pts, std::size_t i, float reach, float subbeamMaxShift, float* wx,
                           float* wy) noexcept {
  const float mxAbs = pts.x(i);
  const float myAbs = pts.y(i);
  const float reach2 = reach * reach;
  const std::size_t kmax = pts.maxOffsetAt(i, reach);
  const float splitReach = subbeamMaxShift + 2.0F * pts.range(i) * pts.angleIncrement();
  const std::size_t kSplitBound = pts.maxOffsetAt(i, splitReach);
  const std::size_t kSplit = kSplitBound < kmax ? kSplitBound : kmax;
  RefineWindow w;
  w.splitReach2 = splitReach * splitReach;
  std::size_t m = 0;
  auto take = [&](std::size_t j) {
    const float qx = pts.x(j) - mxAbs;
    const float qy = pts.y(j) - myAbs;
    wx[m] = qx;
    wy[m] = qy;
    m += qx * qx + qy * qy <= reach2 ? 1U : 0U;  // invalid readings are far away
  };
  falko_detail::walkBeamsInOrder(pts, i, -1, kSplit + 1, kmax, take);
  w.qStart = m;
  falko_detail::walkBeamsInOrder(pts, i, -1, 1, kSplit, take);
  w.mLeft = m;
  take(i);
  falko_detail::walkBeamsInOrder(pts, i, 1, 1, kSplit, take);
  w.qEnd = m;
  falko_detail::walkBeamsInOrder(pts, i, 1, kSplit + 1, kmax, take);
  w.count = m;
  return w;
}

/// Sums of the whole window: the earlier points nearest first, then the candidate and the later
/// points.
LineAcc windowSums(const float* wx, const float* wy, std::size_t mLeft, std::size_t count) noexcept {
  LineAcc total;
  for (std::size_t a = mLeft; a > 0; --a) {
    total.add(wx[a - 1], wy[a - 1]);
  }
  for (std::size_t a = mLeft; a < count; ++a) {
    total.add(wx[a], wy[a]);
  }
  return total;
}

/// The best two-line split of the window: every split point q within the split reach (excluded
/// from both lines: it is the one nearest the corner) with at least minSide points on each side
/// is tried, and the least total squared orthogonal residual wins. Incremental sums make it
/// linear in the window. Returns the least total residual (+inf: no split tried) and the sums of
/// the points before (bestL) and after (bestR) the best split point.
float bestSplit(const float* wx, const float* wy, const RefineWindow& w, const LineAcc& total, std::size_t minSide,
                LineAcc& bestL, LineAcc& bestR) noexcept {
  float bestCost = std::numeric_limits<float>::infinity();
  const std::size_t m = w.count;
  const std::size_t qStart = w.qStart;
  const std::size_t qEnd = w.qEnd;
  const float splitReach2 = w.splitReach2;
  if (m < 2 * minSide + 1) {
    return bestCost;
  }
  const std::size_t qLast = m - minSide - 1;  // the last split point with minSide after it
  // Split points beyond qEnd are outside the split reach: `before` is not needed there.
  const std::size_t qStop = qEnd <= qLast ? qEnd : qLast + 1;
  LineAcc before;  // points [0, q)
  for (std::size_t q = 0; q < minSide; ++q) {
    before.add(wx[q], wy[q]);
  }
  std::size_t q = minSide;
  for (; q < qStart && q < qStop; ++q) {
    before.add(wx[q], wy[q]);
  }
  for (; q < qStop; ++q) {
    if (wx[q] * wx[q] + wy[q] * wy[q] <= splitReach2) {
      const float costL = before.residual();
      // The residual of the points before the split only grows with q (a line through more
      // points fits no better), so no later split can beat the best one any more.
      if (!(costL < bestCost)) {
        break;
      }
      LineAcc after = total;
      after.subtract(before);
      after.remove(wx[q], wy[q]);
      const float cost = costL + after.residual();
      if (cost < bestCost) {
        bestCost = cost;
        bestL = before;
        bestR = after;
      }
    }
    before.add(wx[q], wy[q]);
  }
  return bestCost;
}

/// One re-fit (passes 2 and 3): the window points within reach of the corner, not within the gap
/// of it and close to their side's line, split at the bearing of the corner, fitted again. Returns
/// false (corner unchanged) when a side has too few points, the lines do not meet, or they meet
/// farther than maxShift from the candidate point.
bool refitNearLines(const float* wx, const float* wy, std::size_t count, const RefitLimits& lim,
                    Corner& corner) noexcept {
  const float ccx = lim.mxAbs + corner.x;
  const float ccy = lim.myAbs + corner.y;
  LineAcc l;
  LineAcc r;
  for (std::size_t q = 0; q < count; ++q) {
    const float qx = wx[q];
    const float qy = wy[q];
    const float ex = qx - corner.x;
    const float ey = qy - corner.y;
    const float e2 = ex * ex + ey * ey;
    if (e2 > lim.reach2 || e2 < lim.gap2) {
      continue;
    }
    // Sign of cross(corner, point) in the sensor frame: negative = clockwise = earlier beam.
    const bool isLeft = ccx * (lim.myAbs + qy) - ccy * (lim.mxAbs + qx) < 0.0F;
    const Line& ln = isLeft ? corner.left : corner.right;
    const float dist = std::fabs(ln.dx * (qy - ln.my) - ln.dy * (qx - ln.mx));
    if (dist > lim.tol) {
      continue;
    }
    (isLeft ? l : r).add(qx, qy);
  }
  Line nl;
  Line nr;
  float c2x = 0.0F;
  float c2y = 0.0F;
  if (!(l.n >= lim.minPts && r.n >= lim.minPts && l.fit(nl) && r.fit(nr) && intersect(nl, nr, c2x, c2y) &&
        c2x * c2x + c2y * c2y <= lim.maxShift2)) {
    return false;
  }
  corner.x = c2x;
  corner.y = c2y;
  corner.left = nl;
  corner.right = nr;
  return true;
}

/// Orientation: mean direction from the corner to the centroids of its two sides. Refined corners
/// use the centroids of the points of each fitted wall, as unit vectors: the bisector of the
/// corner, independent of how much of each wall the sensor sees. Unrefined ones use the
/// neighbourhood sides (sideX, sideY) as they are.
float orientationOf(bool refined, const Corner& c, float sideX, float sideY) noexcept {
  float ox = 0.0F;
  float oy = 0.0F;
  if (refined) {
    const float lx = c.left.mx - c.x;
    const float ly = c.left.my - c.y;
    const float rx = c.right.mx - c.x;
    const float ry = c.right.my - c.y;
    const float ln = std::sqrt(lx * lx + ly * ly);
    const float rn = std::sqrt(rx * rx + ry * ry);
    if (ln > 0.0F && rn > 0.0F) {
      ox = lx / ln + rx / rn;
      oy = ly / ln + ry / rn;
    }
  }
  if (ox == 0.0F && oy == 0.0F) {
    ox = sideX - 2.0F * c.x;
    oy = sideY - 2.0F * c.y;
  }
  return std::atan2(oy, ox);
}

}  // namespace

FalkoDetector::RefineOutcome FalkoDetector::refine(const ScanPoints& pts, std::size_t i, float sideX, float sideY,
                                                   FalkoKeypoint& kp) noexcept {
  const float maxShift2 = params_.subbeamMaxShift * params_.subbeamMaxShift;
  const float reach = params_.refineRadiusFactor * kp.radius;
  float* wx = leftX_.data();  // the side buffers hold the window (the side sums are in sideX/Y)
  float* wy = leftY_.data();
  // Pass 1, window: the points within refineRadiusFactor * r of the candidate, in beam order.
  const RefineWindow w = collectWindow(pts, i, reach, params_.subbeamMaxShift, wx, wy);
  // Pass 1, split: the two lines that explain the window with the least residual.
  const LineAcc total = windowSums(wx, wy, w.mLeft, w.count);
  LineAcc bestL;
  LineAcc bestR;
  const float bestCost = bestSplit(wx, wy, w, total, params_.minSidePoints + 1, bestL, bestR);
  // Pass 1, acceptance: one line explaining the window almost as well as two is a noisy straight
  // wall, not a corner (an addition to the thesis). Two walls meeting farther than
  // subbeamMaxShift away are reported as FarCorner with that meeting point in (kp.x, kp.y): the
  // caller decides whether the beam point is kept (the thesis keeps it, unrefined).
  const bool splitFound = bestCost < std::numeric_limits<float>::infinity();
  if (splitFound && total.residual() <= params_.minCornerResidualRatio * bestCost) {
    return RefineOutcome::Rejected;
  }
  Corner corner;
  const bool ok = splitFound && bestL.fit(corner.left) && bestR.fit(corner.right) &&
                  intersect(corner.left, corner.right, corner.x, corner.y);
  if (ok && corner.x * corner.x + corner.y * corner.y > maxShift2) {
    kp.x = pts.x(i) + corner.x;
    kp.y = pts.y(i) + corner.y;
    return RefineOutcome::FarCorner;
  }
  if (ok) {
    // Passes 2 and 3: the neighbourhood holds few points per side at long range, and the
    // candidate beam may lie a beam or two off the corner. Re-split the points of a wider disc at
    // the bearing of the estimated corner, keep those close to their side's line and not within
    // 1.5 beam spacings of the corner, and fit again.
    const float gap = 1.5F * pts.range(i) * pts.angleIncrement();
    RefitLimits lim;
    lim.mxAbs = pts.x(i);
    lim.myAbs = pts.y(i);
    lim.reach2 = reach * reach;
    lim.gap2 = gap * gap;
    lim.tol = params_.refineInlierDistance;
    lim.minPts = static_cast<float>(params_.minSidePoints);
    lim.maxShift2 = maxShift2;
    for (int pass = 0; pass < 2; ++pass) {
      if (!refitNearLines(wx, wy, w.count, lim, corner)) {
        break;
      }
    }
  } else {
    corner.x = 0.0F;
    corner.y = 0.0F;
  }
  // Acceptance: the corner in the sensor frame, and its orientation.
  kp.refined = ok;
  kp.x = pts.x(i) + corner.x;
  kp.y = pts.y(i) + corner.y;
  kp.orientation = orientationOf(ok, corner, sideX, sideY);
  return RefineOutcome::Accepted;
}

namespace {
/// Triangle front (fx, fy) / candidate (origin) / back (bx, by): base and height at least minLen.
bool triangleHolds(float minLen, float fx, float fy, float bx, float by) noexcept {
  const float base2 = (bx - fx) * (bx - fx) + (by - fy) * (by - fy);
  if (base2 < minLen * minLen) {
    return false;
  }
  const float cross = fx * by - fy * bx;  // = base * height
  return !(cross * cross < base2 * minLen * minLen);
}

/// Side extents of a survivor packed in one word (both below 2^16).
std::uint32_t packExtents(std::size_t kLeft, std::size_t kRight) noexcept {
  return static_cast<std::uint32_t>(kLeft << 16U | kRight);
}
static_assert(kMaxScanBeams < (std::size_t{1} << 16U), "side extents are packed in 16 bits");
}  // namespace

void FalkoDetector::radiiAndWindows(const ScanPoints& pts) noexcept {
  const FalkoParams& p = params_;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const float rho = pts.range(i);
    float radius = p.neighA * std::exp(p.neighB * rho);
    const float maxRadius = p.maxRadiusRangeRatio * rho;
    if (radius > maxRadius) {
      radius = maxRadius;
    }
    const bool candidate = pts.valid(i) && !(rho < p.minExtractionRange || rho > p.maxExtractionRange);
    radius_[i] = radius;
    window_[i] = candidate ? static_cast<std::uint32_t>(pts.maxOffsetAt(i, radius)) : 0U;
  }
}

std::size_t FalkoDetector::rejectOneByOne(const ScanPoints& pts, std::size_t begin, std::size_t end, float invBeta,
                                          std::size_t survivors) noexcept {
  for (std::size_t i = begin; i < end; ++i) {
    score_[i] = kNotCandidate;
    const std::size_t kmax = window_[i];
    if (kmax == 0) {
      continue;
    }
    const float r2 = radius_[i] * radius_[i];
    float fx = 0.0F;
    float fy = 0.0F;
    float bx = 0.0F;
    float by = 0.0F;
    const std::size_t kLeft = farthestWithin(pts, i, -1, kmax, r2, fx, fy);
    if (kLeft == 0) {
      continue;
    }
    const std::size_t kRight = farthestWithin(pts, i, 1, kmax, r2, bx, by);
    if (kRight == 0 || !triangleHolds(radius_[i] * invBeta, fx, fy, bx, by)) {
      continue;
    }
    order_[survivors++] = static_cast<std::uint32_t>(i);
    window_[i] = packExtents(kLeft, kRight);
  }
  return survivors;
}

std::size_t FalkoDetector::rejectInFours(const ScanPoints& pts, float invBeta, std::size_t& next) noexcept {
  const std::size_t n = pts.size();
  const float* xs = pts.xData();
  const float* ys = pts.yData();
  std::size_t survivors = 0;
  std::size_t i0 = 0;
  for (; i0 + 4 <= n; i0 += 4) {
    const std::size_t kTop =
        std::max(std::max(window_[i0], window_[i0 + 1]), std::max(window_[i0 + 2], window_[i0 + 3]));
    if (kTop == 0 || kTop > i0 || i0 + 3 + kTop >= n) {
      survivors = rejectOneByOne(pts, i0, i0 + 4, invBeta, survivors);  // a window reaches a scan end
      continue;
    }
    float kmax[4];
    float r2[4];
    for (std::size_t l = 0; l < 4; ++l) {
      score_[i0 + l] = kNotCandidate;
      kmax[l] = static_cast<float>(window_[i0 + l]);
      r2[l] = radius_[i0 + l] * radius_[i0 + l];
    }
    float left[4];
    float right[4];
    falko_detail::farthestWithin4(xs, ys, i0, -1, kTop, kmax, r2, left);
    if (left[0] == 0.0F && left[1] == 0.0F && left[2] == 0.0F && left[3] == 0.0F) {
      continue;
    }
    falko_detail::farthestWithin4(xs, ys, i0, 1, kTop, kmax, r2, right);
    for (std::size_t l = 0; l < 4; ++l) {
      if (left[l] == 0.0F || right[l] == 0.0F) {
        continue;
      }
      const std::size_t i = i0 + l;
      const auto kLeft = static_cast<std::size_t>(static_cast<int>(left[l]));
      const auto kRight = static_cast<std::size_t>(static_cast<int>(right[l]));
      if (triangleHolds(radius_[i] * invBeta, xs[i - kLeft] - xs[i], ys[i - kLeft] - ys[i], xs[i + kRight] - xs[i],
                        ys[i + kRight] - ys[i])) {
        order_[survivors++] = static_cast<std::uint32_t>(i);
        window_[i] = packExtents(kLeft, kRight);
      }
    }
  }
  next = i0;
  return survivors;
}

std::size_t FalkoDetector::rejectEarly(const ScanPoints& pts) noexcept {
  const float invBeta = 1.0F / params_.beta;
  // Four candidates at a time where the lockstep search exists; one at a time elsewhere and for
  // the last beams. Both give the same survivors.
  std::size_t i0 = 0;
  const std::size_t survivors = falko_detail::kLockstep4 ? rejectInFours(pts, invBeta, i0) : 0;
  return rejectOneByOne(pts, i0, pts.size(), invBeta, survivors);
}

std::size_t FalkoDetector::scoreSurvivors(const ScanPoints& pts, std::size_t survivors) noexcept {
  std::size_t candidates = 0;
  for (std::size_t o = 0; o < survivors; ++o) {
    const std::size_t i = order_[o];
    const float radius = radius_[i];
    Side left;
    Side right;
    if (!gather(pts, i, radius, window_[i] >> 16U, window_[i] & 0xFFFFU, left, right)) {
      continue;
    }
    const float ox = left.sumX / static_cast<float>(left.count) + right.sumX / static_cast<float>(right.count);
    const float oy = left.sumY / static_cast<float>(left.count) + right.sumY / static_cast<float>(right.count);
    const float on = std::sqrt(ox * ox + oy * oy);
    if (!(on > 1.0e-6F * radius)) {
      continue;
    }
    const float score = scoreOf(left, right, ox / on, oy / on);
    if (score <= params_.maxScore) {
      score_[i] = score;
      sideX_[i] = ox;
      sideY_[i] = oy;
      ++candidates;
    }
  }
  return candidates;
}

std::size_t FalkoDetector::candidatesByScore(std::size_t n) noexcept {
  std::size_t nc = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (score_[i] != kNotCandidate) {
      order_[nc++] = static_cast<std::uint32_t>(i);
    }
  }
  const float* sc = score_.data();
  std::sort(order_.begin(), order_.begin() + static_cast<std::ptrdiff_t>(nc),
            [sc](std::uint32_t a, std::uint32_t b) { return sc[a] < sc[b] || (sc[a] == sc[b] && a < b); });
  return nc;
}

bool FalkoDetector::nearAccepted(float x, float y, std::size_t kept, float nms2) const noexcept {
  for (std::size_t c = 0; c < kept; ++c) {
    const float dx = cands_[c].x - x;
    const float dy = cands_[c].y - y;
    if (dx * dx + dy * dy <= nms2) {
      return true;
    }
  }
  return false;
}

std::size_t FalkoDetector::suppressAndRefine(const ScanPoints& pts, std::size_t candidates) noexcept {
  const float nms2 = params_.nmsRadius * params_.nmsRadius;
  std::size_t kept = 0;
  // Pass 1: refined corners. Candidates whose walls meet farther than subbeamMaxShift away are
  // dropped, or with keepFarCorners set aside in order_[0, farCount) (d <= o: compaction in
  // place, still best score first), the meeting point of their walls in rightX_/rightY_ (free
  // after the scoring stage).
  std::size_t farCount = 0;
  for (std::size_t o = 0; o < candidates; ++o) {
    const std::size_t i = order_[o];
    if (nearAccepted(pts.x(i), pts.y(i), kept, nms2)) {
      continue;
    }
    FalkoKeypoint kp;
    kp.beamIndex = static_cast<std::uint32_t>(i);
    kp.radius = radius_[i];
    kp.score = score_[i];
    const RefineOutcome r = refine(pts, i, sideX_[i], sideY_[i], kp);
    if (r == RefineOutcome::Accepted && !nearAccepted(kp.x, kp.y, kept, nms2)) {
      cands_[kept++] = kp;
    } else if (r == RefineOutcome::FarCorner && params_.keepFarCorners) {
      rightX_[farCount] = kp.x;
      rightY_[farCount] = kp.y;
      order_[farCount++] = static_cast<std::uint32_t>(i);
    }
  }
  // Pass 2: the set-aside candidates at their beam point, unrefined (thesis), unless the beam
  // point or the meeting point of its walls lies within nmsRadius of an accepted corner: next to
  // a corner found in pass 1 (typically beside an acute one) the candidate only sees that corner.
  for (std::size_t d = 0; d < farCount; ++d) {
    const std::size_t i = order_[d];
    if (nearAccepted(pts.x(i), pts.y(i), kept, nms2) || nearAccepted(rightX_[d], rightY_[d], kept, nms2)) {
      continue;
    }
    FalkoKeypoint kp;
    kp.beamIndex = static_cast<std::uint32_t>(i);
    kp.radius = radius_[i];
    kp.score = score_[i];
    kp.x = pts.x(i);
    kp.y = pts.y(i);
    kp.refined = false;
    kp.orientation = std::atan2(sideY_[i], sideX_[i]);
    cands_[kept++] = kp;
  }
  return kept;
}

Status FalkoDetector::emitInBeamOrder(std::size_t kept, IVector<FalkoKeypoint>& out) noexcept {
  std::sort(cands_.begin(), cands_.begin() + static_cast<std::ptrdiff_t>(kept),
            [](const FalkoKeypoint& a, const FalkoKeypoint& b) { return a.beamIndex < b.beamIndex; });
  Status result = Status::Ok;
  for (std::size_t c = 0; c < kept; ++c) {
    if (!isOk(out.push_back(cands_[c]))) {
      result = Status::CapacityExceeded;
    }
  }
  return result;
}

Status FalkoDetector::detect(const ScanPoints& pts, IVector<FalkoKeypoint>& out) noexcept {
  out.clear();
  candidateCount_ = 0;
  if (!isValid(params_)) {
    return Status::InvalidArgument;
  }
  // 0. Radius and beam window of every beam, in a loop of its own: the exponential and the window
  //    bound then overlap from beam to beam instead of waiting behind the searches below.
  radiiAndWindows(pts);
  // 1. Early rejection by the triangle test, four candidates in lockstep where possible; the
  //    survivors are listed in order_ with their side extents packed in window_.
  const std::size_t survivors = rejectEarly(pts);
  // 2. Sides and score of the survivors; the candidates keep their score in score_.
  candidateCount_ = scoreSurvivors(pts, survivors);
  // 3. Non-maxima suppression, best score first, with the sub-beam refinement of every candidate
  //    not suppressed.
  const std::size_t kept = suppressAndRefine(pts, candidatesByScore(pts.size()));
  // 4. Output in beam order.
  return emitInBeamOrder(kept, out);
}

}  // namespace agv
