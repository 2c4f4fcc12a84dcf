#pragma once
/// @file intrinsic_calibration.hpp
/// Per-laser intrinsic calibration of a multi-beam lidar from scans of a planar target (the
/// thesis' method, Muhammad 2012; docs/lidar-calibration.md). Host code, uses Ceres.
///
/// Cost (the thesis'; `PlaneResidual::Orthogonal`): the sum over target scans of the mean squared distance of the
/// scan's target points, computed by the point model (laser_ray.hpp) from the raw returns, to the scan's PCA plane.
/// Solved with Ceres as one least-squares problem in which each scan's plane (unit normal on the sphere manifold,
/// offset) is a parameter next to the per-laser parameters, residual = (n . P - d) / sqrt(N_scan): for fixed intrinsics
/// the best plane is the PCA plane, so the joint minimum is the thesis' minimum (the result reports both figures to
/// show it). The thesis' minimum is biased under range noise (the noise's share of the cost depends on the
/// parameters); by default its first-order bias is removed after the solve (`correctNoiseBias`), which makes the
/// reported 1-sigma describe the errors. `PlaneResidual::AlongBeam` replaces the distance by the range error along
/// the beam (unbiased under range noise; same planes, same structure).
///
/// Gauge: rotating every point about the sensor's z axis (the same offset on every alpha) moves
/// each plane along and leaves the cost unchanged, so the mean of the alphas is held at the start
/// values (one constraint); with D_corr and V_o both estimated, a common z shift (D_corr += c
/// sin(theta), V_o += c cos(theta)) is a second gauge, held the same way. The common theta offset
/// is a near-gauge of a wall protocol and held too by default (`holdMeanTheta`).
///
/// Observability: from the Jacobian at the start (and again at the solution), with the planes
/// eliminated (Schur complement) and the columns normalised: the singular values, the directions
/// of the smallest, and per laser the correlations of its parameters. A laser whose parameters lie
/// in a null direction, two of whose parameters correlate beyond `maxCorrelation`, or whose 1-sigma
/// exceeds `maxSigmaLength` / `maxSigmaAngle`, is held at
/// its start values and reported as not observable with the reason; lasers with too few target
/// points are refused by name. The checks run again at the solution (there with the sigma bounds,
/// the residual then being the noise's): a laser failing them is held too and the pass solved
/// again without it (no garbage from a near-degenerate set). Held lasers' returns leave the
/// problem (their untrusted start values would bias the planes).

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "agv/lidar3d/laser_intrinsics.hpp"
#include "agv/lidar3d/laser_ray.hpp"
#include "agv/lidar_calibration/target_segmentation.hpp"

