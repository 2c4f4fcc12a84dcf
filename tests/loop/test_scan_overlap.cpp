// Scan agreement (hits and free-space conflicts) of two ray-cast scans of a room: the true
// transform agrees, a wrong one does not; a point in free space conflicts, an occluded one does
// not, a beam without a return says nothing; refusals; no allocation.
#include <cmath>
#include <cstddef>

#include "agv/loop/scan_overlap.hpp"
#include "agv_test.hpp"

using namespace agv;

namespace {

struct Segment {
  double ax, ay, bx, by;
};

// A 12 m x 8 m room with a pillar and a wall stub: not symmetric.
constexpr Segment kRoom[] = {
    {0, 0, 12, 0},  {12, 0, 12, 8}, {12, 8, 0, 8}, {0, 8, 0, 0},  // walls
    {4, 3, 5, 3},   {5, 3, 5, 4},   {5, 4, 4, 4},  {4, 4, 4, 3},  // pillar
    {8, 8, 8, 5.5},                                               // wall stub
};

// Ray-casts a 181-beam, 180-degree scan (1 degree) from `pose`; ranges beyond 30 m are no return.
void castScan(const Pose2d& pose, LaserScan& scan) {
  scan.ranges.clear();
  scan.angleMin = -1.5707963F;
  scan.angleIncrement = 0.017453292F;
  scan.rangeMin = 0.05F;
  scan.rangeMax = 30.0F;
  for (std::size_t b = 0; b < 181; ++b) {
    const double a = pose.theta + static_cast<double>(scan.angle(b));
    const double dx = std::cos(a);
    const double dy = std::sin(a);
    double best = 1e9;
    for (const Segment& s : kRoom) {
      const double ex = s.bx - s.ax;
      const double ey = s.by - s.ay;
      const double den = dx * ey - dy * ex;
      if (std::fabs(den) < 1e-12) {
        continue;
      }
      const double wx = s.ax - pose.x;
      const double wy = s.ay - pose.y;
      const double t = (wx * ey - wy * ex) / den;
      const double u = (wx * dy - wy * dx) / den;
      if (t > 1e-9 && u >= 0.0 && u <= 1.0 && t < best) {
        best = t;
      }
    }
    (void)scan.ranges.push_back(static_cast<float>(best < 30.0 ? best : 50.0));
  }
}

// A scan with the given readings at 1-degree steps from -90 degrees.
void scanOf(std::initializer_list<float> ranges, LaserScan& scan) {
  scan.ranges.clear();
  scan.angleMin = -1.5707963F;
  scan.angleIncrement = 0.017453292F;
  scan.rangeMin = 0.05F;
  scan.rangeMax = 30.0F;
  for (float r : ranges) {
    (void)scan.ranges.push_back(r);
  }
}

}  // namespace

TEST_CASE("scan overlap: the true transform agrees, wrong ones do not", "[loop][scan_overlap]") {
  static LaserScan a;
  static LaserScan b;
  static ScanOverlap first;
  static ScanOverlap second;
  const Pose2d poseA{2.0, 2.0, 0.3};
  const Pose2d poseB{3.0, 5.5, -0.2};
  castScan(poseA, a);
  castScan(poseB, b);
  const Pose2d truth = between(poseA, poseB);  // b's sensor in a's frame
  MutualOverlap ov;
  REQUIRE(mutualOverlap(first, a, second, b, truth, ov) == Status::Ok);
  // 0.71: the two 180-degree views share about that much of the walls (each sees walls the other
  // does not); no point of either lies in the other's free space.
  CHECK(ov.hitFraction > 0.65);
  CHECK(ov.conflictFraction < 0.01);
  CHECK(ov.inViewFraction > 0.75);

  // Shifted by 0.5 m or 1.5 m, turned by 0.1 rad or 0.3 rad: walls apart and in free space
  // (hits 0.01-0.43, conflicts 0.19-0.38).
  const Pose2d wrong[] = {{0.5, 0.0, 0.0}, {0.0, 1.5, 0.0}, {0.0, 0.0, 0.1}, {0.0, 0.0, 0.3}};
  for (const Pose2d& w : wrong) {
    INFO("error " << w.x << ", " << w.y << ", " << w.theta);
    REQUIRE(mutualOverlap(first, a, second, b, truth.compose(w), ov) == Status::Ok);
    CHECK(ov.hitFraction < 0.45);
    CHECK(ov.conflictFraction > 0.15);
  }

  // One direction: the score counts every valid reading of the placed scan.
  ScanOverlapScore s;
  REQUIRE(first.setReference(a) == Status::Ok);
  REQUIRE(first.score(b, truth, s) == Status::Ok);
  CHECK(s.points == 181);
  CHECK(s.hits <= s.points);
  CHECK(s.conflicts <= s.inView);
  CHECK(s.hitFraction() == Approx(static_cast<double>(s.hits) / 181.0));
}

