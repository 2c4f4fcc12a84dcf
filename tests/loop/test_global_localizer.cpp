// Global localization against a LandmarkMap: a synthetic warehouse of 256 reflector poles (no ray
// casting, but physically honest: every pole within 30 m and 360 deg is seen with 1 cm noise, 10 %
// are missed, 2 spurious detections per scan, a laser mounted off the logical point), random true
// poses; symmetric layouts refused as ambiguous; weak, empty, NaN and over-capacity inputs refused;
// zero wrong poses over 200 trials; the multi-scan confirmation; no allocation.
// Portable: also runs in the Cortex-M7 image (big objects are static).
#include <cmath>
#include <cstddef>

#include "agv/localization/landmark_map.hpp"
#include "agv/loop/global_localizer.hpp"
#include "agv_test.hpp"
#include "loop_test_util.hpp"

using namespace agv;
using agv::test::LoopRng;

namespace {

constexpr std::size_t kPoles = 256;
constexpr double kSide = 220.0;  // [m] hall side: ~15 poles within 30 m on average
constexpr double kRange = 30.0;  // [m] laser range
constexpr double kSigma = 0.01;  // [m] detection noise per coordinate
constexpr double kMiss = 0.10;   // probability of missing a pole
constexpr std::size_t kSpurious = 2;
constexpr double kDeg = 0.017453292519943295;
#ifdef AGV_TEST_MCU
constexpr std::size_t kTrials = 40;  // emulated Cortex-M7: fewer trials, same checks
constexpr std::size_t kHallTrials = 20;
#else
constexpr std::size_t kTrials = 200;
constexpr std::size_t kHallTrials = 100;
#endif

const Pose2d kMount{0.85, 0.05, 0.02};  // laser in the vehicle frame

LandmarkMap& warehouseMap() {
  static LandmarkMap map;
  return map;
}
GlobalLocalizer& localizer() {
  static GlobalLocalizer loc;
  return loc;
}

Eigen::Vector2d g_poles[kPoles];
LandmarkKind g_kinds[kPoles];

/// Random poles; every `cornerEvery`-th one (0: none) is a FALKO corner instead of a reflector.
void buildWarehouse(std::uint64_t seed, std::size_t cornerEvery = 0) {
  LoopRng rng{seed};
  static Eigen::Vector2f pts[kPoles];
  agv::test::randomPoints(rng, kPoles, 0.0, 0.0, kSide, kSide, 3.0, pts);
  LandmarkMap& map = warehouseMap();
  map.clear();
  for (std::size_t i = 0; i < kPoles; ++i) {
    g_poles[i] = pts[i].cast<double>();
    g_kinds[i] = cornerEvery != 0 && i % cornerEvery == 0 ? LandmarkKind::Corner : LandmarkKind::Reflector;
    REQUIRE(map.addSurveyed(g_kinds[i], g_poles[i].x(), g_poles[i].y(), 0.005, static_cast<std::uint32_t>(i + 1)).ok());
  }
}

/// One scan seen from vehicle pose `truth` (laser frame); returns the number of true detections.
std::size_t scan(const Pose2d& truth, LoopRng& rng, PointObservation* out, std::size_t& n, bool spurious = true,
                 double miss = kMiss) {
  const Pose2d laser = truth.compose(kMount);
  n = 0;
  std::size_t real = 0;
  for (std::size_t i = 0; i < kPoles && n < kMaxLoopPoints; ++i) {
    const Eigen::Vector2d p = laser.inverseTransformPoint(g_poles[i]);
    if (p.norm() > kRange) {
      continue;
    }
    if (rng.uniform() < miss) {
      continue;
    }
    out[n].x = p.x() + kSigma * rng.normal();
    out[n].y = p.y() + kSigma * rng.normal();
    out[n].kind = g_kinds[i];
    ++n;
    ++real;
  }
  for (std::size_t s = 0; spurious && s < kSpurious && n < kMaxLoopPoints; ++s) {
    const double r = rng.uniform(1.0, kRange);
    const double a = rng.uniform(-3.14159, 3.14159);
    out[n].x = r * std::cos(a);
    out[n].y = r * std::sin(a);
    out[n].kind = LandmarkKind::Reflector;
    ++n;
  }
  return real;
}

double posError(const Pose2d& a, const Pose2d& b) {
  return std::hypot(a.x - b.x, a.y - b.y);
}
double angError(const Pose2d& a, const Pose2d& b) {
  return std::fabs(angleDiff(a.theta, b.theta));
}

GlobalLocalizerParams params() {
  GlobalLocalizerParams p;
  p.laserMount = kMount;
  return p;
}

/// A 720-beam full-turn scan of walls 20 m away all round, nothing nearer: every pole of the
/// map within 20 m of a pose is in its clear view.
void openRoomScan(LaserScan& scan) {
  scan.angleMin = -3.14159265F;
  scan.angleIncrement = 2.0F * 3.14159265F / 720.0F;
  scan.rangeMin = 0.1F;
  scan.rangeMax = 50.0F;
  scan.ranges.clear();
  for (std::size_t i = 0; i < 720; ++i) {
    REQUIRE(scan.ranges.push_back(20.0F) == Status::Ok);
  }
}

/// The copy scene of the negative-evidence tests: four poles seen from the origin (kSeenPoles),
/// a copy of the first three 40 m along x, and `extras` (more poles, near the copy), static.
const Eigen::Vector2d kSeenPoles[4] = {{5.0, 0.5}, {0.5, 6.0}, {-4.0, -3.0}, {3.0, -5.5}};
/// Clears `map` and surveys the four poles seen from the origin; `id` is then the next free id.
/// (void: the MCU runner's REQUIRE returns from the function.)
void surveySeenPoles(LandmarkMap& map, std::uint32_t& id) {
  map.clear();
  id = 1;
  for (const Eigen::Vector2d& p : kSeenPoles) {
    REQUIRE(map.addSurveyed(LandmarkKind::Reflector, p.x(), p.y(), 0.001, id++).ok());
  }
}

void buildCopyScene(LandmarkMap& map, const Eigen::Vector2d* extras, std::size_t extraCount) {
  std::uint32_t id = 1;
  surveySeenPoles(map, id);
  for (std::size_t i = 0; i < 3; ++i) {
    REQUIRE(map.addSurveyed(LandmarkKind::Reflector, kSeenPoles[i].x() + 40.0, kSeenPoles[i].y(), 0.001, id++).ok());
  }
  for (std::size_t i = 0; i < extraCount; ++i) {
    REQUIRE(map.addSurveyed(LandmarkKind::Reflector, extras[i].x(), extras[i].y(), 0.001, id++).ok());
  }
  map.setMode(MapMode::Static);
}

/// The four seen poles as observations from the origin (laser at the logical point), into obs[0..3].
void seenPoleObservations(PointObservation* obs) {
  for (std::size_t i = 0; i < 4; ++i) {
    obs[i] = PointObservation{kSeenPoles[i].x(), kSeenPoles[i].y(), LandmarkKind::Reflector};
  }
}

}  // namespace

