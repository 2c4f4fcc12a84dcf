// Host-side checks of the SocketCAN transport that need no CAN stack: error-frame decoding
// against the kernel's published error-frame layout (linux/can/error.h), configuration
// validation and the closed-bus contract. The transport on a real CAN stack is tested in the VM
// (test_socketcan_vm.cpp, run by run-vcan-vm.sh).
#include <linux/can/error.h>

#include "agv/drivers/linux/can_error.hpp"
#include "agv/drivers/linux/socketcan_bus.hpp"
#include "agv_test.hpp"

#include <string>

using agv::Status;
using agv::drivers::CanControllerState;
using agv::drivers::CanErrorReport;
using agv::drivers::CanFrame;

namespace {
CanFrame errorFrame(std::uint32_t classes, std::uint8_t d0 = 0, std::uint8_t d1 = 0, std::uint8_t d2 = 0,
                    std::uint8_t d3 = 0, std::uint8_t d4 = 0, std::uint8_t d6 = 0, std::uint8_t d7 = 0) {
  CanFrame f;
  f.error = true;
  f.id = classes;
  f.dlc = CAN_ERR_DLC;
  const std::uint8_t d[8] = {d0, d1, d2, d3, d4, 0, d6, d7};
  for (int i = 0; i < 8; ++i)
    f.data[i] = d[i];
  return f;
}
}  // namespace

TEST_CASE("a data frame is not an error report", "[socketcan]") {
  CanFrame f;
  f.id = CAN_ERR_BUSOFF;
  CanErrorReport r;
  r.busOff = true;
  CHECK(decodeCanError(f, r) == Status::InvalidArgument);
  CHECK_FALSE(r.busOff);
  CHECK(r.classes == 0U);
}

TEST_CASE("bus-off is decoded and is the worst state", "[socketcan]") {
  CanErrorReport r;
  // Bus-off together with a passive report (a controller may send both): bus-off wins.
  REQUIRE(decodeCanError(errorFrame(CAN_ERR_BUSOFF | CAN_ERR_CRTL, 0, CAN_ERR_CRTL_TX_PASSIVE), r) == Status::Ok);
  CHECK(r.busOff);
  CHECK(r.controllerProblem);
  CHECK(r.stateKnown);
  CHECK(r.state == CanControllerState::BusOff);
  CHECK_FALSE(r.noAck);
  CHECK_FALSE(r.restarted);
  CHECK(r.classes == (CAN_ERR_BUSOFF | CAN_ERR_CRTL));
}

TEST_CASE("controller state changes follow the status byte", "[socketcan]") {
  struct Case {
    std::uint8_t detail;
    CanControllerState state;
  };
  const Case cases[] = {
      {CAN_ERR_CRTL_RX_WARNING, CanControllerState::ErrorWarning},
      {CAN_ERR_CRTL_TX_WARNING, CanControllerState::ErrorWarning},
      {CAN_ERR_CRTL_RX_PASSIVE, CanControllerState::ErrorPassive},
      {CAN_ERR_CRTL_TX_PASSIVE | CAN_ERR_CRTL_RX_WARNING, CanControllerState::ErrorPassive},
      {CAN_ERR_CRTL_ACTIVE, CanControllerState::ErrorActive},
  };
  for (const Case& c : cases) {
    CanErrorReport r;
    REQUIRE(decodeCanError(errorFrame(CAN_ERR_CRTL, 0, c.detail), r) == Status::Ok);
    CHECK(r.controllerProblem);
    CHECK(r.controllerDetail == c.detail);
    CHECK(r.stateKnown);
    CHECK(r.state == c.state);
    CHECK_FALSE(r.rxOverflow);
  }
}

TEST_CASE("overflows, no-ACK and restart are reported without inventing a state", "[socketcan]") {
  CanErrorReport r;
  REQUIRE(decodeCanError(errorFrame(CAN_ERR_CRTL, 0, CAN_ERR_CRTL_RX_OVERFLOW), r) == Status::Ok);
  CHECK(r.rxOverflow);
  CHECK_FALSE(r.txOverflow);
  CHECK_FALSE(r.stateKnown);

  REQUIRE(decodeCanError(errorFrame(CAN_ERR_ACK), r) == Status::Ok);
  CHECK(r.noAck);
  CHECK_FALSE(r.stateKnown);
  CHECK_FALSE(r.busOff);

  REQUIRE(decodeCanError(errorFrame(CAN_ERR_RESTARTED), r) == Status::Ok);
  CHECK(r.restarted);
  CHECK(r.stateKnown);
  CHECK(r.state == CanControllerState::ErrorActive);
}

