// PLC register map against libmodbus (host only): our float packing is what libmodbus's
// modbus_get_float_* read, and libmodbus 3.1.6's modbus_set_float_abcd is not ABCD on a
// little-endian host (which is why the register map packs floats itself).
#include <modbus.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "agv/drivers/protocol/plc/plc_register_map.hpp"
#include "agv_test.hpp"

using agv::Span;
using agv::Status;
using namespace agv::drivers::plc;

namespace {
float libmodbusGet(const std::uint16_t* r, WordOrder o) {
  switch (o) {
    case WordOrder::ABCD:
      return modbus_get_float_abcd(r);
    case WordOrder::CDAB:
      return modbus_get_float_cdab(r);
    case WordOrder::BADC:
      return modbus_get_float_badc(r);
    case WordOrder::DCBA:
      return modbus_get_float_dcba(r);
  }
  return 0.0F;
}
const WordOrder kOrders[] = {WordOrder::ABCD, WordOrder::CDAB, WordOrder::BADC, WordOrder::DCBA};

bool sameBits(float a, float b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}
}  // namespace

TEST_CASE("Float word orders agree with modbus_get_float_*", "[drivers][modbus]") {
  std::uint16_t r[2];
  std::mt19937 rng(7);
  std::uniform_int_distribution<std::uint32_t> bits;
  std::vector<float> values = {
      0.0F, -0.0F, 1.0F, -2.5F, 3.14159265F, 1e-40F, 3.4e38F, -1e-3F, std::numeric_limits<float>::infinity()};
  for (int i = 0; i < 2000; ++i) {
    const std::uint32_t b = bits(rng);
    float f;
    std::memcpy(&f, &b, sizeof f);
    if (!std::isnan(f))
      values.push_back(f);
  }
  for (WordOrder o : kOrders) {
    for (float v : values) {
      packFloat(v, o, r);
      REQUIRE(sameBits(libmodbusGet(r, o), v));
      REQUIRE(sameBits(unpackFloat(r, o), v));
    }
  }
}

TEST_CASE("libmodbus 3.1.6 modbus_set_float_abcd does not produce ABCD on this host (why we pack ourselves)",
          "[drivers][modbus]") {
  std::uint16_t ours[2];
  std::uint16_t theirs[2];
  packFloat(1.0F, WordOrder::ABCD, ours);
  modbus_set_float_abcd(1.0F, theirs);
  const bool hostLittleEndian = [] {
    const std::uint16_t one = 1;
    std::uint8_t b;
    std::memcpy(&b, &one, 1);
    return b == 1;
  }();
  // Informative: on a little-endian host libmodbus 3.1.6 writes BADC under the ABCD name; our
  // packing is what modbus_get_float_abcd (checked above) reads.
  if (hostLittleEndian && LIBMODBUS_VERSION_HEX == 0x030106) {
    CHECK_FALSE((ours[0] == theirs[0] && ours[1] == theirs[1]));
  }
  CHECK(modbus_get_float_abcd(ours) == 1.0F);
}
