#include "agv/sim/sim_plc.hpp"

namespace agv::sim {

Status SimPlcPeer::publish(const hal::PoseReport& report) noexcept {
  if (!report.pose.isFinite()) {
    return Status::NonFiniteInput;  // a real PLC program rejects it too; nothing recorded
  }
  reports_.push_back(report);
  return Status::Ok;
}

Status SimPlcPeer::readCommand(hal::PlcCommand& out) noexcept {
  if (commands_.empty()) {
    return Status::NotFound;
  }
  out = commands_.front();
  commands_.pop_front();
  return Status::Ok;
}

}  // namespace agv::sim