TEST_CASE("global localizer: finds random poses in a 256-pole warehouse, never a wrong one", "[loop][reloc]") {
  buildWarehouse(17);
  GlobalLocalizer& loc = localizer();
  loc.setParams(params());
  LoopRng rng{2024};
  static PointObservation obs[kMaxLoopPoints];
  std::size_t found = 0;
  std::size_t refused = 0;
  std::size_t wrong = 0;
  std::size_t ambiguous = 0;
  std::size_t weak = 0;
  std::size_t other = 0;
  double worstPos = 0.0;
  double worstAng = 0.0;
  for (std::size_t t = 0; t < kTrials; ++t) {
    // Interior poses: a 30 m range sees poles all round (~15 detections on average).
    const Pose2d truth{rng.uniform(20.0, kSide - 20.0), rng.uniform(20.0, kSide - 20.0), rng.uniform(-3.14, 3.14)};
    std::size_t n = 0;
    (void)scan(truth, rng, obs, n);
    RelocReport r;
    const Status st = loc.localize(warehouseMap(), Span<const PointObservation>(obs, n), r);
    if (st == Status::Ok) {
      const double e = posError(r.pose, truth);
      const double ea = angError(r.pose, truth);
      if (e > 0.05 || ea > 0.5 * kDeg) {
        ++wrong;
      } else {
        ++found;
        worstPos = e > worstPos ? e : worstPos;
        worstAng = ea > worstAng ? ea : worstAng;
      }
    } else {
      ++refused;
      if (r.outcome == RelocOutcome::Ambiguous) {
        ++ambiguous;
      } else if (r.outcome == RelocOutcome::WeakSupport) {
        ++weak;
      } else {
        ++other;
      }
    }
  }
  INFO("found " << found << " refused " << refused << " (ambiguous " << ambiguous << ", weak " << weak << ", other "
                << other << ") wrong " << wrong << " worst " << worstPos << " m " << worstAng / kDeg << " deg");
#ifndef AGV_TEST_MCU
  WARN("reloc trials: found " << found << " refused " << refused << " (ambiguous " << ambiguous << ", weak " << weak
                              << ", other " << other << ") wrong " << wrong << "; worst " << worstPos << " m, "
                              << worstAng / kDeg << " deg");
#endif
  CHECK(wrong == 0U);
  CHECK(other == 0U);
  CHECK(found * 10U >= kTrials * 9U);
  CHECK(worstPos <= 0.05);
  CHECK(worstAng <= 0.5 * kDeg);
}

