// CiA 402 power state machine, controlword / statusword coding, expedited SDO frames, abort code
// names and EMCY decoding. Every expected value is written out here from CiA 402 / CiA 301 (the
// state masks and the transition table, the SDO command specifiers and byte layout, the abort code
// list), not taken from the code under test. Portable subset of agv_test.hpp (runs on the MCU).
#include <cstdint>
#include <cstring>

#include "agv/drivers/protocol/canopen/canopen_encoders.hpp"
#include "agv/drivers/protocol/canopen/cia402.hpp"
#include "agv/drivers/protocol/canopen/sdo.hpp"
#include "agv_test.hpp"

using namespace agv;
using namespace agv::drivers;
using namespace agv::drivers::canopen;

namespace {
struct SwCase {
  std::uint16_t word;
  PowerState state;
};

// Statuswords with the state bits of CiA 402 and unrelated bits (voltage enabled 4, warning 7,
// remote 9, target reached 10, set-point acknowledge 12, manufacturer bits 14/15) mixed in.
const SwCase kStatuswords[] = {
    {0x0000, PowerState::NotReadyToSwitchOn},
    {0x0010, PowerState::NotReadyToSwitchOn},  // voltage bit is not part of the mask
    {0x0020, PowerState::NotReadyToSwitchOn},  // nor is quick stop (x0xx 0000)
    {0x0040, PowerState::SwitchOnDisabled},
    {0x0060, PowerState::SwitchOnDisabled},
    {0x0250, PowerState::SwitchOnDisabled},
    {0x0021, PowerState::ReadyToSwitchOn},
    {0x0231, PowerState::ReadyToSwitchOn},
    {0x0023, PowerState::SwitchedOn},
    {0x8233, PowerState::SwitchedOn},
    {0x0027, PowerState::OperationEnabled},
    {0x1637, PowerState::OperationEnabled},
    {0x0007, PowerState::QuickStopActive},
    {0x0217, PowerState::QuickStopActive},
    {0x000F, PowerState::FaultReactionActive},
    {0x002F, PowerState::FaultReactionActive},
    {0x001F, PowerState::FaultReactionActive},
    {0x0008, PowerState::Fault},
    {0x0028, PowerState::Fault},
    {0x0218, PowerState::Fault},
    {0x0001, PowerState::Unknown},  // ready to switch on without quick stop: no state
    {0x0003, PowerState::Unknown},
    {0x0041, PowerState::Unknown},  // switch on disabled together with ready to switch on
    {0x0048, PowerState::Unknown},
};

constexpr PowerState kAllStates[] = {PowerState::NotReadyToSwitchOn,  PowerState::SwitchOnDisabled,
                                     PowerState::ReadyToSwitchOn,     PowerState::SwitchedOn,
                                     PowerState::OperationEnabled,    PowerState::QuickStopActive,
                                     PowerState::FaultReactionActive, PowerState::Fault};
constexpr Cia402Command kAllCommands[] = {Cia402Command::Shutdown,         Cia402Command::SwitchOn,
                                          Cia402Command::DisableOperation, Cia402Command::EnableOperation,
                                          Cia402Command::DisableVoltage,   Cia402Command::QuickStop,
                                          Cia402Command::FaultReset};

// The transition table of CiA 402, one row per state, one column per command in the order of
// kAllCommands. X = refused (no transition). Numbers in the comments are the standard's.
constexpr PowerState X = PowerState::Unknown;
constexpr PowerState NR = PowerState::NotReadyToSwitchOn;
constexpr PowerState SOD = PowerState::SwitchOnDisabled;
constexpr PowerState RTSO = PowerState::ReadyToSwitchOn;
constexpr PowerState SO = PowerState::SwitchedOn;
constexpr PowerState OE = PowerState::OperationEnabled;
constexpr PowerState QSA = PowerState::QuickStopActive;
constexpr PowerState FRA = PowerState::FaultReactionActive;
constexpr PowerState F = PowerState::Fault;
//                         shutdown  switchOn disableOp enableOp disableV quickStop faultReset
const PowerState kTable[8][7] = {
    /* NR   */ {X, X, X, X, X, X, X},            // left automatically (1)
    /* SOD  */ {RTSO, X, X, X, SOD, SOD, X},     // 2
    /* RTSO */ {RTSO, SO, SO, OE, SOD, SOD, X},  // 3, 3+4, 7
    /* SO   */ {RTSO, SO, SO, OE, SOD, SOD, X},  // 6, 4, 10
    /* OE   */ {RTSO, SO, SO, OE, SOD, QSA, X},  // 8, 5, 9, 11
    /* QSA  */ {X, X, X, X, SOD, QSA, X},        // 12 (16 only with the option)
    /* FRA  */ {X, X, X, X, X, X, X},            // left automatically (14)
    /* F    */ {X, X, X, X, X, X, SOD},          // 15
};
}  // namespace

