# agv_strict_warnings(target): the project's warning set for library and program code.
#   -Wall -Wextra -Wpedantic -Wshadow -Wconversion -Wsign-conversion -Wold-style-cast
#   -Wdouble-promotion (silent float->double promotions cost cycles on a single-precision FPU)
# agv_test_warnings(target): the same minus the conversion family, which in test code mostly
#   flags literal ground-truth values mixed across float/double/int.
# AGVNAV_WERROR turns them into errors (CI does).
function(agv_strict_warnings target)
  if(CMAKE_CXX_COMPILER_ID MATCHES "GNU|Clang")
    target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow -Wconversion -Wsign-conversion
                                             -Wold-style-cast -Wdouble-promotion
                                             $<$<BOOL:${AGVNAV_WERROR}>:-Werror>)
  endif()
endfunction()

function(agv_test_warnings target)
  if(CMAKE_CXX_COMPILER_ID MATCHES "GNU|Clang")
    target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow $<$<BOOL:${AGVNAV_WERROR}>:-Werror>)
  endif()
endfunction()
