#include "sim_drives.hpp"

#include <cstdlib>

namespace agv::simdrives {

using drivers::CanFrame;
using drivers::canopen::NmtState;
using drivers::canopen::PowerState;

namespace {
const char* nmtName(NmtState s) {
  switch (s) {
    case NmtState::BootUp:
      return "boot-up";
    case NmtState::Stopped:
      return "stopped";
    case NmtState::Operational:
      return "operational";
    case NmtState::PreOperational:
      return "pre-operational";
    case NmtState::Unknown:
      break;
  }
  return "unknown";
}

sim::SimCia402NodeParams nodeParams(std::uint8_t id, std::int32_t position) {
  sim::SimCia402NodeParams p;
  p.nodeId = id;
  p.initialPosition = position;
  return p;
}
}  // namespace

bool parseInjection(const std::string& text, Injection::Kind kind, Injection& out, std::string& error) {
  Injection in;
  in.kind = kind;
  const std::size_t at = text.find('@');
  if (at == std::string::npos) {
    error = "'" + text + "': expected NODE" + std::string(kind == Injection::Kind::Fault ? ":CODE" : "") + "@SECONDS";
    return false;
  }
  std::string head = text.substr(0, at);
  const std::string when = text.substr(at + 1);
  if (kind == Injection::Kind::Fault) {
    const std::size_t colon = head.find(':');
    if (colon == std::string::npos) {
      error = "'" + text + "': expected NODE:CODE@SECONDS";
      return false;
    }
    const std::string code = head.substr(colon + 1);
    char* end = nullptr;
    const unsigned long c = std::strtoul(code.c_str(), &end, 16);
    if (code.empty() || end == nullptr || *end != '\0' || c == 0 || c > 0xFFFFUL) {
      error = "'" + text + "': the error code must be hexadecimal 1..FFFF";
      return false;
    }
    in.errorCode = static_cast<std::uint16_t>(c);
    head = head.substr(0, colon);
  }
  char* end = nullptr;
  const long node = std::strtol(head.c_str(), &end, 10);
  if (head.empty() || end == nullptr || *end != '\0' || node < 1 || node > 127) {
    error = "'" + text + "': the node id must be 1..127";
    return false;
  }
  in.nodeId = static_cast<std::uint8_t>(node);
  const double t = std::strtod(when.c_str(), &end);
  if (when.empty() || end == nullptr || *end != '\0' || !(t >= 0.0) || t > 1e6) {
    error = "'" + text + "': the time must be seconds >= 0";
    return false;
  }
  in.atSeconds = t;
  out = in;
  return true;
}

SimDrives::SimDrives(const SimDrivesOptions& options, std::FILE* log)
    : options_(options),
      log_(log),
      traction_(nodeParams(options.tractionNode, 0)),
      steering_(nodeParams(options.steeringNode, options.steeringInitialPosition)) {}

void SimDrives::receive(const CanFrame& frame, Timestamp now) noexcept {
  traction_.receive(frame, now);
  steering_.receive(frame, now);
}

void SimDrives::report(Timestamp now, const sim::SimCia402Node& n, PowerState& lastState, NmtState& lastNmt) {
  if (log_ == nullptr) {
    return;
  }
  const double t = (now - start_).seconds();
  if (n.nmtState() != lastNmt) {
    std::fprintf(log_, "%.3f node %u: NMT %s\n", t, static_cast<unsigned>(n.nodeId()), nmtName(n.nmtState()));
    lastNmt = n.nmtState();
  }
  if (n.state() != lastState) {
    std::fprintf(log_, "%.3f node %u: %s (mode %d, statusword 0x%04X)\n", t, static_cast<unsigned>(n.nodeId()),
                 drivers::canopen::toString(n.state()), static_cast<int>(n.modeDisplay()),
                 static_cast<unsigned>(n.statusword()));
    lastState = n.state();
  }
}

std::size_t SimDrives::step(Timestamp now, Span<CanFrame> out) {
  if (!started_) {
    started_ = true;
    start_ = now;
  }
  const double t = (now - start_).seconds();
  for (Injection& in : options_.injections) {
    if (in.done || t < in.atSeconds) {
      continue;
    }
    in.done = true;
    if (in.nodeId != traction_.nodeId() && in.nodeId != steering_.nodeId()) {
      continue;
    }
    sim::SimCia402Node& n = node(in.nodeId);
    if (in.kind == Injection::Kind::Fault) {
      n.injectFault(in.errorCode);
    } else {
      n.setSilent(in.kind == Injection::Kind::Silence);
    }
    if (log_ != nullptr) {
      const char* what = in.kind == Injection::Kind::Fault     ? "fault"
                         : in.kind == Injection::Kind::Silence ? "silent"
                                                               : "speaks";
      std::fprintf(log_, "%.3f node %u: injected %s 0x%04X\n", t, static_cast<unsigned>(in.nodeId), what,
                   static_cast<unsigned>(in.errorCode));
    }
  }
  std::size_t count = 0;
  CanFrame buf[kMaxFrames];
  sim::SimCia402Node* nodes[2] = {&traction_, &steering_};
  for (int i = 0; i < 2; ++i) {
    const std::size_t n = nodes[i]->step(now, Span<CanFrame>(buf));
    for (std::size_t k = 0; k < n; ++k) {
      nodes[1 - i]->receive(buf[k], now);  // the other node hears it on the bus
      if (count < out.size()) {
        out[count++] = buf[k];
      }
    }
  }
  report(now, traction_, lastState_[0], lastNmt_[0]);
  report(now, steering_, lastState_[1], lastNmt_[1]);
  return count;
}

}  // namespace agv::simdrives
