// Simulated vehicle: exact arc integration against tricycleArc, encoder quantisation and noise,
// servo limits, path following on the built-in warehouse, and the PLC peer.
#include <cmath>
#include <vector>

#include "agv/core/angle.hpp"
#include "agv/kinematics/tricycle.hpp"
#include "agv/sim/path_follower.hpp"
#include "agv/sim/sim_clock.hpp"
#include "agv/sim/sim_plc.hpp"
#include "agv/sim/sim_vehicle.hpp"
#include "agv_test.hpp"

using agv::Duration;
using agv::Pose2d;
using agv::Status;
using agv::Timestamp;
using agv::sim::SimVehicle;
using agv::sim::SimVehicleParams;

namespace {

SimVehicleParams idealParams() {
  SimVehicleParams p;
  p.slipNoise = 0.0;
  p.steerNoiseStdDev = 0.0;
  return p;
}

// Sets the steering servo at rest, then places the vehicle at `start` at time 0.
void presetSteering(SimVehicle& v, double measuredAngle, const Pose2d& start) {
  v.reset(Pose2d{}, Timestamp{});
  REQUIRE(v.command(agv::hal::DriveCommand{Timestamp{}, 0.0, measuredAngle}) == Status::Ok);
  v.advanceTo(Timestamp::fromSeconds(5.0));
  REQUIRE(v.servoAngle() == Approx(measuredAngle).margin(1e-12));
  v.reset(start, Timestamp{});
}

// Drives at `speed` for `seconds`, then stops; returns the signed wheel travel from the ticks.
void driveFor(SimVehicle& v, double speed, double steer, double seconds) {
  const Timestamp t0 = v.now();
  REQUIRE(v.command(agv::hal::DriveCommand{t0, speed, steer}) == Status::Ok);
  v.advanceTo(t0 + Duration::fromSeconds(seconds));
  REQUIRE(v.stop() == Status::Ok);
  v.advanceTo(v.now() + Duration::fromSeconds(5.0));
  REQUIRE(v.isStandstill());
}

}  // namespace

TEST_CASE("Constant steering moves the logical point along the tricycleArc prediction", "[sim][vehicle]") {
  const SimVehicleParams p = idealParams();
  for (double steer : {agv::deg2rad(25.0), agv::deg2rad(-40.0), 0.0}) {
    for (double speed : {0.8, -0.5}) {
      SimVehicle v(p, 1);
      const Pose2d start{3.0, -2.0, 0.6};
      presetSteering(v, steer, start);
      driveFor(v, speed, steer, 6.0);
      // The ticks give the wheel travel to one tick; the offset depends on the travel direction.
      agv::hal::EncoderSample s;
      agv::hal::EncoderSample last;
      std::int64_t ticks0 = 0;
      bool first = true;
      while (v.read(s) == Status::Ok) {
        if (first) {
          ticks0 = s.driveTicks;
          first = false;
        }
        last = s;
      }
      REQUIRE_FALSE(first);
      const double travel = static_cast<double>(last.driveTicks - ticks0) * p.truth.driveScale;
      const double offset = speed > 0 ? p.truth.steerOffsetForward : p.truth.steerOffsetBackward;
      const Pose2d predicted = start.compose(agv::tricycleArc(travel, steer + offset, p.truth.wheelbase));
      const Pose2d& actual = v.truePose();
      // Tolerance: two ticks of travel (first sample after start, quantisation of the last).
      const double tol = 2.0 * p.truth.driveScale;
      CHECK(actual.x == Approx(predicted.x).margin(tol));
      CHECK(actual.y == Approx(predicted.y).margin(tol));
      CHECK(std::fabs(agv::angleDiff(actual.theta, predicted.theta)) < tol / p.truth.wheelbase + 1e-12);
      CHECK(v.odometer() == Approx(std::fabs(travel)).margin(tol));
    }
  }
}

TEST_CASE("Drive ticks are the floor of the wheel travel over s_w", "[sim][vehicle][encoder]") {
  const SimVehicleParams p = idealParams();
  SimVehicle v(p, 1);
  v.reset(Pose2d{}, Timestamp{});
  // Measured angle -alpha_F: the wheel itself is straight.
  REQUIRE(v.command(agv::hal::DriveCommand{Timestamp{}, 0.37, -p.truth.steerOffsetForward}) == Status::Ok);
  Timestamp prev{};
  int samples = 0;
  double prevTravel = 0.0;
  for (int k = 1; k <= 300; ++k) {
    v.advanceTo(Timestamp::fromSeconds(0.01 * k));
    agv::hal::EncoderSample s;
    while (v.read(s) == Status::Ok) {
      CHECK(s.stamp > prev);
      CHECK((s.stamp - prev) == p.encoderPeriod);
      prev = s.stamp;
      ++samples;
      // Straight driving without slip: the wheel travel is the x coordinate at the sample time.
      const double travel = v.truePose().x;
      CHECK(static_cast<double>(s.driveTicks) * p.truth.driveScale <= travel + 1e-12);
      CHECK(static_cast<double>(s.driveTicks + 1) * p.truth.driveScale > travel);
      CHECK(travel >= prevTravel);
      prevTravel = travel;
    }
  }
  CHECK(samples == 300);
}

