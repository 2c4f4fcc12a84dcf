# cmake -DEMULATOR=<cmd|arg|...> -DIMAGE=<elf> -DEXPECT=<regex> -P McuExpectFailure.cmake
# Runs a bare-metal test image that is meant to fail and passes only when it does so for the
# intended reason: a non-zero exit code AND output matching EXPECT. (A plain WILL_FAIL test would
# also pass when the image crashed or failed to start for an unrelated reason.)
string(REPLACE "|" ";" emulator "${EMULATOR}")
execute_process(COMMAND ${emulator} ${IMAGE} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err TIMEOUT 60)
message(STATUS "${IMAGE} exited with ${rc}:\n${out}${err}")
if(rc EQUAL 0)
  message(FATAL_ERROR "the image passed, but it must fail (expected: ${EXPECT})")
endif()
if(NOT "${out}${err}" MATCHES "${EXPECT}")
  message(FATAL_ERROR "the image failed, but not with the expected report: ${EXPECT}")
endif()
message(STATUS "failed as expected")
