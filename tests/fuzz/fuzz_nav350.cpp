// libFuzzer target: a binary CoLa (CoLa B) byte stream cut by the framer and decoded as NAV350
// mNPOSGetData replies; the input is also decoded directly as a payload. Invariants: capacities
// respected, pose angle in (-pi, pi], a failed decode leaves nothing valid.
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "agv/drivers/protocol/sick/nav350.hpp"
#include "agv/drivers/protocol/sick/telegram_framer.hpp"
#include "fuzz_support.hpp"

using namespace agv::drivers::sick;

namespace {
using agv::fuzz::check;

void decode(agv::Span<const std::uint8_t> t) {
  static Nav350PoseReply reply;
  const agv::Status s = parseNav350PoseReply(t, Nav350Config{}, agv::Timestamp{}, reply);
  check(reply.reflectors.size() <= agv::kMaxReflectors);
  check(reply.scan.size() <= agv::kMaxScanBeams);
  if (s != agv::Status::Ok && s != agv::Status::CapacityExceeded) {
    check(!reply.poseValid && !reply.scanValid && reply.reflectors.size() == 0U);
    return;
  }
  if (reply.poseValid) {
    check(reply.pose.theta > -3.1415927 && reply.pose.theta <= 3.1415927);
  }
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  decode(agv::Span<const std::uint8_t>(data, size));
  static TelegramFramer framer(Framing::ColaB);
  const std::size_t chunk = size > 0 ? static_cast<std::size_t>(data[size - 1] % 97U) + 1U : 1U;
  agv::fuzz::feedInChunks(framer, data, size, chunk, [](agv::Span<const std::uint8_t> t) { decode(t); });
  return 0;
}
