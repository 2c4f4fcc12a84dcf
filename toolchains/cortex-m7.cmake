# Bare-metal build of core/ for a Cortex-M7 with a single-precision FPU (FPv5-SP-D16), with
# Debian's arm-none-eabi GCC and newlib (gcc-arm-none-eabi, libstdc++-arm-none-eabi-newlib).
# Test images run on QEMU's mps2-an500 board (Cortex-M7) through semihosting.
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)
set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_CXX_COMPILER arm-none-eabi-g++)
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)

set(AGVNAV_MCU ON CACHE BOOL "Bare-metal MCU build (set by toolchains/cortex-m7.cmake)" FORCE)
set(AGVNAV_MCU_SUPPORT_DIR "${CMAKE_CURRENT_LIST_DIR}/cortex-m7" CACHE PATH "Start-up code and linker script" FORCE)

set(_agv_cpu "-mcpu=cortex-m7 -mthumb -mfpu=fpv5-sp-d16 -mfloat-abi=hard")
set(CMAKE_C_FLAGS_INIT "${_agv_cpu} -ffunction-sections -fdata-sections")
set(CMAKE_CXX_FLAGS_INIT "${_agv_cpu} -ffunction-sections -fdata-sections -fno-exceptions -fno-rtti -fno-threadsafe-statics -DEIGEN_NO_MALLOC")
set(CMAKE_EXE_LINKER_FLAGS_INIT "${_agv_cpu} -nostartfiles --specs=nano.specs --specs=nosys.specs -Wl,--gc-sections")

set(CMAKE_CROSSCOMPILING_EMULATOR
    qemu-system-arm;-M;mps2-an500;-cpu;cortex-m7;-nographic;-monitor;none;-semihosting-config;enable=on,target=native;-kernel)
set(AGVNAV_MCU_SIZE arm-none-eabi-size)
set(AGVNAV_MCU_NM arm-none-eabi-nm)

set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE BOTH)
