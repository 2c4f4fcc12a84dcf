#!/usr/bin/env bash
# Installs the Debian packages agvnav needs (idempotent: only what is missing is installed).
#   scripts/install-deps.sh          build + run the library, apps and native tests
#   scripts/install-deps.sh --all    also what the whole suite needs (scripts/test-all.sh): the ARM
#                                    cross compilers, qemu-user/qemu-system-arm, the bare-metal
#                                    toolchain, and for the SocketCAN VM test a Debian kernel with
#                                    CAN modules, busybox and can-utils (~2.5 GB), clang 14 with
#                                    libclang-rt for the fuzz tests, ccache for the five trees' builds
set -euo pipefail

base=(cmake make g++ pkg-config libeigen3-dev catch2 libbenchmark-dev zlib1g-dev libcli11-dev nlohmann-json3-dev clang-format clang-tidy
      libmodbus-dev libsqlite3-dev libceres-dev)
cross=(g++-aarch64-linux-gnu g++-arm-linux-gnueabihf qemu-user qemu-system-arm
       gcc-arm-none-eabi binutils-arm-none-eabi libnewlib-arm-none-eabi libstdc++-arm-none-eabi-newlib
       qemu-system-x86 linux-image-amd64 busybox-static can-utils cpio xz-utils clang-14 libclang-rt-14-dev ccache)

want=("${base[@]}")
case "${1:-}" in
  --all) want+=("${cross[@]}") ;;
  "") ;;
  *) echo "usage: $0 [--all]" >&2; exit 2 ;;
esac

missing=()
for p in "${want[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#want[@]} packages present"
  exit 0
fi

sudo=""
if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get -o DPkg::Lock::Timeout=900 update -q
$sudo apt-get -o DPkg::Lock::Timeout=900 install -y -q --no-install-recommends "${missing[@]}"
