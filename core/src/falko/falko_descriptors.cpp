#include "agv/falko/falko_descriptors.hpp"

#include <cmath>

#include "agv/core/angle.hpp"
#include "falko_math.hpp"

namespace agv {

namespace {
unsigned popcount16(std::uint16_t v) noexcept {
  unsigned x = v;
  x = x - ((x >> 1U) & 0x5555U);
  x = (x & 0x3333U) + ((x >> 2U) & 0x3333U);
  x = (x + (x >> 4U)) & 0x0F0FU;
  return (x + (x >> 8U)) & 0x1FU;
}
static_assert(kBscSectors == 16, "BSC rings are 16-bit masks and use the 16-sector fast path");
static_assert(kBscRings == 8, "the ring search in describe takes three halving steps over 7 boundaries");
}  // namespace

std::uint32_t bscDistance(const BscDescriptor& a, const BscDescriptor& b) noexcept {
  std::uint32_t d = 0;
  for (std::size_t r = 0; r < kBscRings; ++r) {
    d += popcount16(static_cast<std::uint16_t>(a.rings[r] ^ b.rings[r]));
  }
  return d;
}

float cghDistance(const CghDescriptor& a, const CghDescriptor& b) noexcept {
  float sum = 0.0F;
  for (std::size_t k = 0; k < kCghBins; ++k) {
    const float s = a.bins[k] + b.bins[k];
    if (s > 0.0F) {
      const float d = a.bins[k] - b.bins[k];
      sum += d * d / s;
    }
  }
  return 0.5F * sum;
}

FalkoDescriber::FalkoDescriber(const FalkoDescriptorParams& params) noexcept : params_(params) {
  valid_ = std::isfinite(params.radius) && params.radius > 0.0F && std::isfinite(params.cghSigmaBins) &&
           params.cghSigmaBins > 0.0F;
  if (!valid_) {
    return;
  }
  // Discrete Gaussian over +-3 bins (weight at 3 bins with sigma 0.6: 4e-6 of the centre),
  // normalised to sum 1 so that each point contributes 1 before the histogram normalisation.
  float sum = 0.0F;
  const float inv2s2 = 0.5F / (params.cghSigmaBins * params.cghSigmaBins);
  for (std::size_t k = 0; k < kernel_.size(); ++k) {
    const float d = static_cast<float>(k) - static_cast<float>(kKernelHalfWidth);
    kernel_[k] = std::exp(-d * d * inv2s2);
    sum += kernel_[k];
  }
  for (float& w : kernel_) {
    w /= sum;
  }
  for (std::size_t b = 0; b + 1 < kBscRings; ++b) {
    const float rb = params.radius * static_cast<float>(b + 1) / static_cast<float>(kBscRings);
    ringBound2_[b] = rb * rb;
  }
}

Status FalkoDescriber::describe(const ScanPoints& points, const FalkoKeypoint& keypoint, BscDescriptor& bsc,
                                CghDescriptor& cgh) const noexcept {
  bsc = BscDescriptor{};
  cgh = CghDescriptor{};
  if (!valid_) {
    return Status::InvalidArgument;
  }
  const std::size_t n = points.size();
  const std::size_t i = keypoint.beamIndex;
  if (i >= n) {
    return Status::OutOfRange;
  }
  if (!std::isfinite(keypoint.x) || !std::isfinite(keypoint.y) || !std::isfinite(keypoint.orientation)) {
    return Status::NonFiniteInput;
  }
  const float R = params_.radius;
  const float r2 = R * R;
  const float px = keypoint.x;
  const float py = keypoint.y;
  const float c = std::cos(keypoint.orientation);
  const float s = std::sin(keypoint.orientation);
  const float binsPerRadian = static_cast<float>(kCghBins) / kTwoPi<float>;
  std::array<std::uint16_t, kCghBins> counts{};

  // Points within R of the keypoint lie within R + shift of its beam point; the beams that can
  // hold one are visited in plain index runs (the set, not the order, matters: cells and counts
  // commute). Invalid readings sit at ScanPoints::kFarAway: the disc test drops them without a
  // branch of their own. Only the points inside the disc take the sector and ring work.
  const float sx = px - points.x(i);
  const float sy = py - points.y(i);
  const float reach = R + std::sqrt(sx * sx + sy * sy);
  const std::size_t kmax = points.maxOffsetAt(i, reach);
  std::size_t runBegin[2];
  std::size_t runEnd[2];
  const std::size_t runs = falko_detail::beamRuns(points, i, kmax, runBegin, runEnd);
  const float* xs = points.xData();
  const float* ys = points.yData();
  for (std::size_t run = 0; run < runs; ++run) {
    for (std::size_t j = runBegin[run]; j < runEnd[run]; ++j) {
      const float dx = xs[j] - px;
      const float dy = ys[j] - py;
      const float d2 = dx * dx + dy * dy;
      if (d2 > r2 || d2 < 1.0e-12F) {
        continue;
      }
      // Rotate into the keypoint frame (x along the orientation).
      const float u = dx * c + dy * s;
      const float v = dy * c - dx * s;
      // Branch-free where a vector unit exists (its quadrant branches mispredict on x86); the
      // branchy form takes fewer instructions on in-order cores.
      const unsigned sector =
          falko_detail::kFourWide ? falko_detail::sector16Branchless(u, v) : falko_detail::sector16(u, v);
      // Ring from squared distance: count the ring boundaries below (no square root).
      // Three halving steps over the 7 sorted boundaries, without branches.
      unsigned ring = d2 >= ringBound2_[3] ? 4U : 0U;
      ring += d2 >= ringBound2_[ring + 1U] ? 2U : 0U;
      ring += d2 >= ringBound2_[ring] ? 1U : 0U;
      bsc.rings[ring] = static_cast<std::uint16_t>(bsc.rings[ring] | (1U << sector));
      const unsigned bin = kCghBins == kBscSectors
                               ? sector
                               : falko_detail::sectorOf(v, u, binsPerRadian, static_cast<unsigned>(kCghBins));
      ++counts[bin];
    }
  }

  float total = 0.0F;
  for (std::size_t b = 0; b < kCghBins; ++b) {
    if (counts[b] == 0U) {
      continue;
    }
    const auto cnt = static_cast<float>(counts[b]);
    for (std::size_t k = 0; k < kernel_.size(); ++k) {
      const std::size_t t = (b + kCghBins + k - kKernelHalfWidth) % kCghBins;
      cgh.bins[t] += cnt * kernel_[k];
    }
    total += cnt;
  }
  if (total > 0.0F) {
    const float inv = 1.0F / total;
    for (float& h : cgh.bins) {
      h *= inv;
    }
  }
  return Status::Ok;
}

Status FalkoDescriber::describe(const ScanPoints& points, const IVector<FalkoKeypoint>& keypoints,
                                IVector<BscDescriptor>& bsc, IVector<CghDescriptor>& cgh) const noexcept {
  bsc.clear();
  cgh.clear();
  if (!valid_) {
    return Status::InvalidArgument;
  }
  Status result = Status::Ok;
  for (const FalkoKeypoint& kp : keypoints) {
    BscDescriptor b;
    CghDescriptor g;
    const Status st = describe(points, kp, b, g);
    if (!isOk(st) && isOk(result)) {
      result = st;
    }
    if (!isOk(bsc.push_back(b))) {
      result = Status::CapacityExceeded;
    }
    if (!isOk(cgh.push_back(g))) {
      result = Status::CapacityExceeded;
    }
  }
  return result;
}

}  // namespace agv
