#!/usr/bin/env bash
# README command 2: the whole test suite, ending in ONE ctest run whose summary counts everything:
#   native tree (build/ci, warnings as errors): unit, allocation, consumer-package, app tests
#   build/asan      : the unit tests again under AddressSanitizer + UndefinedBehaviorSanitizer
#   build/aarch64   : the portable parts (core/, hal/, drivers/protocol/) and their tests for
#                     aarch64 Linux, run under qemu-aarch64
#   build/armhf     : the same for armhf Linux, run under qemu-arm
#   build/cortex-m7 : the portable parts bare-metal for Cortex-M7 (FPv5-SP), test image run on
#                     qemu-system-arm mps2-an500, size report (per library too), heap-symbol check
# The other trees are built first; the native tree's ctest includes their tests
# (AGVNAV_AGGREGATE_TEST_DIRS), labelled asan / aarch64 / armhf / cortex-m7.
# Every compile goes through ccache (installed by install-deps.sh --all; CCACHE_DISABLE=1 turns it
# off): a second run of the suite on the same machine, from any clone, rebuilds only what changed.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
jobs=$(nproc)

scripts/install-deps.sh --all

section() { printf '\n==== %s ====\n' "$*"; }
launcher=()
if command -v ccache >/dev/null; then
  # Hits across clones: paths below the repository root are hashed relative to it, and the
  # compile's working directory (only in the debug info) is left out of the hash.
  export CCACHE_BASEDIR="$root" CCACHE_NOHASHDIR=true CCACHE_MAXSIZE="${CCACHE_MAXSIZE:-20G}"
  launcher=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
  ccache --zero-stats >/dev/null
fi
build_tree() {  # preset
  section "configure + build: $1"
  cmake --preset "$1" "${launcher[@]}" >"build/$1.configure.log" 2>&1 || { cat "build/$1.configure.log"; return 1; }
  cmake --build --preset "$1" -j "$jobs"
}
mkdir -p build
trees=()
for preset in asan aarch64 armhf cortex-m7; do
  build_tree "$preset"
  trees+=("$root/build/$preset")
done
rm -f build/*.configure.log

section "size report (Cortex-M7 images, bytes)"
cat build/cortex-m7/tests/*.size.txt

section "configure + build: native (ci)"
agg=$(IFS=';'; echo "${trees[*]}")
cmake --preset ci "${launcher[@]}" "-DAGVNAV_AGGREGATE_TEST_DIRS=$agg" >/dev/null
cmake --build --preset ci -j "$jobs"

if [ ${#launcher[@]} -gt 0 ]; then
  section "ccache"
  ccache --show-stats | grep -iE 'hits|misses' || true
fi

section "ctest: all trees"
ctest --preset ci
