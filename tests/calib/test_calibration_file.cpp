// Calibration file: round trips over random calibrations, every documented error, all-or-nothing
// parsing, every cut of a written file refused (format version 2), version 1 still read, and no
// allocation in parse or format.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>

#include "agv/calib/calibration_file.hpp"
#include "agv_test.hpp"

using agv::CalibrationFileReport;
using agv::Span;
using agv::Status;
using agv::VehicleCalibration;

namespace {

Span<const char> spanOf(const std::string& s) {
  return Span<const char>(s.data(), s.size());
}

const std::string kGood =
    "# written by hand\r\n"
    "agvnav-calibration 2\r\n"
    "\n"
    "laser_theta 3.1 0.0003   # keys in any order\n"
    "wheelbase 1.5\n"
    "drive_scale 5.0e-4 3e-8\n"
    "steer_offset_forward\t0.0174533\t0.00008\n"
    "steer_offset_backward -0.0087266\n"
    "laser_x -0.8 0.0007\n"
    "laser_y +0.3 0.0009\n"
    "end 7   # seven keys\r\n";

VehicleCalibration sentinel() {
  VehicleCalibration c;
  c.params.wheelbase = 7.0;
  c.laserPose.x = 7.0;
  return c;
}

/// Replaces the first line starting with `key` and a blank by `line` (or appends it when `key` is absent).
std::string withLine(const std::string& key, const std::string& line) {
  std::string out;
  std::size_t pos = 0;
  bool replaced = false;
  while (pos < kGood.size()) {
    std::size_t nl = kGood.find('\n', pos);
    if (nl == std::string::npos) {
      nl = kGood.size() - 1;
    }
    const std::string l = kGood.substr(pos, nl + 1 - pos);
    if (!replaced && l.compare(0, key.size(), key) == 0 && l.size() > key.size() &&
        (l[key.size()] == ' ' || l[key.size()] == '\t')) {
      out += line + "\n";
      replaced = true;
    } else {
      out += l;
    }
    pos = nl + 1;
  }
  if (!replaced) {
    out += line + "\n";
  }
  return out;
}

}  // namespace

TEST_CASE("a hand-written calibration file is read with its values, sigmas and comments") {
  VehicleCalibration cal;
  CalibrationFileReport rep;
  REQUIRE(agv::parseCalibrationFile(spanOf(kGood), cal, &rep) == Status::Ok);
  CHECK(rep.errorLine == 0);
  CHECK(rep.version == 2U);
  CHECK(rep.records == 7U);
  CHECK(cal.params.wheelbase == 1.5);
  CHECK(cal.params.driveScale == Approx(5.0e-4).epsilon(1e-15));
  CHECK(cal.params.steerOffsetForward == Approx(0.0174533).epsilon(1e-15));
  CHECK(cal.params.steerOffsetBackward == Approx(-0.0087266).epsilon(1e-15));
  CHECK(cal.laserPose.x == Approx(-0.8).epsilon(1e-15));
  CHECK(cal.laserPose.y == Approx(0.3).epsilon(1e-15));
  CHECK(cal.laserPose.theta == Approx(3.1).epsilon(1e-15));
  CHECK(cal.sigmas.driveScale == Approx(3e-8).epsilon(1e-15));
  CHECK(cal.sigmas.steerOffsetForward == Approx(0.00008).epsilon(1e-15));
  CHECK(cal.sigmas.steerOffsetBackward == 0.0);  // absent = not known
  CHECK(cal.sigmas.laserX == Approx(0.0007).epsilon(1e-15));
  CHECK(cal.sigmas.laserTheta == Approx(0.0003).epsilon(1e-15));
}

TEST_CASE("a laser heading beyond pi is normalised on reading") {
  VehicleCalibration cal;
  REQUIRE(agv::parseCalibrationFile(spanOf(withLine("laser_theta", "laser_theta 4.0")), cal) == Status::Ok);
  CHECK(cal.laserPose.theta == Approx(4.0 - 2.0 * M_PI).margin(1e-12));
}

