#include "agv/lidar3d/normal_signature.hpp"

#include <cmath>

namespace agv {

std::size_t normalBin(float nz) noexcept {
  constexpr float kHalf = static_cast<float>(kNormalSignatureBins - 1) / 2.0F;  // 50
  const float x = (nz + 1.0F) * kHalf + 0.5F;
  if (!(x > 0.0F)) {  // also NaN
    return 0;
  }
  const auto b = static_cast<std::size_t>(x);
  return b < kNormalSignatureBins ? b : kNormalSignatureBins - 1;
}

Status computeNormalSignature(const RangeImageBase& image, const NormalSignatureParams& params,
                              NormalSignature& out) noexcept {
  out = NormalSignature{};
  if (!isValid(params.normals) || image.columns() <= 2 * params.normals.firingStep) {
    return Status::InvalidArgument;
  }
  if (image.validCount() == 0) {
    return Status::EmptyInput;
  }
  std::array<std::uint32_t, kNormalSignatureBins> counts{};
  const std::size_t rows = image.rows();
  const std::size_t cols = image.columns();
  for (std::size_t r = 0; r < rows; ++r) {
    for (std::size_t c = 0; c < cols; ++c) {
      if (!image.at(r, c).valid()) {
        continue;  // no return: not counted (most cells of a sparse image)
      }
      Eigen::Vector3f n;
      switch (beamNormal(image, r, c, params.normals, n)) {
        case NormalSkip::None:
          ++counts[normalBin(n.z())];
          ++out.counts.normals;
          break;
        case NormalSkip::OutOfRange:
          ++out.counts.outOfRange;
          break;
        case NormalSkip::MissingNeighbour:
          ++out.counts.missingNeighbour;
          break;
        case NormalSkip::NeighbourTooFar:
          ++out.counts.neighbourTooFar;
          break;
        case NormalSkip::Degenerate:
          ++out.counts.degenerate;
          break;
      }
    }
  }
  if (out.counts.normals == 0 || out.counts.normals < params.minNormals) {
    const NormalCounts seen = out.counts;
    out = NormalSignature{};
    out.counts = seen;
    out.counts.belowMinimum = seen.normals;
    out.counts.normals = 0;
    return Status::NotEnoughData;
  }
  const float inv = 1.0F / static_cast<float>(out.counts.normals);
  for (std::size_t b = 0; b < kNormalSignatureBins; ++b) {
    out.bins[b] = static_cast<float>(counts[b]) * inv;
  }
  return Status::Ok;
}

float chiSquareDistance(const NormalSignature& a, const NormalSignature& b) noexcept {
  float d = 0.0F;
  for (std::size_t i = 0; i < kNormalSignatureBins; ++i) {
    const float diff = a.bins[i] - b.bins[i];
    d += diff * diff / (a.bins[i] + b.bins[i] + 1.0F);
  }
  return d;
}

float sorensenDistance(const NormalSignature& a, const NormalSignature& b) noexcept {
  float num = 0.0F;
  float den = 0.0F;
  for (std::size_t i = 0; i < kNormalSignatureBins; ++i) {
    num += std::fabs(a.bins[i] - b.bins[i]);
    den += a.bins[i] + b.bins[i];
  }
  return den > 0.0F ? num / den : 0.0F;
}

}  // namespace agv
