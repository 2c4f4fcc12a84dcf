// Localizer behaviour on hand-built scenes: bad inputs, health flags, map lifecycle through the
// localizer, zero allocations in steady state (host only).
#include <Eigen/Core>
#include <memory>
#include <random>
#include <vector>

#include "agv/localization/localizer.hpp"
#include "agv_test.hpp"
#include "stand_still.hpp"

using namespace agv;

namespace {
struct Scene {
  LocalizerParams params;
  std::unique_ptr<Localizer> loc;
  std::unique_ptr<LandmarkMap> map;
  std::unique_ptr<ScanObservations> scan;
  Pose2d truth{2.0, 1.0, 0.3};
  Timestamp t = Timestamp::fromSeconds(10.0);
  std::vector<Eigen::Vector2d> world;
  std::mt19937_64 rng{3};

  explicit Scene(MapMode mode = MapMode::Static, bool surveyed = true, std::int16_t minHitsToCorrect = 0) {
    params.laser.mounting = Pose2d{1.0, 0.0, 0.0};
    params.map.minHitsToCorrect = minHitsToCorrect;
    loc = std::make_unique<Localizer>(params);
    LandmarkMapParams mp;
    mp.mode = mode;
    map = std::make_unique<LandmarkMap>(mp);
    scan = std::make_unique<ScanObservations>();
    for (int i = 0; i < 8; ++i) {
      const double a = 0.5 * i - 1.75;  // all inside the 270 deg field of view
      world.emplace_back(truth.x + 6.0 * std::cos(a + truth.theta) + 0.3 * i,
                         truth.y + 6.0 * std::sin(a + truth.theta));
    }
    if (surveyed) {
      std::uint32_t id = 1;
      for (const auto& w : world)
        REQUIRE(map->addSurveyed(LandmarkKind::Reflector, w.x(), w.y(), 0.0, id++).ok());
    }
    Eigen::Matrix3d P0 = Eigen::Matrix3d::Zero();
    P0(0, 0) = P0(1, 1) = 1e-4;
    P0(2, 2) = 1e-5;
    REQUIRE(loc->reset(t, truth, P0) == Status::Ok);
  }
  /// Standing still: one zero increment per 10 ms.
  void stand(int steps) { test::standStill(*loc, t, steps); }
  /// Noisy observations of `points` (world) from the true pose, stamped now.
  void observe(const std::vector<Eigen::Vector2d>& points, LandmarkKind kind = LandmarkKind::Reflector) {
    scan->stamp = t;
    scan->kindsDetected = kAllLandmarkKinds;
    scan->points.clear();
    std::normal_distribution<double> n(0.0, 0.002);
    const Pose2d lw = truth.compose(params.laser.mounting);
    for (const auto& w : points) {
      const Eigen::Vector2d z = lw.inverseTransformPoint(w);
      REQUIRE(scan->points.push_back(PointObservation{z.x() + n(rng), z.y() + n(rng), kind}) == Status::Ok);
    }
  }
  const LocalizerHealth& cycle() { return loc->correct(*scan, *map); }
};
}  // namespace

TEST_CASE("localizer: refuses to work before initialisation and refuses a bad initial state",
          "[localization][localizer]") {
  auto loc = std::make_unique<Localizer>();
  auto map = std::make_unique<LandmarkMap>();
  auto scan = std::make_unique<ScanObservations>();
  const LocalizerHealth& h = loc->correct(*scan, *map);
  CHECK(h.status == Status::NotInitialized);
  CHECK(hasFlag(h.flags, LocalizerFlag::NotInitialized));
  OdometryIncrement inc;
  inc.stamp = Timestamp::fromSeconds(1.0);
  CHECK(loc->predict(inc) == Status::NotInitialized);
  CHECK(loc->reset(Timestamp{}, Pose2d{std::nan(""), 0.0, 0.0}, Eigen::Matrix3d::Identity()) ==
        Status::InvalidArgument);
  CHECK_FALSE(loc->initialized());
}