TEST_CASE("statusword decodes to the CiA 402 state by the standard masks", "[cia402]") {
  for (const SwCase& c : kStatuswords) {
    INFO("statusword " << c.word);
    CHECK(decodeStatusword(c.word) == c.state);
  }
  // The simulated drive's statusword for each state decodes to that state.
  for (PowerState s : kAllStates) {
    CHECK(decodeStatusword(statuswordBits(s)) == s);
  }
  CHECK(std::strcmp(toString(PowerState::OperationEnabled), "Operation enabled") == 0);
  CHECK(std::strcmp(toString(PowerState::Unknown), "unknown state") == 0);
}

TEST_CASE("controlword commands have the CiA 402 bit patterns", "[cia402]") {
  CHECK(controlwordFor(Cia402Command::Shutdown) == 0x0006);
  CHECK(controlwordFor(Cia402Command::SwitchOn) == 0x0007);
  CHECK(controlwordFor(Cia402Command::DisableOperation) == 0x0007);
  CHECK(controlwordFor(Cia402Command::EnableOperation) == 0x000F);
  CHECK(controlwordFor(Cia402Command::DisableVoltage) == 0x0000);
  CHECK(controlwordFor(Cia402Command::QuickStop) == 0x0002);
  CHECK(controlwordFor(Cia402Command::FaultReset) == 0x0080);

  // Decoding: bits 0-3 with the don't-care bits set both ways, and the bit-7 edge.
  CHECK(decodeControlword(0, 0x0006) == Cia402Command::Shutdown);
  CHECK(decodeControlword(0, 0x000E) == Cia402Command::Shutdown);  // 0xxx x110
  CHECK(decodeControlword(0, 0x0007) == Cia402Command::SwitchOn);
  CHECK(decodeControlword(0, 0x0017) == Cia402Command::SwitchOn);  // mode bit 4 does not matter
  CHECK(decodeControlword(0, 0x000F) == Cia402Command::EnableOperation);
  CHECK(decodeControlword(0, 0x003F) == Cia402Command::EnableOperation);
  CHECK(decodeControlword(0, 0x0000) == Cia402Command::DisableVoltage);
  CHECK(decodeControlword(0, 0x000D) == Cia402Command::DisableVoltage);  // 0xxx xx0x
  CHECK(decodeControlword(0, 0x0002) == Cia402Command::QuickStop);
  CHECK(decodeControlword(0, 0x000B) == Cia402Command::QuickStop);  // 0xxx x01x
  CHECK(decodeControlword(0x0000, 0x0080) == Cia402Command::FaultReset);
  CHECK(decodeControlword(0x000F, 0x008F) == Cia402Command::FaultReset);
  // Bit 7 held high is no new reset: the other bits decide.
  CHECK(decodeControlword(0x0080, 0x0080) == Cia402Command::DisableVoltage);
  CHECK(decodeControlword(0x0086, 0x0086) == Cia402Command::Shutdown);
}

