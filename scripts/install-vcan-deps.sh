#!/usr/bin/env bash
# Installs what the vcan VM test (tests/vcan/run-vcan-vm.sh) needs on a Debian host:
# an x86-64 system emulator, a stock Debian kernel whose modules include the CAN stack
# (linux-image-amd64; the -cloud- flavour has no CAN), a static busybox for the initramfs,
# can-utils (cansend/candump as the peer and the bus monitor), cpio and xz.
# Installing linux-image-amd64 puts a kernel into /boot of the host; the host does not boot it,
# the test only reads it.
set -euo pipefail

packages=(qemu-system-x86 linux-image-amd64 busybox-static can-utils cpio xz-utils)

if [[ $(id -u) -ne 0 ]]; then
  sudo=sudo
else
  sudo=
fi

export DEBIAN_FRONTEND=noninteractive
missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed'; then
    missing+=("$p")
  fi
done
if [[ ${#missing[@]} -eq 0 ]]; then
  echo "install-vcan-deps: all present (${packages[*]})"
  exit 0
fi
echo "install-vcan-deps: installing ${missing[*]}"
$sudo apt-get -o DPkg::Lock::Timeout=900 update
$sudo apt-get -o DPkg::Lock::Timeout=900 install -y --no-install-recommends "${missing[@]}"