TEST_CASE("format then parse returns every value and sigma within the written precision") {
  std::mt19937_64 rng(20261121);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  char buf[2048];
  for (int trial = 0; trial < 300; ++trial) {
    VehicleCalibration in;
    in.params.wheelbase = 0.1 + 19.9 * (0.5 + 0.5 * u(rng));
    in.params.driveScale = 1e-6 + 1e-3 * (0.5 + 0.5 * u(rng));
    in.params.steerOffsetForward = 0.5 * u(rng);
    in.params.steerOffsetBackward = 0.5 * u(rng);
    in.laserPose = agv::Pose2d{50.0 * u(rng), 50.0 * u(rng), M_PI * u(rng)};
    in.sigmas.driveScale = 1e-7 * (0.5 + 0.5 * u(rng));
    in.sigmas.steerOffsetForward = 1e-3 * (0.5 + 0.5 * u(rng));
    in.sigmas.steerOffsetBackward = 1e-3 * (0.5 + 0.5 * u(rng));
    in.sigmas.laserX = 1e-3 * (0.5 + 0.5 * u(rng));
    in.sigmas.laserY = 1e-3 * (0.5 + 0.5 * u(rng));
    in.sigmas.laserTheta = 1e-3 * (0.5 + 0.5 * u(rng));
    const agv::Result<std::size_t> n = agv::formatCalibrationFile(in, Span<char>(buf, sizeof buf));
    REQUIRE(n.ok());
    VehicleCalibration out;
    REQUIRE(agv::parseCalibrationFile(Span<const char>(buf, n.value()), out) == Status::Ok);
    // 9 decimals (s_w: 12) written, rounded: half a unit of the last place plus double rounding.
    const double q = 0.5e-9 + 1e-14;
    CHECK(std::fabs(out.params.wheelbase - in.params.wheelbase) <= q);
    CHECK(std::fabs(out.params.driveScale - in.params.driveScale) <= 0.5e-12 + 1e-17);
    CHECK(std::fabs(out.params.steerOffsetForward - in.params.steerOffsetForward) <= q);
    CHECK(std::fabs(out.params.steerOffsetBackward - in.params.steerOffsetBackward) <= q);
    CHECK(std::fabs(out.laserPose.x - in.laserPose.x) <= q);
    CHECK(std::fabs(out.laserPose.y - in.laserPose.y) <= q);
    CHECK(std::fabs(out.laserPose.theta - in.laserPose.theta) <= q);
    CHECK(std::fabs(out.sigmas.driveScale - in.sigmas.driveScale) <= 0.5e-12 + 1e-17);
    CHECK(std::fabs(out.sigmas.laserTheta - in.sigmas.laserTheta) <= q);
  }
}

TEST_CASE("formatting refuses values the parser would refuse and a buffer that is too small") {
  VehicleCalibration cal;
  REQUIRE(agv::parseCalibrationFile(spanOf(kGood), cal) == Status::Ok);
  char buf[1024];
  const agv::Result<std::size_t> full = agv::formatCalibrationFile(cal, Span<char>(buf, sizeof buf));
  REQUIRE(full.ok());
  for (std::size_t size = 0; size < full.value(); size += 7) {
    CHECK(agv::formatCalibrationFile(cal, Span<char>(buf, size)).status() == Status::Truncated);
  }
  CHECK(agv::formatCalibrationFile(cal, Span<char>(buf, full.value())).ok());

  VehicleCalibration bad = cal;
  bad.params.driveScale = std::nan("");
  CHECK(agv::formatCalibrationFile(bad, Span<char>(buf, sizeof buf)).status() == Status::OutOfRange);
  bad = cal;
  bad.params.driveScale = 0.0;
  CHECK(agv::formatCalibrationFile(bad, Span<char>(buf, sizeof buf)).status() == Status::OutOfRange);
  bad = cal;
  bad.sigmas.laserY = -1e-3;
  CHECK(agv::formatCalibrationFile(bad, Span<char>(buf, sizeof buf)).status() == Status::OutOfRange);
  bad = cal;
  bad.sigmas.laserX = 1e10;  // could not be written with 9 decimals
  CHECK(agv::formatCalibrationFile(bad, Span<char>(buf, sizeof buf)).status() == Status::OutOfRange);
  bad = cal;
  bad.params.steerOffsetForward = 0.6;
  CHECK(agv::formatCalibrationFile(bad, Span<char>(buf, sizeof buf)).status() == Status::OutOfRange);
}

