#include "agv/lidar3d/beam_normals.hpp"

#include <Eigen/Geometry>
#include <cmath>

namespace agv {

bool isValid(const BeamNormalParams& p) noexcept {
  return p.firingStep >= 1 && p.laserStep >= 1 && std::isfinite(p.minRange) && std::isfinite(p.maxRange) &&
         p.minRange >= 0.0F && p.minRange < p.maxRange && std::isfinite(p.maxNeighbourRatio) &&
         p.maxNeighbourRatio > 0.0F && std::isfinite(p.minSine) && p.minSine >= 0.0F && p.minSine < 1.0F;
}

NormalSkip beamNormal(const RangeImageBase& image, std::size_t row, std::size_t column, const BeamNormalParams& params,
                      Eigen::Vector3f& normal) noexcept {
  const RangeCell& c = image.at(row, column);
  if (!c.valid() || c.range < params.minRange || c.range > params.maxRange) {
    return NormalSkip::OutOfRange;
  }
  const std::size_t cols = image.columns();
  if (row < params.laserStep || row + params.laserStep >= image.rows()) {
    return NormalSkip::MissingNeighbour;
  }
  const std::size_t k = params.firingStep;  // < cols / 2 (precondition)
  const RangeCell& before = image.at(row, column >= k ? column - k : column + cols - k);
  const RangeCell& after = image.at(row, column + k < cols ? column + k : column + k - cols);
  const RangeCell& below = image.at(row - params.laserStep, column);
  const RangeCell& above = image.at(row + params.laserStep, column);
  if (!before.valid() || !after.valid() || !below.valid() || !above.valid()) {
    return NormalSkip::MissingNeighbour;
  }
  const float maxGap2 = (params.maxNeighbourRatio * c.range) * (params.maxNeighbourRatio * c.range);
  if ((before.point - c.point).squaredNorm() > maxGap2 || (after.point - c.point).squaredNorm() > maxGap2 ||
      (below.point - c.point).squaredNorm() > maxGap2 || (above.point - c.point).squaredNorm() > maxGap2) {
    return NormalSkip::NeighbourTooFar;
  }
  const Eigen::Vector3f u = after.point - before.point;
  const Eigen::Vector3f v = above.point - below.point;
  Eigen::Vector3f n = u.cross(v);
  const float n2 = n.squaredNorm();
  const float uv2 = u.squaredNorm() * v.squaredNorm();
  // |u x v| = |u| |v| sin(angle): compare squares (no sqrt for the test).
  if (!(n2 > params.minSine * params.minSine * uv2) || !(n2 > 0.0F)) {
    return NormalSkip::Degenerate;
  }
  n /= std::sqrt(n2);
  if (n.dot(c.point) > 0.0F) {
    n = -n;
  }
  normal = n;
  return NormalSkip::None;
}

}  // namespace agv
