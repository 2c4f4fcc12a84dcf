// Catch2's main, compiled once per build tree (Debian's prebuilt Catch2 main is x86-only).
#define CATCH_CONFIG_MAIN
#include <catch.hpp>
