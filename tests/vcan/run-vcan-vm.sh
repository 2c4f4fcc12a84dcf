#!/usr/bin/env bash
# Runs the SocketCAN transport test against a real Linux CAN stack.
#
# The build host's kernel may have no CAN support (and no KVM), so this script boots a stock
# Debian kernel (package linux-image-amd64; the -cloud- flavour has no CAN) under
# qemu-system-x86_64 with TCG emulation. A busybox initramfs loads can-dev, vcan, can and can-raw,
# creates vcan0 and vcan1, starts `candump -L vcan0` as the bus monitor, runs the statically
# linked test program (which spawns `cansend` as the peer), checks candump's log for the frames
# the test transmitted, prints one result line and powers off. See docs/vcan-testing.md.
#
# usage: run-vcan-vm.sh --test-binary PATH --work-dir DIR [--timeout SECONDS] [--kernel VMLINUZ]
#                       [--companion PATH]... [--program PATH]... [-- TEST-ARGS...]
# A companion is a further, dynamically linked test program (e.g. one that needs libmodbus, which
# Debian ships as a shared library only): it is copied into the VM with its shared libraries and
# the loader, and run after the test binary with the same arguments. A program is copied into the
# VM's /test the same way (with its shared libraries when it has any) but not run: the tests start
# it (e.g. agvnav-sim-drives).
# Exit status: 0 when the line "AGV-VCAN-RESULT: PASS" was seen, 1 otherwise (missing packages,
# kernel without CAN modules, test failure, VM timeout). It never skips.
#
# The initramfs without the test binary and the uncompressed kernel are cached in the work
# directory, keyed by the kernel, busybox, can-utils, C library and this script; a run only
# appends the current test binary as a second cpio archive.
set -euo pipefail

test_binary=""
work_dir=""
timeout_s=120
kernel="${AGV_VCAN_KERNEL:-}"
test_args=()
companions=()
programs=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --test-binary) test_binary="$2"; shift 2 ;;
    --work-dir) work_dir="$2"; shift 2 ;;
    --timeout) timeout_s="$2"; shift 2 ;;
    --kernel) kernel="$2"; shift 2 ;;
    --companion) companions+=("$2"); shift 2 ;;
    --program) programs+=("$2"); shift 2 ;;
    --) shift; test_args=("$@"); break ;;
    *) echo "run-vcan-vm: unknown argument '$1'" >&2; exit 1 ;;
  esac
done

fail() {
  echo "AGV-VCAN: FAILED: $*" >&2
  exit 1
}

[[ -n "$test_binary" && -n "$work_dir" ]] || fail "usage: run-vcan-vm.sh --test-binary PATH --work-dir DIR [--timeout S]"
[[ -x "$test_binary" ]] || fail "test binary '$test_binary' not found or not executable"
[[ "$timeout_s" =~ ^[0-9]+$ ]] || fail "--timeout must be a whole number of seconds"

install_hint="install the packages with scripts/install-deps.sh --all (qemu-system-x86 linux-image-amd64 busybox-static can-utils cpio xz-utils)"

# ---- tools -----------------------------------------------------------------------------------
need() {
  command -v "$1" >/dev/null 2>&1 || fail "'$1' not found; $install_hint"
}
need qemu-system-x86_64
need cpio
need cansend
need candump
need cangen
need ldd
need timeout
busybox="${AGV_VCAN_BUSYBOX:-}"
if [[ -z "$busybox" ]]; then
  for b in /bin/busybox /usr/bin/busybox; do
    if [[ -x "$b" ]]; then busybox="$b"; break; fi
  done
fi
[[ -n "$busybox" && -x "$busybox" ]] || fail "busybox not found; $install_hint"
if ldd "$busybox" >/dev/null 2>&1; then
  fail "$busybox is dynamically linked; the initramfs needs busybox-static ($install_hint)"
fi
if ldd "$test_binary" >/dev/null 2>&1; then
  fail "test binary '$test_binary' is dynamically linked; it must be static"
fi
for c in "${companions[@]}"; do
  [[ -x "$c" ]] || fail "companion '$c' not found or not executable"
  ldd "$c" >/dev/null 2>&1 || fail "companion '$c' is not a dynamically linked program"
done
for p in "${programs[@]}"; do
  [[ -x "$p" ]] || fail "program '$p' not found or not executable"
done

