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
# Exit 1: the scenario ran, but with the nominal parameters (no calibration) and two reflectors
# the localizer cannot meet 2 cm / 0.1 deg.
if(NOT rc EQUAL 1 OR NOT out MATCHES "requirement .*: NOT MET" OR NOT out MATCHES "A +run 1: +(4\\.9|5\\.0)[0-9] m" OR NOT out MATCHES "calibration FAILED")
  message(FATAL_ERROR "custom world: exit ${rc}\n${out}\n${err}")
endif()
# A bad mission (pieces after its last stop) is refused with its line; a custom world's mission
# is driven in every mode, stopping at its operation points.
file(WRITE "${WORK_DIR}/bad_mission.world"
     "hall 0 0 20 10\nreflector 19 5 0.04\npath A 1 5 0 S 5\nmission B 1 3 0 S 4 stop S 4\n")
execute_process(COMMAND "${HIL}" --short --world "${WORK_DIR}/bad_mission.world" RESULT_VARIABLE rc
                ERROR_VARIABLE err OUTPUT_QUIET)
if(NOT rc EQUAL 2 OR NOT err MATCHES "line 4: mission: must end with stop")
  message(FATAL_ERROR "bad mission: exit ${rc}, ${err}")
endif()
file(WRITE "${WORK_DIR}/mission.world"
     "hall 0 0 20 10\nreflector 19 5 0.04\nreflector 10 9 0.04\npallet 8 6 9.2 7\npath A 1 5 0 S 5\n"
     "mission B 1 3 0 S 4 stop S 4 stop\n")
execute_process(COMMAND "${HIL}" --short --world "${WORK_DIR}/mission.world" RESULT_VARIABLE rc OUTPUT_VARIABLE out
                ERROR_VARIABLE err)
if(NOT rc EQUAL 1 OR NOT out MATCHES "missions: 1 \\(8\\.0 m, 2 operation points" OR
   NOT out MATCHES "reflectors +B +run 1: +[0-9.]+ m in [0-9. ]+ s \\| 2 stops")
  message(FATAL_ERROR "custom world with a mission: exit ${rc}\n${out}\n${err}")
endif()
