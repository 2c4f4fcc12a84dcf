// libFuzzer target: a CoLa A byte stream cut into telegrams by the framer (read sizes taken from
// the input) and decoded as LMDscandata; the whole input is also decoded as one telegram.
// Invariants beyond "no crash, no sanitizer report": the scan never exceeds its capacity, every
// decoded range is a number or +inf, a failed decode leaves no beams.
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "agv/drivers/sick/cola_a_scan.hpp"
#include "agv/drivers/sick/telegram_framer.hpp"

using namespace agv::drivers::sick;

namespace {
void check(bool ok) {
  if (!ok) {
    __builtin_trap();
  }
}

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
  framer.reset();
  const std::size_t chunk = size > 0 ? static_cast<std::size_t>(data[0] % 64U) + 1U : 1U;
  std::size_t pos = 0;
  while (pos < size) {
    const std::size_t n = size - pos < chunk ? size - pos : chunk;
    std::size_t fed = 0;
    while (fed < n) {
      const std::size_t k = framer.feed(agv::Span<const std::uint8_t>(data + pos + fed, n - fed));
      fed += k;
      agv::Span<const std::uint8_t> t;
      while (framer.next(t)) {
        check(t.data() != nullptr && t.size() < TelegramFramer::kCapacity);
        decode(t);
      }
      check(k > 0 || fed == n);  // the framer always makes room after next() returned false
    }
    pos += n;
  }
  return 0;
}