TEST_CASE("global localizer: whole hall, edges included, never a wrong pose", "[loop][reloc]") {
  buildWarehouse(99);
  GlobalLocalizer& loc = localizer();
  loc.setParams(params());
  LoopRng rng{7};
  static PointObservation obs[kMaxLoopPoints];
  std::size_t wrong = 0;
  std::size_t found = 0;
  for (std::size_t t = 0; t < kHallTrials; ++t) {
    const Pose2d truth{rng.uniform(0.0, kSide), rng.uniform(0.0, kSide), rng.uniform(-3.14, 3.14)};
    std::size_t n = 0;
    (void)scan(truth, rng, obs, n);
    RelocReport r;
    if (n > 0 && loc.localize(warehouseMap(), Span<const PointObservation>(obs, n), r) == Status::Ok) {
      if (posError(r.pose, truth) > 0.05 || angError(r.pose, truth) > 0.5 * kDeg) {
        ++wrong;
      } else {
        ++found;
      }
    }
  }
#ifndef AGV_TEST_MCU
  WARN("reloc whole hall: found " << found << " of " << kHallTrials << ", wrong " << wrong);
#endif
  CHECK(wrong == 0U);
  CHECK(found * 10U >= kHallTrials * 6U);
}

TEST_CASE("global localizer: mixed map of reflectors and corners, kinds respected", "[loop][reloc]") {
  buildWarehouse(41, 3);  // a third of the landmarks are FALKO corners
  GlobalLocalizer& loc = localizer();
  loc.setParams(params());
  LoopRng rng{43};
  static PointObservation obs[kMaxLoopPoints];
  std::size_t found = 0;
  std::size_t wrong = 0;
  for (std::size_t t = 0; t < kHallTrials; ++t) {
    const Pose2d truth{rng.uniform(20.0, kSide - 20.0), rng.uniform(20.0, kSide - 20.0), rng.uniform(-3.14, 3.14)};
    std::size_t n = 0;
    (void)scan(truth, rng, obs, n);
    RelocReport r;
    if (loc.localize(warehouseMap(), Span<const PointObservation>(obs, n), r) == Status::Ok) {
      (posError(r.pose, truth) > 0.05 || angError(r.pose, truth) > 0.5 * kDeg ? wrong : found) += 1;
    }
  }
#ifndef AGV_TEST_MCU
  WARN("reloc mixed kinds: found " << found << " of " << kHallTrials << ", wrong " << wrong);
#endif
  CHECK(wrong == 0U);
  CHECK(found * 10U >= kHallTrials * 9U);
}

TEST_CASE("global localizer: symmetric reflector layouts are refused as ambiguous", "[loop][reloc]") {
  LandmarkMap& map = warehouseMap();
  GlobalLocalizer& loc = localizer();
  loc.setParams(params());
  static PointObservation obs[kMaxLoopPoints];
  // (1) a 20 x 10 m rectangle of poles every 5 m along its sides: 180 deg symmetric (and mirror).
  // (2) a 180 deg rotationally symmetric pattern with no mirror symmetry.
  const double rect[][2] = {{0, 0},  {5, 0},   {10, 0},  {15, 0},  {20, 0}, {0, 10},
                            {5, 10}, {10, 10}, {15, 10}, {20, 10}, {0, 5},  {20, 5}};
  const double rot[][2] = {{0, 0}, {3, 1}, {7, -2}, {-4, 5}, {2, 6}, {-3, -1}, {-7, 2}, {4, -5}, {-2, -6}};
  for (int layout = 0; layout < 2; ++layout) {
    map.clear();
    const std::size_t count = layout == 0 ? sizeof(rect) / sizeof(rect[0]) : sizeof(rot) / sizeof(rot[0]);
    for (std::size_t i = 0; i < count; ++i) {
      const double* p = layout == 0 ? rect[i] : rot[i];
      REQUIRE(map.addSurveyed(LandmarkKind::Reflector, p[0], p[1], 0.005, static_cast<std::uint32_t>(i + 1)).ok());
      g_poles[i] = Eigen::Vector2d(p[0], p[1]);
      g_kinds[i] = LandmarkKind::Reflector;
    }
    for (std::size_t i = count; i < kPoles; ++i) {
      g_poles[i] = Eigen::Vector2d(1e4, 1e4);  // out of range
    }
    LoopRng rng{static_cast<std::uint64_t>(300 + layout)};
    for (int t = 0; t < 10; ++t) {
      const Pose2d truth = layout == 0 ? Pose2d{rng.uniform(3.0, 17.0), rng.uniform(2.0, 8.0), rng.uniform(-3.1, 3.1)}
                                       : Pose2d{rng.uniform(-3.0, 3.0), rng.uniform(-3.0, 3.0), rng.uniform(-3.1, 3.1)};
      std::size_t n = 0;
      (void)scan(truth, rng, obs, n, false, 0.0);
      RelocReport r;
      const Status st = loc.localize(map, Span<const PointObservation>(obs, n), r);
      INFO("layout " << layout << " trial " << t << " outcome " << static_cast<int>(r.outcome) << " inliers "
                     << r.inliers << " second " << r.secondInliers);
      CHECK(st == Status::Rejected);
      CHECK(r.outcome == RelocOutcome::Ambiguous);
      CHECK(r.hasSecond);
      CHECK(r.secondInliers == r.inliers);
    }
  }
  // Breaking the rectangle's symmetry with three extra poles on one side makes the pose unique.
  map.clear();
  const double extra[][2] = {{2.0, 12.5}, {7.5, 13.0}, {13.0, 12.0}};
  std::size_t count = 0;
  for (const auto& p : rect) {
    g_poles[count] = Eigen::Vector2d(p[0], p[1]);
    ++count;
  }
  for (const auto& p : extra) {
    g_poles[count] = Eigen::Vector2d(p[0], p[1]);
    ++count;
  }
  for (std::size_t i = 0; i < count; ++i) {
    g_kinds[i] = LandmarkKind::Reflector;
    REQUIRE(map.addSurveyed(LandmarkKind::Reflector, g_poles[i].x(), g_poles[i].y(), 0.005,
                            static_cast<std::uint32_t>(i + 1))
                .ok());
  }
  LoopRng rng{400};
  const Pose2d truth{9.0, 4.0, 0.7};
  std::size_t n = 0;
  (void)scan(truth, rng, obs, n, false, 0.0);
  RelocReport r;
  CHECK(loc.localize(map, Span<const PointObservation>(obs, n), r) == Status::Ok);
  CHECK(posError(r.pose, truth) < 0.05);
}