# ---- kernel with CAN modules -------------------------------------------------------------------
# A kernel image qualifies when /lib/modules/<version> has can-dev, vcan, can and can-raw.
module_path() {  # module_path <version> <relative path without .ko>
  local base="/lib/modules/$1/kernel/$2"
  local ext
  for ext in .ko .ko.xz .ko.zst .ko.gz; do
    if [[ -f "$base$ext" ]]; then echo "$base$ext"; return 0; fi
  done
  return 1
}
module_rel=(drivers/net/can/dev/can-dev drivers/net/can/vcan net/can/can net/can/can-raw)
has_can_modules() {
  local rel
  for rel in "${module_rel[@]}"; do module_path "$1" "$rel" >/dev/null || return 1; done
}
kver=""
if [[ -n "$kernel" ]]; then
  [[ -f "$kernel" ]] || fail "kernel image '$kernel' not found"
  kver="${AGV_VCAN_KERNEL_VERSION:-$(basename "$kernel" | sed 's/^vmlinuz-//')}"
  has_can_modules "$kver" || fail "no CAN modules for kernel $kver under /lib/modules/$kver"
else
  while IFS= read -r k; do
    v="${k#/boot/vmlinuz-}"
    if has_can_modules "$v"; then kernel="$k"; kver="$v"; break; fi
  done < <(ls -1 /boot/vmlinuz-* 2>/dev/null | sort -rV)
  [[ -n "$kernel" ]] || fail "no kernel in /boot with CAN modules (can-dev, vcan, can, can-raw); the -cloud- kernel has none; $install_hint"
fi
[[ -r "$kernel" ]] || fail "kernel image '$kernel' is not readable (run as root or chmod a+r it)"

mkdir -p "$work_dir"
work_dir="$(cd "$work_dir" && pwd)"
log="$work_dir/console.log"

# ---- cached parts: uncompressed kernel + base initramfs --------------------------------------
fingerprint() {
  local f
  for f in "$@"; do
    [[ -e "$f" ]] && stat -L -c '%n %s %Y' "$f"
  done
  return 0
}
libs_of() {  # absolute paths of the shared libraries (and the loader) of a program
  ldd "$1" | awk '{ for (i = 1; i <= NF; ++i) if ($i ~ /^\//) print $i }' | sort -u
}
cansend_bin="$(command -v cansend)"
candump_bin="$(command -v candump)"
cangen_bin="$(command -v cangen)"
mapfile -t libs < <( (libs_of "$cansend_bin"; libs_of "$candump_bin"; libs_of "$cangen_bin") | sort -u)
modules=()
for rel in "${module_rel[@]}"; do modules+=("$(module_path "$kver" "$rel")"); done
key="$( (echo "kernel $kver"; fingerprint "$kernel" "$busybox" "$cansend_bin" "$candump_bin" "$cangen_bin" "${libs[@]}" "${modules[@]}";
         sha256sum "${BASH_SOURCE[0]}" | cut -d' ' -f1) | sha256sum | cut -d' ' -f1)"

base_cpio="$work_dir/base.cpio"
vmlinux="$work_dir/vmlinux"
boot_image="$kernel"
t_start=$(date +%s%N)

extract_vmlinux() {  # like the kernel's scripts/extract-vmlinux: find a compressed payload that is an ELF
  # Magic numbers without their trailing NUL (bash strings cannot hold one); tools to match.
  local magics=($'\xfd7zXZ' $'\x28\xb5\x2f\xfd' $'\x1f\x8b\x08')
  local tools=("xz -dc --single-stream" "zstd -dcq" "gzip -dcq")
  local i pos tool
  for i in 0 1 2; do
    tool="${tools[$i]}"
    command -v "${tool%% *}" >/dev/null 2>&1 || continue
    while IFS=: read -r pos _; do
      tail -c "+$((pos + 1))" "$kernel" | $tool > "$vmlinux.tmp" 2>/dev/null || true
      if [[ -s "$vmlinux.tmp" ]] && [[ "$(head -c 4 "$vmlinux.tmp" | od -An -c | tr -d ' ')" == '177ELF' ]]; then
        mv "$vmlinux.tmp" "$vmlinux"
        return 0
      fi
    done < <(LC_ALL=C grep -aboF "${magics[$i]}" "$kernel" | head -n 4 || true)
  done
  rm -f "$vmlinux.tmp"
  return 1
}

