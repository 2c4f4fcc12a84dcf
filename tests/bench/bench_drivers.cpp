// Benchmarks of the portable driver decoders: one CoLa A LMDscandata telegram (LMS1xx, 541 beams;
// LMS5xx-like, 1141 beams), one NAV350 reply (1440 beams, 16 reflectors), one CANopen PDO pair.
// The telegrams are built here from the documented layouts (docs/drivers.md).
#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "agv/drivers/protocol/canopen/canopen_encoders.hpp"
#include "agv/drivers/protocol/canopen/cia402_drive.hpp"
#include "agv/drivers/protocol/sick/cola_a_scan.hpp"
#include "agv/drivers/protocol/sick/nav350.hpp"
#include "agv/drivers/protocol/sick/telegram_framer.hpp"
#include "agv/sim/sim_cia402_node.hpp"

namespace {
/// 541 beams: LMS1xx, 0.5 deg from -45 deg; more: LMS5xx-like, 0.1667 deg (1141 beams = 190 deg).
/// (A 0.5 deg step over 1141 beams would span 570 deg and is refused as implausible.)
std::string colaTelegram(int beams) {
  std::string s =
      "sSN LMDscandata 1 1 89A27F 0 0 343 347 27477BA9 2747813B 0 0 7 0 0 1388 168 0 1 DIST1 3F800000 00000000 "
      "FFF92230 ";
  s += beams > 541 ? "683 " : "1388 ";
  char b[16];
  std::snprintf(b, sizeof b, "%X", beams);
  s += b;
  for (int i = 0; i < beams; ++i) {
    std::snprintf(b, sizeof b, " %X", 500 + (i * 37) % 20000);
    s += b;
  }
  return s + " 0 0 0 0 0 0";
}

void put32(std::vector<std::uint8_t>& v, std::uint32_t x) {
  for (int k = 3; k >= 0; --k)
    v.push_back(static_cast<std::uint8_t>(x >> (8 * k)));
}
void put16(std::vector<std::uint8_t>& v, std::uint32_t x) {
  v.push_back(static_cast<std::uint8_t>(x >> 8));
  v.push_back(static_cast<std::uint8_t>(x));
}

std::vector<std::uint8_t> navPayload(int beams, int reflectors) {
  const std::string head = "sAN mNPOSGetData ";
  std::vector<std::uint8_t> v(head.begin(), head.end());
  put16(v, 1);
  v.push_back(0);
  v.push_back(1);
  v.push_back(2);
  put16(v, 1);
  put32(v, 1000);
  put32(v, 2000);
  put32(v, 90000);
  put16(v, 0);
  put16(v, 1);
  v.push_back(1);
  put16(v, static_cast<std::uint32_t>(reflectors));
  for (int i = 0; i < reflectors; ++i) {
    put16(v, 1);
    put32(v, 1000U * static_cast<std::uint32_t>(i));
    put32(v, 500);
    put16(v, 1);
    put32(v, 3000);
    put32(v, 20000U * static_cast<std::uint32_t>(i));
    put16(v, 0);
  }
  put16(v, 1);
  const std::string dist = "DIST1";
  v.insert(v.end(), dist.begin(), dist.end());
  put32(v, 0x3F800000);
  put32(v, 0);
  put32(v, 0);
  put16(v, 250);
  put32(v, 0);
  put16(v, static_cast<std::uint32_t>(beams));
  for (int i = 0; i < beams; ++i)
    put32(v, 1000U + static_cast<std::uint32_t>(i));
  put16(v, 0);
  return v;
}

void BM_ColaAScan(benchmark::State& state) {
  const std::string t = colaTelegram(static_cast<int>(state.range(0)));
  const agv::Span<const std::uint8_t> span(reinterpret_cast<const std::uint8_t*>(t.data()), t.size());
  static agv::LaserScan scan;
  if (agv::drivers::sick::parseColaAScan(span, agv::drivers::sick::ColaAScanConfig{}, agv::Timestamp{}, scan) !=
      agv::Status::Ok) {
    state.SkipWithError("the telegram does not decode: the benchmark would time a refusal");
    return;
  }
  for (auto _ : state) {
    benchmark::DoNotOptimize(
        agv::drivers::sick::parseColaAScan(span, agv::drivers::sick::ColaAScanConfig{}, agv::Timestamp{}, scan));
  }
  state.SetBytesProcessed(state.iterations() * static_cast<std::int64_t>(t.size()));
}
BENCHMARK(BM_ColaAScan)->Arg(541)->Arg(1141);

void BM_Nav350Reply(benchmark::State& state) {
  const auto p = navPayload(1440, 16);
  static agv::drivers::sick::Nav350PoseReply reply;
  for (auto _ : state) {
    benchmark::DoNotOptimize(agv::drivers::sick::parseNav350PoseReply(agv::Span<const std::uint8_t>(p.data(), p.size()),
                                                                      agv::drivers::sick::Nav350Config{},
                                                                      agv::Timestamp{}, reply));
  }
}
BENCHMARK(BM_Nav350Reply);

void BM_FramerColaA(benchmark::State& state) {
  const std::string t = "\x02" + colaTelegram(541) + "\x03";
  static agv::drivers::sick::TelegramFramer framer(agv::drivers::sick::Framing::ColaA);
  for (auto _ : state) {
    std::size_t pos = 0;
    while (pos < t.size()) {  // 1460-byte TCP segments
      const std::size_t n = std::min<std::size_t>(1460, t.size() - pos);
      pos += framer.feed(agv::Span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(t.data()) + pos, n));
      agv::Span<const std::uint8_t> tel;
      while (framer.next(tel))
        benchmark::DoNotOptimize(tel);
    }
  }
  state.SetBytesProcessed(state.iterations() * static_cast<std::int64_t>(t.size()));
}
BENCHMARK(BM_FramerColaA);

