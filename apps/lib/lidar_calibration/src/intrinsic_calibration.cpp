#include "agv/lidar_calibration/intrinsic_calibration.hpp"

#include <ceres/ceres.h>
#include <ceres/jet.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <thread>

namespace agv::lidar_calibration {

bool EstimatedParams::operator[](int k) const noexcept {
  switch (k) {
    case kDistCorrection:
      return distCorrection;
    case kVertOffset:
      return vertOffset;
    case kHorizOffset:
      return horizOffset;
    case kTheta:
      return theta;
    default:
      return alpha;
  }
}

const char* laserParamName(int k) noexcept {
  static const char* const names[kLaserParamCount] = {"D_corr", "V_o", "H_o", "theta", "alpha"};
  return k >= 0 && k < kLaserParamCount ? names[k] : "?";
}

std::vector<Eigen::Vector3d> scanPoints(const CalibrationScan& scan, const LaserIntrinsics& intrinsics) {
  std::vector<Eigen::Vector3d> points;
  points.reserve(scan.returns.size());
  for (const RawReturn& r : scan.returns) {
    const Eigen::Matrix<double, kLaserParamCount, 1> p = toVector(intrinsics.params(r.laser));
    points.push_back(laserModelPoint(p.data(), r.phi, r.range));
  }
  return points;
}

std::vector<double> planeResiduals(const std::vector<CalibrationScan>& scans,
                                   const std::vector<std::vector<std::size_t>>& targets,
                                   const LaserIntrinsics& intrinsics) {
  std::vector<double> out;
  for (std::size_t s = 0; s < scans.size() && s < targets.size(); ++s) {
    double ms = 0.0;
    if (targets[s].size() >= 3) {
      pcaPlane(scanPoints(scans[s], intrinsics), &targets[s], &ms);
    }
    out.push_back(std::sqrt(ms));
  }
  return out;
}

namespace {

using Vec5 = Eigen::Matrix<double, kLaserParamCount, 1>;
using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

/// The target returns of one laser in one scan.
struct Group {
  std::size_t scan = 0;
  std::size_t laser = 0;
  std::vector<double> phi;
  std::vector<double> range;
};

/// The residual of one return against the plane (normal, offset): the orthogonal distance
/// n . P - d (the thesis' cost), or along the beam (n . P - d) / (n . u), the range error that
/// puts P on the plane (no bias from range noise: see IntrinsicCalibrationConfig::residual).
/// `beamCosine` (optional) receives n . u.
template <typename T, typename N>
T planeResidual(const T* laser, const N& normal, const T& offset, double phi, double range, bool alongBeam,
                T* beamCosine = nullptr) {
  const LaserRay<T> ray = laserRay(laser, phi);
  const Eigen::Matrix<T, 3, 1> p = ray.origin + (T(range) + laser[kDistCorrection]) * ray.direction;
  const T r = normal[0] * p[0] + normal[1] * p[1] + normal[2] * p[2] - offset;
  if (!alongBeam && beamCosine == nullptr) {
    return r;
  }
  const T c = normal[0] * ray.direction[0] + normal[1] * ray.direction[1] + normal[2] * ray.direction[2];
  if (beamCosine != nullptr) {
    *beamCosine = c;
  }
  return alongBeam ? r / c : r;
}

/// Residuals of one group, times weight.
struct PlaneCost {
  const Group* group;
  double weight;
  bool alongBeam;
  template <typename T>
  bool operator()(const T* laser, const T* normal, const T* offset, T* residual) const {
    for (std::size_t k = 0; k < group->phi.size(); ++k) {
      residual[k] = T(weight) * planeResidual(laser, normal, offset[0], group->phi[k], group->range[k], alongBeam);
    }
    return true;
  }
};

/// One linear gauge constraint: weight * sum_l coef_l . (x_l - x0_l) over laser blocks.
class GaugeCost final : public ceres::CostFunction {
 public:
  GaugeCost(std::vector<Vec5> coef, std::vector<Vec5> start, double weight)
      : coef_(std::move(coef)), start_(std::move(start)), weight_(weight) {
    set_num_residuals(1);
    for (std::size_t k = 0; k < coef_.size(); ++k) {
      mutable_parameter_block_sizes()->push_back(kLaserParamCount);
    }
  }
  bool Evaluate(double const* const* x, double* residual, double** jacobians) const override {
    double r = 0.0;
    for (std::size_t k = 0; k < coef_.size(); ++k) {
      for (int i = 0; i < kLaserParamCount; ++i) {
        r += coef_[k][i] * (x[k][i] - start_[k][i]);
        if (jacobians != nullptr && jacobians[k] != nullptr) {
          jacobians[k][i] = weight_ * coef_[k][i];
        }
      }
    }
    residual[0] = weight_ * r;
    return true;
  }