TEST_CASE("the transition table of CiA 402, illegal transitions refused", "[cia402]") {
  for (std::size_t s = 0; s < 8; ++s) {
    for (std::size_t c = 0; c < 7; ++c) {
      const Result<PowerState> r = nextState(kAllStates[s], kAllCommands[c]);
      INFO("from " << toString(kAllStates[s]) << " on " << toString(kAllCommands[c]));
      if (kTable[s][c] == X) {
        CHECK_FALSE(r.ok());
        CHECK(r.status() == Status::Rejected);
      } else {
        REQUIRE(r.ok());
        CHECK(r.value() == kTable[s][c]);
      }
    }
  }
  // Transition 16 only when the quick-stop option code allows it.
  Cia402Options opt;
  opt.quickStopToOperationEnabled = true;
  const Result<PowerState> back = nextState(PowerState::QuickStopActive, Cia402Command::EnableOperation, opt);
  REQUIRE(back.ok());
  CHECK(back.value() == PowerState::OperationEnabled);
  CHECK(nextState(PowerState::Unknown, Cia402Command::Shutdown).status() == Status::InvalidArgument);
  // NR and FRA are unused names otherwise (kept for the table's readability).
  CHECK(NR != FRA);
  CHECK(F != QSA);
}

TEST_CASE("the command towards Operation enabled follows the table", "[cia402]") {
  // From Switch on disabled, the commands chosen step by step reach Operation enabled in 3 steps;
  // from Fault, a fault reset first.
  PowerState s = PowerState::Fault;
  int steps = 0;
  Cia402Command c = Cia402Command::DisableVoltage;
  while (commandTowardsEnabled(s, c) && steps < 10) {
    const Result<PowerState> r = nextState(s, c);
    REQUIRE(r.ok());
    s = r.value();
    ++steps;
  }
  CHECK(s == PowerState::OperationEnabled);
  CHECK(steps == 4);
  CHECK_FALSE(commandTowardsEnabled(PowerState::QuickStopActive, c));
  CHECK_FALSE(commandTowardsEnabled(PowerState::NotReadyToSwitchOn, c));
}