TEST_CASE("localizer: a good cycle uses every landmark and reports consistent test ratios",
          "[localization][localizer]") {
  Scene s;
  s.stand(10);
  s.observe(s.world);
  const LocalizerHealth& h = s.cycle();
  CHECK(h.status == Status::Ok);
  CHECK(h.used == s.world.size());
  CHECK(h.expectedInView == s.world.size());
  CHECK(h.flags == 0U);
  CHECK(h.maxTestRatio < 1.0);
  CHECK(h.meanTestRatio > 0.0);
  CHECK(h.positionSigma < 0.01);
  CHECK_FALSE(h.lost);
  AGV_CHECK_NEAR(s.loc->pose().x, s.truth.x, 0.005);
  AGV_CHECK_NEAR(s.loc->pose().y, s.truth.y, 0.005);
}

TEST_CASE("localizer: bad observations and odometry are refused, counted and flagged without corrupting the state",
          "[localization][localizer]") {
  Scene s;
  s.stand(5);
  const Pose2d before = s.loc->pose();
  const Eigen::Matrix3d Pbefore = s.loc->covariance();
  // Non-finite odometry and an out-of-order increment: refused, state unchanged, flagged next cycle.
  OdometryIncrement bad;
  bad.stamp = s.t + Duration::fromMilliseconds(10);
  bad.delta = Pose2d{std::nan(""), 0.0, 0.0};
  CHECK(s.loc->predict(bad) == Status::NonFiniteInput);
  bad.delta = Pose2d{0.1, 0.0, 0.0};
  bad.covariance(2, 2) = std::numeric_limits<double>::infinity();
  CHECK(s.loc->predict(bad) == Status::NonFiniteInput);
  OdometryIncrement old;
  old.stamp = s.t;  // not after the newest
  CHECK(s.loc->predict(old) == Status::InvalidArgument);
  CHECK(s.loc->pose().x == before.x);
  CHECK(s.loc->covariance() == Pbefore);
  // A scan of only non-finite and out-of-view points: nothing used, pose unchanged.
  s.scan->stamp = s.t;
  s.scan->points.clear();
  (void)s.scan->points.push_back(PointObservation{std::nan(""), 1.0, LandmarkKind::Reflector});
  (void)s.scan->points.push_back(
      PointObservation{1.0, std::numeric_limits<double>::infinity(), LandmarkKind::Reflector});
  (void)s.scan->points.push_back(PointObservation{100.0, 0.0, LandmarkKind::Reflector});  // beyond range
  (void)s.scan->points.push_back(PointObservation{-5.0, 0.0, LandmarkKind::Reflector});   // behind: outside 270 deg
  const LocalizerHealth h = s.cycle();
  CHECK(h.rejectedNonFinite == 2U);
  CHECK(h.rejectedOutOfView == 2U);
  CHECK(h.used == 0U);
  CHECK(hasFlag(h.flags, LocalizerFlag::ObservationNonFinite));
  CHECK(hasFlag(h.flags, LocalizerFlag::ObservationOutOfView));
  CHECK(hasFlag(h.flags, LocalizerFlag::OdometryRejected));
  CHECK(hasFlag(h.flags, LocalizerFlag::NoFix));
  CHECK(s.loc->pose().x == before.x);
  CHECK(s.loc->pose().theta == before.theta);
  CHECK(s.loc->covariance() == Pbefore);
  // A NaN among good observations does not stop the good ones.
  s.stand(1);
  s.observe(s.world);
  (void)s.scan->points.push_back(PointObservation{std::nan(""), std::nan(""), LandmarkKind::Reflector});
  const LocalizerHealth h2 = s.cycle();
  CHECK(h2.used == s.world.size());
  CHECK(h2.rejectedNonFinite == 1U);
  CHECK_FALSE(hasFlag(h2.flags, LocalizerFlag::OdometryRejected));  // reported once
  CHECK(s.loc->pose().isFinite());
}

