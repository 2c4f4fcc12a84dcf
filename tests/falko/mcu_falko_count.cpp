// Cortex-M7 image: instructions of FALKO detect and describe on one dense1440 scan (360 deg,
// 0.25 deg, simulated room, 1 cm noise), counted with the instruction counter of
// toolchains/cortex-m7 (QEMU -icount shift=0, SysTick, self-calibrated). Prints the counts
// through semihosting.
#include <cstdint>

#include "agv/falko/falko_descriptors.hpp"
#include "agv/falko/falko_detector.hpp"
#include "instruction_counter.h"
#include "room_sim.hpp"
#include "semihosting.h"

namespace {

void print(const char* label, std::uint32_t value) {
  semihosting_write0(label);
  semihosting_write_int(value);
  semihosting_write0("\n");
}

agv::LaserScan g_scan;
agv::FalkoDetector g_detector;
agv::FalkoDescriber g_describer;
agv::FalkoKeypoints g_keypoints;
agv::BscDescriptors g_bsc;
agv::CghDescriptors g_cgh;

}  // namespace

int main() {
  const agv::test::World w = agv::test::testRoom();
  agv::test::simulateScan(w, agv::test::SensorPose{3.5, 2.5, 0.3}, -3.14159265F, 0.25F * 0.017453292F, 1440, 0.01, 1U,
                          g_scan);
  (void)g_detector.detect(g_scan, g_keypoints);  // warm-up: builds the trig tables of the geometry
  if (agv_icount_init() == 0U) {
    semihosting_write0("SysTick does not run: start QEMU with -icount shift=0\n");
    return 1;
  }
  const std::uint64_t t0 = agv_icount_ticks();
  const agv::Status s1 = g_detector.detect(g_scan, g_keypoints);
  const std::uint64_t t1 = agv_icount_ticks();
  const agv::Status s2 = g_describer.describe(g_detector.points(), g_keypoints, g_bsc, g_cgh);
  const std::uint64_t t2 = agv_icount_ticks();
  print("keypoints: ", static_cast<std::uint32_t>(g_keypoints.size()));
  print("detect instructions: ", static_cast<std::uint32_t>(agv_icount_instructions(t1 - t0)));
  print("describe instructions: ", static_cast<std::uint32_t>(agv_icount_instructions(t2 - t1)));
  return (s1 == agv::Status::Ok && s2 == agv::Status::Ok && !g_keypoints.empty()) ? 0 : 1;
}
