// Benchmarks of the simulation: one 1440-beam laser sweep of the built-in warehouse with the
// grid-accelerated ray caster, and the same beams by brute force (the grid's gain); one encoder
// measurement through the simulated CAN bus (nodes' frames, the vehicle's CANopen decoder).
#include <benchmark/benchmark.h>

#include <cmath>

#include "agv/core/angle.hpp"
#include "agv/sim/can_encoder_source.hpp"
#include "agv/sim/sim_laser.hpp"
#include "agv/sim/world.hpp"

namespace {

const agv::sim::World& warehouse() {
  static agv::sim::World w = [] {
    agv::sim::World x;
    agv::sim::WorldParseError e;
    static_cast<void>(agv::sim::parseWorld(agv::sim::defaultWorldText(), x, e));
    return x;
  }();
  return w;
}

// Sensor at the entrance of lane y = 10, looking into it (the HIL's typical view).
const agv::Pose2d kSensor{25.0, 10.0, 0.05};

void BM_SimLaserScan(benchmark::State& state) {
  const agv::sim::RayCaster caster(warehouse(), 1.0);
  agv::sim::SimLaserParams p;
  p.angularResolution = agv::kTwoPi<double> / static_cast<double>(state.range(0));
  agv::sim::SimLaser laser(caster, p, 1);
  static agv::hal::LaserMeasurement m;
  for (auto _ : state) {
    benchmark::DoNotOptimize(laser.scan(kSensor, agv::Timestamp{}, m));
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_SimLaserScan)->Arg(360)->Arg(1440)->Unit(benchmark::kMicrosecond);

void BM_SimRayCastBruteForce(benchmark::State& state) {
  const agv::sim::RayCaster caster(warehouse(), 1.0);
  const int n = static_cast<int>(state.range(0));
  for (auto _ : state) {
    double sum = 0.0;
    for (int i = 0; i < n; ++i) {
      const double a = kSensor.theta - agv::kPi<double> + agv::kTwoPi<double> * i / n;
      sum += caster.castBruteForce(agv::sim::Point2{kSensor.x, kSensor.y}, a, 50.0).range;
    }
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_SimRayCastBruteForce)->Arg(1440)->Unit(benchmark::kMicrosecond);

/// A vehicle driving forward: one new encoder measurement (10 ms later) each time it is armed.
class EncoderRamp final : public agv::hal::EncoderSource {
 public:
  void arm() noexcept { pending_ = true; }
  agv::Status read(agv::hal::EncoderSample& out) noexcept override {
    if (!pending_) {
      return agv::Status::NotFound;
    }
    pending_ = false;
    s_.stamp = s_.stamp + agv::Duration::fromMilliseconds(10);
    s_.driveTicks += 99;  // 1 m/s at 1e-4 m/tick
    s_.steeringAngle = s_.steeringAngle > 0.5 ? -0.5 : s_.steeringAngle + 0.001;
    out = s_;
    return agv::Status::Ok;
  }
  agv::Status health() const noexcept override { return agv::Status::Ok; }

 private:
  bool pending_ = false;
  agv::hal::EncoderSample s_{};
};

// One measurement: decoder service, the nodes' TPDOs (and a heartbeat pair every 10th), decoding,
// the sample (the HIL's encoder path per 10 ms).
void BM_SimCanEncoders(benchmark::State& state) {
  EncoderRamp ramp;
  agv::sim::CanEncoderSource bus(ramp, agv::sim::defaultSimCanEncoders(16384));
  agv::hal::EncoderSample s;
  for (auto _ : state) {
    ramp.arm();
    benchmark::DoNotOptimize(bus.read(s));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_SimCanEncoders);

}  // namespace
