#include "agv/calib/rigid_fit.hpp"

#include <cmath>
#include <cstddef>

namespace agv {

Pose2d fitRigid2d(Span<const Eigen::Vector2d> first, Span<const Eigen::Vector2d> second,
                  Span<const std::uint16_t> pairOf) noexcept {
  Eigen::Vector2d cf = Eigen::Vector2d::Zero();
  Eigen::Vector2d cs = Eigen::Vector2d::Zero();
  std::size_t count = 0;
  const std::size_t n = second.size() < pairOf.size() ? second.size() : pairOf.size();
  for (std::size_t j = 0; j < n; ++j) {
    if (pairOf[j] != kNoPair && pairOf[j] < first.size()) {
      cf += first[pairOf[j]];
      cs += second[j];
      ++count;
    }
  }
  if (count == 0) {
    return Pose2d{};
  }
  cf /= static_cast<double>(count);
  cs /= static_cast<double>(count);
  double dot = 0.0;
  double cross = 0.0;
  for (std::size_t j = 0; j < n; ++j) {
    if (pairOf[j] != kNoPair && pairOf[j] < first.size()) {
      const Eigen::Vector2d q = second[j] - cs;
      const Eigen::Vector2d p = first[pairOf[j]] - cf;
      dot += q.dot(p);
      cross += q.x() * p.y() - q.y() * p.x();
    }
  }
  const double phi = std::atan2(cross, dot);
  const double c = std::cos(phi);
  const double s = std::sin(phi);
  return Pose2d{cf.x() - (c * cs.x() - s * cs.y()), cf.y() - (s * cs.x() + c * cs.y()), phi};
}

double rigidFitRms(Span<const Eigen::Vector2d> first, Span<const Eigen::Vector2d> second,
                   Span<const std::uint16_t> pairOf, const Pose2d& motion) noexcept {
  double sum = 0.0;
  std::size_t count = 0;
  const std::size_t n = second.size() < pairOf.size() ? second.size() : pairOf.size();
  for (std::size_t j = 0; j < n; ++j) {
    if (pairOf[j] != kNoPair && pairOf[j] < first.size()) {
      sum += (first[pairOf[j]] - motion.transformPoint(second[j])).squaredNorm();
      ++count;
    }
  }
  return count > 0 ? std::sqrt(sum / static_cast<double>(count)) : 0.0;
}

}  // namespace agv