TEST_CASE("localizer: scans outside the odometry history or out of order are refused", "[localization][localizer]") {
  Scene s;
  s.stand(20);
  s.observe(s.world);
  const Pose2d before = s.loc->pose();
  s.scan->stamp = s.t + Duration::fromMilliseconds(150);  // newer than the odometry by > 100 ms
  LocalizerHealth h = s.cycle();
  CHECK(h.status == Status::Rejected);
  CHECK(hasFlag(h.flags, LocalizerFlag::ScanRejected));
  CHECK(hasFlag(h.flags, LocalizerFlag::ScanTooNew));
  s.scan->stamp = Timestamp::fromSeconds(9.0);  // before the history
  h = s.cycle();
  CHECK(hasFlag(h.flags, LocalizerFlag::ScanTooOld));
  CHECK(s.loc->pose().x == before.x);
  // a scan 50 ms old is fused; one older than it afterwards is refused
  s.scan->stamp = s.t - Duration::fromMilliseconds(45);
  h = s.cycle();
  CHECK(h.status == Status::Ok);
  CHECK(h.used == s.world.size());
  s.scan->stamp = s.t - Duration::fromMilliseconds(55);
  h = s.cycle();
  CHECK(hasFlag(h.flags, LocalizerFlag::ScanTooOld));
  // a scan slightly ahead of the odometry (within maxScanLead) is fused at the newest state
  s.scan->stamp = s.t + Duration::fromMilliseconds(20);
  h = s.cycle();
  CHECK(h.status == Status::Ok);
  CHECK(h.used == s.world.size());
}

TEST_CASE("localizer: gate, duplicate and lost health", "[localization][localizer]") {
  Scene s;
  s.stand(2);
  s.observe(s.world);
  // a ghost 0.1 m off one landmark (~9 sigma): it has a candidate within the search radius but fails the gate
  const Eigen::Vector2d ghost =
      s.truth.compose(s.params.laser.mounting).inverseTransformPoint(s.world[0] + Eigen::Vector2d(0.1, 0.0));
  (void)s.scan->points.push_back(PointObservation{ghost.x(), ghost.y(), LandmarkKind::Reflector});
  // a second detection 3 mm from another landmark: both within the gate, one is a duplicate
  const PointObservation twin{s.scan->points[1].x + 0.003, s.scan->points[1].y, LandmarkKind::Reflector};
  (void)s.scan->points.push_back(twin);
  LocalizerHealth h = s.cycle();
  CHECK(h.rejectedGate == 1U);
  CHECK(h.rejectedDuplicate == 1U);
  CHECK(h.used == s.world.size());
  CHECK(hasFlag(h.flags, LocalizerFlag::GateRejected));
  CHECK(hasFlag(h.flags, LocalizerFlag::DuplicateRejected));
  // Landmarks expected but none seen: bad cycles, lost after lostAfterBadCycles (latched).
  for (int c = 1; c <= 5; ++c) {
    s.stand(10);
    s.scan->stamp = s.t;
    s.scan->points.clear();
    h = s.cycle();
    // flagged bad up to the cycle that turns lost; a lost localizer only reports Lost
    CHECK(hasFlag(h.flags, LocalizerFlag::BadCycle) == (c <= s.params.health.lostAfterBadCycles));
    CHECK(h.lost == (c >= s.params.health.lostAfterBadCycles));
  }
  CHECK(h.status == Status::Lost);
  CHECK(hasFlag(h.flags, LocalizerFlag::Lost));
  s.stand(1);
  s.observe(s.world);
  CHECK(s.cycle().lost);  // latched
  Eigen::Matrix3d P0 = Eigen::Matrix3d::Identity() * 1e-4;
  REQUIRE(s.loc->reset(s.t, s.truth, P0) == Status::Ok);
  CHECK_FALSE(s.loc->lost());
}

