#include "agv/datasets/trajectory_error.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>

#include "agv/core/angle.hpp"

namespace agv {
namespace datasets {

ErrorStats errorStats(std::vector<double> v) {
  ErrorStats s;
  s.count = v.size();
  if (v.empty()) {
    return s;
  }
  double sum = 0.0;
  double sq = 0.0;
  for (double x : v) {
    sum += x;
    sq += x * x;
    s.max = std::max(s.max, x);
  }
  s.mean = sum / static_cast<double>(v.size());
  s.rms = std::sqrt(sq / static_cast<double>(v.size()));
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  s.median = v[mid];
  if (v.size() % 2 == 0) {
    const double lower = *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid));
    s.median = 0.5 * (s.median + lower);
  }
  return s;
}

RelativeError relativeError(const std::vector<Pose2d>& truth, const std::vector<Pose2d>& estimate, double length) {
  const std::size_t n = std::min(truth.size(), estimate.size());
  std::vector<double> cum(n, 0.0);
  for (std::size_t i = 1; i < n; ++i) {
    cum[i] = cum[i - 1] + std::hypot(truth[i].x - truth[i - 1].x, truth[i].y - truth[i - 1].y);
  }
  std::vector<double> pos;
  std::vector<double> head;
  std::size_t j = 0;
  for (std::size_t i = 0; i < n; ++i) {
    j = std::max(j, i);
    while (j < n && cum[j] - cum[i] < length) {
      ++j;
    }
    if (j >= n) {
      break;
    }
    const Pose2d gt = between(truth[i], truth[j]);
    const Pose2d est = between(estimate[i], estimate[j]);
    const Pose2d e = between(gt, est);
    pos.push_back(std::hypot(e.x, e.y));
    head.push_back(std::fabs(normalizeAngle(e.theta)));
  }
  return RelativeError{errorStats(pos), errorStats(head)};
}

AbsoluteError absoluteError(const std::vector<Pose2d>& truth, const std::vector<Pose2d>& estimate) {
  const std::size_t n = std::min(truth.size(), estimate.size());
  std::vector<double> pos;
  std::vector<double> head;
  if (n == 0) {
    return {};
  }
  const Pose2d align = truth[0].compose(estimate[0].inverse());
  for (std::size_t i = 0; i < n; ++i) {
    const Pose2d e = align.compose(estimate[i]);
    pos.push_back(std::hypot(e.x - truth[i].x, e.y - truth[i].y));
    head.push_back(std::fabs(normalizeAngle(e.theta - truth[i].theta)));
  }
  return AbsoluteError{errorStats(pos), errorStats(head)};
}

AbsoluteError absoluteErrorOf(const std::vector<Pose2d>& truth, const std::vector<Pose2d>& estimate,
                              const std::vector<bool>& select) {
  std::vector<double> pos;
  std::vector<double> head;
  const std::size_t n = std::min({truth.size(), estimate.size(), select.size()});
  for (std::size_t i = 0; i < n; ++i) {
    if (select[i]) {
      pos.push_back(std::hypot(estimate[i].x - truth[i].x, estimate[i].y - truth[i].y));
      head.push_back(std::fabs(normalizeAngle(estimate[i].theta - truth[i].theta)));
    }
  }
  return AbsoluteError{errorStats(pos), errorStats(head)};
}

}  // namespace datasets
}  // namespace agv
