#include "agv/drivers/protocol/canopen/cia402.hpp"

namespace agv::drivers::canopen {

using namespace cia402;

const char* toString(PowerState state) noexcept {
  switch (state) {
    case PowerState::NotReadyToSwitchOn:
      return "Not ready to switch on";
    case PowerState::SwitchOnDisabled:
      return "Switch on disabled";
    case PowerState::ReadyToSwitchOn:
      return "Ready to switch on";
    case PowerState::SwitchedOn:
      return "Switched on";
    case PowerState::OperationEnabled:
      return "Operation enabled";
    case PowerState::QuickStopActive:
      return "Quick stop active";
    case PowerState::FaultReactionActive:
      return "Fault reaction active";
    case PowerState::Fault:
      return "Fault";
    case PowerState::Unknown:
      break;
  }
  return "unknown state";
}

PowerState decodeStatusword(std::uint16_t statusword) noexcept {
  const std::uint16_t m4f = statusword & 0x004FU;
  const std::uint16_t m6f = statusword & 0x006FU;
  if (m4f == 0x0000U) {
    return PowerState::NotReadyToSwitchOn;
  }
  if (m4f == 0x0040U) {
    return PowerState::SwitchOnDisabled;
  }
  if (m4f == 0x000FU) {
    return PowerState::FaultReactionActive;
  }
  if (m4f == 0x0008U) {
    return PowerState::Fault;
  }
  if (m6f == 0x0021U) {
    return PowerState::ReadyToSwitchOn;
  }
  if (m6f == 0x0023U) {
    return PowerState::SwitchedOn;
  }
  if (m6f == 0x0027U) {
    return PowerState::OperationEnabled;
  }
  if (m6f == 0x0007U) {
    return PowerState::QuickStopActive;
  }
  return PowerState::Unknown;
}

std::uint16_t statuswordBits(PowerState state) noexcept {
  switch (state) {
    case PowerState::NotReadyToSwitchOn:
      return 0x0000U;
    case PowerState::SwitchOnDisabled:
      return kSwSwitchOnDisabled;
    case PowerState::ReadyToSwitchOn:
      return kSwQuickStop | kSwVoltageEnabled | kSwReadyToSwitchOn;
    case PowerState::SwitchedOn:
      return kSwQuickStop | kSwVoltageEnabled | kSwSwitchedOn | kSwReadyToSwitchOn;
    case PowerState::OperationEnabled:
      return kSwQuickStop | kSwVoltageEnabled | kSwOperationEnabled | kSwSwitchedOn | kSwReadyToSwitchOn;
    case PowerState::QuickStopActive:
      return kSwVoltageEnabled | kSwOperationEnabled | kSwSwitchedOn | kSwReadyToSwitchOn;
    case PowerState::FaultReactionActive:
      return kSwVoltageEnabled | kSwFault | kSwOperationEnabled | kSwSwitchedOn | kSwReadyToSwitchOn;
    case PowerState::Fault:
      return kSwFault;
    case PowerState::Unknown:
      break;
  }
  return 0U;
}

const char* toString(Cia402Command command) noexcept {
  switch (command) {
    case Cia402Command::Shutdown:
      return "shutdown";
    case Cia402Command::SwitchOn:
      return "switch on";
    case Cia402Command::DisableOperation:
      return "disable operation";
    case Cia402Command::EnableOperation:
      return "enable operation";
    case Cia402Command::DisableVoltage:
      return "disable voltage";
    case Cia402Command::QuickStop:
      return "quick stop";
    case Cia402Command::FaultReset:
      return "fault reset";
  }
  return "unknown command";
}

std::uint16_t controlwordFor(Cia402Command command) noexcept {
  switch (command) {
    case Cia402Command::Shutdown:
      return kCwQuickStop | kCwEnableVoltage;
    case Cia402Command::SwitchOn:
    case Cia402Command::DisableOperation:
      return kCwQuickStop | kCwEnableVoltage | kCwSwitchOn;
    case Cia402Command::EnableOperation:
      return kCwEnableOperation | kCwQuickStop | kCwEnableVoltage | kCwSwitchOn;
    case Cia402Command::DisableVoltage:
      return 0x0000U;
    case Cia402Command::QuickStop:
      return kCwEnableVoltage;
    case Cia402Command::FaultReset:
      return kCwFaultReset;
  }
  return 0x0000U;
}

Cia402Command decodeControlword(std::uint16_t previous, std::uint16_t current) noexcept {
  if ((current & kCwFaultReset) != 0U && (previous & kCwFaultReset) == 0U) {
    return Cia402Command::FaultReset;
  }
  if ((current & kCwEnableVoltage) == 0U) {
    return Cia402Command::DisableVoltage;
  }
  if ((current & kCwQuickStop) == 0U) {
    return Cia402Command::QuickStop;
  }
  if ((current & kCwSwitchOn) == 0U) {
    return Cia402Command::Shutdown;
  }
  if ((current & kCwEnableOperation) == 0U) {
    return Cia402Command::SwitchOn;
  }
  return Cia402Command::EnableOperation;
}

Result<PowerState> nextState(PowerState from, Cia402Command command, const Cia402Options& options) noexcept {
  using S = PowerState;
  using C = Cia402Command;
  const C c = command == C::DisableOperation ? C::SwitchOn : command;  // the same controlword
  switch (from) {
    case S::NotReadyToSwitchOn:
    case S::FaultReactionActive:
      return Status::Rejected;
    case S::SwitchOnDisabled:
      if (c == C::Shutdown) {
        return S::ReadyToSwitchOn;  // 2
      }
      if (c == C::DisableVoltage || c == C::QuickStop) {
        return S::SwitchOnDisabled;
      }
      return Status::Rejected;
    case S::ReadyToSwitchOn:
    case S::SwitchedOn:  // the two states answer every command alike
      switch (c) {
        case C::Shutdown:
          return S::ReadyToSwitchOn;  // RTSO: stays; SO: 6
        case C::SwitchOn:
          return S::SwitchedOn;  // RTSO: 3; SO: stays
        case C::EnableOperation:
          return S::OperationEnabled;  // RTSO: 3 + 4; SO: 4
        case C::DisableVoltage:
        case C::QuickStop:
          return S::SwitchOnDisabled;  // RTSO: 7; SO: 10
        default:
          return Status::Rejected;
      }
    case S::OperationEnabled:
      switch (c) {
        case C::Shutdown:
          return S::ReadyToSwitchOn;  // 8
        case C::SwitchOn:
          return S::SwitchedOn;  // 5
        case C::EnableOperation:
          return S::OperationEnabled;
        case C::DisableVoltage:
          return S::SwitchOnDisabled;  // 9
        case C::QuickStop:
          return S::QuickStopActive;  // 11
        default:
          return Status::Rejected;
      }
    case S::QuickStopActive:
      if (c == C::QuickStop) {
        return S::QuickStopActive;
      }
      if (c == C::DisableVoltage) {
        return S::SwitchOnDisabled;  // 12
      }
      if (c == C::EnableOperation && options.quickStopToOperationEnabled) {
        return S::OperationEnabled;  // 16
      }
      return Status::Rejected;
    case S::Fault:
      if (c == C::FaultReset) {
        return S::SwitchOnDisabled;  // 15
      }
      return Status::Rejected;
    case S::Unknown:
      break;
  }
  return Status::InvalidArgument;
}

bool commandTowardsEnabled(PowerState state, Cia402Command& command) noexcept {
  switch (state) {
    case PowerState::SwitchOnDisabled:
      command = Cia402Command::Shutdown;
      return true;
    case PowerState::ReadyToSwitchOn:
      command = Cia402Command::SwitchOn;
      return true;
    case PowerState::SwitchedOn:
      command = Cia402Command::EnableOperation;
      return true;
    case PowerState::Fault:
      command = Cia402Command::FaultReset;
      return true;
    default:
      return false;
  }
}

}  // namespace agv::drivers::canopen
