#pragma once
// Small physically simulated world for the localizer tests (host only): point landmarks
// (reflector poles, corners), a tricycle vehicle driven along a path with the exact arc model,
// a drive encoder with tick quantisation and wheel slip, a noisy steering encoder, and a laser at a
// mounting pose that sees the landmarks within range and field of view with range/bearing noise,
// missed detections and spurious points. The scan reaches the localizer `lagSeconds` after it was
// taken, while odometry keeps flowing.
#include <cmath>
#include <cstdint>
#include <deque>
#include <random>
#include <vector>

#include "agv/kinematics/tricycle.hpp"
#include "agv/localization/localizer.hpp"

namespace agv::sim {

struct WorldLandmark {
  double x, y;
  LandmarkKind kind;
};

struct SimNoise {
  double slipVariancePerMetre = 4e-6;  // true wheel slip (random walk in distance)
  double steeringSigma = 0.1 * kPi<double> / 180.0;
  double rangeSigma = 0.005;
  double bearingSigma = 0.0005;
  double missProbability = 0.0;
  double spuriousFraction = 0.0;  // spurious points per real detection
  double cornerSigma = 0.01;      // extra isotropic noise of a corner (FALKO keypoint) position
};

/// Path: steering angle as a function of distance along the path, and a trapezoidal speed profile.
struct PathSpec {
  double length = 12.0;  // [m]
  double vmax = 1.0;     // [m/s]
  double accel = 0.5;    // [m/s^2]
  // piecewise: steering changes linearly between knots (distance [m], steering [rad])
  std::vector<std::pair<double, double>> steering;
  double steerAt(double s) const {
    if (steering.empty())
      return 0.0;
    if (s <= steering.front().first)
      return steering.front().second;
    for (std::size_t i = 1; i < steering.size(); ++i) {
      if (s <= steering[i].first) {
        const double f = (s - steering[i - 1].first) / (steering[i].first - steering[i - 1].first);
        return steering[i - 1].second + f * (steering[i].second - steering[i - 1].second);
      }
    }
    return steering.back().second;
  }
};

/// 12 m: 4 m straight, a left turn of about 90 deg, straight to the end.
inline PathSpec path12m() {
  PathSpec p;
  p.length = 12.0;
  const double a = 30.0 * kPi<double> / 180.0;
  // turn of ds*sin(a)/L = 90 deg -> ds = (pi/2)*1.5/sin(30) = 4.71 m
  p.steering = {{3.5, 0.0}, {4.0, a}, {8.2, a}, {8.7, 0.0}, {12.0, 0.0}};
  return p;
}
/// 7 m: an S-curve into a corridor.
inline PathSpec path7m() {
  PathSpec p;
  p.length = 7.0;
  const double a = 20.0 * kPi<double> / 180.0;
  p.steering = {{1.0, 0.0}, {1.5, a}, {2.8, a}, {3.3, -a}, {4.6, -a}, {5.1, 0.0}, {7.0, 0.0}};
  return p;
}

/// Reflector poles on both sides of a 40 m x 30 m hall around the paths (every 4 m, 2.5 m off the
/// aisle lines), plus the hall walls.
inline std::vector<WorldLandmark> reflectorWorld() {
  std::vector<WorldLandmark> w;
  for (double x = -6.0; x <= 26.0; x += 4.0) {
    w.push_back({x, -3.0, LandmarkKind::Reflector});
    w.push_back({x + 2.0, 3.5, LandmarkKind::Reflector});
    w.push_back({x + 1.0, 12.0, LandmarkKind::Reflector});
  }
  for (double y = -2.0; y <= 14.0; y += 4.0) {
    w.push_back({-8.0, y, LandmarkKind::Reflector});
    w.push_back({14.0, y + 1.0, LandmarkKind::Reflector});
  }
  return w;
}

/// Block-storage corridor: rack posts every 2.7 m on both sides of a 4 m aisle (one FALKO corner
/// each) and the hall's wall corners further out.
inline std::vector<WorldLandmark> cornerWorld() {
  std::vector<WorldLandmark> w;
  for (double x = -4.0; x <= 24.0; x += 2.7) {
    w.push_back({x, -2.0, LandmarkKind::Corner});
    w.push_back({x + 1.2, 2.6, LandmarkKind::Corner});
  }
  for (double x = -6.0; x <= 26.0; x += 5.0) {
    w.push_back({x, -8.0, LandmarkKind::Corner});
    w.push_back({x + 2.5, 9.0, LandmarkKind::Corner});
  }
  return w;
}

struct TruthSample {
  Timestamp stamp;
  Pose2d pose;
};

/// The vehicle, its sensors and the delivery of scans with a lag.
class Simulator {
 public:
  Simulator(const TricycleParams& vehicle, const LaserModel& laser, const SimNoise& noise,
            std::vector<WorldLandmark> world, std::uint32_t seed)
      : vehicle_(vehicle), laser_(laser), noise_(noise), world_(std::move(world)), rng_(seed) {}

  double dt = 0.01;         // encoder period [s]
  double scanPeriod = 0.1;  // [s]
  double lagSeconds = 0.0;  // scan delivery delay [s]

  Pose2d truePose{};
  double wheelTravel = 0.0;  // what the encoder sees [m]
  double pathS = 0.0;        // distance along the path [m]
  double speed = 0.0;
  Timestamp now{};
  std::int64_t step = 0;