 private:
  std::vector<Vec5> coef_;
  std::vector<Vec5> start_;
  double weight_;
};

/// The state of the problem.
struct State {
  std::vector<Vec5> x;                  ///< per laser
  std::vector<Vec5> start;              ///< per laser
  std::vector<Eigen::Vector3d> normal;  ///< per scan
  std::vector<double> offset;           ///< per scan
  std::vector<std::size_t> scanPoints;  ///< target points per scan (all groups)
  std::vector<Group> groups;
  std::vector<bool> held;              ///< per laser (held at start or refused)
  std::vector<bool> refused;           ///< per laser: too few points
  std::vector<Vec5> beforeCorrection;  ///< per laser: the thesis' minimum (before the noise-bias correction)
};

/// Column layout of the information matrices: estimated laser parameters, then 3 per scan.
struct Columns {
  std::vector<std::array<int, kLaserParamCount>> laser;  ///< -1: not a column
  std::vector<int> laserColumnLaser;                     ///< laser of each laser column
  std::vector<int> laserColumnParam;                     ///< parameter of each laser column
  int laserCount = 0;
  int planeStart = 0;
  int count = 0;
};

Columns makeColumns(const State& st, const EstimatedParams& est) {
  Columns c;
  c.laser.assign(st.x.size(), {-1, -1, -1, -1, -1});
  for (std::size_t l = 0; l < st.x.size(); ++l) {
    if (st.held[l]) {
      continue;
    }
    for (int k = 0; k < kLaserParamCount; ++k) {
      if (est[k]) {
        c.laser[l][static_cast<std::size_t>(k)] = c.laserCount++;
        c.laserColumnLaser.push_back(static_cast<int>(l));
        c.laserColumnParam.push_back(k);
      }
    }
  }
  c.planeStart = c.laserCount;
  c.count = c.laserCount + 3 * static_cast<int>(st.normal.size());
  return c;
}

/// The gauge constraint gradients in the laser columns: common alpha; common theta (a near-gauge,
/// when held); common z when D_corr and V_o are estimated.
std::vector<std::pair<std::string, Eigen::VectorXd>> gauges(const State& st, const Columns& c,
                                                            const EstimatedParams& est, bool holdMeanTheta) {
  std::vector<std::pair<std::string, Eigen::VectorXd>> out;
  // The same offset on parameter k of every laser.
  const auto common = [&](int k, const char* name) {
    Eigen::VectorXd g = Eigen::VectorXd::Zero(c.count);
    for (std::size_t l = 0; l < st.x.size(); ++l) {
      if (c.laser[l][static_cast<std::size_t>(k)] >= 0) {
        g[c.laser[l][static_cast<std::size_t>(k)]] = 1.0;
      }
    }
    if (g.squaredNorm() > 0.0) {
      out.emplace_back(name, g);
    }
  };
  if (est.alpha) {
    common(kAlpha, "common alpha");
  }
  if (est.theta && holdMeanTheta) {
    common(kTheta, "common theta");
  }
  if (est.distCorrection && est.vertOffset) {
    Eigen::VectorXd g = Eigen::VectorXd::Zero(c.count);
    for (std::size_t l = 0; l < st.x.size(); ++l) {
      if (c.laser[l][kDistCorrection] >= 0) {
        g[c.laser[l][kDistCorrection]] = std::sin(st.start[l][kTheta]);
        g[c.laser[l][kVertOffset]] = std::cos(st.start[l][kTheta]);
      }
    }
    if (g.squaredNorm() > 0.0) {
      out.emplace_back("common z", g);
    }
  }
  return out;
}

/// Information (H = sum w^2 a a^T), its sandwich middle (M = sum w^4 v a a^T, v the residual's
/// variance in units of the range noise's: (n . u)^2 for the orthogonal distance, 1 along the
/// beam), the gradient of the cost (G = sum w^2 r a), the gradient of its expected noise part
/// (B = sum w^2 c dc, c = n . u: E[w^2 r^2] = w^2 (r0^2 + sigma^2 c^2) for the orthogonal
/// distance) and residual sums.
struct Information {
  Eigen::MatrixXd h;
  Eigen::MatrixXd m;
  Eigen::VectorXd g;
  Eigen::VectorXd b;
  double ssr = 0.0;   ///< unweighted sum of squared residuals
  double sumV = 0.0;  ///< sum of v over the residuals (E[ssr] = sigma^2 sumV at the truth)
  std::size_t n = 0;
};

Information accumulate(const State& st, const Columns& c, bool alongBeam) {
  using Jet = ceres::Jet<double, 8>;
  Information info;
  info.h = Eigen::MatrixXd::Zero(c.count, c.count);
  info.m = Eigen::MatrixXd::Zero(c.count, c.count);
  info.g = Eigen::VectorXd::Zero(c.count);
  info.b = Eigen::VectorXd::Zero(c.count);
  std::vector<Eigen::Matrix<double, 3, 2>> basis;
  for (const Eigen::Vector3d& n : st.normal) {
    basis.push_back(planeAxes(n));
  }
  for (const Group& g : st.groups) {
    std::array<Jet, kLaserParamCount> x;
    for (int k = 0; k < kLaserParamCount; ++k) {
      x[static_cast<std::size_t>(k)] = Jet(st.x[g.laser][k], k);
    }
    const Eigen::Vector3d& n0 = st.normal[g.scan];
    const Eigen::Matrix<double, 3, 2>& b = basis[g.scan];
    // The plane in its tangent coordinates: n = n0 + B t, d = d0 + e (derivatives 5, 6, 7).
    const Eigen::Matrix<Jet, 3, 1> n =
        n0.cast<Jet>() + b.col(0).cast<Jet>() * Jet(0.0, 5) + b.col(1).cast<Jet>() * Jet(0.0, 6);
    const Jet d(st.offset[g.scan], 7);
    std::array<int, 8> col{};
    for (int k = 0; k < kLaserParamCount; ++k) {
      col[static_cast<std::size_t>(k)] = c.laser[g.laser][static_cast<std::size_t>(k)];
    }
    const int p0 = c.planeStart + 3 * static_cast<int>(g.scan);
    col[5] = p0;
    col[6] = p0 + 1;
    col[7] = p0 + 2;
    const double w2 = 1.0 / static_cast<double>(st.scanPoints[g.scan]);
    for (std::size_t k = 0; k < g.phi.size(); ++k) {
      Jet cosine;
      const Jet r = planeResidual(x.data(), n, d, g.phi[k], g.range[k], alongBeam, &cosine);
      const Eigen::Matrix<double, 8, 1> a = r.v;
      const double res = r.a;
      const double var = alongBeam ? 1.0 : cosine.a * cosine.a;
      info.ssr += res * res;
      info.sumV += var;
      ++info.n;
      for (int i = 0; i < 8; ++i) {
        if (col[static_cast<std::size_t>(i)] < 0) {
          continue;
        }
        info.g[col[static_cast<std::size_t>(i)]] += w2 * res * a[i];
        info.b[col[static_cast<std::size_t>(i)]] += w2 * cosine.a * cosine.v[i];
        for (int j = 0; j < 8; ++j) {
          if (col[static_cast<std::size_t>(j)] < 0) {
            continue;
          }
          const double v = a[i] * a[j];
          info.h(col[static_cast<std::size_t>(i)], col[static_cast<std::size_t>(j)]) += w2 * v;
          info.m(col[static_cast<std::size_t>(i)], col[static_cast<std::size_t>(j)]) += w2 * w2 * var * v;
        }
      }
    }
  }
  return info;
}

/// Analysis of one information matrix: conditioning, null directions, covariance.
struct Analysis {
  ConditioningReport report;
  std::vector<int> nullLasers;  ///< lasers taking part in a non-gauge null direction
  Eigen::MatrixXd covariance;   ///< laser columns, sandwich, scaled by sigma^2
  Eigen::MatrixXd shape;        ///< laser columns of H_c^-1 (the correlations, also without noise)
  double sigma = 0.0;           ///< unweighted residual standard deviation
  double rangeSigma = 0.0;      ///< range noise standard deviation estimated from the residuals
};

/// The information with the gauges fixed by constraints: H_c = H + lambda * g g^T (g in the laser columns).
Eigen::MatrixXd constrainedInformation(const Eigen::MatrixXd& h, int laserColumns,
                                       const std::vector<std::pair<std::string, Eigen::VectorXd>>& gaugeList) {
  Eigen::MatrixXd hc = h;
  double meanDiag = 0.0;
  for (int i = 0; i < laserColumns; ++i) {
    meanDiag += h(i, i) / laserColumns;
  }
  for (const auto& gauge : gaugeList) {
    const Eigen::VectorXd& grad = gauge.second;
    hc += 1e3 * meanDiag / grad.squaredNorm() * grad * grad.transpose();
  }
  return hc;
}

/// Range noise sigma from the residuals: E[ssr] = sigma^2 sumV, less the parameters' share.
double rangeNoiseSigma(const Information& info, const Columns& c) {
  if (info.n == 0 || info.sumV <= 0.0) {
    return 0.0;
  }
  const double n = static_cast<double>(info.n);
  const double dof = info.n > static_cast<std::size_t>(c.count) ? n - static_cast<double>(c.count) : 1.0;
  return std::sqrt(info.ssr / (info.sumV * dof / n));
}

std::string laserColumnName(const Columns& c, int col) {
  return "laser " + std::to_string(c.laserColumnLaser[static_cast<std::size_t>(col)]) + " " +
         laserParamName(c.laserColumnParam[static_cast<std::size_t>(col)]);
}

/// `given`: the information already accumulated (at these or nearly these values), else accumulated here.
Analysis analyse(const State& st, const Columns& c, const EstimatedParams& est, double nullThreshold,
                 bool holdMeanTheta, bool alongBeam, const Information* given = nullptr) {
  Analysis out;
  const Information info = given != nullptr ? *given : accumulate(st, c, alongBeam);
  const int nl = c.laserCount;
  const int np = c.count - nl;
  out.report.parameters = static_cast<std::size_t>(nl);
  if (nl == 0) {
    return out;
  }
  // Reduced information (planes eliminated).
  const Eigen::MatrixXd hpp = info.h.bottomRightCorner(np, np);
  const Eigen::MatrixXd hlp = info.h.topRightCorner(nl, np);
  const Eigen::LDLT<Eigen::MatrixXd> ldltP(hpp);
  const Eigen::MatrixXd s = info.h.topLeftCorner(nl, nl) - hlp * ldltP.solve(hlp.transpose());
  Eigen::VectorXd scale(nl);
  for (int i = 0; i < nl; ++i) {
    scale[i] = s(i, i) > 0.0 ? 1.0 / std::sqrt(s(i, i)) : 1.0;
  }
  const Eigen::MatrixXd sn = scale.asDiagonal() * s * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(sn);
  const double lmax = std::max(es.eigenvalues()[nl - 1], 1e-300);
  const auto g = gauges(st, c, est, holdMeanTheta);
  for (int i = 0; i < nl; ++i) {
    out.report.singularValues.push_back(std::sqrt(std::max(0.0, es.eigenvalues()[i])));
  }
  for (int i = 0; i < nl; ++i) {
    const Eigen::VectorXd v = es.eigenvectors().col(i);
    std::string gaugeName;
    for (const auto& [name, grad] : g) {
      const Eigen::VectorXd gn = (grad.head(nl).array() / scale.array()).matrix().normalized();
      if (std::fabs(gn.dot(v)) > 0.9) {
        gaugeName = name;
      }
    }
    const bool isNull = es.eigenvalues()[i] < nullThreshold * lmax;
    if (isNull && gaugeName.empty()) {
      ++out.report.nullDirections;
      for (int j = 0; j < nl; ++j) {
        if (v[j] * v[j] > 0.05) {
          out.nullLasers.push_back(c.laserColumnLaser[static_cast<std::size_t>(j)]);
        }
      }
    }
    if (i < 6 || (isNull && gaugeName.empty())) {
      ConditionDirection d;
      d.singularValue = out.report.singularValues[static_cast<std::size_t>(i)];
      d.gauge = gaugeName;
      std::vector<int> order(static_cast<std::size_t>(nl));
      for (int j = 0; j < nl; ++j) {
        order[static_cast<std::size_t>(j)] = j;
      }
      std::sort(order.begin(), order.end(), [&](int a, int b) { return std::fabs(v[a]) > std::fabs(v[b]); });
      for (std::size_t j = 0; j < order.size() && j < 4; ++j) {
        char buf[96];
        std::snprintf(buf, sizeof buf, "%s%s %.3f", j == 0 ? "" : ", ", laserColumnName(c, order[j]).c_str(),
                      v[order[j]]);
        d.components += buf;
      }
      if (order.size() > 4) {
        d.components += ", ...";
      }
      out.report.smallest.push_back(d);
    }
  }
  const Eigen::MatrixXd hc = constrainedInformation(info.h, nl, g);
  Eigen::MatrixXd snc = sn;
  for (const auto& gauge : g) {
    const Eigen::VectorXd gn = (gauge.second.head(nl).array() / scale.array()).matrix();
    snc += gn * gn.transpose() / gn.squaredNorm();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> esc(snc, Eigen::EigenvaluesOnly);
  out.report.conditionNumber = std::sqrt(esc.eigenvalues()[nl - 1] / std::max(esc.eigenvalues()[0], 1e-300));
  const std::size_t dof = info.n > static_cast<std::size_t>(c.count) ? info.n - static_cast<std::size_t>(c.count) : 1;
  out.sigma = std::sqrt(info.ssr / static_cast<double>(dof));
  out.rangeSigma = rangeNoiseSigma(info, c);
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(hc);
  const Eigen::MatrixXd hinv = ldlt.solve(Eigen::MatrixXd::Identity(c.count, c.count));
  // Residual i has the variance sigma_range^2 v_i (v_i = (n . u_i)^2 for the orthogonal distance):
  // the sandwich's middle carries v_i, the scale is the range noise's.
  out.covariance = (hinv * info.m * hinv).topLeftCorner(nl, nl) * out.rangeSigma * out.rangeSigma;
  out.shape = hinv.topLeftCorner(nl, nl);
  return out;
}

/// The thesis' cost's noise bias removed from its minimum: Gauss-Newton steps on the cost less its
/// expected noise part, sum_i w_i^2 (r_i^2 - sigma^2 c_i^2), c_i = n . u_i. At the thesis' minimum the
/// cost's own gradient G is zero and the step is H_c^-1 sigma^2 B: the first-order bias of the
/// minimiser (the expected noise part sigma^2 sum w^2 c^2 is smallest towards grazing beams, and the
/// minimiser leans that way). sigma is the range noise estimated from the residuals there. The
/// laser parameters and the planes move; the gauge constraints hold.
NoiseBiasCorrection correctNoiseBias(State& st, const Columns& c, const EstimatedParams& est, bool holdMeanTheta,
                                     const Information& atMinimum, int steps) {
  NoiseBiasCorrection out;
  const auto g = gauges(st, c, est, holdMeanTheta);
  double sigma2 = 0.0;
  for (int it = 0; it < steps; ++it) {
    const Information info = it == 0 ? atMinimum : accumulate(st, c, false);
    if (it == 0) {
      out.rangeSigma = rangeNoiseSigma(info, c);
      sigma2 = out.rangeSigma * out.rangeSigma;
    }
    const Eigen::VectorXd grad = info.g - sigma2 * info.b;
    const Eigen::MatrixXd hc = constrainedInformation(info.h, c.laserCount, g);
    const Eigen::VectorXd delta = -hc.ldlt().solve(grad);
    if (!delta.allFinite()) {
      break;
    }
    double largest = 0.0;  // step times sqrt(H_ii): in units of the range noise, about sigma x (step / its 1-sigma)
    for (std::size_t l = 0; l < st.x.size(); ++l) {
      for (int k = 0; k < kLaserParamCount; ++k) {
        const int col = c.laser[l][static_cast<std::size_t>(k)];
        if (col >= 0) {
          st.x[l][k] += delta[col];
          out.step[k] = std::max(out.step[k], std::fabs(st.x[l][k] - st.beforeCorrection[l][k]));
          largest = std::max(largest, std::fabs(delta[col]) * std::sqrt(info.h(col, col)));
        }
      }
    }
    for (std::size_t s = 0; s < st.normal.size(); ++s) {
      const int p0 = c.planeStart + 3 * static_cast<int>(s);
      const Eigen::Matrix<double, 3, 2> b = planeAxes(st.normal[s]);
      st.normal[s] = (st.normal[s] + b * delta.segment<2>(p0)).normalized();
      st.offset[s] += delta[p0 + 2];
    }
    out.iterations = it + 1;
    if (largest < 1e-3 * std::max(out.rangeSigma, 1e-12)) {  // below a thousandth of a 1-sigma
      break;
    }
  }
  out.applied = out.iterations > 0;
  return out;
}

}  // namespace

namespace {

/// Largest |correlation| between two columns of `laser` in `shape`; the pair's name.
double laserCorrelation(const Eigen::MatrixXd& shape, const Columns& c, std::size_t laser, std::string& pair) {
  double best = 0.0;
  pair.clear();
  for (int a = 0; a < kLaserParamCount; ++a) {
    for (int b = a + 1; b < kLaserParamCount; ++b) {
      const int i = c.laser[laser][static_cast<std::size_t>(a)];
      const int j = c.laser[laser][static_cast<std::size_t>(b)];
      if (i < 0 || j < 0 || shape(i, i) <= 0.0 || shape(j, j) <= 0.0) {
        continue;
      }
      const double r = std::fabs(shape(i, j) / std::sqrt(shape(i, i) * shape(j, j)));
      if (r > best) {
        best = r;
        pair = std::string(laserParamName(a)) + "/" + laserParamName(b);
      }
    }
  }
  return best;
}

void say(const IntrinsicCalibrationConfig& config, const std::string& line) {
  if (config.progress) {
    config.progress(line);
  }
}

class ProgressCallback final : public ceres::IterationCallback {
 public:
  ProgressCallback(const IntrinsicCalibrationConfig& config, int pass) : config_(config), pass_(pass) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    char buf[160];
    std::snprintf(buf, sizeof buf, "pass %d iteration %d: cost %.6e m^2, step %.2e, %.2f s", pass_, s.iteration,
                  2.0 * s.cost, s.step_norm, s.cumulative_time_in_seconds);
    say(config_, buf);
    return ceres::SOLVER_CONTINUE;
  }