TEST_CASE("global localizer: weak, empty, non-finite and over-capacity inputs are refused", "[loop][reloc]") {
  buildWarehouse(5);
  GlobalLocalizer& loc = localizer();
  loc.setParams(params());
  static PointObservation obs[kMaxLoopPoints + 1];
  LoopRng rng{11};
  const Pose2d truth{110.0, 110.0, 0.3};
  std::size_t n = 0;
  (void)scan(truth, rng, obs, n, false, 0.0);
  REQUIRE(n >= 6U);
  RelocReport r;
  // Three true detections: a clique of 3 fixes a pose, but 3 < N_min = 4.
  CHECK(loc.localize(warehouseMap(), Span<const PointObservation>(obs, 3), r) == Status::NotEnoughData);
  CHECK(r.outcome == RelocOutcome::WeakSupport);
  // Empty observations, empty map.
  CHECK(loc.localize(warehouseMap(), Span<const PointObservation>(), r) == Status::EmptyInput);
  // NaN and infinity.
  const double saved = obs[2].x;
  obs[2].x = std::nan("");
  CHECK(loc.localize(warehouseMap(), Span<const PointObservation>(obs, n), r) == Status::NonFiniteInput);
  CHECK(r.outcome == RelocOutcome::NonFiniteInput);
  obs[2].x = saved;
  obs[3].y = HUGE_VAL;
  CHECK(loc.localize(warehouseMap(), Span<const PointObservation>(obs, n), r) == Status::NonFiniteInput);
  (void)scan(truth, rng, obs, n, false, 0.0);
  // Over capacity: 65 observations, counted.
  for (std::size_t i = n; i < kMaxLoopPoints + 1; ++i) {
    obs[i] = obs[i % n];
  }
  CHECK(loc.localize(warehouseMap(), Span<const PointObservation>(obs, kMaxLoopPoints + 1), r) ==
        Status::CapacityExceeded);
  CHECK(r.outcome == RelocOutcome::OverCapacity);
  CHECK(r.refusedObservations == 1U);
  // Invalid parameters.
  GlobalLocalizerParams bad = params();
  bad.minSupport = 2;
  loc.setParams(bad);
  CHECK(loc.localize(warehouseMap(), Span<const PointObservation>(obs, n), r) == Status::InvalidArgument);
  // Work bound: one node for the whole call is hit and reported.
  GlobalLocalizerParams tight = params();
  tight.maxTotalNodes = 1;
  loc.setParams(tight);
  CHECK(loc.localize(warehouseMap(), Span<const PointObservation>(obs, n), r) == Status::NotConverged);
  CHECK(r.outcome == RelocOutcome::WorkBoundHit);
  loc.setParams(params());
  CHECK(loc.localize(warehouseMap(), Span<const PointObservation>(obs, n), r) == Status::Ok);
  CHECK(posError(r.pose, truth) < 0.05);
  // Steady state: no allocation.
  AGV_CHECK_NO_ALLOCATIONS((void)loc.localize(warehouseMap(), Span<const PointObservation>(obs, n), r));
  // An empty map.
  warehouseMap().clear();
  CHECK(loc.localize(warehouseMap(), Span<const PointObservation>(obs, n), r) == Status::EmptyInput);
}

