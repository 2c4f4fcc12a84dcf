#include "semihosting.h"

#define SYS_WRITE0 0x04
#define SYS_CLOCK 0x10
#define SYS_EXIT 0x18
#define ADP_STOPPED_APPLICATION_EXIT 0x20026
#define ADP_STOPPED_RUNTIME_ERROR_UNKNOWN 0x20023

static int semihosting_call(int op, const void* arg) {
  register int r0 __asm__("r0") = op;
  register const void* r1 __asm__("r1") = arg;
  __asm__ volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
  return r0;
}

void semihosting_write0(const char* text) {
  (void)semihosting_call(SYS_WRITE0, text);
}

void semihosting_write_int(long long value) {
  char buf[24];
  int i = 23;
  unsigned long long u = value < 0 ? 0ULL - (unsigned long long)value : (unsigned long long)value;
  buf[i] = '\0';
  do {
    buf[--i] = (char)('0' + (int)(u % 10U));
    u /= 10U;
  } while (u != 0U && i > 1);
  if (value < 0) {
    buf[--i] = '-';
  }
  semihosting_write0(buf + i);
}

int semihosting_clock_cs(void) {
  return semihosting_call(SYS_CLOCK, 0);
}

void semihosting_exit(int status) {
  /* AArch32 SYS_EXIT takes the reason code itself: ApplicationExit -> host exit 0, else 1. */
  (void)semihosting_call(SYS_EXIT,
                         (const void*)(status == 0 ? ADP_STOPPED_APPLICATION_EXIT : ADP_STOPPED_RUNTIME_ERROR_UNKNOWN));
  for (;;) {
  }
}
