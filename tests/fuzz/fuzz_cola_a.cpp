// libFuzzer target: a CoLa A byte stream cut into telegrams by the framer (read sizes taken from
// the input) and decoded as LMDscandata; the whole input is also decoded as one telegram.
// Invariants beyond "no crash, no sanitizer report": the scan never exceeds its capacity, every
// decoded range is a number or +inf, a failed decode leaves no beams.
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "agv/drivers/protocol/sick/cola_a_scan.hpp"
#include "agv/drivers/protocol/sick/telegram_framer.hpp"
#include "fuzz_support.hpp"

using namespace agv::drivers::sick;

namespace {
using agv::fuzz::check;

void decode(agv::Span<const std::uint8_t> t) {
  static agv::LaserScan scan;
  const agv::Status s = parseColaAScan(t, ColaAScanConfig{}, agv::Timestamp{}, scan);
  check(scan.size() <= agv::kMaxScanBeams);
  if (s != agv::Status::Ok && s != agv::Status::CapacityExceeded) {
    check(scan.size() == 0U);
  }
  for (std::size_t i = 0; i < scan.size(); ++i) {
    check(!std::isnan(scan.ranges[i]));
  }
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  decode(agv::Span<const std::uint8_t>(data, size));
  static TelegramFramer framer(Framing::ColaA);
  const std::size_t chunk = size > 0 ? static_cast<std::size_t>(data[0] % 64U) + 1U : 1U;
  agv::fuzz::feedInChunks(framer, data, size, chunk, [](agv::Span<const std::uint8_t> t) { decode(t); });
  return 0;
}