build_base() {
  local root="$work_dir/root"
  rm -rf "$root" "$base_cpio" "$vmlinux"
  mkdir -p "$root"/{bin,sbin,proc,sys,dev,tmp,test,lib/agv-modules}
  cp "$busybox" "$root/bin/busybox"
  local m name
  for m in "${modules[@]}"; do
    name="$(basename "$m")"; name="${name%%.ko*}"
    case "$m" in
      *.ko.xz) xz -dc "$m" > "$root/lib/agv-modules/$name.ko" ;;
      *.ko.zst) zstd -dcq "$m" > "$root/lib/agv-modules/$name.ko" ;;
      *.ko.gz) gzip -dc "$m" > "$root/lib/agv-modules/$name.ko" ;;
      *) cp "$m" "$root/lib/agv-modules/$name.ko" ;;
    esac
  done
  cp "$cansend_bin" "$candump_bin" "$cangen_bin" "$root/bin/"
  local lib
  for lib in "${libs[@]}"; do
    mkdir -p "$root$(dirname "$lib")"
    cp -L "$lib" "$root$lib"
  done
  cat > "$root/init" <<'INIT'
#!/bin/busybox sh
# Init of the vcan test VM (written by tests/vcan/run-vcan-vm.sh).
/bin/busybox mount -t proc proc /proc
/bin/busybox --install -s /bin
export PATH=/bin:/sbin
mount -t sysfs sysfs /sys
mount -t devtmpfs devtmpfs /dev 2>/dev/null
mount -t tmpfs tmpfs /tmp

result() {
  echo "AGV-VCAN-RESULT: $*"
  poweroff -f
  sleep 10
}

for m in can-dev vcan can can-raw; do
  insmod /lib/agv-modules/$m.ko || result "FAIL insmod $m"
done
for i in vcan0 vcan1; do
  { ip link add dev $i type vcan && ip link set up $i; } || result "FAIL cannot create $i"
done
# Loopback (down after boot): the vehicle loop test's laser server listens on 127.0.0.1.
ip link set up lo || result "FAIL cannot bring up lo"

# Bus monitor; wait until it records (a sync frame shows up in its log).
candump -L vcan0 > /tmp/candump.log 2> /tmp/candump.err &
candump_pid=$!
n=0
while ! grep -q '7F0#A5' /tmp/candump.log; do
  n=$((n + 1))
  [ $n -gt 100 ] && result "FAIL candump does not record: $(cat /tmp/candump.err)"
  cansend vcan0 7F0#A5
  sleep 0.05
done

args=$(cat /test/args 2>/dev/null)
echo "AGV-VCAN: $(cut -d' ' -f1 /proc/uptime) s after boot: CAN up, running /test/test_vcan_socketcan $args"
cd /test
AGV_VCAN_IF=vcan0 AGV_VCAN_IF2=vcan1 AGV_CANSEND=cansend ./test_vcan_socketcan --use-colour no $args
rc=$?
for c in $(cat /test/companions 2>/dev/null); do
  echo "AGV-VCAN: $(cut -d' ' -f1 /proc/uptime) s after boot: running /test/$c $args"
  AGV_VCAN_IF=vcan0 AGV_VCAN_IF2=vcan1 ./$c --use-colour no $args
  c_rc=$?
  [ $rc -eq 0 ] && rc=$c_rc
done

# The frames the test transmitted on vcan0, as candump -L prints them. candump may still be
# writing: give it up to 5 s before calling a frame missing.
n=0
while :; do
  missing=""
  # 000#0111, 000#0112, 080#: NMT Start and SYNC from the CANopen encoder source test.
  # 000#8001, 000#0101, 77F#05, 201#06/07/0F...: the calibration routine's drive controller: the
  # traction drive (node 1) to pre-operational and started, the controller's heartbeat, and the
  # power state machine's shutdown, switch on and enable operation (controlword + target 0), and
  # the traction quick stop (controlword 0x0002, target 0) of the Stop, heartbeat and fault cases.
  for f in 201#11223344 1ABCDE01#01 202#R 000#0111 000#0112 080# \
           000#8001 000#0101 77F#05 201#060000000000 201#070000000000 201#0F0000000000 \
           201#020000000000; do
    grep -q " vcan0 $f\$" /tmp/candump.log || missing="$missing $f"
  done
  [ -z "$missing" ] && break
  n=$((n + 1))
  [ $n -gt 50 ] && break
  sleep 0.1
done
kill $candump_pid 2>/dev/null
echo "AGV-VCAN: $(cut -d' ' -f1 /proc/uptime) s after boot: test done, exit $rc"
echo "AGV-VCAN: candump recorded $(wc -l < /tmp/candump.log) frames on vcan0"
if [ $rc -eq 0 ] && [ -z "$missing" ]; then
  result "PASS (test exit 0, candump saw the transmitted frames)"
elif [ $rc -ne 0 ]; then
  result "FAIL (test exit $rc; candump missing:${missing:- none})"
