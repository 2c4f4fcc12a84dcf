#pragma once
// The PLC's side of the Modbus link as the tests play it with libmodbus, shared by the vehicle's
// process tests (vehicle_process.hpp) and the vcan VM's calibration case over Modbus.
#include <modbus.h>

#include <cstdint>

#include "agv/drivers/protocol/plc/word_order.hpp"
#include "agv/hal/plc_messages.hpp"

namespace agv::test {

/// Writes the whole command block (registers 100-108, docs/plc-link.md) in one request: the code,
/// `sequence` (a new value makes it a new command), the set-pose and the PLC heartbeat (108, given
/// the sequence so that it moves too). True when the vehicle accepted the write.
inline bool writePlcCommand(modbus_t* plc, std::uint16_t sequence, hal::PlcCommandKind kind, float x = 0.0F,
                            float y = 0.0F, float theta = 0.0F) {
  std::uint16_t cmd[9] = {};
  cmd[0] = static_cast<std::uint16_t>(kind);
  cmd[1] = sequence;
  // Our packing: libmodbus' setters write ABCD byte-swapped (docs/plc-link.md).
  using drivers::plc::WordOrder;
  drivers::plc::packFloat(x, WordOrder::ABCD, &cmd[2]);
  drivers::plc::packFloat(y, WordOrder::ABCD, &cmd[4]);
  drivers::plc::packFloat(theta, WordOrder::ABCD, &cmd[6]);
  cmd[8] = sequence;
  return modbus_write_registers(plc, 100, 9, cmd) == 9;
}

}  // namespace agv::test