TEST_CASE("bad files are refused with the line or key named, and the output is left untouched") {
  struct Case {
    std::string text;
    Status status;
    std::size_t line;  // 0: not checked
    const char* key;   // nullptr: not checked
  };
  const std::string noHeader = kGood.substr(kGood.find("laser_theta"));
  const auto version = [](const char* v) {
    std::string t = kGood;
    return t.replace(t.find("calibration 2"), 13, std::string("calibration ") + v);
  };
  const auto end = [](const char* line) {
    std::string t = kGood;
    return t.replace(t.find("end 7"), std::strlen("end 7"), line);
  };
  const std::string noEnd = kGood.substr(0, kGood.find("end 7"));
  std::string noLaserY = withLine("laser_y", "");
  noLaserY.replace(noLaserY.find("end 7"), 5, "end 6");
  const Case cases[] = {
      {"", Status::EmptyInput, 0, nullptr},
      {"# only a comment\n\n", Status::EmptyInput, 0, nullptr},
      {noHeader, Status::Malformed, 1, nullptr},
      {version("3"), Status::Unsupported, 2, nullptr},
      {version("0"), Status::Malformed, 2, nullptr},
      {version("2.0"), Status::Malformed, 2, nullptr},
      {version("2 x"), Status::Malformed, 2, nullptr},
      {noEnd, Status::Truncated, 10, nullptr},
      {end("end 6"), Status::Malformed, 11, nullptr},
      {end("end 8"), Status::Malformed, 11, nullptr},
      {end("end"), Status::Malformed, 11, nullptr},
      {end("end 7 7"), Status::Malformed, 11, nullptr},
      {end("end -7"), Status::Malformed, 11, nullptr},
      {kGood + "laser_x 0.1\n", Status::Malformed, 12, nullptr},  // a record after the end
      {kGood + "end 7\n", Status::Malformed, 12, nullptr},
      {kGood + "\n\n# x\n \t\n&", Status::Malformed, 16, nullptr},
      {withLine("laser_y", "laser_z 0.3"), Status::Malformed, 0, nullptr},
      {withLine("laser_y", "laser_y"), Status::Malformed, 0, "laser_y"},
      {withLine("laser_y", "laser_y 0.3 0.1 0.2"), Status::Malformed, 0, "laser_y"},
      {withLine("laser_y", "laser_y 0.3m"), Status::Malformed, 0, "laser_y"},
      {withLine("laser_y", "laser_y nan"), Status::Malformed, 0, "laser_y"},
      {withLine("laser_y", "laser_y inf"), Status::Malformed, 0, "laser_y"},
      {withLine("laser_y", "laser_y 1e999"), Status::Malformed, 0, "laser_y"},
      {withLine("wheelbase", "wheelbase 1.5 0.001"), Status::Malformed, 0, "wheelbase"},
      {withLine("laser_y", "laser_y 51"), Status::OutOfRange, 0, "laser_y"},
      {withLine("laser_y", "laser_y 0.3 -0.001"), Status::OutOfRange, 0, "laser_y"},
      {withLine("laser_y", "laser_y 0.3 100.001"), Status::OutOfRange, 0, "laser_y"},
      {withLine("drive_scale", "drive_scale 5e-4 1e19"), Status::OutOfRange, 0, "drive_scale"},
      {withLine("drive_scale", "drive_scale 0"), Status::OutOfRange, 0, "drive_scale"},
      {withLine("drive_scale", "drive_scale -5e-4"), Status::OutOfRange, 0, "drive_scale"},
      {withLine("wheelbase", "wheelbase 0.05"), Status::OutOfRange, 0, "wheelbase"},
      {withLine("steer_offset_forward", "steer_offset_forward 0.6"), Status::OutOfRange, 0, "steer_offset_forward"},
      {withLine("laser_theta", "laser_theta 7"), Status::OutOfRange, 0, "laser_theta"},
      {withLine("laser_y", ""), Status::Malformed, 11, nullptr},  // 6 keys before "end 7"
      {noLaserY, Status::NotFound, 0, "laser_y"},
      {withLine("wheelbase", "end 1"), Status::Malformed, 6, nullptr},  // the key lines after it
      {withLine("laser_y", "laser_y 0.3\nlaser_x 0.1"), Status::InvalidArgument, 11, "laser_x"},
  };
  for (const Case& c : cases) {
    INFO(c.text);
    VehicleCalibration cal = sentinel();
    CalibrationFileReport rep;
    CHECK(agv::parseCalibrationFile(spanOf(c.text), cal, &rep) == c.status);
    if (c.status == Status::Truncated || c.status == Status::Unsupported) {
      CHECK(rep.detail != nullptr);
    }
    if (c.line != 0) {
      CHECK(rep.errorLine == c.line);
    }
    if (c.status == Status::Malformed && c.key == nullptr && c.line == 0) {
      CHECK(rep.errorLine > 0);
    }
    if (c.key != nullptr) {
      REQUIRE(rep.key != nullptr);
      CHECK(std::strcmp(rep.key, c.key) == 0);
    }
    CHECK(cal.params.wheelbase == 7.0);
    CHECK(cal.laserPose.x == 7.0);
  }
}

