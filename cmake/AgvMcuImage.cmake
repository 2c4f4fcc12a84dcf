# Bare-metal images for the Cortex-M7 build (toolchains/cortex-m7.cmake).
#
# agv_add_mcu_image(<name> SOURCES <src>... [LIBS <lib>...])
#   Links <name>.elf with the start-up code and linker script, writes <name>.map and prints the
#   size report (text/data/bss) after every link, then the same split by library (core, drivers,
#   C library, the image's own objects) from the link map; both also into <name>.size.txt.
# agv_add_mcu_heap_check(<name> [WILL_FAIL])
#   CTest test "<prefix><name>.no_heap": fails if malloc, _sbrk or operator new is linked.

function(agv_add_mcu_image name)
  cmake_parse_arguments(I "" "" "SOURCES;LIBS" ${ARGN})
  add_executable(${name} ${I_SOURCES} "${AGVNAV_MCU_SUPPORT_DIR}/startup.c" "${AGVNAV_MCU_SUPPORT_DIR}/semihosting.c")
  set_target_properties(${name} PROPERTIES SUFFIX ".elf")
  target_include_directories(${name} PRIVATE "${AGVNAV_MCU_SUPPORT_DIR}")
  target_link_libraries(${name} PRIVATE ${I_LIBS})
  target_link_options(${name} PRIVATE "-T${AGVNAV_MCU_SUPPORT_DIR}/mps2_an500.ld"
                      "-Wl,-Map=$<TARGET_FILE_DIR:${name}>/${name}.map")
  set_property(TARGET ${name} APPEND PROPERTY LINK_DEPENDS "${AGVNAV_MCU_SUPPORT_DIR}/mps2_an500.ld")
  add_custom_command(TARGET ${name} POST_BUILD
    COMMAND ${CMAKE_COMMAND} -E echo "== size report (Cortex-M7, bytes): ${name}.elf =="
    COMMAND ${AGVNAV_MCU_SIZE} -B -d $<TARGET_FILE:${name}>
    COMMAND ${AGVNAV_MCU_SIZE} -B -d $<TARGET_FILE:${name}> > $<TARGET_FILE_DIR:${name}>/${name}.size.txt
    COMMAND ${CMAKE_COMMAND} -DMAP=$<TARGET_FILE_DIR:${name}>/${name}.map -DOUT=$<TARGET_FILE_DIR:${name}>/${name}.size.txt
            -P "${PROJECT_SOURCE_DIR}/cmake/McuSizeByLibrary.cmake"
    VERBATIM)
endfunction()

function(agv_add_mcu_heap_check name)
  cmake_parse_arguments(H "WILL_FAIL" "" "" ${ARGN})
  set(test "${AGVNAV_TEST_PREFIX}${name}.no_heap")
  add_test(NAME "${test}" COMMAND ${CMAKE_COMMAND} -DNM=${AGVNAV_MCU_NM} -DELF=$<TARGET_FILE:${name}>
                                  -P "${PROJECT_SOURCE_DIR}/cmake/CheckNoHeapSymbols.cmake")
  set_tests_properties("${test}" PROPERTIES LABELS "alloc;${AGVNAV_TEST_LABEL}" TIMEOUT 60)
  if(H_WILL_FAIL)
    set_tests_properties("${test}" PROPERTIES WILL_FAIL TRUE)
  endif()
endfunction()

# agv_add_mcu_expected_failure(<name> EXPECT <regex>)
#   CTest test "<prefix><name>.fails": runs <name>.elf on QEMU; passes only when the image exits
#   with failure and prints <regex> (cmake/McuExpectFailure.cmake). Proves that a check can fail.
function(agv_add_mcu_expected_failure name)
  cmake_parse_arguments(F "" "EXPECT" "" ${ARGN})
  set(test "${AGVNAV_TEST_PREFIX}${name}.fails")
  string(REPLACE ";" "|" emulator "${CMAKE_CROSSCOMPILING_EMULATOR}")
  add_test(NAME "${test}" COMMAND ${CMAKE_COMMAND} "-DEMULATOR=${emulator}" -DIMAGE=$<TARGET_FILE:${name}>
                                  "-DEXPECT=${F_EXPECT}" -P "${PROJECT_SOURCE_DIR}/cmake/McuExpectFailure.cmake")
  set_tests_properties("${test}" PROPERTIES LABELS "unit;${AGVNAV_TEST_LABEL}" TIMEOUT 120)
endfunction()
