// libFuzzer target: the CiA 402 / SDO / EMCY decoding and the drive controller fed arbitrary frames.
// Each 14 bytes of input are one frame: id (2, 11 bits), dlc (1, 0..8), flags (1: extended, rtr,
// error, "poll after"), data (8), time step in 0.1 ms (2). Every frame goes through the stateless
// decoders (SDO request and response for its node, EMCY, statusword and controlword of its first
// bytes) and into a started `Cia402DriveController`, which is polled when the flag says so.
// Invariants: no crash or sanitizer report; a decoded SDO message re-encodes and decodes to the
// same message; abort names are never null; states stay within their enums; the controller's
// outbox never holds more than its capacity and emits only standard 11-bit data frames.
#include <cstddef>
#include <cstdint>

#include "agv/drivers/protocol/canopen/canopen_encoders.hpp"
#include "agv/drivers/protocol/canopen/cia402.hpp"
#include "agv/drivers/protocol/canopen/cia402_drive.hpp"
#include "agv/drivers/protocol/canopen/sdo.hpp"
#include "fuzz_support.hpp"

using namespace agv::drivers;
using namespace agv::drivers::canopen;

namespace {
using agv::fuzz::check;

bool sameMessage(const SdoMessage& a, const SdoMessage& b) {
  if (a.kind != b.kind || a.index != b.index || a.subIndex != b.subIndex) {
    return false;
  }
  if (a.kind == SdoKind::Abort) {
    return a.abortCode == b.abortCode;
  }
  if (a.kind == SdoKind::DownloadRequest || a.kind == SdoKind::UploadResponse) {
    return a.value == b.value && a.size == b.size;
  }
  return true;
}

void checkSdo(const CanFrame& f, std::uint8_t node) {
  SdoMessage m;
  if (decodeSdoRequest(f, node, m) == agv::Status::Ok) {
    check(m.size <= 4);
    CanFrame again;
    check(encodeSdoRequest(node, m, again) == agv::Status::Ok);
    SdoMessage back;
    check(decodeSdoRequest(again, node, back) == agv::Status::Ok && sameMessage(m, back));
  }
  if (decodeSdoResponse(f, node, m) == agv::Status::Ok) {
    check(m.size <= 4);
    CanFrame again;
    check(encodeSdoResponse(node, m, again) == agv::Status::Ok);
    SdoMessage back;
    check(decodeSdoResponse(again, node, back) == agv::Status::Ok && sameMessage(m, back));
    if (m.kind == SdoKind::Abort) {
      check(sdoAbortName(m.abortCode) != nullptr);
    }
  }
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static Cia402DriveConfig cfg;  // defaults: traction node 1, steering node 2, controller 127
  Cia402DriveController ctl(cfg);
  agv::Timestamp now{1000000000};
  check(ctl.start(now) == agv::Status::Ok);
  CanFrame out[CanOutbox::kCapacity + 1];
  for (std::size_t pos = 0; pos + 14 <= size; pos += 14) {
    const std::uint8_t* p = data + pos;
    CanFrame f = agv::fuzz::canFrameFromBytes(p);
    now = now + agv::Duration::fromMicroseconds(100 * static_cast<std::int64_t>(agv::fuzz::u16le(p + 12)));
    f.stamp = now;

    // Stateless decoders.
    checkSdo(f, static_cast<std::uint8_t>((f.id & 0x7FU) == 0 ? 1 : (f.id & 0x7FU)));
    EmcyRecord r;
    if (decodeEmcy(f, r) == agv::Status::Ok) {
      check(r.nodeId >= 1 && r.nodeId <= 127);
    }
    const std::uint16_t word = static_cast<std::uint16_t>(f.data[0] | (f.data[1] << 8));
    const PowerState s = decodeStatusword(word);
    check(static_cast<unsigned>(s) <= static_cast<unsigned>(PowerState::Unknown));
    check(toString(s) != nullptr);
    const Cia402Command c = decodeControlword(static_cast<std::uint16_t>(f.data[2] | (f.data[3] << 8)), word);
    const agv::Result<PowerState> next = nextState(s, c);
    check(!next.ok() || static_cast<unsigned>(next.value()) < static_cast<unsigned>(PowerState::Unknown));

    // The controller.
    ctl.onFrame(f);
    if ((p[3] & 8) != 0) {
      ctl.poll(now);
      const std::size_t n = ctl.takeFrames(agv::Span<CanFrame>(out));
      check(n <= CanOutbox::kCapacity);
      for (std::size_t i = 0; i < n; ++i) {
        check(!out[i].extended && !out[i].rtr && !out[i].error && out[i].id <= 0x7FFU && out[i].dlc <= 8);
      }
    }
    if ((p[3] & 16) != 0) {
      agv::hal::DriveCommand cmd;
      cmd.speed = static_cast<double>(static_cast<std::int8_t>(p[4])) / 64.0;
      cmd.steeringAngle = static_cast<double>(static_cast<std::int8_t>(p[5])) / 64.0;
      (void)ctl.command(cmd);
    }
    if ((p[3] & 96) == 96) {
      (void)ctl.release();  // the end of a motion task, in whatever state the controller is
    }
    check(static_cast<unsigned>(ctl.state()) <= static_cast<unsigned>(DriveControllerState::Released));
    check(static_cast<unsigned>(ctl.traction().phase()) <= static_cast<unsigned>(AxisPhase::Released));
  }
  return 0;
}
