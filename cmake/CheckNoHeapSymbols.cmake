# cmake -DNM=<nm> -DELF=<image> -P CheckNoHeapSymbols.cmake
# Fails when the image links a heap allocator: malloc and friends, newlib's reentrant forms,
# _sbrk, or any operator new / new[] (Itanium-mangled _Znwj / _Znaj on 32-bit ARM).
execute_process(COMMAND ${NM} ${ELF} OUTPUT_VARIABLE syms RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "${NM} ${ELF} failed (${rc})")
endif()
string(REGEX MATCHALL "[ \t](malloc|calloc|realloc|_malloc_r|_calloc_r|_realloc_r|memalign|_sbrk|_sbrk_r|_Znwj[A-Za-z0-9_]*|_Znaj[A-Za-z0-9_]*)\n" hits "${syms}")
if(hits)
  string(REPLACE "\n" "" hits "${hits}")
  message(FATAL_ERROR "heap allocator linked into ${ELF}:${hits}")
endif()
message(STATUS "no heap allocator symbols in ${ELF}")
