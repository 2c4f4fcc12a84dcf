// agvnav-vehicle as a process on this host: the laser points at a loopback SICK CoLa A server, the
// PLC link is a Modbus server on a free loopback port read by a libmodbus client, and the CAN
// interface does not exist. The program must keep running, publish the encoder fault and the laser
// state in the health registers, and exit 0 within 1 s of SIGTERM. A bad configuration makes it
// exit 2 with the file, line and key on stderr.
#include <string>

#include "agv/core/status.hpp"
#include "vehicle_process.hpp"

using agv::drivers::plc::PlcHealthBit;
using agv::test::RunningVehicle;
using agv::test::runVehicle;

TEST_CASE("agvnav-vehicle runs without its CAN interface, reports the encoder fault and stops on SIGTERM",
          "[vehicle][modbus][laser]") {
  RunningVehicle v;
  REQUIRE(v.ready());
  CHECK_FALSE(v.hasBit(PlcHealthBit::EncodersOk));
  CHECK(v.hasBit(PlcHealthBit::MapLoaded));
  CHECK(v.hasBit(PlcHealthBit::CalibrationValid));
  CHECK_FALSE(v.hasBit(PlcHealthBit::LaserTimeout));
  CHECK_FALSE(v.hasBit(PlcHealthBit::CommandRejected));
  CHECK(v.regs[3] == static_cast<std::uint16_t>(agv::Status::DeviceFault));  // last status code
  CHECK(v.regs[1] == 3U);  // lost: localizing from the configured initial pose, but without encoders
  // Calibration published from the file: wheelbase 1.5 m (registers 38-39, ABCD).
  CHECK(modbus_get_float_abcd(v.regs + 38) == Approx(1.5f));
  CHECK(modbus_get_float_abcd(v.regs + 26) == Approx(0.0005f));

  // Still running: the heartbeat counter moves.
  const std::uint16_t beat = v.regs[0];
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  REQUIRE(v.poll());
  CHECK(v.regs[0] != beat);

  // SIGTERM: exit 0 within 1 s, links closed.
  CHECK(v.terminate() == 0);
  const std::string log = v.log();
  INFO(log);
  CHECK(v.subscriptions.load() == 1);
  CHECK(log.find("agvcan7") != std::string::npos);  // the missing interface is named
  CHECK(log.find("stopped after") != std::string::npos);
}

TEST_CASE("agvnav-vehicle carries out the PLC's Stop and Localize and refuses Calibrate visibly",
          "[vehicle][modbus][laser]") {
  RunningVehicle v;
  REQUIRE(v.ready());
  using agv::hal::PlcCommandKind;
  const auto mode = [&v]() { return v.regs[1]; };
  REQUIRE(mode() == 3U);  // lost (no encoders), localizing from the configured initial pose

  // Stop: idle.
  REQUIRE(v.command(PlcCommandKind::Stop));
  CHECK(v.waitFor([&]() { return mode() == 0U; }));
  CHECK_FALSE(v.hasBit(PlcHealthBit::CommandRejected));

  // Calibrate: refused, bit 8 set, the mode stays idle, and the log says why.
  REQUIRE(v.command(PlcCommandKind::Calibrate));
  CHECK(v.waitFor([&]() { return v.hasBit(PlcHealthBit::CommandRejected); }));
  CHECK(mode() == 0U);
  CHECK(v.regs[3] == static_cast<std::uint16_t>(agv::Status::DeviceFault));  // the encoder fault comes first
  // Still set a few publications later: it lasts until the next command.
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  REQUIRE(v.poll());
  CHECK(v.hasBit(PlcHealthBit::CommandRejected));

  // Localize from a set-pose: carried out, bit 8 cleared, the published pose is the set-pose
  // (no odometry and no landmark in view move it).
  REQUIRE(v.command(PlcCommandKind::Localize, 3.25F, -1.5F, 0.75F));
  CHECK(v.waitFor([&]() { return mode() == 3U && !v.hasBit(PlcHealthBit::CommandRejected); }));
  CHECK(modbus_get_float_abcd(v.regs + 4) == Approx(3.25F).margin(1e-6));
  CHECK(modbus_get_float_abcd(v.regs + 6) == Approx(-1.5F).margin(1e-6));
  CHECK(modbus_get_float_abcd(v.regs + 8) == Approx(0.75F).margin(1e-6));

  // Calibrate while localizing: refused, localization goes on from the same pose.
  REQUIRE(v.command(PlcCommandKind::Calibrate));
  CHECK(v.waitFor([&]() { return v.hasBit(PlcHealthBit::CommandRejected); }));
  CHECK(mode() == 3U);
  CHECK(modbus_get_float_abcd(v.regs + 4) == Approx(3.25F).margin(1e-6));

  CHECK(v.terminate() == 0);
  const std::string log = v.log();
  INFO(log);
  CHECK(log.find("PLC command 2 (calibrate) refused") != std::string::npos);
  CHECK(log.find("4 PLC commands, 2 refused") != std::string::npos);
}