 private:
  const IntrinsicCalibrationConfig& config_;
  int pass_;
};

/// Segments every scan with the current intrinsics and regroups the target returns.
bool segmentAll(const std::vector<CalibrationScan>& scans, const LaserIntrinsics& current,
                const IntrinsicCalibrationConfig& config, State& st, std::vector<ScanReport>& reports,
                std::string& error) {
  st.groups.clear();
  st.normal.assign(scans.size(), Eigen::Vector3d::UnitX());
  st.offset.assign(scans.size(), 0.0);
  st.scanPoints.assign(scans.size(), 0);
  // The scans are segmented independently (each with its own seed) on `threads` threads; the
  // results are taken in scan order, so the outcome does not depend on the thread count.
  std::vector<TargetSegment> segments(scans.size());
  std::vector<std::string> whys(scans.size());
  std::vector<char> segmented(scans.size(), 0);
  const auto segmentEvery = [&](std::size_t first, std::size_t stride) {
    for (std::size_t s = first; s < scans.size(); s += stride) {
      TargetSegmentationConfig sc = config.segmentation;
      sc.seed = config.segmentation.seed + s;
      segmented[s] = segmentTarget(scanPoints(scans[s], current), sc, segments[s], whys[s]) ? 1 : 0;
    }
  };
  const std::size_t threads = std::max<std::size_t>(
      1, std::min<std::size_t>(static_cast<std::size_t>(std::max(1, config.threads)), scans.size()));
  std::vector<std::thread> helpers;
  for (std::size_t t = 1; t < threads; ++t) {
    helpers.emplace_back(segmentEvery, t, threads);
  }
  segmentEvery(0, threads);
  for (std::thread& h : helpers) {
    h.join();
  }
  for (std::size_t s = 0; s < scans.size(); ++s) {
    const TargetSegment& seg = segments[s];
    if (segmented[s] == 0) {
      error = "scan " + std::to_string(s) + " '" + scans[s].name + "': " + whys[s];
      return false;
    }
    reports[s].targets = seg.indices;
    reports[s].targetPoints = seg.indices.size();
    reports[s].extent = seg.extent;
    std::vector<Group> byLaser(current.size());
    for (const std::size_t i : seg.indices) {
      const RawReturn& r = scans[s].returns[i];
      if (config.residual == PlaneResidual::AlongBeam) {
        const Vec5 p = toVector(current.params(r.laser));
        if (std::fabs(laserRay(p.data(), r.phi).direction.dot(seg.plane.normal)) < config.minBeamCosine) {
          continue;  // grazing: the range error along the beam is ill-defined
        }
      }
      Group& g = byLaser[r.laser];
      g.scan = s;
      g.laser = r.laser;
      g.phi.push_back(r.phi);
      g.range.push_back(r.range);
    }
    st.normal[s] = seg.plane.normal;
    st.offset[s] = seg.plane.offset;
    for (Group& g : byLaser) {
      if (!g.phi.empty()) {
        st.groups.push_back(std::move(g));
      }
    }
  }
  return true;
}

}  // namespace

bool calibrateIntrinsics(const std::vector<CalibrationScan>& scans, const LaserIntrinsics& start,
                         const IntrinsicCalibrationConfig& config, IntrinsicCalibrationResult& result,
                         std::string& error) {
  result = IntrinsicCalibrationResult{};
  result.calibrated = start;
  const EstimatedParams& est = config.estimate;
  const bool alongBeam = config.residual == PlaneResidual::AlongBeam;
  if (start.size() == 0) {
    error = "the start intrinsics have no laser";
    return false;
  }
  if (scans.empty()) {
    error = "no scan";
    return false;
  }
  if (!(est.distCorrection || est.vertOffset || est.horizOffset || est.theta || est.alpha)) {
    error = "no parameter to estimate";
    return false;
  }
  for (std::size_t s = 0; s < scans.size(); ++s) {
    const std::string where = "scan " + std::to_string(s) + " '" + scans[s].name + "'";
    if (scans[s].returns.empty()) {
      error = where + " has no return";
      return false;
    }
    for (std::size_t i = 0; i < scans[s].returns.size(); ++i) {
      const RawReturn& r = scans[s].returns[i];
      if (!std::isfinite(r.phi) || !std::isfinite(r.range)) {
        error = where + " return " + std::to_string(i) + ": non-finite azimuth or range";
        return false;
      }
      if (r.laser >= start.size()) {
        error = where + " return " + std::to_string(i) + ": laser " + std::to_string(r.laser) +
                " is not in the intrinsics (" + std::to_string(start.size()) + " lasers)";
        return false;
      }
    }
  }

  State st;
  for (std::size_t l = 0; l < start.size(); ++l) {
    st.x.push_back(toVector(start.params(l)));
  }
  st.start = st.x;
  st.held.assign(start.size(), false);
  st.refused.assign(start.size(), false);
  result.scans.resize(scans.size());
  for (std::size_t s = 0; s < scans.size(); ++s) {
    result.scans[s].name = scans[s].name;
    result.scans[s].returns = scans[s].returns.size();
  }
  result.lasers.resize(start.size());
  for (std::size_t l = 0; l < start.size(); ++l) {
    result.lasers[l].laser = l;
    result.lasers[l].start = start.params(l);
    result.lasers[l].estimate = start.params(l);
    result.lasers[l].minimum = start.params(l);
  }

  LaserIntrinsics current = start;
  for (int pass = 1; pass <= std::max(1, config.passes); ++pass) {
    const Clock::time_point t0 = Clock::now();
    if (!segmentAll(scans, current, config, st, result.scans, error)) {
      return false;
    }
    result.secondsSegmentation += secondsSince(t0);
    // Points per laser: refuse lasers that (almost) never hit the target; drop their returns.
    std::vector<std::size_t> points(start.size(), 0);
    std::vector<std::size_t> scansHit(start.size(), 0);
    for (const Group& g : st.groups) {
      points[g.laser] += g.phi.size();
      ++scansHit[g.laser];
    }
    for (std::size_t l = 0; l < start.size(); ++l) {
      result.lasers[l].points = points[l];
      result.lasers[l].scans = scansHit[l];
      if (points[l] < config.minLaserPoints && !st.refused[l]) {
        st.refused[l] = true;
        st.held[l] = true;
        result.lasers[l].reason = points[l] == 0 ? "never hit the target"
                                                 : "only " + std::to_string(points[l]) + " target points (needs " +
                                                       std::to_string(config.minLaserPoints) + ")";
      }
    }
    // Held and refused lasers' returns leave the problem: their start values are not trusted to
    // carry the planes (they would bias the lasers estimated).
    const auto dropHeld = [&st]() {
      st.groups.erase(
          std::remove_if(st.groups.begin(), st.groups.end(), [&](const Group& g) { return st.held[g.laser]; }),
          st.groups.end());
      std::fill(st.scanPoints.begin(), st.scanPoints.end(), 0U);
      for (const Group& g : st.groups) {
        st.scanPoints[g.scan] += g.phi.size();
      }
    };
    dropHeld();
    const std::vector<Eigen::Vector3d> segNormal = st.normal;
    const std::vector<double> segOffset = st.offset;
    for (int attempt = 0; attempt < 4; ++attempt) {
      // Observability at the current values: hold lasers in null directions or correlated beyond the bound.
      const Clock::time_point t1 = Clock::now();
      bool newlyHeld = false;
      for (int round = 0; round < 4; ++round) {
        const Columns cols = makeColumns(st, est);
        const Analysis a = analyse(st, cols, est, config.nullThreshold, config.holdMeanTheta, alongBeam);
        if (round == 0 && pass == 1) {
          result.startConditioning = a.report;
        }
        bool changed = false;
        for (const int l : a.nullLasers) {
          if (!st.held[static_cast<std::size_t>(l)]) {
            st.held[static_cast<std::size_t>(l)] = true;
            result.lasers[static_cast<std::size_t>(l)].reason = "not observable (a null direction of the data)";
            changed = true;
          }
        }
        if (!changed) {
          for (std::size_t l = 0; l < start.size(); ++l) {
            std::string pair;
            const double r = st.held[l] ? 0.0 : laserCorrelation(a.shape, cols, l, pair);
            if (r > config.maxCorrelation) {
              st.held[l] = true;
              char buf[96];
              std::snprintf(buf, sizeof buf, "not observable: %s correlated %.5f", pair.c_str(), r);
              result.lasers[l].reason = buf;
              changed = true;
            }
          }
        }
        if (!changed && attempt > 0) {
          // At a solution (the residual sigma is then the noise's): determined too loosely to be worth changing the
          // factory value (a runaway along a flat, curved valley of the cost shows here even where the correlations
          // look fine).
          for (std::size_t l = 0; l < start.size(); ++l) {
            for (int k = 0; k < kLaserParamCount && !st.held[l]; ++k) {
              const int col = cols.laser[l][static_cast<std::size_t>(k)];
              const bool angle = k == kTheta || k == kAlpha;
              const double bound = angle ? config.maxSigmaAngle : config.maxSigmaLength;
              const double sigma = col >= 0 ? std::sqrt(std::max(0.0, a.covariance(col, col))) : 0.0;
              if (sigma > bound) {
                st.held[l] = true;
                std::string pair;
                const double r = laserCorrelation(a.shape, cols, l, pair);
                char buf[160];
                std::snprintf(buf, sizeof buf, "not determined: sigma(%s) %.3g %s > %.3g (%s correlated %.3f)",
                              laserParamName(k), angle ? sigma * 180.0 / 3.14159265358979323846 : sigma,
                              angle ? "deg" : "m", angle ? bound * 180.0 / 3.14159265358979323846 : bound, pair.c_str(),
                              r);
                result.lasers[l].reason = buf;
                changed = true;
              }
            }
          }
        }
        newlyHeld = newlyHeld || changed;
        dropHeld();
        if (!changed) {
          break;
        }
      }
      result.secondsAnalysis += secondsSince(t1);
      if (attempt > 0 && !newlyHeld) {
        break;  // the solution passes the observability checks too
      }
      if (attempt > 0) {
        // A laser failed the checks at the solution: back to the start values for the held lasers
        // and to the segmentation's planes, and solve again without them.
        say(config, "pass " + std::to_string(pass) + ": lasers unobservable at the solution held, solving again");
        st.normal = segNormal;
        st.offset = segOffset;
        for (std::size_t l = 0; l < start.size(); ++l) {
          if (st.held[l]) {
            st.x[l] = st.start[l];
            static_cast<void>(current.set(l, start.params(l)));
          }
        }
      }
      std::size_t free = 0;
      for (std::size_t l = 0; l < start.size(); ++l) {
        free += st.held[l] ? 0U : 1U;
      }
      if (free == 0) {
        result.lasersHeld = start.size();
        error = "no laser is observable from these scans (see the per-laser reasons)";
        return false;
      }
      char line[160];
      std::snprintf(line, sizeof line, "pass %d: %zu scans segmented (%.2f s), %zu lasers estimated, %zu held", pass,
                    scans.size(), secondsSince(t0), free, start.size() - free);
      say(config, line);

      // The Ceres problem.
      const Clock::time_point t2 = Clock::now();
      ceres::Problem::Options po;
      po.manifold_ownership = ceres::TAKE_OWNERSHIP;
      ceres::Problem problem(po);
      std::vector<int> constant;
      for (int k = 0; k < kLaserParamCount; ++k) {
        if (!est[k]) {
          constant.push_back(k);
        }
      }
      std::vector<double> normalStore(3 * scans.size());
      for (std::size_t s = 0; s < scans.size(); ++s) {
        Eigen::Map<Eigen::Vector3d> n(&normalStore[3 * s]);
        n = st.normal[s];
      }
      std::vector<bool> added(start.size(), false);
      for (const Group& g : st.groups) {
        auto* cost = new ceres::AutoDiffCostFunction<PlaneCost, ceres::DYNAMIC, kLaserParamCount, 3, 1>(
            new PlaneCost{&g, 1.0 / std::sqrt(static_cast<double>(st.scanPoints[g.scan])), alongBeam},
            static_cast<int>(g.phi.size()));
        problem.AddResidualBlock(cost, nullptr, st.x[g.laser].data(), &normalStore[3 * g.scan], &st.offset[g.scan]);
        added[g.laser] = true;
      }
      for (std::size_t s = 0; s < scans.size(); ++s) {
        if (problem.HasParameterBlock(&normalStore[3 * s])) {
          problem.SetManifold(&normalStore[3 * s], new ceres::SphereManifold<3>());
        }
      }
      for (std::size_t l = 0; l < start.size(); ++l) {
        if (!added[l]) {
          continue;
        }
        if (st.held[l]) {
          problem.SetParameterBlockConstant(st.x[l].data());
        } else if (!constant.empty()) {
          problem.SetManifold(st.x[l].data(), new ceres::SubsetManifold(kLaserParamCount, constant));
        }
      }
      // Gauge constraints over the free lasers.
      const Columns cols = makeColumns(st, est);
      for (const auto& gauge : gauges(st, cols, est, config.holdMeanTheta)) {
        std::vector<Vec5> coef;
        std::vector<Vec5> x0;
        std::vector<double*> blocks;
        for (std::size_t l = 0; l < start.size(); ++l) {
          if (st.held[l] || !added[l]) {
            continue;
          }
          Vec5 cf = Vec5::Zero();
          for (int k = 0; k < kLaserParamCount; ++k) {
            const int col = cols.laser[l][static_cast<std::size_t>(k)];
            cf[k] = col >= 0 ? gauge.second[col] : 0.0;
          }
          coef.push_back(cf);
          x0.push_back(st.start[l]);
          blocks.push_back(st.x[l].data());
        }
        problem.AddResidualBlock(new GaugeCost(coef, x0, 1e3), nullptr, blocks);
      }
      ceres::Solver::Options so;
      so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
      so.num_threads = std::max(1, config.threads);
      so.max_num_iterations = config.maxIterations;
      so.function_tolerance = 1e-14;
      so.gradient_tolerance = 1e-16;
      so.parameter_tolerance = 1e-12;
      so.logging_type = ceres::SILENT;
      ProgressCallback callback(config, pass);
      if (config.progress) {
        so.callbacks.push_back(&callback);
      }
      ceres::Solver::Summary summary;
      ceres::Solve(so, &problem, &summary);
      result.iterations += static_cast<int>(summary.iterations.size()) - 1;
      result.secondsSolve += secondsSince(t2);
      if (summary.termination_type == ceres::FAILURE || summary.termination_type == ceres::USER_FAILURE) {
        error = "the solver failed: " + summary.message;
        return false;
      }
      for (std::size_t s = 0; s < scans.size(); ++s) {
        st.normal[s] = Eigen::Map<Eigen::Vector3d>(&normalStore[3 * s]);
      }
      for (std::size_t l = 0; l < start.size(); ++l) {
        if (!st.held[l]) {
          static_cast<void>(current.set(l, toLaserParams(st.x[l])));
        }
      }
      std::snprintf(line, sizeof line, "pass %d: %s, %d iterations, cost %.6e -> %.6e m^2 (%.2f s)", pass,
                    ceres::TerminationTypeToString(summary.termination_type),
                    static_cast<int>(summary.iterations.size()) - 1, 2.0 * summary.initial_cost,
                    2.0 * summary.final_cost, secondsSince(t2));
      say(config, line);
    }
  }

  // Figures at the solution (the thesis' minimum; with the noise-bias correction, below, the
  // calibrated values move off it by their bias).
  const Clock::time_point t3 = Clock::now();
  double joint = 0.0;
  std::vector<double> sumSq(scans.size(), 0.0);
  for (const Group& g : st.groups) {
    for (std::size_t k = 0; k < g.phi.size(); ++k) {
      const double r =
          st.normal[g.scan].dot(laserModelPoint(st.x[g.laser].data(), g.phi[k], g.range[k])) - st.offset[g.scan];
      sumSq[g.scan] += r * r;
    }
  }
  std::vector<std::vector<std::size_t>> targets;
  for (const ScanReport& r : result.scans) {
    targets.push_back(r.targets);
  }
  const std::vector<double> before = planeResiduals(scans, targets, start);
  const std::vector<double> after = planeResiduals(scans, targets, current);
  for (std::size_t s = 0; s < scans.size(); ++s) {
    joint += st.scanPoints[s] > 0 ? sumSq[s] / static_cast<double>(st.scanPoints[s]) : 0.0;
    result.scans[s].rmsStart = before[s];
    result.scans[s].rmsFinal = after[s];
    result.costStart += before[s] * before[s];
    result.costFinal += after[s] * after[s];
    const Plane pca = pcaPlane(scanPoints(scans[s], current), &targets[s], nullptr);
    result.maxPlaneAngle =
        std::max(result.maxPlaneAngle, std::acos(std::min(1.0, std::fabs(pca.normal.dot(st.normal[s])))));
  }
  result.costFinalJoint = joint;
  result.costCalibrated = result.costFinal;
  const Columns cols = makeColumns(st, est);
  const Information atMinimum = accumulate(st, cols, alongBeam);
  const bool correct = !alongBeam && config.correctNoiseBias && config.noiseBiasSteps > 0;
  if (correct) {
    st.beforeCorrection = st.x;
    result.noiseBias = correctNoiseBias(st, cols, est, config.holdMeanTheta, atMinimum, config.noiseBiasSteps);
    for (std::size_t l = 0; l < start.size(); ++l) {
      if (!st.held[l]) {
        static_cast<void>(current.set(l, toLaserParams(st.x[l])));
      }
    }
    const std::vector<double> corrected = planeResiduals(scans, targets, current);
    result.costCalibrated = 0.0;
    for (std::size_t s = 0; s < scans.size(); ++s) {
      result.scans[s].rmsFinal = corrected[s];
      result.costCalibrated += corrected[s] * corrected[s];
    }
  }
  // One correction step (the default) moves the values by about their bias, which changes the
  // geometry of the information negligibly: the analysis at the minimum serves (and its residuals
  // are the noise's estimate). More steps: analysed again at the corrected values.
  const bool again = correct && config.noiseBiasSteps > 1;
  const Analysis a =
      analyse(st, cols, est, config.nullThreshold, config.holdMeanTheta, alongBeam, again ? nullptr : &atMinimum);
  result.conditioning = a.report;
  result.noiseSigma = a.sigma;
  result.rangeSigma = a.rangeSigma;
  result.calibrated = current;
  for (std::size_t l = 0; l < start.size(); ++l) {
    LaserReport& lr = result.lasers[l];
    lr.estimate = current.params(l);
    lr.minimum = st.held[l] || st.beforeCorrection.empty() ? lr.estimate : toLaserParams(st.beforeCorrection[l]);
    lr.estimated = !st.held[l];
    if (lr.estimated) {
      ++result.lasersEstimated;
      for (int k = 0; k < kLaserParamCount; ++k) {
        const int col = cols.laser[l][static_cast<std::size_t>(k)];
        lr.sigma[k] = col >= 0 ? std::sqrt(std::max(0.0, a.covariance(col, col))) : 0.0;
      }
      lr.maxCorrelation = laserCorrelation(a.shape, cols, l, lr.maxCorrelationPair);
    } else {
      ++result.lasersHeld;
    }
  }
  result.secondsAnalysis += secondsSince(t3);
  return true;
}

}  // namespace agv::lidar_calibration
