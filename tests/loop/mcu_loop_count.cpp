// Cortex-M7 image: instructions of one loop-closure association (correspondence graph, affine
// Hough, RANSAC) and of one GLAROT signature + SL1, counted with the instruction counter of
// toolchains/cortex-m7 (QEMU -icount shift=0, SysTick, self-calibrated). Two scenes: 16 points
// against a noisy (1 cm) moved copy with 5 outliers (256 CG vertices, the capacity), and 5 points
// against 5 (a typical fr079 scan has 4-5 FALKO keypoints). Prints the counts through semihosting.
#include <cstdint>

#include "agv/loop/affine_hough.hpp"
#include "agv/loop/correspondence_graph.hpp"
#include "agv/loop/glarot.hpp"
#include "agv/loop/ransac_association.hpp"
#include "instruction_count.hpp"
#include "instruction_counter.h"
#include "loop_test_util.hpp"
#include "semihosting.h"

namespace {

constexpr std::size_t kN = 16;
Eigen::Vector2f g_first[kN];
Eigen::Vector2f g_second[kN];
agv::CorrespondenceGraphMatcher g_cg;
agv::AffineHoughMatcher g_ah;
agv::RansacMatcher g_ransac;
agv::PointAssociation g_out;
agv::GlarotSignature g_sa;
agv::GlarotSignature g_sb;

}  // namespace

using agv::mcu::printValue;

int main() {
  agv::test::LoopRng rng{100};
  agv::test::randomPoints(rng, kN, -4.0, -4.0, 8.0, 8.0, 0.5, g_first);
  agv::test::transformPoints(agv::Pose2d{1.2, -0.8, 0.6}.inverse(), g_first, kN, 0.01, rng, g_second);
  agv::test::randomPoints(rng, 5, -5.0, -5.0, 10.0, 10.0, 0.5, g_second);  // 5 outliers
  if (agv_icount_init() == 0U) {
    semihosting_write0("SysTick does not run: start QEMU with -icount shift=0\n");
    return 1;
  }
  int failures = 0;
  for (std::size_t n : {kN, std::size_t{5}}) {
    // The small scene: points 5..9 and their moved copies (the outliers replaced points 0..4).
    const agv::Span<const Eigen::Vector2f> a(n == kN ? g_first : g_first + 5, n);
    const agv::Span<const Eigen::Vector2f> b(n == kN ? g_second : g_second + 5, n);
    semihosting_write0(n == kN ? "scene 16x16 (5 outliers)\n" : "scene 5x5\n");
    agv::Status st = agv::Status::Ok;
    printValue("  cg instructions: ", agv::mcu::countInstructions([&] { st = g_cg.match(a, b, g_out); }));
    printValue("  cg pairs: ", static_cast<std::uint32_t>(g_out.pairs.size()));
    failures += st == agv::Status::Ok ? 0 : 1;
    printValue("  ah instructions: ", agv::mcu::countInstructions([&] { st = g_ah.match(a, b, g_out); }));
    printValue("  ransac instructions: ", agv::mcu::countInstructions([&] { st = g_ransac.match(a, b, g_out); }));
    printValue("  glarot signature instructions: ",
               agv::mcu::countInstructions([&] { (void)agv::computeGlarot(a, agv::GlarotParams{}, g_sa); }));
    (void)agv::computeGlarot(b, agv::GlarotParams{}, g_sb);
    printValue("  glarot SL1 instructions: ",
               agv::mcu::countInstructions([&] { (void)agv::glarotDistance(g_sa, g_sb); }));
  }
  return failures == 0 ? 0 : 1;
}