TEST_CASE("agvnav-vehicle refuses a bad configuration with exit 2, naming file, line and key", "[vehicle]") {
  agv::test::TempFolder dir;
  REQUIRE(dir.ok());
  dir.write("calibration.txt", agv::test::goodCalibration());
  dir.write("landmarks.txt", agv::test::goodMap());
  std::string text = agv::test::goodVehicleConfig();
  text.replace(text.find("can.drive.node = 1"), std::strlen("can.drive.node = 1"), "can.drive.node = 300");
  const std::string conf = dir.write("bad.conf", text);
  std::string log;
  CHECK(runVehicle({"--config", conf}, dir, log) == 2);
  CHECK(log.find(conf + ":3: can.drive.node: ") != std::string::npos);

  CHECK(runVehicle({"--config", dir.path() + "/absent.conf"}, dir, log) == 2);
  CHECK(log.find("absent.conf") != std::string::npos);

  dir.write("landmarks.txt", "agvnav-landmarks 2\nreflector 1 5.0\nend 1\n");
  const std::string good = dir.write("good.conf", agv::test::goodVehicleConfig());
  CHECK(runVehicle({"--config", good}, dir, log) == 2);
  CHECK(log.find("landmarks.txt:2: map.file: ") != std::string::npos);

  dir.write("landmarks.txt", agv::test::goodMap());
  CHECK(runVehicle({"--config", good, "--check"}, dir, log) == 0);
  CHECK(log.find("configuration ok (3 landmarks)") != std::string::npos);

  CHECK(runVehicle({"--no-such-option"}, dir, log) == 2);
}

namespace {

/// agvnav-vehicle with the drives enabled and the free area `area`: a libmodbus client localizes it
/// at (3.25, -1.5, 0) and writes Calibrate, which must be refused (bit 8); `r` gets registers
/// 44-48, `log` the program's log after SIGTERM (exit 0).
void refusedCalibrate(const char* area, std::uint16_t (&r)[5], std::string& log) {
  using agv::hal::PlcCommandKind;
  agv::test::VehicleSetup setup;
  setup.settings = {{"drives.enabled", "true"}, {"calibration.area", area}};
  RunningVehicle v("", setup);
  REQUIRE(v.ready());
  REQUIRE(v.command(PlcCommandKind::Localize, 3.25F, -1.5F, 0.0F));
  CHECK(v.waitFor([&]() { return modbus_get_float_abcd(v.regs + 4) == Approx(3.25F).margin(1e-6); }));
  REQUIRE(v.command(PlcCommandKind::Calibrate));
  CHECK(v.waitFor([&]() { return v.hasBit(PlcHealthBit::CommandRejected); }));
  REQUIRE(modbus_read_registers(v.plc, 44, 5, r) == 5);
  CHECK(v.regs[1] != 2U);  // not calibrating
  CHECK(v.terminate() == 0);
  log = v.log();
}

}  // namespace

TEST_CASE("agvnav-vehicle with drives: a Calibrate it cannot run is refused with the reason on registers 44-48",
          "[vehicle][modbus][laser]") {
  std::uint16_t r[5] = {};
  std::string log;
  // A free area too small around the set-pose: refused before the drives are touched.
  refusedCalibrate("0 -4 7 1", r, log);
  INFO(log);
  CHECK(r[0] == 0U);  // state idle: nothing started
  CHECK(r[3] == 0U);  // no plan
  CHECK(r[4] == static_cast<std::uint16_t>(agv::Status::OutOfRange));
  CHECK(log.find("calibrate refused before any motion") != std::string::npos);
  CHECK(log.find("leaves the free area") != std::string::npos);
  CHECK(log.find("drives") == std::string::npos);  // the drives were not brought up
  // The plan fits, but the drives' CAN interface does not exist: refused with DeviceFault.
  refusedCalibrate("-100 -100 100 100", r, log);
  CHECK(r[0] == 0U);
  CHECK(r[4] == static_cast<std::uint16_t>(agv::Status::DeviceFault));
  CHECK(log.find("the drives are not enabled (the drives' CAN interface cannot be opened)") != std::string::npos);
}
