# Runs a program that writes a JSON file, then parses the file and checks it.
#   cmake -DPROGRAM=<exe> -DARGS="<arg>|<arg>|..." -DJSON_FILE=<file> -DCHECKS=<checks.cmake>
#         [-DEXPECT_OUTPUT=<regex on stdout+stderr>] [-DEXPECT_EXIT=<code>] [-D<var>=<value> for the checks]
#         -P run_json_program.cmake
# The program must exit with EXPECT_EXIT (default 0); JSON_FILE is removed first (no stale file passes); CHECKS is
# included with the document in `j` and the functions of JsonChecks.cmake.
cmake_minimum_required(VERSION 3.25)
include("${CMAKE_CURRENT_LIST_DIR}/JsonChecks.cmake")
file(REMOVE "${JSON_FILE}")
string(REPLACE "|" ";" args "${ARGS}")
execute_process(COMMAND "${PROGRAM}" ${args} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
message("${out}${err}")
if(NOT DEFINED EXPECT_EXIT)
  set(EXPECT_EXIT 0)
endif()
if(NOT rc EQUAL EXPECT_EXIT)
  message(FATAL_ERROR "${PROGRAM} exited with ${rc}, expected ${EXPECT_EXIT}")
endif()
if(DEFINED EXPECT_OUTPUT AND NOT "${out}${err}" MATCHES "${EXPECT_OUTPUT}")
  message(FATAL_ERROR "output does not match '${EXPECT_OUTPUT}'")
endif()
if(NOT EXISTS "${JSON_FILE}")
  message(FATAL_ERROR "${PROGRAM} did not write ${JSON_FILE}")
endif()
file(READ "${JSON_FILE}" j)
string(JSON type ERROR_VARIABLE parse_error TYPE "${j}")
if(parse_error OR NOT type STREQUAL "OBJECT")
  message(FATAL_ERROR "${JSON_FILE} is not a JSON object: ${parse_error}")
endif()
include("${CHECKS}")
message(STATUS "${JSON_FILE}: parsed and checked")