TEST_CASE("localizer: dynamic map without a prior map: insert, confirm, forget", "[localization][localizer][map]") {
  Scene s(MapMode::Dynamic, false);
  const std::int16_t maxHits = s.map->params().maxHits;
  std::vector<Eigen::Vector2d> seen = s.world;
  // first scan inserts every observation
  s.stand(10);
  s.observe(seen, LandmarkKind::Corner);
  LocalizerHealth h = s.cycle();
  CHECK(h.unmatched == seen.size());
  CHECK(h.inserted == seen.size());
  CHECK(s.map->size() == seen.size());
  // later scans match them: hits grow to the cap
  for (int c = 0; c < maxHits + 3; ++c) {
    s.stand(10);
    s.observe(seen, LandmarkKind::Corner);
    h = s.cycle();
    CHECK(h.used == seen.size());
    CHECK(h.inserted == 0U);
  }
  s.map->forEach([&](LandmarkIndex, const Landmark& l) { CHECK(l.hits == maxHits); });
  // a transient point (a person) seen once: inserted, then deleted the next cycle it is missed
  std::vector<Eigen::Vector2d> withPerson = seen;
  withPerson.emplace_back(s.truth.x + 3.0 * std::cos(s.truth.theta), s.truth.y + 3.0 * std::sin(s.truth.theta) + 0.5);
  s.stand(10);
  s.observe(withPerson, LandmarkKind::Corner);
  h = s.cycle();
  CHECK(h.inserted == 1U);
  CHECK(s.map->size() == seen.size() + 1U);
  s.stand(10);
  s.observe(seen, LandmarkKind::Corner);
  h = s.cycle();
  CHECK(h.deleted == 1U);
  CHECK(s.map->size() == seen.size());
  // a landmark that disappears for good (a pallet moved) dies after maxHits cycles in view
  const Eigen::Vector2d gone = seen.back();
  seen.pop_back();
  int cycles = 0;
  for (; cycles < 100 && s.map->size() > seen.size(); ++cycles) {
    s.stand(10);
    s.observe(seen, LandmarkKind::Corner);
    (void)s.cycle();
  }
  CHECK(cycles == maxHits);
  (void)gone;
  // Reflector detections do not decrement corners when the corner detector did not run.
  s.stand(10);
  s.observe({}, LandmarkKind::Corner);
  s.scan->kindsDetected = landmarkKindBit(LandmarkKind::Reflector);
  const std::size_t sizeBefore = s.map->size();
  for (int c = 0; c < 2 * maxHits; ++c) {
    s.stand(10);
    s.scan->stamp = s.t;
    (void)s.cycle();
  }
  CHECK(s.map->size() == sizeBefore);
}

TEST_CASE("localizer: a new dynamic landmark is tentative (matched, not used) until minHitsToCorrect",
          "[localization][localizer][map]") {
  constexpr std::int16_t kNeed = 5;
  Scene s(MapMode::Dynamic, false, kNeed);
  const std::size_t n = s.world.size();
  s.stand(10);
  s.observe(s.world, LandmarkKind::Corner);
  LocalizerHealth h = s.cycle();
  REQUIRE(h.inserted == n);
  const std::int16_t initialHits = s.map->params().initialHits;
  // Matched but not used while the hit count is below kNeed: the filter state is exactly the
  // prediction's, the map still counts the matches and averages the positions.
  int tentativeCycles = 0;
  for (std::int16_t hits = initialHits; hits < kNeed; ++hits) {
    s.stand(10);
    s.observe(s.world, LandmarkKind::Corner);
    const Pose2d before = s.loc->pose();
    const Eigen::Matrix3d covBefore = s.loc->covariance();
    h = s.cycle();
    CHECK(h.used == 0U);
    CHECK(h.tentative == n);
    CHECK(h.inserted == 0U);
    CHECK((h.flags & static_cast<std::uint32_t>(LocalizerFlag::NoFix)) != 0U);
    CHECK((h.flags & static_cast<std::uint32_t>(LocalizerFlag::BadCycle)) == 0U);  // a tentative match counts as seen
    CHECK_FALSE(s.loc->lost());
    CHECK(s.loc->pose().x == before.x);
    CHECK(s.loc->pose().theta == before.theta);
    CHECK(s.loc->covariance() == covBefore);
    s.map->forEach([&](LandmarkIndex, const Landmark& l) { CHECK(l.hits == hits + 1); });
    ++tentativeCycles;
  }
  CHECK(tentativeCycles == kNeed - initialHits);
  // Confirmed: every match now corrects, and the position uncertainty shrinks.
  s.stand(10);
  s.observe(s.world, LandmarkKind::Corner);
  const double varBefore = s.loc->covariance()(0, 0);
  h = s.cycle();
  CHECK(h.used == n);
  CHECK(h.tentative == 0U);
  CHECK(s.loc->covariance()(0, 0) < 0.5 * varBefore);
}

