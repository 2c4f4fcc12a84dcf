// Cortex-M7 image: instructions of FALKO detect and describe on one dense1440 scan (360 deg,
// 0.25 deg, simulated room, 1 cm noise). Run under QEMU with `-icount shift=0` (one instruction
// per virtual nanosecond): the SysTick, clocked at the 25 MHz CPU clock of the mps2-an500 model,
// then counts 40 instructions per tick. Prints the counts through semihosting.
#include <cstdint>

#include "agv/falko/falko_descriptors.hpp"
#include "agv/falko/falko_detector.hpp"
#include "room_sim.hpp"
#include "semihosting.h"

namespace {

volatile std::uint32_t* const kSysTickCtrl = reinterpret_cast<volatile std::uint32_t*>(0xE000E010U);
volatile std::uint32_t* const kSysTickLoad = reinterpret_cast<volatile std::uint32_t*>(0xE000E014U);
volatile std::uint32_t* const kSysTickVal = reinterpret_cast<volatile std::uint32_t*>(0xE000E018U);

void print(const char* label, std::uint32_t value) {
  char buf[64];
  int n = 0;
  for (const char* p = label; *p != '\0' && n < 48; ++p) {
    buf[n++] = *p;
  }
  char digits[12];
  int d = 0;
  do {
    digits[d++] = static_cast<char>('0' + value % 10U);
    value /= 10U;
  } while (value != 0U && d < 11);
  while (d > 0) {
    buf[n++] = digits[--d];
  }
  buf[n++] = '\n';
  buf[n] = '\0';
  semihosting_write0(buf);
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
  *kSysTickLoad = 0x00FFFFFFU;
  *kSysTickVal = 0U;
  *kSysTickCtrl = 5U;  // enable, processor clock, no interrupt
  const std::uint32_t t0 = *kSysTickVal;
  const agv::Status s1 = g_detector.detect(g_scan, g_keypoints);
  const std::uint32_t t1 = *kSysTickVal;
  const agv::Status s2 = g_describer.describe(g_detector.points(), g_keypoints, g_bsc, g_cgh);
  const std::uint32_t t2 = *kSysTickVal;
  // Calibration: 100000 iterations of nop / subs / bne = 300000 instructions.
  const std::uint32_t c0 = *kSysTickVal;
  std::uint32_t n = 100000U;
  __asm__ volatile("1: nop\n subs %0, %0, #1\n bne 1b" : "+r"(n) : : "cc");
  const std::uint32_t c1 = *kSysTickVal;
  print("calibration (300000 expected): ", ((c0 - c1) & 0x00FFFFFFU) * 40U);
  const std::uint32_t detectTicks = (t0 - t1) & 0x00FFFFFFU;
  const std::uint32_t describeTicks = (t1 - t2) & 0x00FFFFFFU;
  print("keypoints: ", static_cast<std::uint32_t>(g_keypoints.size()));
  print("detect instructions: ", detectTicks * 40U);
  print("describe instructions: ", describeTicks * 40U);
  return (s1 == agv::Status::Ok && s2 == agv::Status::Ok && !g_keypoints.empty()) ? 0 : 1;
}
