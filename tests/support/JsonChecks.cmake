# Checks on a JSON document parsed with string(JSON) (CMake >= 3.19), shared by the tests that
# read a program's JSON output. Every failure names the path inside the document.

# expect_type(<json> <OBJECT|ARRAY|STRING|NUMBER|BOOLEAN|NULL> <path>...)
function(expect_type json type)
  string(JSON t ERROR_VARIABLE e TYPE "${json}" ${ARGN})
  if(e OR NOT t STREQUAL type)
    message(FATAL_ERROR "JSON: ${ARGN} should be ${type}, is '${t}' ${e}")
  endif()
endfunction()

# expect_keys(<json> "<key1;key2;...>" <path>...): the object at <path> has exactly these keys (CMake's
# parser lists members sorted, so the order is not checked here; the C++ tests check it).
function(expect_keys json keys)
  expect_type("${json}" OBJECT ${ARGN})
  string(JSON n LENGTH "${json}" ${ARGN})
  set(found "")
  if(n GREATER 0)
    math(EXPR last "${n} - 1")
    foreach(i RANGE ${last})
      string(JSON k MEMBER "${json}" ${ARGN} ${i})
      list(APPEND found "${k}")
    endforeach()
  endif()
  set(wanted ${keys})
  list(SORT found)
  list(SORT wanted)
  if(NOT found STREQUAL wanted)
    message(FATAL_ERROR "JSON: ${ARGN} has keys '${found}', expected '${keys}'")
  endif()
endfunction()

# expect_number_in(<json> <min> <max> <path>...)
function(expect_number_in json lo hi)
  expect_type("${json}" NUMBER ${ARGN})
  string(JSON v GET "${json}" ${ARGN})
  if(v LESS lo OR v GREATER hi)
    message(FATAL_ERROR "JSON: ${ARGN} = ${v}, expected ${lo} .. ${hi}")
  endif()
endfunction()

# expect_true(<json> <path>...): the value at <path> is the boolean true.
function(expect_true json)
  expect_type("${json}" BOOLEAN ${ARGN})
  string(JSON v GET "${json}" ${ARGN})
  if(NOT v)
    message(FATAL_ERROR "JSON: ${ARGN} is ${v}, expected true")
  endif()
endfunction()

# expect_no_wrong_restart(<json> <log name>): an agvnav-replay document (tests/replay) whose field
# relocalizations and resyncs never restarted the localizer at a wrong pose (more than 0.3 m or
# 5 deg from the corrected pose).
function(expect_no_wrong_restart json logName)
  string(JSON wrong GET "${json}" field_relocalization wrong)
  string(JSON resyncWrong GET "${json}" scan_matching resync_wrong)
  if(NOT wrong EQUAL 0 OR NOT resyncWrong EQUAL 0)
    message(FATAL_ERROR
            "JSON: ${logName}: ${wrong} field relocalizations and ${resyncWrong} resyncs restarted the localizer at a wrong pose")
  endif()
endfunction()