TEST_CASE("reloc confirmer: confirms a true candidate over K scans, rejects a wrong one", "[loop][reloc]") {
  buildWarehouse(23);
  LoopRng rng{31};
  static PointObservation obs[kMaxLoopPoints];
  Pose2d truth{100.0, 90.0, 1.0};
  const Pose2d step{0.5, 0.0, 0.05};  // odometry between scans (vehicle frame)
  RelocConfirmer good;
  RelocConfirmer bad;
  good.start(Pose2d{truth.x + 0.02, truth.y - 0.01, truth.theta + 0.002});
  bad.start(Pose2d{truth.x + 1.0, truth.y, truth.theta});
  CHECK(good.state() == RelocConfirmState::Pending);
  RelocConfirmState sg = RelocConfirmState::Pending;
  RelocConfirmState sb = RelocConfirmState::Pending;
  for (int k = 0; k < 3; ++k) {
    truth = truth.compose(step).normalized();
    std::size_t n = 0;
    (void)scan(truth, rng, obs, n);
    sg = good.step(step, warehouseMap(), Span<const PointObservation>(obs, n), kMount);
    sb = bad.step(step, warehouseMap(), Span<const PointObservation>(obs, n), kMount);
    if (k < 2) {
      CHECK(sg == RelocConfirmState::Pending);
    }
    CHECK(sb == RelocConfirmState::Rejected);
  }
  CHECK(sg == RelocConfirmState::Confirmed);
  CHECK(good.confirmedScans() == 3U);
  CHECK(posError(good.pose(), truth) < 0.03);
  // A NaN odometry increment rejects.
  good.start(truth);
  CHECK(good.step(Pose2d{std::nan(""), 0.0, 0.0}, warehouseMap(), Span<const PointObservation>(obs, 1), kMount) ==
        RelocConfirmState::Rejected);
}

#ifndef AGV_TEST_MCU
namespace {

/// A regular warehouse: 16 x 16 poles on a `pitch` grid, each moved by up to +-jitter per axis.
void buildGrid(double pitch, double jitter, std::uint64_t seed) {
  LoopRng rng{seed};
  LandmarkMap& map = warehouseMap();
  map.clear();
  for (std::size_t i = 0; i < kPoles; ++i) {
    g_poles[i] = Eigen::Vector2d(static_cast<double>(i % 16) * pitch + rng.uniform(-jitter, jitter),
                                 static_cast<double>(i / 16) * pitch + rng.uniform(-jitter, jitter));
    g_kinds[i] = LandmarkKind::Reflector;
    REQUIRE(map.addSurveyed(LandmarkKind::Reflector, g_poles[i].x(), g_poles[i].y(), 0.005,
                            static_cast<std::uint32_t>(i + 1))
                .ok());
  }
}

}  // namespace

#ifdef AGV_TEST_EMULATED
constexpr std::size_t kGridTrials = 40;  // trials per grid; qemu-user (agv_test.hpp): 90 % of this file's time natively
#else
constexpr std::size_t kGridTrials = 200;
#endif

TEST_CASE("global localizer: regular pole grids, heavy clutter: refusals, never a wrong pose", "[loop][reloc]") {
  GlobalLocalizer& loc = localizer();
  loc.setParams(params());
  static PointObservation obs[kMaxLoopPoints];
  struct Case {
    const char* name;
    double jitter;  // [m]
    double miss;
    bool spurious;
  };
  const Case cases[] = {{"perfect 12 m grid", 0.0, kMiss, true},
                        {"12 m grid, 0.05 m jitter", 0.05, kMiss, true},
                        {"12 m grid, 0.1 m jitter", 0.1, kMiss, true},
                        {"12 m grid, 0.3 m jitter", 0.3, kMiss, true},
                        {"12 m grid, 0.3 m jitter, 30 % missed", 0.3, 0.30, true}};
  for (const Case& c : cases) {
    buildGrid(12.0, c.jitter, 77);
    LoopRng rng{555};
    std::size_t found = 0;
    std::size_t refused = 0;
    std::size_t wrong = 0;
    for (std::size_t t = 0; t < kGridTrials; ++t) {
      const Pose2d truth{rng.uniform(20.0, 160.0), rng.uniform(20.0, 160.0), rng.uniform(-3.14, 3.14)};
      std::size_t n = 0;
      (void)scan(truth, rng, obs, n, c.spurious, c.miss);
      RelocReport r;
      if (loc.localize(warehouseMap(), Span<const PointObservation>(obs, n), r) == Status::Ok) {
        (posError(r.pose, truth) > 0.05 || angError(r.pose, truth) > 0.5 * kDeg ? wrong : found) += 1;
      } else {
        ++refused;
      }
    }
    WARN("reloc " << c.name << ": found " << found << " refused " << refused << " wrong " << wrong);
    CHECK(wrong == 0U);
    if (c.jitter == 0.0) {
      CHECK(found == 0U);  // a perfect grid is translation-symmetric: always ambiguous
    }
  }
}
#endif