else
  result "FAIL (candump did not record:$missing)"
fi
INIT
  chmod +x "$root/init"
  (cd "$root" && find . | LC_ALL=C sort | cpio -o -H newc -R 0:0 --quiet) > "$base_cpio.tmp"
  mv "$base_cpio.tmp" "$base_cpio"
  rm -rf "$root"
  extract_vmlinux || echo "AGV-VCAN: could not extract an uncompressed vmlinux; booting $kernel directly (slower)"
  echo "$key" > "$work_dir/base.key"
}

if [[ ! -f "$base_cpio" || "$(cat "$work_dir/base.key" 2>/dev/null)" != "$key" ]]; then
  echo "AGV-VCAN: building the initramfs for kernel $kver in $work_dir"
  rm -f "$work_dir/base.key"
  build_base
else
  echo "AGV-VCAN: cached initramfs for kernel $kver"
fi
[[ -f "$vmlinux" ]] && boot_image="$vmlinux"

# ---- per-run part: the test binary ------------------------------------------------------------
run_root="$work_dir/run"
rm -rf "$run_root"
mkdir -p "$run_root/test"
cp "$test_binary" "$run_root/test/test_vcan_socketcan"
# Debug information only slows the boot (the initramfs is unpacked in emulation).
if command -v strip >/dev/null 2>&1; then strip --strip-debug "$run_root/test/test_vcan_socketcan"; fi
printf '%s ' "${test_args[@]}" > "$run_root/test/args"
# Companions: the program (without debug information) and its shared libraries at their paths.
for c in "${companions[@]}"; do
  name="$(basename "$c")"
  cp "$c" "$run_root/test/$name"
  if command -v strip >/dev/null 2>&1; then strip --strip-debug "$run_root/test/$name"; fi
  echo "$name" >> "$run_root/test/companions"
  while IFS= read -r lib; do
    mkdir -p "$run_root$(dirname "$lib")"
    cp -L "$lib" "$run_root$lib"
  done < <(libs_of "$c")
done
# Programs the tests start: copied the same way; not run by /init.
for p in "${programs[@]}"; do
  name="$(basename "$p")"
  cp "$p" "$run_root/test/$name"
  if command -v strip >/dev/null 2>&1; then strip --strip-debug "$run_root/test/$name"; fi
  if ldd "$p" >/dev/null 2>&1; then
    while IFS= read -r lib; do
      mkdir -p "$run_root$(dirname "$lib")"
      cp -L "$lib" "$run_root$lib"
    done < <(libs_of "$p")
  fi
done
(cd "$run_root" && find . -mindepth 1 | sed 's|^\./||' | LC_ALL=C sort | cpio -o -H newc -R 0:0 --quiet) > "$work_dir/test.cpio"
cat "$base_cpio" "$work_dir/test.cpio" > "$work_dir/initramfs.cpio"
rm -rf "$run_root"
t_built=$(date +%s%N)

# ---- boot --------------------------------------------------------------------------------------
echo "AGV-VCAN: booting $boot_image (timeout ${timeout_s} s)"
set +e
timeout --kill-after=5 "$timeout_s" \
  qemu-system-x86_64 -accel tcg -m 512M -smp 1 -no-user-config -nodefaults -display none \
    -serial stdio -monitor none -no-reboot \
    -kernel "$boot_image" -initrd "$work_dir/initramfs.cpio" \
    -append "console=ttyS0 quiet loglevel=3 panic=-1 rdinit=/init" < /dev/null 2>&1 | tr -d '\r' | tee "$log"
qemu_rc=${PIPESTATUS[0]}
set -e
t_end=$(date +%s%N)
ms() { echo $(( ($2 - $1) / 1000000 )); }
echo "AGV-VCAN: prepare $(ms "$t_start" "$t_built") ms, VM $(ms "$t_built" "$t_end") ms, total $(ms "$t_start" "$t_end") ms"

if grep -q '^AGV-VCAN-RESULT: PASS' "$log"; then
  echo "AGV-VCAN: PASSED"
  exit 0
fi
if [[ $qemu_rc -eq 124 || $qemu_rc -eq 137 ]]; then
  fail "the VM did not finish within ${timeout_s} s (console: $log)"
fi
line="$(grep '^AGV-VCAN-RESULT:' "$log" | tail -n 1 || true)"
[[ -n "$line" ]] || fail "the VM stopped without a result line (qemu exit $qemu_rc; console: $log)"
fail "${line#AGV-VCAN-RESULT: }"