TEST_CASE("scan overlap: free space conflicts, occlusion and no return do not", "[loop][scan_overlap]") {
  static LaserScan ref;
  static LaserScan placed;
  static ScanOverlap overlap;
  // Reference: a wall 5 m ahead on beams 80-100 (-10..+10 degrees), no return elsewhere.
  ref.ranges.clear();
  scanOf({}, ref);
  for (std::size_t i = 0; i < 181; ++i) {
    (void)ref.ranges.push_back(i >= 80 && i <= 100 ? 5.0F : 50.0F);
  }
  REQUIRE(overlap.setReference(ref) == Status::Ok);
  ScanOverlapScore s;
  // Placed at the reference's pose: one point at 2 m straight ahead (free space: conflict), one at
  // 5 m (on the wall: hit), one at 8 m (behind the wall: occluded, neither), one at 2 m at -60
  // degrees (the reference had no return there: nothing).
  placed.ranges.clear();
  scanOf({}, placed);
  for (std::size_t i = 0; i < 181; ++i) {
    (void)placed.ranges.push_back(50.0F);
  }
  placed.ranges[90] = 2.0F;
  placed.ranges[91] = 5.0F;
  placed.ranges[89] = 8.0F;
  placed.ranges[30] = 2.0F;
  REQUIRE(overlap.score(placed, Pose2d{}, s) == Status::Ok);
  CHECK(s.points == 4);
  CHECK(s.hits == 1);
  CHECK(s.inView == 3);
  CHECK(s.conflicts == 1);
  // Within the margin (0.30 m at 5 m: 4.75 m) a point is not a conflict.
  placed.ranges[90] = 4.75F;
  REQUIRE(overlap.score(placed, Pose2d{}, s) == Status::Ok);
  CHECK(s.conflicts == 0);
  // Placed behind the reference sensor (turned by pi): out of view, nothing.
  REQUIRE(overlap.score(placed, Pose2d{0.0, 0.0, 3.14159265}, s) == Status::Ok);
  CHECK(s.inView == 0);
  CHECK(s.conflicts == 0);
}

TEST_CASE("scan overlap: refusals", "[loop][scan_overlap]") {
  static LaserScan scan;
  static LaserScan empty;
  static ScanOverlap overlap;
  castScan(Pose2d{6.0, 2.0, 1.0}, scan);
  ScanOverlapScore s;
  s.points = 7;
  CHECK(overlap.score(scan, Pose2d{}, s) == Status::NotInitialized);
  CHECK(s.points == 0);
  // Parameters: every field finite and > 0.
  ScanOverlapParams p;
  CHECK(isValid(p));
  p.cell = 0.0F;
  CHECK(overlap.setParams(p) == Status::InvalidArgument);
  p = ScanOverlapParams{};
  p.conflictMargin = std::nanf("");
  CHECK(overlap.setParams(p) == Status::InvalidArgument);
  p = ScanOverlapParams{};
  p.conflictRatio = -0.1F;
  CHECK(overlap.setParams(p) == Status::InvalidArgument);
  CHECK(overlap.setParams(ScanOverlapParams{}) == Status::Ok);
  // A scan without a valid reading, and a bad angle increment.
  scanOf({50.0F, 0.0F, std::nanf(""), 31.0F}, empty);
  CHECK(overlap.setReference(empty) == Status::EmptyInput);
  CHECK(overlap.score(scan, Pose2d{}, s) == Status::NotInitialized);
  REQUIRE(overlap.setReference(scan) == Status::Ok);
  CHECK(overlap.score(empty, Pose2d{}, s) == Status::EmptyInput);
  CHECK(overlap.score(scan, Pose2d{std::nan(""), 0.0, 0.0}, s) == Status::NonFiniteInput);
  CHECK(overlap.score(scan, Pose2d{0.0, 0.0, INFINITY}, s) == Status::NonFiniteInput);
  CHECK(s.points == 0);
  scan.angleIncrement = 0.0F;
  CHECK(overlap.score(scan, Pose2d{}, s) == Status::InvalidArgument);
  CHECK(overlap.setReference(scan) == Status::InvalidArgument);
  MutualOverlap m;
  CHECK(mutualOverlap(overlap, scan, overlap, scan, Pose2d{}, m) == Status::InvalidArgument);
  CHECK(m.hitFraction == 0.0);
  CHECK(m.conflictFraction == 1.0);
}

TEST_CASE("scan overlap: verifying allocates nothing", "[loop][scan_overlap]") {
  static LaserScan a;
  static LaserScan b;
  static ScanOverlap first;
  static ScanOverlap second;
  castScan(Pose2d{2.0, 2.0, 0.3}, a);
  castScan(Pose2d{3.0, 5.5, -0.2}, b);
  const Pose2d t = between(Pose2d{2.0, 2.0, 0.3}, Pose2d{3.0, 5.5, -0.2});
  MutualOverlap ov;
  Status st = Status::InvalidArgument;
  AGV_CHECK_NO_ALLOCATIONS({ st = mutualOverlap(first, a, second, b, t, ov); });
  CHECK(st == Status::Ok);
  CHECK(ov.hitFraction > 0.65);
}