TEST_CASE("global localizer: a scan's clear view refutes a pose that expects undetected poles", "[loop][reloc]") {
  // Four poles seen from the origin; 40 m away a copy of three of them and two more poles that a
  // vehicle standing at the copy would have in clear view. The copy explains 3 of the 4
  // observations: within the margin of 2 by inliers alone. With the scan, it expects the two
  // extra poles, nothing was detected there, and it scores 3 - 2 = 1 against 4.
  static LandmarkMap map;
  const Eigen::Vector2d extras[2] = {{42.0, 2.0}, {38.0, 2.5}};
  buildCopyScene(map, extras, 2);
  PointObservation obs[4];
  seenPoleObservations(obs);
  const Span<const PointObservation> o(obs, 4);
  static GlobalLocalizer loc;  // laser at the logical point
  static LaserScan scan;
  openRoomScan(scan);
  RelocReport r;
  {  // inliers alone: ambiguous
    CHECK(loc.localize(map, o, r) == Status::Rejected);
    CHECK(r.outcome == RelocOutcome::Ambiguous);
    CHECK(r.inliers == 4U);
    CHECK(r.secondInliers == 3U);
  }
  {  // with the scan: found, the copy refuted
    REQUIRE(loc.localize(map, o, scan, r) == Status::Ok);
    CHECK(r.outcome == RelocOutcome::Found);
    CHECK(std::hypot(r.pose.x, r.pose.y) < 0.01);
    CHECK(std::fabs(r.pose.theta) < 0.01);
    CHECK(r.missed == 0U);
    CHECK(r.hasSecond);
    CHECK(r.secondInliers == 3U);
    CHECK(r.secondMissed == 2U);
    CHECK(std::fabs(r.secondPose.x - 40.0) < 0.05);
    AGV_CHECK_NO_ALLOCATIONS((void)loc.localize(map, o, scan, r));
  }
  {  // one of the two extra poles detected after all: ambiguous
    PointObservation more[5] = {obs[0], obs[1], obs[2], obs[3], PointObservation{2.0, 2.0, LandmarkKind::Reflector}};
    // The fifth detection is not on the map under the truth; under the copy it is the pole at
    // (42, 2), which is then explained: 4 inliers, 1 missed, against the truth's 4, 0 missed.
    CHECK(loc.localize(map, Span<const PointObservation>(more, 5), scan, r) == Status::Rejected);
    CHECK(r.outcome == RelocOutcome::Ambiguous);
  }
  {  // the poles hidden in the scan (something 1 m away all round): ambiguous (last: it changes the scan)
    for (std::size_t i = 0; i < scan.ranges.size(); ++i) {
      scan.ranges[i] = 1.0F;
    }
    CHECK(loc.localize(map, o, scan, r) == Status::Rejected);
    CHECK(r.outcome == RelocOutcome::Ambiguous);
    CHECK(r.secondMissed == 0U);
  }
}

#ifndef AGV_TEST_MCU  // host only: a second map, localizer and scan would not fit the M7 image's RAM budget
TEST_CASE("global localizer: the margin against a runner-up the scan refutes, and decoys completing a copy",
          "[loop][reloc]") {
  // Four poles seen from the origin; 40 m away a copy of three of them and `extra` more poles in
  // a vehicle's clear view at the copy. The copy explains 3 of the 4 observations.
  static LandmarkMap map;
  // Farther from the copy than the seen poles: the three nearest detections (the anchors) stay true.
  const Eigen::Vector2d extraPoles[3] = {{48.0, 3.0}, {33.0, 4.0}, {46.0, -6.0}};
  const auto build = [&](std::size_t extra) { buildCopyScene(map, extraPoles, extra); };
  PointObservation obs[7];
  seenPoleObservations(obs);
  static GlobalLocalizer loc;  // laser at the logical point
  static LaserScan scan;
  openRoomScan(scan);
  RelocReport r;
  GlobalLocalizerParams p;
  {  // one extra pole: the copy scores 3 - 1 = 2 against 4. Margin 2: ambiguous.
    build(1);
    loc.setParams(p);
    CHECK(loc.localize(map, Span<const PointObservation>(obs, 4), scan, r) == Status::Rejected);
    CHECK(r.outcome == RelocOutcome::Ambiguous);
    CHECK(r.secondInliers == 3U);
    CHECK(r.secondMissed == 1U);
    // Margin 1 against a refuted runner-up: found, at the truth.
    p.refutedMargin = 1;
    loc.setParams(p);
    REQUIRE(loc.localize(map, Span<const PointObservation>(obs, 4), scan, r) == Status::Ok);
    CHECK(r.outcome == RelocOutcome::Found);
    CHECK(std::hypot(r.pose.x, r.pose.y) < 0.01);
    CHECK(r.secondMissed == 1U);
    AGV_CHECK_NO_ALLOCATIONS((void)loc.localize(map, Span<const PointObservation>(obs, 4), scan, r));
  }
  {  // three extra poles and three decoys where the copy expects them: the copy explains 6 of 7,
     // nothing missed; the truth 4, nothing missed. The truth is not refuted: margin 2 holds.
    build(3);
    for (std::size_t i = 0; i < 3; ++i) {
      obs[4 + i] = PointObservation{extraPoles[i].x() - 40.0, extraPoles[i].y(), LandmarkKind::Reflector};
    }
    const Span<const PointObservation> o(obs, 7);
    p.refutedMargin = 1;
    loc.setParams(p);
    CHECK(loc.localize(map, o, scan, r) == Status::Rejected);
    CHECK(r.outcome == RelocOutcome::Ambiguous);
    CHECK(r.inliers == 6U);
    CHECK(r.secondInliers == 4U);
    CHECK(r.secondMissed == 0U);
    // A margin of 1 for every runner-up takes the decoy-completed copy: the wrong pose.
    p.ambiguityMargin = 1;
    loc.setParams(p);
    REQUIRE(loc.localize(map, o, scan, r) == Status::Ok);
    CHECK(std::fabs(r.pose.x - 40.0) < 0.05);
  }
}

