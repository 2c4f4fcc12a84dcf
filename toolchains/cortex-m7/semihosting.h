/* ARM semihosting calls used by the bare-metal test images (M-profile: BKPT 0xAB). */
#ifndef AGV_SEMIHOSTING_H
#define AGV_SEMIHOSTING_H

#ifdef __cplusplus
extern "C" {
#endif

/* Writes a NUL-terminated string to the host's console (SYS_WRITE0). */
void semihosting_write0(const char* text);
/* Writes a signed decimal integer to the host's console (no newline). */
void semihosting_write_int(long long value);
/* Ends the emulation; status 0 reports success, anything else failure (SYS_EXIT). */
void semihosting_exit(int status) __attribute__((noreturn));
/* Reads the host's elapsed-time tick counter in centiseconds (SYS_CLOCK). */
int semihosting_clock_cs(void);

#ifdef __cplusplus
}
#endif

#endif
