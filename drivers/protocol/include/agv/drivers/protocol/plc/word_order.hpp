#pragma once
/// @file word_order.hpp
/// 32-bit values (IEEE-754 float, uint32) in two 16-bit Modbus registers, in the four byte/word
/// orders PLCs use. Packed by hand: libmodbus 3.1.6's modbus_set_float_abcd family writes the
/// wrong layout on little-endian hosts (its modbus_get_float_* readers are right, and the tests
/// check this packing against them).
///
/// With the float's big-endian bytes A B C D (A holds the sign and exponent):
///   ABCD: reg[0] = A B, reg[1] = C D   (big-endian, "high word first"; Modbus standard)
///   CDAB: reg[0] = C D, reg[1] = A B   (word swap; Siemens/Schneider "low word first")
///   BADC: reg[0] = B A, reg[1] = D C   (byte swap in each word)
///   DCBA: reg[0] = D C, reg[1] = B A   (little-endian)

#include <cstdint>
#include <cstring>

namespace agv::drivers::plc {

/// Order of the four bytes of a 32-bit value over two registers (see the file comment).
enum class WordOrder : std::uint8_t { ABCD = 0, CDAB = 1, BADC = 2, DCBA = 3 };

/// Writes `v` into dst[0], dst[1].
inline void packU32(std::uint32_t v, WordOrder order, std::uint16_t* dst) noexcept {
  const auto a = static_cast<std::uint16_t>((v >> 24U) & 0xFFU);
  const auto b = static_cast<std::uint16_t>((v >> 16U) & 0xFFU);
  const auto c = static_cast<std::uint16_t>((v >> 8U) & 0xFFU);
  const auto d = static_cast<std::uint16_t>(v & 0xFFU);
  switch (order) {
    case WordOrder::ABCD:
      dst[0] = static_cast<std::uint16_t>((a << 8U) | b);
      dst[1] = static_cast<std::uint16_t>((c << 8U) | d);
      break;
    case WordOrder::CDAB:
      dst[0] = static_cast<std::uint16_t>((c << 8U) | d);
      dst[1] = static_cast<std::uint16_t>((a << 8U) | b);
      break;
    case WordOrder::BADC:
      dst[0] = static_cast<std::uint16_t>((b << 8U) | a);
      dst[1] = static_cast<std::uint16_t>((d << 8U) | c);
      break;
    case WordOrder::DCBA:
      dst[0] = static_cast<std::uint16_t>((d << 8U) | c);
      dst[1] = static_cast<std::uint16_t>((b << 8U) | a);
      break;
  }
}

/// Reads the value of src[0], src[1].
inline std::uint32_t unpackU32(const std::uint16_t* src, WordOrder order) noexcept {
  std::uint32_t hi = 0;  // A B
  std::uint32_t lo = 0;  // C D
  const auto swap = [](std::uint16_t w) noexcept {
    return static_cast<std::uint32_t>(((w & 0xFFU) << 8U) | (w >> 8U));
  };
  switch (order) {
    case WordOrder::ABCD:
      hi = src[0];
      lo = src[1];
      break;
    case WordOrder::CDAB:
      hi = src[1];
      lo = src[0];
      break;
    case WordOrder::BADC:
      hi = swap(src[0]);
      lo = swap(src[1]);
      break;
    case WordOrder::DCBA:
      hi = swap(src[1]);
      lo = swap(src[0]);
      break;
  }
  return (hi << 16U) | lo;
}

/// Writes the IEEE-754 bits of `v` into dst[0], dst[1].
inline void packFloat(float v, WordOrder order, std::uint16_t* dst) noexcept {
  std::uint32_t bits = 0;
  std::memcpy(&bits, &v, sizeof bits);
  packU32(bits, order, dst);
}

/// Reads a float from src[0], src[1].
inline float unpackFloat(const std::uint16_t* src, WordOrder order) noexcept {
  const std::uint32_t bits = unpackU32(src, order);
  float v = 0.0F;
  std::memcpy(&v, &bits, sizeof v);
  return v;
}

}  // namespace agv::drivers::plc