TEST_CASE("localizer: surveyed landmarks correct at once whatever minHitsToCorrect", "[localization][localizer][map]") {
  Scene s(MapMode::Static, true, 20);
  s.stand(10);
  s.observe(s.world);
  const LocalizerHealth& h = s.cycle();
  CHECK(h.used == s.world.size());
  CHECK(h.tentative == 0U);
}

TEST_CASE("localizer: a full map refuses new landmarks and the health says so", "[localization][localizer][map]") {
  Scene s(MapMode::Dynamic, true);
  // fill the rest of the map far away, out of view
  for (std::size_t i = s.map->size(); i < kMaxLandmarks; ++i) {
    REQUIRE(s.map
                ->insert(LandmarkKind::Corner, 500.0 + static_cast<double>(i % 64U),
                         500.0 + static_cast<double>(i / 64U), 1e-4)
                .ok());
  }
  s.stand(10);
  std::vector<Eigen::Vector2d> pts = s.world;
  pts.emplace_back(s.truth.x + 4.0 * std::cos(s.truth.theta), s.truth.y + 4.0 * std::sin(s.truth.theta));
  s.observe(pts);
  const std::uint32_t refusedBefore = s.map->counters().refusedFull;
  const LocalizerHealth h = s.cycle();
  CHECK(h.used == s.world.size());
  CHECK(h.insertRefused == 1U);
  CHECK(hasFlag(h.flags, LocalizerFlag::MapInsertRefused));
  CHECK(s.map->counters().refusedFull == refusedBefore + 1U);
}

TEST_CASE("localizer: the steady-state cycle allocates nothing", "[localization][localizer][alloc]") {
  Scene s(MapMode::Dynamic, true);
  s.stand(10);
  s.observe(s.world);
  (void)s.cycle();
  OdometryIncrement inc;
  inc.covariance = Eigen::Matrix3d::Identity() * 1e-9;
  for (int c = 0; c < 5; ++c) {
    s.observe(s.world);
    s.scan->stamp = s.t + Duration::fromMilliseconds(70);  // 30 ms before the newest odometry below
    AGV_CHECK_NO_ALLOCATIONS(for (int i = 0; i < 10; ++i) {
      s.t = s.t + Duration::fromMilliseconds(10);
      inc.stamp = s.t;
      (void)s.loc->predict(inc);
    }(void)s.loc->correct(*s.scan, *s.map));
    CHECK(s.loc->health().used == s.world.size());
  }
}

TEST_CASE("localizer: an observation between two landmarks inside the gate is ambiguous, not used",
          "[localization][localizer]") {
  Scene s;
  // two more reflectors 4 cm apart; the pose is known to ~1 cm, so both fall inside the gate
  const Eigen::Vector2d a = s.truth.compose(Pose2d{5.0, 0.5, 0.0}).translation();
  const Eigen::Vector2d b = a + Eigen::Vector2d(0.0, 0.04);
  REQUIRE(s.map->addSurveyed(LandmarkKind::Reflector, a.x(), a.y(), 0.0, 100U).ok());
  REQUIRE(s.map->addSurveyed(LandmarkKind::Reflector, b.x(), b.y(), 0.0, 101U).ok());
  s.stand(1);
  std::vector<Eigen::Vector2d> pts = s.world;
  pts.push_back(0.5 * (a + b));  // midway: neither can be told from the other
  s.observe(pts);
  LocalizerHealth h = s.cycle();
  CHECK(h.rejectedAmbiguous == 1U);
  CHECK(hasFlag(h.flags, LocalizerFlag::AmbiguityRejected));
  CHECK(h.used == s.world.size());
  // with the pose now known to ~1 mm, an observation of `a` itself is no longer ambiguous
  s.stand(1);
  pts.back() = a;
  s.observe(pts);
  h = s.cycle();
  CHECK(h.rejectedAmbiguous == 0U);
  CHECK(h.used == s.world.size() + 1U);
}

