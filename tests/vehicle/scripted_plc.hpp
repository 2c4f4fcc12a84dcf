#pragma once
// The PLC as the calibration tests play it, shared by vehicle.calibration (in-process) and the vcan
// VM's calibration cases: commands queued by the test, every published report kept, the routine
// states seen on register 44 and the reports in mode Calibrating counted.
#include <deque>

#include "agv/core/pose2.hpp"
#include "agv/core/status.hpp"
#include "agv/hal/plc_link.hpp"

namespace agv::test {

class ScriptedPlc final : public hal::PlcLink {
 public:
  Status publish(const hal::PoseReport& report) noexcept override {
    last = report;
    ++reports;
    if (report.health.mode == hal::NavMode::Calibrating) {
      ++calibratingReports;
    }
    seen[report.health.calibration.state & 15U] = true;  // no allocation: the cycles are counted
    return Status::Ok;
  }
  Status readCommand(hal::PlcCommand& out) noexcept override {
    if (queue.empty()) {
      return Status::NotFound;
    }
    out = queue.front();
    queue.pop_front();
    return Status::Ok;
  }
  void send(hal::PlcCommandKind kind, const Pose2d& pose = Pose2d{}) {
    hal::PlcCommand c;
    c.kind = kind;
    c.initialPose = pose;
    queue.push_back(c);
  }
  std::deque<hal::PlcCommand> queue;
  hal::PoseReport last;
  int reports = 0;
  int calibratingReports = 0;
  bool seen[16] = {};
};

}  // namespace agv::test
