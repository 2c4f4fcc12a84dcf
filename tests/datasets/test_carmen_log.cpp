// CARMEN / FLIRTLib log reader on hand-written lines and on the shared real logs.
#include <cmath>
#include <string>

#include "agv/datasets/carmen_log.hpp"
#include "agv_test.hpp"

using agv::datasets::CarmenLog;

namespace {
const std::string kData = std::string(AGV_SHARED_DATA_DIR) + "/laser2d/";

CarmenLog mustRead(const std::string& rel) {
  CarmenLog log;
  std::string err;
  INFO(kData + rel);
  REQUIRE(agv::datasets::readCarmenLog(kData + rel, log, err));  // a missing data folder fails loudly
  return log;
}
}  // namespace

TEST_CASE("carmen log: records, ground truth and malformed lines with their number", "[datasets]") {
  const std::string text =
      "# comment\n"
      "PARAM robot_frontlaser_offset -0.04 host 0\n"
      "VERTEX2 7 1.0 2.0 0.5\n"
      "ROBOTLASER1 0 -1.570796 3.141593 0.785398 50.0 0.1 0 4 1.0 2.5 81.83 0.3 0 "
      "4.9648966975 5.9808229785 0.5 5.0 6.0 0.5 0.1 0.0 0 0 0 12.5 x 12.75\n"
      "ODOM 1 2 0.1 0.5 0.01 0 100.5 pippo 100.25\n"
      "FLASER 3 1.0 2.0 3.0 4.0 5.0 0.3 4.0 5.0 0.3 7.5 pippo 7.25\n"
      "ROBOTLASER1 0 -1.5 3.1 0.01 50.0 0.1 0 5 1.0 2.0\n"  // line 7: truncated
      "VERTEX2 8 1.0 abc 0.5\n"                             // line 8: not a number
      "ODOM 1 2\n"                                          // line 9: truncated
      "EDGE2 7 8 0 0 0 100 0 100 500 0 0\n"
      "FLASER 2 1.0 nan? 0 0 0 0 0 0 0 h 0\n";  // line 11
  const CarmenLog log = agv::datasets::parseCarmenLog(text);
  CHECK(log.lines == 11U);
  REQUIRE(log.scans.size() == 2U);
  REQUIRE(log.odometry.size() == 1U);
  REQUIRE(log.vertices.size() == 1U);
  REQUIRE(log.issues.size() == 4U);
  CHECK(log.issues[0].line == 7U);
  CHECK(log.issues[1].line == 8U);
  CHECK(log.issues[2].line == 9U);
  CHECK(log.issues[3].line == 11U);
  const auto& s = log.scans[0];
  CHECK(s.line == 4U);
  CHECK(s.ranges.size() == 4U);
  CHECK(s.angleMin == Approx(-1.570796F));
  CHECK(s.angleIncrement == Approx(0.785398F));
  CHECK(s.timestamp == Approx(12.75));
  REQUIRE(s.hasGroundTruth);
  CHECK(s.vertexId == 7);
  // Laser 4 cm behind the robot along its heading: ground truth = vertex (+) offset.
  CHECK(s.groundTruth.x == Approx(1.0 - 0.04 * std::cos(0.5)).margin(1e-8));
  CHECK(s.groundTruth.y == Approx(2.0 - 0.04 * std::sin(0.5)).margin(1e-8));
  agv::LaserScan scan;
  REQUIRE(s.toLaserScan(scan));
  CHECK(scan.isValid(0));
  CHECK_FALSE(scan.isValid(2));  // 81.83: no return
  const auto& f = log.scans[1];
  CHECK(f.ranges.size() == 3U);
  CHECK(f.angleMin == Approx(-1.5707963F));
  CHECK(f.angleIncrement == Approx(1.5707963F));  // odd count: both ends included
  CHECK(f.groundTruth.x == Approx(4.0));
  CHECK(log.odometry[0].timestamp == Approx(100.25));
  CHECK(log.odometry[0].tv == Approx(0.5));
}

TEST_CASE("carmen log: numbers are decimal and finite; a range may be inf", "[datasets]") {
  const std::string text =
      "FLASER 3 010 inf 2.5e0 +1.0 2.0 0.5 1.0 2.0 0.5 7.5 h 7.25\n"  // line 1: 010 is ten; inf: no echo
      "FLASER 2 1.0 2.0 nan 2.0 0.5 1.0 2.0 0.5 7.5 h 7.5\n"          // line 2: a pose must be finite
      "FLASER 2 1.0 2.0 0x1 2.0 0.5 1.0 2.0 0.5 7.5 h 7.75\n"         // line 3: not decimal
      "ODOM 1 2 0.1 0.5 0.01 0 100.5 h 1e400\n"                       // line 4: out of range
      "VERTEX2 0x7 1.0 2.0 0.5\n"                                     // line 5: id not decimal
      "VERTEX2 07 1.0 2.0 0.5\n";                                     // line 6: id 7
  const CarmenLog log = agv::datasets::parseCarmenLog(text);
  REQUIRE(log.scans.size() == 1U);
  CHECK(log.scans[0].ranges[0] == 10.0F);
  CHECK(std::isinf(log.scans[0].ranges[1]));
  CHECK(log.scans[0].ranges[2] == 2.5F);
  CHECK(log.scans[0].laserPose.x == 1.0);
  REQUIRE(log.issues.size() == 4U);
  CHECK(log.issues[0].line == 2U);
  CHECK(log.issues[1].line == 3U);
  CHECK(log.issues[2].line == 4U);
  CHECK(log.issues[3].line == 5U);
  REQUIRE(log.vertices.size() == 1U);
  CHECK(log.vertices[0].id == 7);
  agv::LaserScan scan;
  REQUIRE(log.scans[0].toLaserScan(scan));
  CHECK(scan.isValid(0));
  CHECK_FALSE(scan.isValid(1));  // inf: no return
}