TEST_CASE("LocalizerParams::validate refuses each sub-struct's out-of-domain values", "[localizer][params]") {
  CHECK(agv::LocalizerParams{}.validate() == agv::Status::Ok);
  const auto refused = [](auto edit) {
    agv::LocalizerParams p;
    edit(p);
    return p.validate();
  };
  using P = agv::LocalizerParams;
  CHECK(refused([](P& p) { p.association.gate = 0.0; }) == agv::Status::InvalidArgument);
  CHECK(refused([](P& p) { p.association.gate = NAN; }) == agv::Status::NonFiniteInput);
  CHECK(refused([](P& p) { p.association.maxSearchRadius = -1.0; }) == agv::Status::InvalidArgument);
  CHECK(refused([](P& p) { p.laser.rangeMin = 40.0; }) == agv::Status::InvalidArgument);  // above rangeMax
  CHECK(refused([](P& p) { p.laser.angleMax = p.laser.angleMin; }) == agv::Status::InvalidArgument);
  CHECK(refused([](P& p) { p.laser.mounting.theta = INFINITY; }) == agv::Status::NonFiniteInput);
  CHECK(refused([](P& p) { p.laser.kindSigma[1] = -0.01; }) == agv::Status::InvalidArgument);
  CHECK(refused([](P& p) { p.occlusion.sigmas = 0.0; }) == agv::Status::InvalidArgument);
  CHECK(refused([](P& p) { p.occlusion.kindDepth[0] = -0.05; }) == agv::Status::InvalidArgument);
  CHECK(refused([](P& p) { p.map.insertSeparation = -0.3; }) == agv::Status::InvalidArgument);
  CHECK(refused([](P& p) { p.map.minHitsToCorrect = -1; }) == agv::Status::InvalidArgument);
  CHECK(refused([](P& p) { p.health.detectionRate[1] = 1.5; }) == agv::Status::InvalidArgument);
  CHECK(refused([](P& p) { p.health.minMatchedFraction = NAN; }) == agv::Status::NonFiniteInput);
  CHECK(refused([](P& p) { p.health.lostAfterBadCycles = 0; }) == agv::Status::InvalidArgument);
  CHECK(refused([](P& p) { p.health.maxPositionSigma = 0.0; }) == agv::Status::InvalidArgument);
  CHECK(refused([](P& p) { p.ekf.varianceFloorXY = 0.0; }) == agv::Status::InvalidArgument);
  CHECK(refused([](P& p) { p.maxScanLead = agv::Duration::fromMilliseconds(-1); }) == agv::Status::InvalidArgument);
  // Boundaries that are valid.
  CHECK(refused([](P& p) { p.health.detectionRate[0] = 1.0; }) == agv::Status::Ok);
  CHECK(refused([](P& p) { p.association.ambiguityMargin = 0.0; }) == agv::Status::Ok);
}