TEST_CASE("SDO requests and responses have the CiA 301 byte layout", "[cia402][sdo]") {
  CanFrame f;
  SdoMessage m;
  // Write modes of operation = 3 (1 byte) to node 5: 0x2F = ccs 1, n = 3, e = 1, s = 1.
  m.kind = SdoKind::DownloadRequest;
  m.index = 0x6060;
  m.subIndex = 0;
  m.value = 3;
  m.size = 1;
  REQUIRE(encodeSdoRequest(5, m, f) == Status::Ok);
  const std::uint8_t write1[8] = {0x2F, 0x60, 0x60, 0x00, 0x03, 0x00, 0x00, 0x00};
  CHECK(f.id == 0x605);
  CHECK(f.dlc == 8);
  CHECK(std::memcmp(f.data, write1, 8) == 0);
  // Consumer heartbeat time (u32) of node 127, 200 ms: 0x23 = 4 bytes.
  m.index = 0x1016;
  m.subIndex = 1;
  m.value = 0x007F00C8;
  m.size = 4;
  REQUIRE(encodeSdoRequest(0x12, m, f) == Status::Ok);
  const std::uint8_t write4[8] = {0x23, 0x16, 0x10, 0x01, 0xC8, 0x00, 0x7F, 0x00};
  CHECK(f.id == 0x612);
  CHECK(std::memcmp(f.data, write4, 8) == 0);
  // 2 bytes: 0x2B; 3 bytes: 0x27.
  m.size = 2;
  m.value = 0x0032;
  REQUIRE(encodeSdoRequest(1, m, f) == Status::Ok);
  CHECK(f.data[0] == 0x2B);
  m.size = 3;
  REQUIRE(encodeSdoRequest(1, m, f) == Status::Ok);
  CHECK(f.data[0] == 0x27);
  // Read modes of operation display: 0x40.
  m = SdoMessage{};
  m.kind = SdoKind::UploadRequest;
  m.index = 0x6061;
  REQUIRE(encodeSdoRequest(5, m, f) == Status::Ok);
  const std::uint8_t read[8] = {0x40, 0x61, 0x60, 0x00, 0x00, 0x00, 0x00, 0x00};
  CHECK(std::memcmp(f.data, read, 8) == 0);
  // Server: expedited upload response of 1 byte (0x4F) from node 5, download response 0x60, abort 0x80.
  m.kind = SdoKind::UploadResponse;
  m.value = 3;
  m.size = 1;
  REQUIRE(encodeSdoResponse(5, m, f) == Status::Ok);
  const std::uint8_t up1[8] = {0x4F, 0x61, 0x60, 0x00, 0x03, 0x00, 0x00, 0x00};
  CHECK(f.id == 0x585);
  CHECK(std::memcmp(f.data, up1, 8) == 0);
  m.kind = SdoKind::DownloadResponse;
  m.index = 0x6040;
  REQUIRE(encodeSdoResponse(5, m, f) == Status::Ok);
  CHECK(f.data[0] == 0x60);
  CHECK(f.data[1] == 0x40);
  CHECK(f.data[2] == 0x60);
  m.kind = SdoKind::Abort;
  m.index = 0x2000;
  m.subIndex = 0;
  m.abortCode = 0x06020000;
  REQUIRE(encodeSdoResponse(5, m, f) == Status::Ok);
  const std::uint8_t abort[8] = {0x80, 0x00, 0x20, 0x00, 0x00, 0x00, 0x02, 0x06};
  CHECK(std::memcmp(f.data, abort, 8) == 0);

  // Refusals.
  m.kind = SdoKind::DownloadRequest;
  m.size = 1;
  m.value = 0x100;  // does not fit one byte
  CHECK(encodeSdoRequest(5, m, f) == Status::InvalidArgument);
  m.value = 1;
  CHECK(encodeSdoRequest(0, m, f) == Status::InvalidArgument);
  CHECK(encodeSdoRequest(128, m, f) == Status::InvalidArgument);
  m.size = 5;
  CHECK(encodeSdoRequest(5, m, f) == Status::InvalidArgument);
  m.size = 1;
  CHECK(encodeSdoResponse(5, m, f) == Status::InvalidArgument);  // a server does not send requests
  m.kind = SdoKind::UploadResponse;
  CHECK(encodeSdoRequest(5, m, f) == Status::InvalidArgument);
}

