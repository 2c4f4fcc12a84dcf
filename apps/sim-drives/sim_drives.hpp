#pragma once
/// @file sim_drives.hpp
/// `agvnav-sim-drives`: the vehicle's traction and steering drives played as two simulated CiA 402
/// nodes (`agv::sim::SimCia402Node`) on one CAN bus, with scheduled fault injections. `SimDrives` is
/// the part without sockets (tested in-process against the drive controller); main.cpp moves its
/// frames over a SocketCAN interface (docs/drives.md).

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "agv/core/span.hpp"
#include "agv/core/status.hpp"
#include "agv/core/timestamp.hpp"
#include "agv/drivers/protocol/can_frame.hpp"
#include "agv/sim/sim_cia402_node.hpp"

namespace agv::simdrives {

/// Something to do to one node at a time after the start.
struct Injection {
  enum class Kind : std::uint8_t { Fault, Silence, Speak };
  Kind kind = Kind::Fault;
  std::uint8_t nodeId = 1;
  std::uint16_t errorCode = 0;  ///< Fault: the EMCY / 0x603F code
  double atSeconds = 0.0;       ///< after the first step
  bool done = false;
};

/// Parses `NODE:CODE@SECONDS` (fault, CODE hexadecimal with or without 0x) or `NODE@SECONDS`
/// (silence / speak again). False with `error` set when it does not parse or the node is not 1..127.
bool parseInjection(const std::string& text, Injection::Kind kind, Injection& out, std::string& error);

struct SimDrivesOptions {
  std::uint8_t tractionNode = 1;
  std::uint8_t steeringNode = 3;
  std::int32_t steeringInitialPosition = 0;  ///< [position units]
  std::vector<Injection> injections;
};

/// The two nodes and the injections; see the file comment.
class SimDrives {
 public:
  /// Most frames one `step()` returns.
  static constexpr std::size_t kMaxFrames = 64;

  /// `log` (may be null) gets one line per state change of a node and per injection.
  SimDrives(const SimDrivesOptions& options, std::FILE* log);

  /// A frame from the bus.
  void receive(const drivers::CanFrame& frame, Timestamp now) noexcept;
  /// Advances both nodes to `now`, applies the injections due, hands each node's frames to the
  /// other node and returns in `out` the frames to put on the bus.
  std::size_t step(Timestamp now, Span<drivers::CanFrame> out);

  const sim::SimCia402Node& traction() const noexcept { return traction_; }
  const sim::SimCia402Node& steering() const noexcept { return steering_; }
  sim::SimCia402Node& node(std::uint8_t id) noexcept { return id == traction_.nodeId() ? traction_ : steering_; }

 private:
  void report(Timestamp now, const sim::SimCia402Node& n, drivers::canopen::PowerState& lastState,
              drivers::canopen::NmtState& lastNmt);

  SimDrivesOptions options_;
  std::FILE* log_;
  sim::SimCia402Node traction_;
  sim::SimCia402Node steering_;
  bool started_ = false;
  Timestamp start_{};
  drivers::canopen::PowerState lastState_[2] = {drivers::canopen::PowerState::Unknown,
                                                drivers::canopen::PowerState::Unknown};
  drivers::canopen::NmtState lastNmt_[2] = {drivers::canopen::NmtState::Unknown, drivers::canopen::NmtState::Unknown};
};

}  // namespace agv::simdrives