TEST_CASE("protocol, arbitration, transceiver and counter details", "[socketcan]") {
  CanErrorReport r;
  REQUIRE(decodeCanError(
              errorFrame(CAN_ERR_PROT | CAN_ERR_LOSTARB | CAN_ERR_TRX | CAN_ERR_CNT, 7, 0,
                         CAN_ERR_PROT_STUFF | CAN_ERR_PROT_TX, CAN_ERR_PROT_LOC_ACK, CAN_ERR_TRX_CANH_NO_WIRE, 130, 12),
              r) == Status::Ok);
  CHECK(r.protocolViolation);
  CHECK(r.protocolType == (CAN_ERR_PROT_STUFF | CAN_ERR_PROT_TX));
  CHECK(r.protocolLocation == CAN_ERR_PROT_LOC_ACK);
  CHECK(r.lostArbitration);
  CHECK(r.arbitrationBit == 7);
  CHECK(r.transceiverProblem);
  CHECK(r.transceiverStatus == CAN_ERR_TRX_CANH_NO_WIRE);
  CHECK(r.countersValid);
  CHECK(r.txErrorCounter == 130);
  CHECK(r.rxErrorCounter == 12);
  // Details of classes the frame does not name are not read.
  CHECK(r.controllerDetail == 0);
  CHECK_FALSE(r.controllerProblem);
}

TEST_CASE("a short error frame yields its classes and zero details", "[socketcan]") {
  CanFrame f = errorFrame(CAN_ERR_CRTL | CAN_ERR_CNT, 0, CAN_ERR_CRTL_TX_PASSIVE, 0, 0, 0, 200, 200);
  f.dlc = 1;  // data[1..7] are not part of the frame
  CanErrorReport r;
  REQUIRE(decodeCanError(f, r) == Status::Ok);
  CHECK(r.controllerProblem);
  CHECK(r.controllerDetail == 0);
  CHECK_FALSE(r.stateKnown);
  CHECK(r.countersValid);
  CHECK(r.txErrorCounter == 0);
}

TEST_CASE("decoding does not allocate", "[socketcan]") {
  const CanFrame f = errorFrame(CAN_ERR_BUSOFF);
  CanErrorReport r;
  Status s = Status::InvalidArgument;
  AGV_CHECK_NO_ALLOCATIONS(s = decodeCanError(f, r));
  CHECK(s == Status::Ok);
}

TEST_CASE("state names are distinct", "[socketcan]") {
  using agv::drivers::CanLinkState;
  CHECK(std::string(toString(CanControllerState::BusOff)) == "bus-off");
  CHECK(std::string(toString(CanControllerState::ErrorActive)) !=
        std::string(toString(CanControllerState::ErrorPassive)));
  CHECK(std::string(toString(CanLinkState::Down)) == "down");
}

TEST_CASE("a bad configuration is refused and leaves the bus closed", "[socketcan]") {
  agv::drivers::SocketCanBus bus;
  agv::drivers::SocketCanConfig cfg;

  cfg.interfaceName = "";
  CHECK(bus.open(cfg) == Status::InvalidArgument);
  cfg.interfaceName = nullptr;
  CHECK(bus.open(cfg) == Status::InvalidArgument);
  cfg.interfaceName = "a_name_of_16_chr";  // IFNAMSIZ is 16 including the terminator
  CHECK(bus.open(cfg) == Status::InvalidArgument);

  cfg.interfaceName = "vcan0";
  REQUIRE(cfg.filters.push_back({0x800U, 0x7FFU, false}) == Status::Ok);  // 12-bit id in a standard filter
  CHECK(bus.open(cfg) == Status::InvalidArgument);
  cfg.filters.clear();
  REQUIRE(cfg.filters.push_back({0x1FFFFFFFU, 0x3FFFFFFFU, true}) == Status::Ok);  // mask beyond 29 bits
  CHECK(bus.open(cfg) == Status::InvalidArgument);
  cfg.filters.clear();

  cfg.reopenBackoffInitial = agv::Duration{};
  CHECK(bus.open(cfg) == Status::InvalidArgument);
  cfg.reopenBackoffInitial = agv::Duration::fromMilliseconds(10);
  cfg.reopenBackoffMax = agv::Duration::fromMilliseconds(5);
  CHECK(bus.open(cfg) == Status::InvalidArgument);

  CHECK(bus.health().link == agv::drivers::CanLinkState::Closed);
  CHECK(bus.fileDescriptor() == -1);
}

TEST_CASE("a closed bus neither receives nor sends, and counts the refusal", "[socketcan]") {
  agv::drivers::SocketCanBus bus;
  CanFrame f;
  f.id = 0x123;
  f.dlc = 2;
  Status rx = Status::Ok;
  AGV_CHECK_NO_ALLOCATIONS(rx = bus.receive(f, agv::Duration::fromMilliseconds(1)));
  CHECK(rx == Status::NotInitialized);
  CHECK(f.id == 0x123U);  // untouched
  CHECK(bus.send(f) == Status::NotInitialized);
  CHECK(bus.health().counters.txRefused == 1U);
}

TEST_CASE("opening an interface that does not exist fails with a reason", "[socketcan]") {
  // On a kernel without CAN the socket itself is refused (Unsupported); with CAN the interface
  // lookup fails (NotFound). Either way the bus stays closed and says why.
  agv::drivers::SocketCanBus bus;
  agv::drivers::SocketCanConfig cfg;
  cfg.interfaceName = "agvnocan9";
  const Status s = bus.open(cfg);
  CHECK((s == Status::Unsupported || s == Status::NotFound));
  CHECK(bus.health().lastFailure == s);
  CHECK(bus.health().lastErrno != 0);
  CHECK_FALSE(bus.isUp());
}
