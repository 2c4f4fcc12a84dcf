#pragma once
/// @file instruction_count.hpp
/// C++ helpers of the instruction-count images (tests/*/mcu_*_count.cpp): count the instructions
/// of a callable with instruction_counter.h, print a labelled value through semihosting.

#include <cstdint>

#include "instruction_counter.h"
#include "semihosting.h"

namespace agv::mcu {

/// Writes "<label><value>\n" through semihosting.
inline void printValue(const char* label, std::uint32_t value) {
  semihosting_write0(label);
  semihosting_write_int(value);
  semihosting_write0("\n");
}

/// Instructions executed by f() (agv_icount_init() must have succeeded).
template <typename F>
std::uint32_t countInstructions(F&& f) {
  const std::uint64_t t0 = agv_icount_ticks();
  f();
  const std::uint64_t t1 = agv_icount_ticks();
  return static_cast<std::uint32_t>(agv_icount_instructions(t1 - t0));
}

}  // namespace agv::mcu