TEST_CASE("SDO frames decode, round trips and refusals", "[cia402][sdo]") {
  CanFrame f;
  f.id = 0x605;
  f.dlc = 8;
  const std::uint8_t write2[8] = {0x2B, 0x17, 0x10, 0x00, 0x32, 0x00, 0xAA, 0xBB};  // bytes 6-7 unused
  std::memcpy(f.data, write2, 8);
  SdoMessage m;
  REQUIRE(decodeSdoRequest(f, 5, m) == Status::Ok);
  CHECK(m.kind == SdoKind::DownloadRequest);
  CHECK(m.index == 0x1017);
  CHECK(m.subIndex == 0);
  CHECK(m.size == 2);
  CHECK(m.value == 0x32);  // bytes past the size are not part of the value
  // Expedited without size indication (0x22): all four bytes.
  f.data[0] = 0x22;
  REQUIRE(decodeSdoRequest(f, 5, m) == Status::Ok);
  CHECK(m.size == 0);
  CHECK(m.value == 0xBBAA0032U);
  // Other node, wrong direction, truncated, extended.
  CHECK(decodeSdoRequest(f, 6, m) == Status::NotFound);
  CHECK(decodeSdoResponse(f, 5, m) == Status::NotFound);
  f.dlc = 7;
  CHECK(decodeSdoRequest(f, 5, m) == Status::Truncated);
  f.dlc = 8;
  f.extended = true;
  CHECK(decodeSdoRequest(f, 5, m) == Status::NotFound);
  f.extended = false;
  // Segmented download initiate (e = 0), block download (ccs 6), reserved ccs 7.
  f.data[0] = 0x21;
  CHECK(decodeSdoRequest(f, 5, m) == Status::Unsupported);
  f.data[0] = 0xC0;
  CHECK(decodeSdoRequest(f, 5, m) == Status::Unsupported);
  f.data[0] = 0xE0;
  CHECK(decodeSdoRequest(f, 5, m) == Status::Malformed);

  // Responses: a 2-byte upload response (0x4B), a normal (segmented) upload response (0x41), abort.
  CanFrame r;
  r.id = 0x585;
  r.dlc = 8;
  const std::uint8_t up2[8] = {0x4B, 0x3F, 0x60, 0x00, 0x10, 0x23, 0xFF, 0xFF};
  std::memcpy(r.data, up2, 8);
  REQUIRE(decodeSdoResponse(r, 5, m) == Status::Ok);
  CHECK(m.kind == SdoKind::UploadResponse);
  CHECK(m.index == 0x603F);
  CHECK(m.size == 2);
  CHECK(m.value == 0x2310);
  r.data[0] = 0x41;
  CHECK(decodeSdoResponse(r, 5, m) == Status::Unsupported);
  const std::uint8_t ab[8] = {0x80, 0x60, 0x60, 0x00, 0x30, 0x00, 0x09, 0x06};
  std::memcpy(r.data, ab, 8);
  REQUIRE(decodeSdoResponse(r, 5, m) == Status::Ok);
  CHECK(m.kind == SdoKind::Abort);
  CHECK(m.index == 0x6060);
  CHECK(m.abortCode == 0x06090030U);

  // Round trips of every kind and size.
  const std::uint32_t values[4] = {0xA5, 0xBEEF, 0x123456, 0xDEADBEEF};
  for (std::uint8_t size = 1; size <= 4; ++size) {
    SdoMessage w;
    w.kind = SdoKind::DownloadRequest;
    w.index = 0x60FF;
    w.subIndex = 0;
    w.size = size;
    w.value = values[size - 1];
    CanFrame e;
    REQUIRE(encodeSdoRequest(33, w, e) == Status::Ok);
    SdoMessage back;
    REQUIRE(decodeSdoRequest(e, 33, back) == Status::Ok);
    CHECK(back.kind == w.kind);
    CHECK(back.index == w.index);
    CHECK(back.size == size);
    CHECK(back.value == w.value);
    w.kind = SdoKind::UploadResponse;
    REQUIRE(encodeSdoResponse(33, w, e) == Status::Ok);
    REQUIRE(decodeSdoResponse(e, 33, back) == Status::Ok);
    CHECK(back.kind == SdoKind::UploadResponse);
    CHECK(back.value == w.value);
    CHECK(back.size == size);
  }
  SdoMessage a;
  a.kind = SdoKind::Abort;
  a.index = 0x1A00;
  a.subIndex = 2;
  a.abortCode = 0x06040042;
  CanFrame e;
  REQUIRE(encodeSdoRequest(9, a, e) == Status::Ok);  // a client may abort too
  SdoMessage back;
  REQUIRE(decodeSdoRequest(e, 9, back) == Status::Ok);
  CHECK(back.kind == SdoKind::Abort);
  CHECK(back.subIndex == 2);
  CHECK(back.abortCode == 0x06040042U);
}