TEST_CASE("carmen log: the shared FLIRTLib logs read completely", "[datasets][realdata]") {
  struct Expect {
    const char* file;
    std::size_t scans;
    std::size_t beams;
    float increment;
  };
  const Expect sets[] = {{"intel/intel-lab.log.gz", 2672, 180, 0.017453F},
                         {"fr079/fr079.log.gz", 1464, 360, 0.008727F},
                         {"mit-csail/mit-cscail.log.gz", 1051, 361, 0.008727F}};
  for (const auto& e : sets) {
    INFO(e.file);
    const CarmenLog log = mustRead(e.file);
    CHECK(log.issues.empty());
    CHECK(log.scans.size() == e.scans);
    CHECK(log.vertices.size() == e.scans);
    std::size_t withTruth = 0;
    std::size_t invalid = 0;
    for (const auto& s : log.scans) {
      CHECK(s.ranges.size() == e.beams);
      CHECK(s.angleIncrement == Approx(e.increment));
      CHECK(s.angleMin == Approx(-1.570796F));
      withTruth += s.hasGroundTruth ? 1U : 0U;
      for (const float r : s.ranges) {
        invalid += r >= s.maxRange ? 1U : 0U;
      }
    }
    CHECK(withTruth == e.scans);
    CHECK(invalid > 0U);  // every log has no-return readings (81.83 / 81.91)
  }
  // fr079: laser 4 cm behind the robot centre.
  const CarmenLog fr = mustRead("fr079/fr079.log.gz");
  const auto& s = fr.scans[100];
  const double d = std::hypot(s.groundTruth.x - fr.vertices[100].pose.x, s.groundTruth.y - fr.vertices[100].pose.y);
  CHECK(d == Approx(0.04).margin(2e-3));
}

TEST_CASE("carmen log: the gmapping-corrected logs read completely", "[datasets][realdata]") {
  struct Expect {
    const char* file;
    std::size_t scans;
    double laserOffset;  // the log's PARAM robot_frontlaser_offset (zcat | grep)
  };
  const Expect sets[] = {{"intel/intel-corrected.log.gz", 910, 0.0},
                         {"fr079/freiburg-079-corrected.log.gz", 4791, -0.04},
                         {"mit-csail/csail-corrected.log.gz", 406, 0.0},
                         {"aces/aces-corrected.log.gz", 440, 0.0}};
  for (const auto& e : sets) {
    INFO(e.file);
    const CarmenLog log = mustRead(e.file);
    CHECK(log.issues.empty());
    CHECK(log.scans.size() == e.scans);
    CHECK(log.odometry.size() >= e.scans);
    CHECK(log.frontLaserOffsetLine > 0U);
    CHECK(log.frontLaserOffset == e.laserOffset);
  }
}

TEST_CASE("carmen log: PARAM robot_frontlaser_offset is read with its line; a bad value is an issue", "[datasets]") {
  const CarmenLog good = agv::datasets::parseCarmenLog(
      "PARAM robot_allow_rear_motion off 1.0 host 1.0\nPARAM robot_frontlaser_offset -0.04 1.0 host 1.0\n");
  CHECK(good.frontLaserOffset == -0.04);
  CHECK(good.frontLaserOffsetLine == 2U);
  CHECK(good.issues.empty());
  const CarmenLog none = agv::datasets::parseCarmenLog("PARAM robot_front_laser_max 80 1.0 host 1.0\n");
  CHECK(none.frontLaserOffsetLine == 0U);
  CHECK(none.frontLaserOffset == 0.0);
  for (const char* bad : {"PARAM robot_frontlaser_offset nan 1.0 h 1.0\n", "PARAM robot_frontlaser_offset 1e9 1 h 1\n",
                          "PARAM robot_frontlaser_offset 0x10 1 h 1\n", "PARAM robot_frontlaser_offset\n"}) {
    INFO(bad);
    const CarmenLog log = agv::datasets::parseCarmenLog(bad);
    CHECK(log.frontLaserOffsetLine == 0U);
    REQUIRE(log.issues.size() == 1U);
    CHECK(log.issues[0].line == 1U);
  }
}

TEST_CASE("carmen log: a missing file is an error", "[datasets]") {
  CarmenLog log;
  std::string err;
  CHECK_FALSE(agv::datasets::readCarmenLog("/nonexistent/file.log.gz", log, err));
  CHECK_FALSE(err.empty());
}