TEST_CASE("every cut of a written file is refused as Truncated, naming the line where it ends") {
  VehicleCalibration cal;
  REQUIRE(agv::parseCalibrationFile(spanOf(kGood), cal) == Status::Ok);
  char buf[1024];
  const agv::Result<std::size_t> n = agv::formatCalibrationFile(cal, Span<char>(buf, sizeof buf));
  REQUIRE(n.ok());
  const std::string full(buf, n.value());
  REQUIRE(full.compare(0, 21, "agvnav-calibration 2\n") == 0);
  REQUIRE(full.compare(full.size() - 6, 6, "end 7\n") == 0);
  VehicleCalibration back;
  CalibrationFileReport rep;
  REQUIRE(agv::parseCalibrationFile(spanOf(full), back, &rep) == Status::Ok);
  CHECK(rep.version == 2U);
  int refused = 0;
  for (std::size_t cut = 0; cut < full.size(); ++cut) {
    const std::string part = full.substr(0, cut);
    VehicleCalibration out = sentinel();
    rep = CalibrationFileReport{};
    const Status s = agv::parseCalibrationFile(spanOf(part), out, &rep);
    INFO("cut at " << cut << ": ..." << part.substr(part.size() > 20 ? part.size() - 20 : 0));
    if (cut + 1U == full.size()) {
      CHECK(s == Status::Ok);  // only the final LF missing: nothing lost
      continue;
    }
    refused += s != Status::Ok ? 1 : 0;
    CHECK(out.params.wheelbase == 7.0);  // untouched
    if (cut <= 21U) {
      CHECK((s == Status::EmptyInput || s == Status::Malformed || s == Status::Truncated));  // inside the header
      continue;
    }
    CHECK(s == Status::Truncated);
    const std::size_t lines =
        static_cast<std::size_t>(std::count(part.begin(), part.end(), '\n')) + (part.back() != '\n' ? 1U : 0U);
    CHECK(rep.errorLine == lines);
    CHECK(rep.detail != nullptr);
  }
  CHECK(refused == static_cast<int>(full.size()) - 1);

  // Version 1 (no end line) is still read, and cannot tell a cut file: the reason for version 2.
  std::string v1 = full.substr(0, full.size() - 6);
  v1.replace(0, 20, "agvnav-calibration 1");
  REQUIRE(agv::parseCalibrationFile(spanOf(v1), back, &rep) == Status::Ok);
  CHECK(rep.version == 1U);
  CHECK(rep.records == 7U);
  int silent = 0;
  for (std::size_t cut = 0; cut < v1.size(); ++cut) {
    VehicleCalibration out;
    silent += agv::parseCalibrationFile(spanOf(v1.substr(0, cut)), out) == Status::Ok ? 1 : 0;
  }
  std::printf("calibration file: version 1 loads %d of %zu cuts; version 2 refuses %d of %zu (all but the final LF)\n",
              silent, v1.size(), refused, full.size());
  CHECK(silent > 0);
  // "end" is no key of version 1.
  REQUIRE(agv::parseCalibrationFile(spanOf(v1 + "end 7\n"), back, &rep) == Status::Malformed);
}

TEST_CASE("parsing and formatting do not allocate") {
  VehicleCalibration cal;
  char buf[1024];
  Status s = Status::NotInitialized;
  bool ok = false;
  AGV_CHECK_NO_ALLOCATIONS(s = agv::parseCalibrationFile(spanOf(kGood), cal);
                           ok = agv::formatCalibrationFile(cal, Span<char>(buf, sizeof buf)).ok());
  CHECK(s == Status::Ok);
  CHECK(ok);
}