namespace agv::lidar_calibration {

/// One scan (revolution) of the target from one placement.
struct CalibrationScan {
  std::string name;                ///< for the messages ("3.0 m tilt 6 deg")
  std::vector<RawReturn> returns;  ///< every return of the revolution (the target is segmented here)
};

/// Which parameters of every laser are estimated.
struct EstimatedParams {
  bool distCorrection = true;
  bool vertOffset = false;
  bool horizOffset = false;
  bool theta = true;
  bool alpha = true;
  /// Flag of parameter `k` (LaserParamIndex).
  bool operator[](int k) const noexcept;
};

/// What a return's residual against its scan's plane is.
enum class PlaneResidual {
  /// The thesis' cost: the orthogonal distance n . P - d (with the per-scan PCA planes: the mean
  /// squared distance to the PCA plane). Biased under range noise: the noise enters the distance
  /// as eps * (n . u) with u the beam direction, which depends on theta and alpha, so its expected
  /// square sigma^2 (n . u)^2 pulls the beams towards grazing; the bias grows with sigma^2 and is
  /// large along the weakly observed directions (measured: docs/lidar-calibration.md).
  Orthogonal,
  /// (n . P - d) / (n . u): the range error along the beam that puts P on the plane. The range
  /// noise enters as eps itself, independent of the parameters: no such bias (the maximum
  /// likelihood residual for range noise). Returns hitting the plane at grazing incidence
  /// (|n . u| < minBeamCosine) are left out.
  AlongBeam,
};

/// Calibration options.
struct IntrinsicCalibrationConfig {
  PlaneResidual residual = PlaneResidual::Orthogonal;
  double minBeamCosine = 0.25;  ///< AlongBeam: returns with |n . u| below this are not used
  TargetSegmentationConfig segmentation;
  EstimatedParams estimate;
  int passes = 2;           ///< segment + solve rounds (later passes segment with the new intrinsics)
  int maxIterations = 100;  ///< Ceres iterations per pass
  /// Threads of the solve (Ceres) and of the segmentation (the scans in parallel; the result does
  /// not depend on the count).
  int threads = 2;
  std::size_t minLaserPoints = 30;   ///< lasers with fewer target points over all scans are refused
  double maxCorrelation = 0.999;     ///< two parameters of a laser correlated beyond this: laser held
  double maxSigmaLength = 0.02;      ///< [m] a laser whose D_corr (V_o, H_o) 1-sigma exceeds this is held
  double maxSigmaAngle = 0.0087266;  ///< [rad] (0.5 deg) the same for theta and alpha
  double nullThreshold = 1e-9;       ///< normalised eigenvalue / largest below this: a null direction
  /// Hold the mean theta at the start values (a third constraint). A common elevation offset of
  /// every laser is, over the narrow azimuth span of a wall in front, nearly a pitch of the head,
  /// which each placement's free plane absorbs: the wall protocol observes it only through the
  /// wide-angle near placements (normalised singular value ~0.01) and the solve wanders along it.
  bool holdMeanTheta = true;
  /// Orthogonal residual: remove the thesis' cost's noise bias from its minimum (Gauss-Newton steps
  /// on the cost less its expected noise part sigma^2 sum w^2 (n . u)^2, sigma the range noise
  /// estimated from the residuals; `NoiseBiasCorrection`). Without it the minimiser's errors are
  /// dominated by that bias and not described by the reported 1-sigma (docs/lidar-calibration.md).
  bool correctNoiseBias = true;
  /// Gauss-Newton steps of the correction (1: the first-order bias, from the information already
  /// computed for the analysis at the minimum; more steps stop when below 1e-3 of a 1-sigma).
  int noiseBiasSteps = 1;
  std::function<void(const std::string&)> progress;  ///< progress lines (none when empty)
};

/// What became of one laser.
struct LaserReport {
  std::size_t laser = 0;
  LaserParams start;
  LaserParams estimate;
  LaserParams minimum;  ///< the thesis' minimum (= estimate unless the noise-bias correction moved it)
  Eigen::Matrix<double, kLaserParamCount, 1> sigma =
      Eigen::Matrix<double, kLaserParamCount, 1>::Zero();  ///< 1-sigma (0: not estimated)
  std::size_t points = 0;                                  ///< target points over all scans
  std::size_t scans = 0;                                   ///< scans in which it hit the target
  bool estimated = false;                                  ///< false: held at start (see `reason`)
  std::string reason;              ///< why not estimated ("never hit the target", "D_corr and theta correlated 0.9998")
  double maxCorrelation = 0.0;     ///< largest |correlation| between two of its estimated parameters
  std::string maxCorrelationPair;  ///< e.g. "D_corr/theta"
};

/// What became of one scan.
struct ScanReport {
  std::string name;
  std::size_t returns = 0;
  std::size_t targetPoints = 0;
  double rmsStart = 0.0;  ///< [m] plane residual (root of the thesis' per-scan cost) with the start intrinsics
  double rmsFinal = 0.0;  ///< [m] the same with the calibrated intrinsics (same target points; after the correction)
  Eigen::Vector2d extent = Eigen::Vector2d::Zero();  ///< [m] target region found
  std::vector<std::size_t> targets;                  ///< indices of the target returns (last pass)
};

/// One direction of the reduced (planes eliminated), column-normalised information matrix.
struct ConditionDirection {
  double singularValue = 0.0;  ///< sqrt of the eigenvalue (normalised: 1 = well determined)
  std::string
      components;  ///< the largest components, e.g. "alpha[*] 0.13 each" or "laser 3 D_corr 0.71, laser 3 theta -0.70"
  std::string gauge;  ///< "common alpha" / "common theta" / "common z" when a held (near-)gauge, else empty
};

/// Conditioning of the estimated parameters by the data.
struct ConditioningReport {
  std::size_t parameters = 0;                ///< estimated laser parameters (columns)
  std::vector<double> singularValues;        ///< ascending, without the gauge constraints
  std::vector<ConditionDirection> smallest;  ///< the smallest few with their components
  double conditionNumber = 0.0;              ///< largest / smallest singular value with the gauges fixed
  std::size_t nullDirections = 0;            ///< below the null threshold, gauges excluded
};

/// The noise-bias correction of the thesis' minimum (`IntrinsicCalibrationConfig::correctNoiseBias`).
struct NoiseBiasCorrection {
  bool applied = false;
  int iterations = 0;
  double rangeSigma = 0.0;  ///< [m] range noise used (estimated at the thesis' minimum)
  Eigen::Matrix<double, kLaserParamCount, 1> step =
      Eigen::Matrix<double, kLaserParamCount, 1>::Zero();  ///< largest |change| per parameter kind [m, rad]
};

/// The outcome.
struct IntrinsicCalibrationResult {
  LaserIntrinsics calibrated;  ///< start values for held / refused lasers
  std::vector<LaserReport> lasers;
  std::vector<ScanReport> scans;
  ConditioningReport startConditioning;  ///< at the start values (what decided the held lasers)
  ConditioningReport conditioning;       ///< at the solution
  double costStart = 0.0;                ///< thesis cost (sum over scans of mean squared plane distance) [m^2], start
  double costFinal = 0.0;                ///< the same at the thesis' minimum, PCA planes
  double costFinalJoint = 0.0;           ///< the same from the Ceres problem's own planes (agrees with costFinal)
  double costCalibrated = 0.0;           ///< the same at the calibrated values (= costFinal without the correction)
  NoiseBiasCorrection noiseBias;         ///< the correction applied to the thesis' minimum (orthogonal residual)
  double maxPlaneAngle = 0.0;            ///< [rad] largest angle between a scan's Ceres plane and its PCA plane
  double noiseSigma = 0.0;               ///< [m] residual standard deviation (unweighted) at the solution
  double rangeSigma = 0.0;  ///< [m] range noise estimated from the residuals (orthogonal: ssr / sum (n . u)^2)
  int iterations = 0;       ///< Ceres iterations, all passes
  double secondsSegmentation = 0.0;
  double secondsSolve = 0.0;
  double secondsAnalysis = 0.0;
  std::size_t lasersEstimated = 0;
  std::size_t lasersHeld = 0;  ///< unobservable or refused
};

/// Calibrates `start`'s lasers from `scans`. False with `error` for input that cannot be used: no
/// scan, an empty scan, a non-finite return, a laser id outside the table, a scan without the
/// target (named), or no laser observable at all (`result` then still holds the reports).
bool calibrateIntrinsics(const std::vector<CalibrationScan>& scans, const LaserIntrinsics& start,
                         const IntrinsicCalibrationConfig& config, IntrinsicCalibrationResult& result,
                         std::string& error);

/// Root mean squared distance of each scan's points `targets[s]` (indices into the returns) to its
/// PCA plane, the points computed with `intrinsics` (e.g. the truth, for the noise floor).
std::vector<double> planeResiduals(const std::vector<CalibrationScan>& scans,
                                   const std::vector<std::vector<std::size_t>>& targets,
                                   const LaserIntrinsics& intrinsics);

/// The points of `scan` by the model with `intrinsics` (sensor frame, double).
std::vector<Eigen::Vector3d> scanPoints(const CalibrationScan& scan, const LaserIntrinsics& intrinsics);

/// Thesis name of parameter `k` ("D_corr", "V_o", "H_o", "theta", "alpha").
const char* laserParamName(int k) noexcept;

}  // namespace agv::lidar_calibration