TEST_CASE("global localizer: net support, the poles a pose expects in clear view and nothing shows count against it",
          "[loop][reloc]") {
  // Four poles seen from the origin and two more in its clear view (a 20 m open room) that nothing
  // detected: the truth explains the 4 observations and misses 2, a net support of 2.
  static LandmarkMap map;
  std::uint32_t id = 1;
  surveySeenPoles(map, id);
  REQUIRE(map.addSurveyed(LandmarkKind::Reflector, 2.0, 2.0, 0.001, id++).ok());
  REQUIRE(map.addSurveyed(LandmarkKind::Reflector, -2.0, 2.5, 0.001, id++).ok());
  map.setMode(MapMode::Static);
  PointObservation obs[6];
  seenPoleObservations(obs);
  const Span<const PointObservation> o(obs, 4);
  static GlobalLocalizer loc;  // laser at the logical point
  static LaserScan scan;
  openRoomScan(scan);
  GlobalLocalizerParams p;
  RelocReport r;
  {  // off (the core default): found at the truth, 2 missed
    loc.setParams(p);
    REQUIRE(loc.localize(map, o, scan, r) == Status::Ok);
    CHECK(std::hypot(r.pose.x, r.pose.y) < 0.01);
    CHECK(r.inliers == 4U);
    CHECK(r.missed == 2U);
  }
  {  // asked for exactly the net support: found
    p.minNetSupport = 2;
    loc.setParams(p);
    REQUIRE(loc.localize(map, o, scan, r) == Status::Ok);
    CHECK(std::hypot(r.pose.x, r.pose.y) < 0.01);
  }
  {  // one more: refused as weak support (not ambiguous: no other place competes), nothing allocated
    p.minNetSupport = 3;
    loc.setParams(p);
    CHECK(loc.localize(map, o, scan, r) == Status::NotEnoughData);
    CHECK(r.outcome == RelocOutcome::WeakSupport);
    CHECK(r.inliers == 4U);
    CHECK(r.missed == 2U);
    AGV_CHECK_NO_ALLOCATIONS((void)loc.localize(map, o, scan, r));
    // The largest value refuses too (no wrap-around to a negative threshold).
    p.minNetSupport = static_cast<std::size_t>(-1);
    loc.setParams(p);
    CHECK(loc.localize(map, o, scan, r) == Status::NotEnoughData);
    CHECK(r.outcome == RelocOutcome::WeakSupport);
    p.minNetSupport = 3;
    loc.setParams(p);
    // Without a scan there is no negative evidence and nothing to net: the inliers decide.
    REQUIRE(loc.localize(map, o, r) == Status::Ok);
    CHECK(std::hypot(r.pose.x, r.pose.y) < 0.01);
  }
  {  // the two poles detected after all: 6 inliers, nothing missed, found
    obs[4] = PointObservation{2.0, 2.0, LandmarkKind::Reflector};
    obs[5] = PointObservation{-2.0, 2.5, LandmarkKind::Reflector};
    REQUIRE(loc.localize(map, Span<const PointObservation>(obs, 6), scan, r) == Status::Ok);
    CHECK(r.inliers == 6U);
    CHECK(r.missed == 0U);
    CHECK(std::hypot(r.pose.x, r.pose.y) < 0.01);
  }
  {  // the poles hidden behind something 1 m away all round: not expected, nothing missed, found
    for (std::size_t i = 0; i < scan.ranges.size(); ++i) {
      scan.ranges[i] = 1.0F;
    }
    REQUIRE(loc.localize(map, o, scan, r) == Status::Ok);
    CHECK(r.missed == 0U);
  }
}

