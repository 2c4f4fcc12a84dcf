# Test registration shared by every tests/ subdirectory.
#
# agv_add_test(<name> SOURCES <src>... [LIBS <lib>...] [LABELS <label>...] [TIMEOUT <s>] [MCU])
#   Linux targets: builds test_<name> (Catch2 + allocation counter) and registers the CTest test
#   "${AGVNAV_TEST_PREFIX}<name>" with LABELS + ${AGVNAV_TEST_LABEL}. Cross builds run it through
#   CMAKE_CROSSCOMPILING_EMULATOR (qemu-user) automatically, and compile the test with
#   AGV_TEST_EMULATED (tests/support/agv_test.hpp: Monte-Carlo cases may run fewer trials there).
#   Bare-metal MCU build: sources of tests marked MCU are collected into one image (see
#   agv_add_mcu_image in tests/CMakeLists.txt); other tests are skipped there.

if(NOT AGVNAV_MCU)
  find_path(AGVNAV_CATCH2_INCLUDE_DIR catch.hpp PATHS /usr/include/catch2 NO_DEFAULT_PATH NO_CMAKE_FIND_ROOT_PATH)
  if(NOT AGVNAV_CATCH2_INCLUDE_DIR)
    message(FATAL_ERROR "Catch2 2.x not found (/usr/include/catch2/catch.hpp): apt-get install catch2")
  endif()
  # Catch2 is included as <catch.hpp> from its own directory: never -I/usr/include, which would
  # put the build machine's C library headers in front of a cross compiler's.
  add_library(agv_catch2 INTERFACE)
  target_include_directories(agv_catch2 SYSTEM INTERFACE "${AGVNAV_CATCH2_INCLUDE_DIR}")

  # Catch2's main, compiled once per tree and without optimisation: it is the runner, not code
  # under test, and at -O2 -g it is the slowest file of the build (29 s here against 12 s at -O0).
  # A test links both object libraries directly (CMake adds an object library's objects only to
  # the targets that link it directly); the VM tests (tests/vcan) count allocations their own way
  # and link the main alone.
  add_library(agv_catch_main OBJECT "${CMAKE_CURRENT_LIST_DIR}/../tests/support/catch_main.cpp")
  target_link_libraries(agv_catch_main PUBLIC agv_catch2)
  target_compile_options(agv_catch_main PRIVATE -O0)
  add_library(agv_test_support OBJECT "${CMAKE_CURRENT_LIST_DIR}/../tests/support/alloc_counter.cpp")
  target_include_directories(agv_test_support PUBLIC "${CMAKE_CURRENT_LIST_DIR}/../tests/support")
  target_link_libraries(agv_test_support PUBLIC agv_catch2)
endif()

function(agv_add_test name)
  cmake_parse_arguments(T "MCU" "TIMEOUT" "SOURCES;LIBS;LABELS" ${ARGN})
  if(NOT T_SOURCES)
    message(FATAL_ERROR "agv_add_test(${name}): no SOURCES")
  endif()
  if(AGVNAV_MCU)
    if(T_MCU)
      foreach(src IN LISTS T_SOURCES)
        get_filename_component(abs "${src}" ABSOLUTE)
        set_property(GLOBAL APPEND PROPERTY AGVNAV_MCU_TEST_SOURCES "${abs}")
      endforeach()
      set_property(GLOBAL APPEND PROPERTY AGVNAV_MCU_TEST_LIBS ${T_LIBS})
    endif()
    return()
  endif()
  if(NOT T_TIMEOUT)
    set(T_TIMEOUT 300)
  endif()
  add_executable(test_${name} ${T_SOURCES})
  target_link_libraries(test_${name} PRIVATE agv_catch_main agv_test_support ${T_LIBS})
  agv_test_warnings(test_${name})
  if(CMAKE_CROSSCOMPILING)
    target_compile_definitions(test_${name} PRIVATE AGV_TEST_EMULATED)
  endif()
  add_test(NAME "${AGVNAV_TEST_PREFIX}${name}" COMMAND test_${name})
  set_tests_properties("${AGVNAV_TEST_PREFIX}${name}" PROPERTIES LABELS "${T_LABELS};${AGVNAV_TEST_LABEL}"
                                                                 TIMEOUT ${T_TIMEOUT})
endfunction()