TEST_CASE("every SDO abort code of CiA 301 is reported by name", "[cia402][sdo]") {
  // The list of CiA 301, written out here.
  const std::uint32_t codes[] = {0x05030000, 0x05040000, 0x05040001, 0x05040002, 0x05040003, 0x05040004, 0x05040005,
                                 0x06010000, 0x06010001, 0x06010002, 0x06020000, 0x06040041, 0x06040042, 0x06040043,
                                 0x06040047, 0x06060000, 0x06070010, 0x06070012, 0x06070013, 0x06090011, 0x06090030,
                                 0x06090031, 0x06090032, 0x06090036, 0x060A0023, 0x08000000, 0x08000020, 0x08000021,
                                 0x08000022, 0x08000023, 0x08000024};
  const std::size_t n = sizeof(codes) / sizeof(codes[0]);
  CHECK(n == sizeof(kSdoAbortCodes) / sizeof(kSdoAbortCodes[0]));
  for (std::size_t i = 0; i < n; ++i) {
    const char* name = sdoAbortName(codes[i]);
    REQUIRE(name != nullptr);
    CHECK(std::strcmp(name, "unknown abort code") != 0);
    CHECK(std::strlen(name) > 5);
    for (std::size_t j = 0; j < i; ++j) {
      CHECK(std::strcmp(name, sdoAbortName(codes[j])) != 0);  // names tell the codes apart
    }
  }
  // Names carry the meaning.
  CHECK(std::strcmp(sdoAbortName(0x06020000), "object does not exist") == 0);
  CHECK(std::strstr(sdoAbortName(0x06090011), "sub-index") != nullptr);
  CHECK(std::strstr(sdoAbortName(0x06010002), "read-only") != nullptr);
  CHECK(std::strstr(sdoAbortName(0x06010001), "write-only") != nullptr);
  CHECK(std::strstr(sdoAbortName(0x08000022), "device state") != nullptr);
  CHECK(std::strstr(sdoAbortName(0x06040041), "mapped") != nullptr);
  CHECK(std::strstr(sdoAbortName(0x05040000), "timed out") != nullptr);
  CHECK(std::strcmp(sdoAbortName(0x12345678), "unknown abort code") == 0);
  CHECK(std::strcmp(sdoAbortName(0), "unknown abort code") == 0);
}

TEST_CASE("EMCY frames decode: code, register, vendor bytes; short ones refused", "[cia402][emcy]") {
  CanFrame f;
  f.id = 0x085;
  f.dlc = 8;
  const std::uint8_t d[8] = {0x10, 0x23, 0x03, 0x01, 0x02, 0x03, 0x04, 0x05};
  std::memcpy(f.data, d, 8);
  f.stamp = Timestamp{77};
  EmcyRecord r;
  REQUIRE(decodeEmcy(f, r) == Status::Ok);
  CHECK(r.nodeId == 5);
  CHECK(r.errorCode == 0x2310);  // continuous over-current (CiA 301 error code class 0x23xx)
  CHECK(r.errorRegister == 0x03);
  CHECK(r.vendor[0] == 0x01);
  CHECK(r.vendor[4] == 0x05);
  CHECK(r.stamp == Timestamp{77});
  f.dlc = 4;
  REQUIRE(decodeEmcy(f, r) == Status::Ok);
  CHECK(r.vendor[0] == 0x01);
  CHECK(r.vendor[1] == 0x00);  // past dlc
  f.dlc = 2;
  EmcyRecord untouched;
  untouched.errorCode = 0xABCD;
  CHECK(decodeEmcy(f, untouched) == Status::Truncated);
  CHECK(untouched.errorCode == 0xABCD);
  f.dlc = 8;
  f.id = 0x080;  // SYNC
  CHECK(decodeEmcy(f, r) == Status::NotFound);
  f.id = 0x100;
  CHECK(decodeEmcy(f, r) == Status::NotFound);
  f.id = 0x0FF;  // node 127
  REQUIRE(decodeEmcy(f, r) == Status::Ok);
  CHECK(r.nodeId == 127);
  f.rtr = true;
  CHECK(decodeEmcy(f, r) == Status::NotFound);
}
