// The agvnav-vehicle loop in-process: after start-up, cycles that read laser sweeps from a loopback
// SICK server, run FALKO and the localizer, and publish to the Modbus server allocate nothing.
// (The CAN interface is absent: the encoder source reports its fault and retries every cycle it may.)
#include <sys/socket.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <thread>
#include <vector>

#include "agv_test.hpp"
#include "loopback_server.hpp"
#include "sick_telegrams.hpp"
#include "vehicle_config.hpp"
#include "vehicle_files.hpp"
#include "vehicle_runtime.hpp"
#include "vehicle_setup.hpp"

TEST_CASE("vehicle cycles with laser sweeps, corrections and publications do not allocate", "[vehicle][laser]") {
  agv::test::TempFolder dir;
  REQUIRE(dir.ok());
  agv::test::LoopbackServer laser;
  REQUIRE(laser.ok());
  // Telegrams built before the peer starts: the peer thread allocates nothing while cycles are
  // counted (the allocation counter is process-wide).
  std::vector<std::vector<std::uint8_t>> telegrams;
  for (std::uint32_t i = 1; i <= 400; ++i) {
    telegrams.push_back(agv::test::colaScanTelegram(i, 3000 + (i % 7), 541, false));
  }
  std::atomic<bool> stop{false};
  laser.start([&](agv::test::LoopbackServer& s) {
    const int fd = s.accept(10000);
    if (fd < 0)
      return;
    char sub[32];
    (void)::recv(fd, sub, sizeof sub, 0);  // the subscription
    for (const auto& t : telegrams) {
      if (stop.load() || ::send(fd, t.data(), t.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(t.size()))
        break;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    while (!stop.load())
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    ::close(fd);
  });

  std::string text = agv::test::goodVehicleConfig("agvcan8", "127.0.0.1", laser.port(), agv::test::closedPort());
  text += "localization.corners = true\n";
  agv::vehicle::VehicleConfig config;
  agv::vehicle::VehicleFiles files;
  agv::vehicle::ConfigError error;
  REQUIRE(agv::test::loadTestVehicle(dir, text, config, files, error));
  agv::vehicle::VehicleRuntime runtime(config, std::move(files));
  std::string openError;
  REQUIRE(runtime.open(openError));

  // Start-up: until the first sweeps came (connection, subscription) and a publication went out.
  for (int i = 0; i < 3000 && runtime.counters().sweeps < 3U; ++i) {
    runtime.cycle();
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  REQUIRE(runtime.counters().sweeps >= 3U);
  const std::uint64_t sweepsBefore = runtime.counters().sweeps;
  const std::uint64_t publicationsBefore = runtime.counters().publications;
  std::uint64_t allocations = 0;
  for (int i = 0; i < 500; ++i) {
    allocations += agv::test::countAllocations([&]() { runtime.cycle(); });
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  stop = true;
  laser.join();
  CHECK(agv::test::allocationCountingActive());
  CHECK(allocations == 0U);
  CHECK(runtime.counters().sweeps - sweepsBefore >= 20U);
  CHECK(runtime.counters().corrections == runtime.counters().sweeps);  // localizing from the initial pose
  CHECK(runtime.counters().publications - publicationsBefore >= 10U);
  // The encoder fault is in the health bits, the laser is fine.
  const auto bits = runtime.healthBits();
  CHECK((bits & static_cast<std::uint16_t>(agv::drivers::plc::PlcHealthBit::DeviceFault)) != 0U);
  CHECK((bits & static_cast<std::uint16_t>(agv::drivers::plc::PlcHealthBit::LaserOk)) != 0U);
}