TEST_CASE("reloc confirmer: a place passed over by its refutation must stay refuted on every sweep", "[loop][reloc]") {
  // The map of the margin test with one extra pole: four poles seen from the origin, a copy of
  // three of them 40 m away and a pole at (48, 3) that a vehicle at the copy has in clear view.
  // With refutedMargin 1 the truth is found over the copy (3 inliers, 1 missed) by the copy's
  // refutation alone; the confirmer keeps checking it.
  static LandmarkMap map;
  const Eigen::Vector2d extra{48.0, 3.0};
  buildCopyScene(map, &extra, 1);
  PointObservation obs[5];
  seenPoleObservations(obs);
  const Span<const PointObservation> truthView(obs, 4);
  // A detection where the copy's laser would see the pole at (48, 3): under the truth it lands on
  // nothing, under the copy on that pole (a decoy).
  obs[4] = PointObservation{8.0, 3.0, LandmarkKind::Reflector};
  const Span<const PointObservation> withDecoy(obs, 5);
  static GlobalLocalizer loc;
  static LaserScan scan;
  openRoomScan(scan);
  GlobalLocalizerParams p;
  p.refutedMargin = 1;
  loc.setParams(p);
  RelocReport r;
  REQUIRE(loc.localize(map, truthView, scan, r) == Status::Ok);
  CHECK(std::hypot(r.pose.x, r.pose.y) < 0.01);
  REQUIRE(r.refutedRivals == 1U);
  CHECK(std::fabs(r.rivals[0].x - 40.0) < 0.05);
  CHECK(std::fabs(r.rivals[0].y) < 0.05);
  // The free function agrees with the search's count.
  CHECK(missedLandmarks(map, truthView, scan, r.pose, p) == r.missed);
  CHECK(missedLandmarks(map, truthView, scan, r.rivals[0], p) == r.secondMissed);
  CHECK(missedLandmarks(map, truthView, scan, r.rivals[0], p) == 1U);
  CHECK(loc.sameAnswer(r, Pose2d(0.1, -0.1, 0.05)));
  CHECK_FALSE(loc.sameAnswer(r, Pose2d(1.0, 0.0, 0.0)));
  CHECK_FALSE(loc.sameAnswer(r, Pose2d(0.0, 0.0, 0.5)));
  // Without the refuted margin (margin 2 for every place) the same sweep is ambiguous: no rivals.
  RelocReport strict;
  GlobalLocalizerParams p2 = p;
  p2.refutedMargin = 2;
  loc.setParams(p2);
  CHECK(loc.localize(map, truthView, scan, strict) == Status::Rejected);
  CHECK_FALSE(loc.sameAnswer(strict, Pose2d{}));
  CHECK(strict.refutedRivals == 0U);
  loc.setParams(p);

  const RelocConfirmParams cp{2, 0.15, 3, 0.6};
  const Pose2d still{};
  {  // the same view on the next sweeps: the copy stays refuted, confirmed after 2 sweeps
    RelocConfirmer c(cp);
    c.start(r, p, map, truthView, scan);
    CHECK(c.step(still, map, truthView, p.laserMount, &scan) == RelocConfirmState::Pending);
    CHECK(c.step(still, map, truthView, p.laserMount, &scan) == RelocConfirmState::Confirmed);
    CHECK(std::hypot(c.pose().x, c.pose().y) < 0.01);
  }
  {  // a confirming sweep whose detections explain the pole at (48, 3) under the copy: the copy
     // scores 4 with nothing missed, within the margin of the truth's 4: rejected
    RelocConfirmer c(cp);
    c.start(r, p, map, truthView, scan);
    CHECK(c.step(still, map, withDecoy, p.laserMount, &scan) == RelocConfirmState::Rejected);
  }
  {  // the pole hidden on a later sweep (something 1 m away all round): the first sweep's
     // refutation stands, nothing explains the pole (the evidence of all sweeps)
    RelocConfirmer c(cp);
    c.start(r, p, map, truthView, scan);
    static LaserScan blocked;
    openRoomScan(blocked);
    for (std::size_t i = 0; i < blocked.ranges.size(); ++i) {
      blocked.ranges[i] = 1.0F;
    }
    CHECK(c.step(still, map, truthView, p.laserMount, &blocked) == RelocConfirmState::Pending);
    AGV_CHECK_NO_ALLOCATIONS((void)c.step(still, map, truthView, p.laserMount, &blocked));
    CHECK(c.state() == RelocConfirmState::Confirmed);
  }
  {  // rivals to refute but no scan to refute them with: rejected
    RelocConfirmer c(cp);
    c.start(r, p, map, truthView, scan);
    CHECK(c.step(still, map, truthView, p.laserMount, nullptr) == RelocConfirmState::Rejected);
  }
  {  // a report that is not Found, or invalid search parameters, cannot be started
    RelocConfirmer c(cp);
    c.start(strict, p, map, truthView, scan);
    CHECK(c.state() == RelocConfirmState::Rejected);
    GlobalLocalizerParams bad = p;
    bad.inlierGate = std::nan("");
    c.start(r, bad, map, truthView, scan);
    CHECK(c.state() == RelocConfirmState::Rejected);
  }
}
#endif
