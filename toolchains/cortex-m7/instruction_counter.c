#include "instruction_counter.h"

#define SYST_CSR (*(volatile uint32_t*)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t*)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t*)0xE000E018u)
#define SYST_RELOAD 0x00FFFFFFu

static uint64_t g_base;    /* ticks accumulated by completed SysTick periods */
static uint32_t g_last;    /* last CVR seen */
static uint32_t g_per1024; /* instructions per 1024 ticks */

void agv_icount_poll(void) {
  const uint32_t now = SYST_CVR & SYST_RELOAD;
  if (now > g_last) { /* wrapped (counts down) */
    g_base += (uint64_t)g_last + 1u + (SYST_RELOAD - now);
  } else {
    g_base += (uint64_t)(g_last - now);
  }
  g_last = now;
}

uint64_t agv_icount_ticks(void) {
  agv_icount_poll();
  return g_base;
}

static void known_loop(uint32_t iterations) {
  /* exactly 2 instructions per iteration: subs + bne */
  __asm__ volatile(
      "1:\n\t"
      "subs %0, %0, #1\n\t"
      "bne 1b\n\t"
      : "+r"(iterations)
      :
      : "cc");
}

uint32_t agv_icount_init(void) {
  SYST_CSR = 0u;
  SYST_RVR = SYST_RELOAD;
  SYST_CVR = 0u;
  SYST_CSR = 0x5u; /* enable, processor clock, no interrupt */
  g_base = 0u;
  g_last = SYST_CVR & SYST_RELOAD;
  const uint32_t iterations = 1000000u;
  const uint64_t t0 = agv_icount_ticks();
  known_loop(iterations);
  const uint64_t t1 = agv_icount_ticks();
  const uint64_t ticks = t1 - t0;
  if (ticks == 0u) {
    g_per1024 = 0u;
    return 0u;
  }
  g_per1024 = (uint32_t)((2ull * iterations * 1024u + ticks / 2u) / ticks);
  return g_per1024;
}

uint64_t agv_icount_instructions(uint64_t ticks) {
  return (ticks * g_per1024 + 512u) / 1024u;
}
