/* Start-up code of the Cortex-M7 bare-metal images (QEMU mps2-an500 memory map).
 * Reset: enable the FPU, copy .data, zero .bss, run static constructors, call main(), report
 * main's return value through semihosting. Any fault ends the emulation with a failure code, so a
 * crashing test never hangs. No heap exists: there is no _sbrk, and the image's symbol check
 * fails the build's tests if an allocator gets linked. */
#include <stdint.h>

#include "semihosting.h"

extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _estack;
extern void __libc_init_array(void);
extern int main(void);

void Reset_Handler(void);
void Fault_Handler(void);

/* Newlib's __libc_init_array calls these; with -nostartfiles nobody else defines them. */
void _init(void) {}
void _fini(void) {}

/* The images never return from main() through exit(), so destructors of statics never run:
 * registering them must not pull atexit() (and its possible allocation) into the image. */
void* __dso_handle = 0;
int __cxa_atexit(void (*fn)(void*), void* arg, void* dso) {
  (void)fn;
  (void)arg;
  (void)dso;
  return 0;
}
int __aeabi_atexit(void* arg, void (*fn)(void*), void* dso) {
  (void)fn;
  (void)arg;
  (void)dso;
  return 0;
}
void __cxa_pure_virtual(void) {
  semihosting_write0("pure virtual call\n");
  semihosting_exit(1);
}
/* assert() from newlib would format with fiprintf (which allocates): report and stop instead. */
void __assert_func(const char* file, int line, const char* func, const char* expr) {
  (void)line;
  (void)func;
  semihosting_write0("assertion failed: ");
  semihosting_write0(expr);
  semihosting_write0(" in ");
  semihosting_write0(file);
  semihosting_write0("\n");
  semihosting_exit(1);
}
void abort(void) {
  semihosting_write0("abort()\n");
  semihosting_exit(1);
}

__attribute__((section(".isr_vector"), used)) void (*const g_vectors[16])(void) = {
    (void (*)(void))(&_estack),
    Reset_Handler,
    Fault_Handler,
    Fault_Handler,
    Fault_Handler,
    Fault_Handler,
    Fault_Handler,
    0,
    0,
    0,
    0,
    Fault_Handler,
    Fault_Handler,
    0,
    Fault_Handler,
    Fault_Handler,
};

void Fault_Handler(void) {
  semihosting_write0("fault exception (HardFault/MemManage/BusFault/UsageFault)\n");
  semihosting_exit(1);
}

void Reset_Handler(void) {
  /* CPACR: full access to CP10/CP11 (the FPU) before any floating-point instruction. */
  volatile uint32_t* const cpacr = (volatile uint32_t*)0xE000ED88u;
  *cpacr |= (0xFu << 20);
  __asm__ volatile("dsb\n\tisb" ::: "memory");

  uint32_t* src = &_sidata;
  for (uint32_t* dst = &_sdata; dst < &_edata;) {
    *dst++ = *src++;
  }
  for (uint32_t* dst = &_sbss; dst < &_ebss;) {
    *dst++ = 0u;
  }
  __libc_init_array();
  semihosting_exit(main());
}