TEST_CASE("The steering reading is quantised to 14 bits with the injected noise", "[sim][vehicle][encoder]") {
  const double quantum = agv::kTwoPi<double> / 16384.0;
  SECTION("noise-free: the nearest code") {
    SimVehicle v(idealParams(), 1);
    for (double a : {0.1234, -0.5, agv::deg2rad(30.0)}) {
      presetSteering(v, a, Pose2d{});
      v.advanceTo(Timestamp::fromSeconds(0.05));
      agv::hal::EncoderSample s;
      REQUIRE(v.read(s) == Status::Ok);
      const double code = s.steeringAngle / quantum;
      CHECK(std::fabs(code - std::round(code)) < 1e-6);
      CHECK(std::fabs(s.steeringAngle - a) <= 0.5 * quantum + 1e-12);
    }
  }
  SECTION("noisy: mean and spread") {
    SimVehicleParams p = idealParams();
    p.steerNoiseStdDev = 5e-4;
    SimVehicle v(p, 9);
    const double a = 0.2;
    presetSteering(v, a, Pose2d{});
    double s1 = 0.0;
    double s2 = 0.0;
    int n = 0;
    agv::hal::EncoderSample s;
    for (int sec = 1; sec <= 100; ++sec) {  // 10000 samples at rest, read every second
      v.advanceTo(Timestamp::fromSeconds(sec));
      while (v.read(s) == Status::Ok) {
        s1 += s.steeringAngle - a;
        s2 += (s.steeringAngle - a) * (s.steeringAngle - a);
        ++n;
      }
    }
    REQUIRE(n == 10000);
    CHECK(v.droppedSamples() == 0U);
    // Unread samples beyond the queue's capacity are dropped and counted.
    v.advanceTo(Timestamp::fromSeconds(150.0));
    CHECK(v.droppedSamples() == 5000U - p.encoderQueue);
    const double mean = s1 / n;
    const double sd = std::sqrt(s2 / n - mean * mean);
    // Quantisation adds q^2/12 to the variance (the noise is wider than a code).
    const double expectedSd = std::sqrt(p.steerNoiseStdDev * p.steerNoiseStdDev + quantum * quantum / 12.0);
    CHECK(std::fabs(mean) < 4.0 * expectedSd / std::sqrt(n));
    CHECK(std::fabs(sd - expectedSd) < 4.0 * expectedSd / std::sqrt(2.0 * n));
  }
}

TEST_CASE("Wheel slip spreads the ground travel as a random walk", "[sim][vehicle]") {
  SimVehicleParams p = idealParams();
  p.slipNoise = 0.004;  // [m/sqrt(m)]
  const double dist = 9.0;
  std::vector<double> err;
  for (std::uint64_t seed = 1; seed <= 60; ++seed) {
    SimVehicle v(p, seed);
    v.reset(Pose2d{}, Timestamp{});
    // Straight, so ground travel = x; wheel travel from the ticks.
    REQUIRE(v.command(agv::hal::DriveCommand{Timestamp{}, 1.0, -p.truth.steerOffsetForward}) == Status::Ok);
    double travel = 0.0;
    agv::hal::EncoderSample s;
    while (travel < dist) {
      v.advanceTo(v.now() + Duration::fromMilliseconds(10));
      while (v.read(s) == Status::Ok) {
        travel = static_cast<double>(s.driveTicks) * p.truth.driveScale;
      }
    }
    err.push_back(v.truePose().x - travel);
  }
  double s1 = 0.0;
  double s2 = 0.0;
  for (double e : err) {
    s1 += e;
    s2 += e * e;
  }
  const double n = static_cast<double>(err.size());
  const double sd = std::sqrt(s2 / n - (s1 / n) * (s1 / n));
  const double expected = p.slipNoise * std::sqrt(dist);            // 12 mm
  CHECK(std::fabs(s1 / n) < 4.0 * expected / std::sqrt(n) + 2e-4);  // + ticks sampled every 10 ms
  CHECK(sd > 0.6 * expected);  // chi distribution with 59 dof: +-40 % is beyond 4 sigma
  CHECK(sd < 1.4 * expected);
}

