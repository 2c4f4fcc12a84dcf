# A world file with an error on line 3 is refused with exit code 2 and the line number.
cmake_minimum_required(VERSION 3.25)
file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")
file(WRITE "${WORK_DIR}/bad.world" "hall 0 0 10 10\n# a comment\nreflector 1 2\npath A 1 1 0 S 5\n")
execute_process(COMMAND "${HIL}" --short --world "${WORK_DIR}/bad.world" RESULT_VARIABLE rc ERROR_VARIABLE err
                OUTPUT_QUIET)
if(NOT rc EQUAL 2)
  message(FATAL_ERROR "expected exit code 2, got ${rc}")
endif()
if(NOT err MATCHES "line 3: reflector needs 3 numbers")
  message(FATAL_ERROR "unexpected error message: ${err}")
endif()
# A world that parses runs its own path.
file(WRITE "${WORK_DIR}/good.world" "hall 0 0 10 10\nreflector 9 5 0.04\nreflector 5 9 0.04\npath A 1 5 0 S 5\n")
execute_process(COMMAND "${HIL}" --short --world "${WORK_DIR}/good.world" RESULT_VARIABLE rc OUTPUT_VARIABLE out
                ERROR_VARIABLE err)
# Two reflectors cannot give a reflector egomotion: the calibration is refused and reported.
if(NOT rc EQUAL 0 OR NOT out MATCHES "A +run 1: +(4\\.9|5\\.0)[0-9] m" OR NOT out MATCHES "calibration FAILED")
  message(FATAL_ERROR "custom world: exit ${rc}\n${out}\n${err}")
endif()