TEST_CASE("Per-source health: reflectors fused, displaced corners gated out, each counted on its own", "[localizer]") {
  // Four surveyed reflectors and four surveyed corners around a vehicle standing at the origin
  // (laser on the logical point). The reflectors are observed where they are (+2 mm), the corners
  // 0.4 m off: the reflectors must be fused with their small innovation, the corners refused.
  LandmarkMap map;
  const double pos[4][2] = {{4.0, 1.0}, {-3.0, 2.0}, {1.0, -5.0}, {-2.0, -3.0}};
  std::uint32_t id = 1;
  for (const auto& p : pos) {
    REQUIRE(map.addSurveyed(LandmarkKind::Reflector, p[0], p[1], 0.001, id++).ok());
    REQUIRE(map.addSurveyed(LandmarkKind::Corner, p[0] + 0.7, p[1] + 0.7, 0.001, id++).ok());
  }
  map.setMode(MapMode::Static);
  LocalizerParams params;
  params.laser.mounting = Pose2d{};
  params.laser.angleMin = -3.14159;
  params.laser.angleMax = 3.14159;
  Localizer loc(params);
  Timestamp t = Timestamp::fromSeconds(1.0);
  REQUIRE(loc.reset(t, Pose2d{}, Eigen::Matrix3d::Identity() * 1e-4) == Status::Ok);
  test::standStill(loc, t, 10);
  ScanObservations scan;
  scan.stamp = t;
  for (const auto& p : pos) {
    REQUIRE(scan.points.push_back(PointObservation{p[0] + 0.002, p[1], LandmarkKind::Reflector}) == Status::Ok);
    REQUIRE(scan.points.push_back(PointObservation{p[0] + 0.7 + 0.4, p[1] + 0.7, LandmarkKind::Corner}) == Status::Ok);
  }
  const LocalizerHealth& h = loc.correct(scan, map);
  const SourceHealth& refl = h.sources[static_cast<std::size_t>(LandmarkKind::Reflector)];
  const SourceHealth& corner = h.sources[static_cast<std::size_t>(LandmarkKind::Corner)];
  CHECK(refl.observed == 4U);
  CHECK(refl.fused == 4U);
  CHECK(refl.rejected == 0U);
  CHECK(refl.innovationRms > 0.0);
  CHECK(refl.innovationRms < 0.003);  // the 2 mm offset, shared out by the first updates
  CHECK(refl.maxTestRatio < 1.0);
  CHECK(refl.meanTestRatio <= refl.maxTestRatio);
  CHECK(corner.observed == 4U);
  CHECK(corner.fused == 0U);
  CHECK(corner.rejected + corner.unmatched == 4U);
  CHECK(corner.innovationRms == 0.0);
  // The per-source counts add up to the cycle's.
  CHECK(refl.fused + corner.fused == h.used);
  CHECK(refl.observed + corner.observed == h.observations);
}

TEST_CASE(
    "A map-less localizer whose covariance outgrows the limit keeps dead reckoning and says so; against a "
    "static map the same growth makes it lost",
    "[localizer]") {
  for (const MapMode mode : {MapMode::Dynamic, MapMode::Static}) {
    LandmarkMapParams mp;
    mp.mode = mode;
    LandmarkMap map(mp);
    LocalizerParams params;
    Localizer loc(params);
    Timestamp t = Timestamp::fromSeconds(1.0);
    REQUIRE(loc.reset(t, Pose2d{}, Eigen::Matrix3d::Identity() * 1e-4) == Status::Ok);
    bool lost = false;
    bool limit = false;
    bool badCycle = false;
    for (int cycle = 0; cycle < 60; ++cycle) {  // 6 s of 10 cm/s-sigma odometry: sigma passes 10 cm
      for (int i = 0; i < 10; ++i) {
        t = t + Duration::fromMilliseconds(10);
        OdometryIncrement inc;
        inc.stamp = t;
        inc.delta = Pose2d{0.01, 0.0, 0.0};
        inc.covariance = Eigen::Matrix3d::Identity() * 1e-4;
        REQUIRE(loc.predict(inc) == Status::Ok);
      }
      ScanObservations scan;  // nothing seen: no landmark in view either
      scan.stamp = t;
      const LocalizerHealth& h = loc.correct(scan, map);
      lost = lost || h.lost;
      limit = limit || hasFlag(h.flags, LocalizerFlag::CovarianceLimit);
      badCycle = badCycle || hasFlag(h.flags, LocalizerFlag::BadCycle);
    }
    INFO((mode == MapMode::Dynamic ? "dynamic" : "static"));
    CHECK(limit);  // the growth is reported either way
    CHECK(lost == (mode == MapMode::Static));
    CHECK(badCycle == (mode == MapMode::Static));
  }
}

