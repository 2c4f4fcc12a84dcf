/* Instruction counting on the emulated Cortex-M7 (QEMU with -icount shift=0).
 *
 * Under -icount, QEMU advances its virtual clock by a fixed time per executed instruction, and
 * SysTick (clocked from the CPU clock) counts virtual time. So SysTick ticks are proportional to
 * executed instructions. The ratio depends on the board clock and the icount shift, so the
 * counter calibrates itself on a loop of known length (2 instructions per iteration) before use.
 * Resolution: one SysTick tick (a few tens of instructions); range: 24-bit SysTick, extended in
 * software by polling (call agv_icount_poll() at least every 2^23 ticks inside long sections). */
#ifndef AGV_INSTRUCTION_COUNTER_H
#define AGV_INSTRUCTION_COUNTER_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Starts SysTick and calibrates; returns instructions per 1024 ticks (0 if SysTick does not run,
 * i.e. QEMU was started without -icount or the board has no CPU clock for SysTick). */
uint32_t agv_icount_init(void);
/* Extends the 24-bit SysTick into 64 bits; call often enough during long sections. */
void agv_icount_poll(void);
/* Elapsed SysTick ticks since agv_icount_init (64-bit, monotonic). */
uint64_t agv_icount_ticks(void);
/* Converts a tick difference into instructions using the calibration. */
uint64_t agv_icount_instructions(uint64_t ticks);

#ifdef __cplusplus
}
#endif

#endif