  /// The encoder sample at the current time.
  TricycleSample encoder() {
    TricycleSample s;
    s.stamp = now;
    s.driveTicks = static_cast<std::int64_t>(std::floor(wheelTravel / vehicle_.driveScale));
    s.steeringAngle = steerTrue_ + gauss(noise_.steeringSigma);
    return s;
  }

  /// Advances one encoder period along `path`; returns false when the path is done and stopped.
  bool advance(const PathSpec& path) {
    const double remaining = path.length - pathS;
    const double vStop = std::sqrt(std::max(0.0, 2.0 * path.accel * remaining));
    double v = std::min({path.vmax, speed + path.accel * dt, vStop});
    if (remaining <= 1e-4)
      v = 0.0;
    speed = v;
    const double ds = v * dt;
    const int sub = 10;
    const double a0 = steerTrue_;
    const double a1 = path.steerAt(pathS + ds);
    double groundTotal = 0.0;
    for (int i = 0; i < sub; ++i) {
      const double a = a0 + (a1 - a0) * (i + 0.5) / sub;
      double g = ds / sub;
      if (g != 0.0)
        g += gauss(std::sqrt(noise_.slipVariancePerMetre * std::fabs(g)));
      groundTotal += g;
      truePose = truePose.compose(tricycleArc(g, a, vehicle_.wheelbase));
    }
    (void)groundTotal;
    wheelTravel += ds;
    pathS += ds;
    steerTrue_ = a1;
    now = now + Duration::fromSeconds(dt);
    ++step;
    truth_.push_back({now, truePose});
    if (isScanStep()) {
      pending_.push_back(makeScan());
    }
    return v > 0.0 || pathS < path.length - 1e-4;
  }

  bool isScanStep() const {
    const std::int64_t every = static_cast<std::int64_t>(std::llround(scanPeriod / dt));
    return step % every == 0;
  }

  /// A scan whose delivery time has come (its stamp + lag <= now), if any.
  bool takeScan(ScanObservations& out) {
    if (pending_.empty())
      return false;
    if ((now - pending_.front().stamp).seconds() + 1e-9 < lagSeconds)
      return false;
    const ScanObservations& s = pending_.front();
    out.stamp = s.stamp;
    out.kindsDetected = s.kindsDetected;
    out.points.clear();
    for (const auto& p : s.points)
      (void)out.points.push_back(p);
    pending_.pop_front();
    return true;
  }

  /// Teleports the vehicle (the encoders notice nothing).
  void kidnap(const Pose2d& offset) { truePose = truePose.compose(offset); }

  std::mt19937_64& rng() { return rng_; }
  double gauss(double sigma) { return sigma > 0.0 ? std::normal_distribution<double>(0.0, sigma)(rng_) : 0.0; }
  double uniform(double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng_); }

 private:
  ScanObservations makeScan() {
    ScanObservations s;
    s.stamp = now;
    s.kindsDetected = kAllLandmarkKinds;
    const Pose2d laserWorld = truePose.compose(laser_.mounting);
    std::size_t real = 0;
    for (const auto& lm : world_) {
      const Eigen::Vector2d p = laserWorld.inverseTransformPoint(Eigen::Vector2d(lm.x, lm.y));
      const double r = p.norm();
      const double b = std::atan2(p.y(), p.x());
      if (r < laser_.rangeMin || r > laser_.rangeMax || b < laser_.angleMin || b > laser_.angleMax)
        continue;
      if (noise_.missProbability > 0.0 && uniform(0.0, 1.0) < noise_.missProbability)
        continue;
      const double rn = r + gauss(noise_.rangeSigma);
      const double bn = b + gauss(noise_.bearingSigma);
      const double extra = lm.kind == LandmarkKind::Corner ? noise_.cornerSigma : 0.0;
      (void)s.points.push_back(
          PointObservation{rn * std::cos(bn) + gauss(extra), rn * std::sin(bn) + gauss(extra), lm.kind});
      ++real;
    }
    if (noise_.spuriousFraction > 0.0) {
      const double expected = noise_.spuriousFraction * static_cast<double>(real);
      std::size_t n = static_cast<std::size_t>(expected);
      if (uniform(0.0, 1.0) < expected - static_cast<double>(n))
        ++n;
      for (std::size_t i = 0; i < n; ++i) {
        const double r = uniform(laser_.rangeMin + 0.5, 15.0);
        const double b = uniform(laser_.angleMin, laser_.angleMax);
        (void)s.points.push_back(PointObservation{r * std::cos(b), r * std::sin(b), LandmarkKind::Reflector});
      }
    }
    return s;
  }

  TricycleParams vehicle_;
  LaserModel laser_;
  SimNoise noise_;
  std::vector<WorldLandmark> world_;
  std::mt19937_64 rng_;
  double steerTrue_ = 0.0;
  std::deque<ScanObservations> pending_;
  std::vector<TruthSample> truth_;

 public:
  /// True pose at `stamp` (must be an encoder instant).
  Pose2d truthAt(Timestamp stamp) const {
    for (auto it = truth_.rbegin(); it != truth_.rend(); ++it) {
      if (it->stamp == stamp)
        return it->pose;
    }
    return truePose;
  }
};

/// Chi-square quantile by the Wilson-Hilferty approximation (relative error < 1e-3 for k >= 10).
inline double chiSquareQuantile(double k, double z) {
  const double a = 2.0 / (9.0 * k);
  const double t = 1.0 - a + z * std::sqrt(a);
  return k * t * t * t;
}

}  // namespace agv::sim