void BM_CanopenPdoPair(benchmark::State& state) {
  agv::drivers::canopen::CanopenEncodersConfig cfg;
  cfg.steering.radiansPerCount = 1e-4;
  agv::drivers::canopen::CanopenEncoders dec(cfg);
  std::int64_t ticks = 0;
  for (auto _ : state) {
    ticks += 17;
    const auto d = agv::drivers::canopen::encodeDrivePdo(cfg.drive, ticks, agv::Timestamp{});
    const auto s = agv::drivers::canopen::encodeSteeringPdo(cfg.steering, 0.1, agv::Timestamp{});
    dec.onFrame(d);
    dec.onFrame(s);
    agv::hal::EncoderSample out;
    benchmark::DoNotOptimize(dec.takeSample(out));
  }
}
BENCHMARK(BM_CanopenPdoPair);

/// One 10 ms control cycle of the CiA 402 drive controller, enabled and commanded: the TPDOs and
/// heartbeats of both drives in, a set-point, poll (supervision, the set-point handshake, two RPDOs,
/// its heartbeat when due), the outbox taken. The controller is brought up against two simulated
/// drives first; the cycle then replays the frames the drives sent in one enabled cycle (the drives
/// themselves are not timed).
void BM_Cia402ControllerCycle(benchmark::State& state) {
  using namespace agv::drivers::canopen;
  Cia402DriveController ctl{Cia402DriveConfig{}};
  agv::sim::SimCia402NodeParams tp;
  tp.nodeId = 1;
  agv::sim::SimCia402NodeParams sp;
  sp.nodeId = 3;
  agv::sim::SimCia402Node traction(tp);
  agv::sim::SimCia402Node steering(sp);
  agv::Timestamp now{1000000000};
  (void)ctl.start(now);
  agv::drivers::CanFrame buf[64];
  std::vector<agv::drivers::CanFrame> replay;
  for (int i = 0; i < 300; ++i) {
    now = now + agv::Duration::fromMilliseconds(10);
    const bool enabled = ctl.state() == DriveControllerState::Enabled;
    for (agv::sim::SimCia402Node* n : {&traction, &steering}) {
      const std::size_t k = n->step(now, agv::Span<agv::drivers::CanFrame>(buf));
      for (std::size_t j = 0; j < k; ++j) {
        ctl.onFrame(buf[j]);
        if (enabled && i >= 290) {
          replay.push_back(buf[j]);  // the last 10 enabled cycles: TPDOs and the heartbeats
        }
      }
    }
    agv::hal::DriveCommand c;
    (void)ctl.command(c);
    ctl.poll(now);
    const std::size_t k = ctl.takeFrames(agv::Span<agv::drivers::CanFrame>(buf));
    for (std::size_t j = 0; j < k; ++j) {
      traction.receive(buf[j], now);
      steering.receive(buf[j], now);
    }
  }
  if (ctl.state() != DriveControllerState::Enabled || replay.empty()) {
    state.SkipWithError("the controller did not come up against the simulated drives");
    return;
  }
  agv::hal::DriveCommand cmd;
  cmd.speed = 0.3;
  std::size_t r = 0;
  const std::size_t perCycle = (replay.size() + 9) / 10;
  for (auto _ : state) {
    now = now + agv::Duration::fromMilliseconds(10);
    for (std::size_t j = 0; j < perCycle; ++j) {
      ctl.onFrame(replay[r]);
      r = r + 1 < replay.size() ? r + 1 : 0;
    }
    benchmark::DoNotOptimize(ctl.command(cmd));
    ctl.poll(now);
    benchmark::DoNotOptimize(ctl.takeFrames(agv::Span<agv::drivers::CanFrame>(buf)));
  }
  if (ctl.state() != DriveControllerState::Enabled) {
    state.SkipWithError("the controller left Enabled during the run");
  }
}
BENCHMARK(BM_Cia402ControllerCycle);
}  // namespace