TEST_CASE("localizer: carried to where its old pose expected nothing, unmatched reflectors make it lost",
          "[localization][localizer]") {
  // The vehicle's pose is believed 40 m away from the surveyed reflectors (nothing in view from
  // there, so the matched/expected check has nothing to check), while the laser sees the
  // reflectors from where it really is: observed, none matched.
  for (const double fraction : {0.3, 0.0}) {
    Scene s;
    s.params.health.minObservedMatchedFraction[0] = fraction;
    s.loc = std::make_unique<Localizer>(s.params);
    Eigen::Matrix3d P0 = Eigen::Matrix3d::Zero();
    P0(0, 0) = P0(1, 1) = 1e-4;
    P0(2, 2) = 1e-5;
    REQUIRE(s.loc->reset(s.t, Pose2d{s.truth.x + 40.0, s.truth.y, s.truth.theta}, P0) == Status::Ok);
    bool lost = false;
    for (int c = 0; c < 5; ++c) {
      s.stand(10);
      s.observe(s.world);
      const LocalizerHealth& h = s.cycle();
      CHECK(h.expectedInView == 0U);
      CHECK(h.used == 0U);
      lost = lost || h.lost;
    }
    INFO("minObservedMatchedFraction " << fraction);
    CHECK(lost == (fraction > 0.0));
  }
  LocalizerParams bad;
  bad.health.minObservedMatchedFraction[0] = 1.5;
  CHECK(bad.validate() == Status::InvalidArgument);
  // The field's side of the check (test_scan_matcher.cpp, "carried away at rest"): a fraction too.
  for (const double f : {-0.1, 1.01}) {
    LocalizerParams p;
    p.health.minFieldInlierFraction = f;
    CHECK(p.validate() == Status::InvalidArgument);
  }
  LocalizerParams nonFinite;
  nonFinite.health.minFieldInlierFraction = std::nan("");
  CHECK(nonFinite.validate() == Status::NonFiniteInput);
  LocalizerParams off;
  off.health.minFieldInlierFraction = 0.0;
  CHECK(off.validate() == Status::Ok);
}

TEST_CASE("localizer: an uncertain prior is not corrected by one observation alone (minimum support)",
          "[localization][localizer]") {
  const auto run = [](double priorSigma, std::size_t observed, std::uint16_t minSupport) {
    Scene s;
    s.params.association.minSupport = minSupport;
    s.loc = std::make_unique<Localizer>(s.params);
    Eigen::Matrix3d P0 = Eigen::Matrix3d::Zero();
    P0(0, 0) = P0(1, 1) = priorSigma * priorSigma;
    P0(2, 2) = 1e-4;
    REQUIRE(s.loc->reset(s.t, s.truth, P0) == Status::Ok);
    s.stand(1);
    s.observe(std::vector<Eigen::Vector2d>(s.world.begin(), s.world.begin() + static_cast<std::ptrdiff_t>(observed)));
    return s.cycle();
  };
  // Uncertain (0.3 m > supportSigma 0.2 m): one reflector is held back, two correct.
  const LocalizerHealth one = run(0.3, 1, 2);
  CHECK(one.used == 0U);
  CHECK(one.rejectedSupport == 1U);
  CHECK(hasFlag(one.flags, LocalizerFlag::SupportRejected));
  CHECK(one.sources[0].rejected == 1U);
  const LocalizerHealth two = run(0.3, 2, 2);
  CHECK(two.used == 2U);
  CHECK(two.rejectedSupport == 0U);
  // Certain (5 cm): one is enough. Off (minSupport 1): one corrects the uncertain prior too.
  CHECK(run(0.05, 1, 2).used == 1U);
  CHECK(run(0.3, 1, 1).used == 1U);
  LocalizerParams bad;
  bad.association.minSupport = 0;
  CHECK(bad.validate() == Status::InvalidArgument);
}