TEST_CASE("Drive commands are validated and servos ramp", "[sim][vehicle]") {
  SimVehicle v(idealParams(), 1);
  v.reset(Pose2d{}, Timestamp{});
  CHECK(v.isStandstill());
  CHECK(v.command(agv::hal::DriveCommand{Timestamp{}, std::nan(""), 0.0}) == Status::NonFiniteInput);
  CHECK(v.command(agv::hal::DriveCommand{Timestamp{}, 5.0, 0.0}) == Status::InvalidArgument);
  CHECK(v.command(agv::hal::DriveCommand{Timestamp{}, 0.5, 2.0}) == Status::InvalidArgument);
  CHECK(v.command(agv::hal::DriveCommand{Timestamp{}, 1.0, agv::deg2rad(45.0)}) == Status::Ok);
  v.advanceTo(Timestamp::fromSeconds(0.5));
  CHECK(v.speed() == Approx(0.25));                     // 0.5 m/s^2
  CHECK(v.servoAngle() == Approx(agv::deg2rad(22.5)));  // 45 deg/s
  CHECK_FALSE(v.isStandstill());
  REQUIRE(v.stop() == Status::Ok);
  v.advanceTo(Timestamp::fromSeconds(2.0));
  CHECK(v.isStandstill());
  CHECK(v.servoAngle() == Approx(agv::deg2rad(45.0)));  // steering is kept by stop()
}

TEST_CASE("The follower drives each warehouse path to its end point", "[sim][vehicle][path]") {
  agv::sim::World w;
  agv::sim::WorldParseError e;
  REQUIRE(agv::sim::parseWorld(agv::sim::defaultWorldText(), w, e) == Status::Ok);
  for (const agv::sim::Path& path : w.paths) {
    INFO("path " << path.name);
    SimVehicle v(SimVehicleParams{}, 4);
    v.reset(path.start, Timestamp{});
    agv::sim::PathFollowerParams fp;
    agv::sim::PathFollower follower(path, fp);
    double maxLateral = 0.0;
    double logicalTravel = 0.0;
    for (int k = 0; k < 10000 && !(follower.finished() && v.isStandstill()); ++k) {
      const agv::hal::DriveCommand cmd = follower.update(v.truePose());
      REQUIRE(v.command(cmd) == Status::Ok);
      const Pose2d before = v.truePose();
      v.advanceTo(v.now() + Duration::fromMilliseconds(20));
      logicalTravel += std::hypot(v.truePose().x - before.x, v.truePose().y - before.y);
      agv::hal::EncoderSample s;
      while (v.read(s) == Status::Ok) {
      }
      // Distance to the nearest path sample.
      double best = 1e9;
      for (const Pose2d& q : path.points) {
        best = std::min(best, std::hypot(q.x - v.truePose().x, q.y - v.truePose().y));
      }
      maxLateral = std::max(maxLateral, best);
    }
    REQUIRE(follower.finished());
    REQUIRE(v.isStandstill());
    const Pose2d& end = path.points.back();
    CHECK(std::hypot(v.truePose().x - end.x, v.truePose().y - end.y) < 0.01);
    CHECK(std::fabs(agv::angleDiff(v.truePose().theta, end.theta)) < agv::deg2rad(1.0));
    CHECK(maxLateral < 0.15);  // pure pursuit cuts the arcs a little
    CHECK(logicalTravel == Approx(path.length).epsilon(0.01));
    CHECK(v.odometer() >= logicalTravel);  // the drive wheel rolls farther than the logical point on arcs
  }
}

TEST_CASE("The PLC peer records publications and hands out commands in order", "[sim][plc]") {
  agv::sim::SimPlcPeer plc;
  agv::hal::PlcLink& link = plc;
  agv::hal::PoseReport r;
  r.pose = Pose2d{1.0, 2.0, 0.3};
  CHECK(link.publish(r) == Status::Ok);
  r.pose.x = std::nan("");
  CHECK(link.publish(r) == Status::NonFiniteInput);
  REQUIRE(plc.reports().size() == 1U);
  CHECK(plc.reports()[0].pose.y == 2.0);
  agv::hal::PlcCommand c;
  CHECK(link.readCommand(c) == Status::NotFound);
  plc.send(agv::hal::PlcCommand{Timestamp{}, agv::hal::PlcCommandKind::Calibrate, Pose2d{}});
  plc.send(agv::hal::PlcCommand{Timestamp{}, agv::hal::PlcCommandKind::Localize, Pose2d{5.0, 0.0, 0.0}});
  REQUIRE(link.readCommand(c) == Status::Ok);
  CHECK(c.kind == agv::hal::PlcCommandKind::Calibrate);
  REQUIRE(link.readCommand(c) == Status::Ok);
  CHECK(c.kind == agv::hal::PlcCommandKind::Localize);
  CHECK(c.initialPose.x == 5.0);
  CHECK(link.readCommand(c) == Status::NotFound);

  agv::sim::SimClock clock;
  clock.set(Timestamp::fromSeconds(2.0));
  clock.set(Timestamp::fromSeconds(1.0));  // never backwards
  CHECK(clock.now() == Timestamp::fromSeconds(2.0));
  clock.advance(Duration::fromMilliseconds(5));
  CHECK(static_cast<const agv::hal::Clock&>(clock).now() == Timestamp::fromSeconds(2.005));
}
