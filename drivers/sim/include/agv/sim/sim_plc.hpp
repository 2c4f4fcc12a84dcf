#pragma once
/// @file sim_plc.hpp
/// In-process PLC peer: records what the navigation publishes and feeds it commands.

#include <deque>
#include <vector>

#include "agv/hal/plc_link.hpp"

namespace agv::sim {

/// The PLC side of the link, in the same process: every published report is kept (the HIL
/// compares them with the truth afterwards); commands are queued by the simulation with `send()`.
class SimPlcPeer final : public hal::PlcLink {
 public:
  Status publish(const hal::PoseReport& report) noexcept override;
  Status readCommand(hal::PlcCommand& out) noexcept override;

  /// Queues a command for the navigation.
  void send(const hal::PlcCommand& cmd) { commands_.push_back(cmd); }
  /// Everything published so far, in order.
  const std::vector<hal::PoseReport>& reports() const noexcept { return reports_; }
  void clearReports() noexcept { reports_.clear(); }

 private:
  std::vector<hal::PoseReport> reports_;
  std::deque<hal::PlcCommand> commands_;
};

}  // namespace agv::sim
