// Cortex-M7 image: instructions of one VLP-16 normal signature (a ray-cast box room with a ramp,
// 16 x 1800 cells, 5 mm range noise), one orientation signature and one relative yaw, counted with
// the instruction counter of toolchains/cortex-m7 (QEMU -icount shift=0, SysTick, self-calibrated).
// Prints the counts through semihosting.
#include <cstdint>

#include "agv/lidar3d/normal_signature.hpp"
#include "agv/lidar3d/orientation_signature.hpp"
#include "instruction_count.hpp"
#include "instruction_counter.h"
#include "lidar3d_sim.hpp"
#include "semihosting.h"

namespace {

agv::Vlp16RangeImage g_image;  // 16 x 1800 cells, 460 KiB
agv::NormalSignature g_sig;
agv::OrientationSignature g_oa;
agv::OrientationSignature g_ob;

}  // namespace

using agv::mcu::printValue;

int main() {
  if (agv_icount_init() == 0U) {
    semihosting_write0("SysTick does not run: start QEMU with -icount shift=0\n");
    return 1;
  }
  const agv::test::SimLidar lidar = agv::test::vlp16At10Hz(0.005);
  const agv::test::SimScene scene = agv::test::rampYard();
  agv::test::LoopRng rng{1};
  const std::size_t points = agv::test::castScene(scene, lidar, Eigen::Vector3d::Zero(), 0.3, 0.0, rng, g_image);
  printValue("vlp16 returns: ", static_cast<std::uint32_t>(points));
  agv::NormalSignatureParams params;
  params.normals.laserStep = 1;  // VLP-16: 2-deg laser steps (tests/lidar3d)
  agv::Status st = agv::Status::Ok;
  printValue("vlp16 signature instructions: ",
             agv::mcu::countInstructions([&] { st = agv::computeNormalSignature(g_image, params, g_sig); }));
  printValue("vlp16 normals: ", g_sig.counts.normals);
  int failures = st == agv::Status::Ok ? 0 : 1;
  printValue("orientation signature instructions: ", agv::mcu::countInstructions([&] {
               st = agv::computeOrientationSignature(g_image, agv::OrientationParams{}, g_oa);
             }));
  failures += st == agv::Status::Ok ? 0 : 1;
  g_ob = g_oa;
  bool ok = false;
  printValue("relative yaw instructions: ",
             agv::mcu::countInstructions([&] { ok = agv::relativeYaw(g_oa, g_ob).ok(); }));
  failures += ok ? 0 : 1;
  return failures == 0 ? 0 : 1;
}
