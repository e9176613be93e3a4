#!/usr/bin/env bash
# run_in_vm.sh [--timeout S] [--results DIR] -- COMMAND [ARGS...]
#
# Runs COMMAND (an absolute host path) inside a throw-away qemu VM that boots Debian's
# stock kernel, so tests get real SocketCAN (vcan0, vcan1) even though this host's kernel
# has no CAN support. The VM sees the host's / read-only (9p) and chroots into it, so
# COMMAND runs unchanged, in the caller's working directory. DIR (default: a temp dir,
# deleted afterwards) is shared read-write at the same absolute path. COMMAND's
# stdout+stderr reach our stdout; we exit with COMMAND's exit status.
# Harness failures (VM did not come up, no vcan, ...) exit 125; a timeout exits 124.
# See tests/vm/README.md.
set -euo pipefail

readonly PROG=run_in_vm
readonly E_HARNESS=125 E_TIMEOUT=124

die() {
  echo "$PROG: ERROR: $*" >&2
  exit "$E_HARNESS"
}
note() { echo "$PROG: $*" >&2; }
usage() {
  echo "usage: $0 [--timeout SECONDS] [--results DIR] -- COMMAND [ARGS...]" >&2
  exit 2
}

timeout_s=300
results=
while [ $# -gt 0 ]; do
  case "$1" in
    --timeout) [ $# -ge 2 ] || usage; timeout_s=$2; shift 2 ;;
    --timeout=*) timeout_s=${1#*=}; shift ;;
    --results) [ $# -ge 2 ] || usage; results=$2; shift 2 ;;
    --results=*) results=${1#*=}; shift ;;
    --) shift; break ;;
    -h|--help) usage ;;
    *) usage ;;
  esac
done
[ $# -ge 1 ] || usage
[[ "$timeout_s" =~ ^[1-9][0-9]*$ ]] || die "--timeout wants a positive whole number of seconds, got '$timeout_s'"
case "$1" in
  /*) ;;
  *) die "COMMAND must be an absolute path (it runs inside the VM's chroot of the host root): '$1'" ;;
esac
[ -x "$1" ] || die "COMMAND '$1' does not exist or is not executable"

# Everything we start is ended on exit, by pid; a default results dir is removed.
qemu_pid= tail_pid= sleep_pid= tmp_results=
cleanup() {
  local p
  for p in $qemu_pid $tail_pid $sleep_pid; do kill "$p" 2>/dev/null || true; done
  [ -z "$tmp_results" ] || rm -rf "$tmp_results"
  return 0
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

# ---------------------------------------------------------------- host prerequisites
hint="install them with scripts/install-deps.sh"
qemu=$(command -v qemu-system-x86_64) || die "qemu-system-x86_64 not found ($hint: qemu-system-x86)"
busybox=
for b in /bin/busybox /usr/bin/busybox; do
  if [ -x "$b" ] && ! LC_ALL=C ldd "$b" >/dev/null 2>&1; then busybox=$b; break; fi
done
[ -n "$busybox" ] || die "no statically linked busybox found ($hint: busybox-static)"
command -v cpio >/dev/null || die "cpio not found ($hint: cpio)"
[ -x /sbin/ip ] || [ -x /usr/sbin/ip ] || [ -x /bin/ip ] || die "iproute2's ip not found ($hint: iproute2)"

# ---------------------------------------------------------------- pick the kernel
# Newest /boot/vmlinuz-* whose /lib/modules tree has vcan (ZEROG_VM_KERNEL=path overrides).
pick_kernel() {
  local k v
  if [ -n "${ZEROG_VM_KERNEL:-}" ]; then
    case "${ZEROG_VM_KERNEL##*/}" in
      vmlinuz-?*) echo "$ZEROG_VM_KERNEL"; return ;;
      *) die "ZEROG_VM_KERNEL must name a file vmlinuz-<version>, got '$ZEROG_VM_KERNEL'" ;;
    esac
  fi
  for k in $(ls -1 /boot/vmlinuz-* 2>/dev/null | sort -V -r); do
    v=${k#/boot/vmlinuz-}
    if compgen -G "/lib/modules/$v/kernel/drivers/net/can/vcan.ko*" >/dev/null; then
      echo "$k"
      return
    fi
  done
}
kernel=$(pick_kernel) || exit "$E_HARNESS"
[ -n "$kernel" ] || die "no /boot/vmlinuz-* with a vcan module under /lib/modules/<version>/kernel/drivers/net/can/ ($hint: linux-image-amd64)"
[ -r "$kernel" ] || die "kernel image $kernel is not readable"
kver=${kernel##*/vmlinuz-}
moddir=/lib/modules/$kver
[ -f "$moddir/modules.dep" ] || die "$moddir/modules.dep missing (kernel $kver)"
compgen -G "$moddir/kernel/drivers/net/can/vcan.ko*" >/dev/null \
  || die "kernel $kver has no vcan module in $moddir/kernel/drivers/net/can/"

# ---------------------------------------------------------------- the VM's /init
# Runs as PID 1 in the initramfs. Loads CAN + virtio/9p/overlay modules, mounts the host
# root read-only (plus a RAM overlay) at /root and the results share read-write over its
# host path, brings up lo, vcan0 and vcan1, then runs the job script (written by us into the results share) in a chroot.
# Any failure prints "ZEROG-VM-FATAL:" on the console (and into vm-run/error when possible)
# and powers off; an init crash panics, and panic=-1 + -no-reboot end qemu.
read -r -d '' INIT_SCRIPT <<'INIT' || true
#!/bin/busybox sh
/bin/busybox --install -s /bin
export PATH=/bin:/sbin
R=/root
results_ok=0
fatal() {
  echo "ZEROG-VM-FATAL: $*"
  if [ "$results_ok" = 1 ]; then echo "$*" > /results/vm-run/error; sync; fi
  poweroff -f
  sleep 5; reboot -f
}
mkdir -p /proc /sys /dev /root /results
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t devtmpfs dev /dev
echo "ZEROG-VM: init started"
while read -r m; do
  [ -n "$m" ] || continue
  insmod "/modules/$m.ko" || fatal "insmod $m failed"
done < /modules/order
# Host root read-only (9p) under a tmpfs overlay: the chroot is writable (/tmp etc.),
# writes stay in the VM's RAM and never reach the host.
mkdir -p /lower /rw
mount -t 9p -o trans=virtio,version=9p2000.L,msize=262144,ro hostroot /lower \
  || fatal "cannot mount the host root (9p tag hostroot)"
mount -t tmpfs -o mode=755 tmpfs /rw && mkdir -p /rw/upper /rw/work \
  || fatal "cannot mount the overlay's tmpfs"
mount -t overlay -o lowerdir=/lower,upperdir=/rw/upper,workdir=/rw/work overlay $R \
  || fatal "cannot mount the overlay of the host root"
mount -t 9p -o trans=virtio,version=9p2000.L,msize=262144,rw results /results \
  || fatal "cannot mount the results share (9p tag results)"
[ -f /results/vm-run/host_path ] || fatal "results share has no vm-run/host_path"
results_ok=1
hp=$(cat /results/vm-run/host_path)
[ -d "$R$hp" ] || fatal "results dir $hp not visible in the host root"
mount -o bind /results "$R$hp" || fatal "cannot bind the results share at $hp"
mount -t proc proc $R/proc || fatal "cannot mount /proc in the chroot"
mount -t sysfs sys $R/sys || fatal "cannot mount /sys in the chroot"
mount -t devtmpfs dev $R/dev || fatal "cannot mount /dev in the chroot"
mkdir -p $R/dev/pts $R/dev/shm 2>/dev/null
mount -t devpts devpts $R/dev/pts 2>/dev/null
mount -t tmpfs tmpfs $R/dev/shm 2>/dev/null
chroot $R ip link set lo up || fatal "ip link set lo up failed"
for i in vcan0 vcan1; do
  chroot $R ip link add dev $i type vcan || fatal "ip link add $i type vcan failed"
  chroot $R ip link set up $i || fatal "ip link set up $i failed"
done
echo "ZEROG-VM: vcan0 vcan1 up, running the command"
echo 1 > /proc/sys/kernel/printk
chroot $R /bin/bash "$hp/vm-run/job.sh"
st=$?
echo "$st" > /results/vm-run/exit_status.tmp && mv /results/vm-run/exit_status.tmp /results/vm-run/exit_status
sync
echo "ZEROG-VM: command exited with status $st"
umount "$R$hp" 2>/dev/null
umount /results 2>/dev/null
poweroff -f
sleep 5; reboot -f
INIT

# ---------------------------------------------------------------- initramfs (cached)
# Modules (and their dependencies, from modules.dep) in load order.
wanted_modules=(can can-raw can-dev vcan virtio_pci 9pnet_virtio 9p overlay)
module_order() {
  local -A seen=()
  local m path deps d i
  add() {  # add <relative path in moddir>
    local rel=$1 line dep j
    [ -n "${seen[$rel]:-}" ] && return 0
    line=$(grep -m1 "^$rel:" "$moddir/modules.dep") || true
    read -r -a dep <<<"${line#*:}"
    for ((j = ${#dep[@]} - 1; j >= 0; j--)); do add "${dep[j]}"; done
    seen[$rel]=1
    echo "$rel"
  }
  for m in "${wanted_modules[@]}"; do
    path=$(grep -m1 -E "(^|/)${m}\.ko(\.[a-z]+)?:" "$moddir/modules.dep" | cut -d: -f1) || true
    if [ -z "$path" ]; then
      # Built into the kernel is fine too.
      grep -qE "(^|/)${m//-/[-_]}\.ko$" "$moddir/modules.builtin" 2>/dev/null && continue
      die "kernel $kver has no module '$m' (needed for the VM: CAN or virtio/9p)"
    fi
    add "$path"
  done
}
mods=$(module_order) || exit "$E_HARNESS"

key_src=$(printf '%s\n' "$INIT_SCRIPT" "$mods" "$(stat -c '%s %Y' "$kernel" "$busybox" "$moddir/modules.dep")")
key=$kver-$(printf '%s' "$key_src" | sha256sum | cut -c1-12)
cache_root=${ZEROG_VM_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/zerog-vm}
initrd=$cache_root/$key/initramfs.cpio
if [ ! -s "$initrd" ]; then
  note "building initramfs for kernel $kver in $cache_root/$key"
  mkdir -p "$cache_root/$key" || die "cannot create cache dir $cache_root/$key"
  stage=$(mktemp -d "$cache_root/$key/stage.XXXXXX")
  mkdir -p "$stage/bin" "$stage/modules"
  cp "$busybox" "$stage/bin/busybox"
  printf '%s\n' "$INIT_SCRIPT" >"$stage/init"
  chmod 755 "$stage/init"
  : >"$stage/modules/order"
  while read -r rel; do
    [ -n "$rel" ] || continue
    src=$moddir/$rel
    name=${rel##*/}
    name=${name%%.ko*}
    case "$src" in
      *.ko) cp "$src" "$stage/modules/$name.ko" ;;
      *.ko.xz) xz -dc "$src" >"$stage/modules/$name.ko" || die "xz -d $src failed ($hint: xz-utils)" ;;
      *.ko.zst) zstd -qdc "$src" >"$stage/modules/$name.ko" || die "zstd -d $src failed (apt-get install zstd)" ;;
      *.ko.gz) gzip -dc "$src" >"$stage/modules/$name.ko" || die "gzip -d $src failed" ;;
      *) die "unknown module format: $src" ;;
    esac
    echo "$name" >>"$stage/modules/order"
  done <<<"$mods"
  (cd "$stage" && find . -print0 | LC_ALL=C sort -z | cpio --null -o -H newc --quiet) >"$stage.cpio" \
    || die "cpio failed while building the initramfs"
  mv -f "$stage.cpio" "$initrd"  # atomic: concurrent runs never see a half-written file
  rm -rf "$stage"
  for old in "$cache_root/$kver"-*; do  # initramfs of older versions of this script
    [ "$old" = "$cache_root/$key" ] || rm -rf "$old"
  done
fi

# ---------------------------------------------------------------- results share + job
if [ -z "$results" ]; then
  results=$(mktemp -d "${TMPDIR:-/tmp}/zerog-vm-results.XXXXXX")
  tmp_results=$results
fi
mkdir -p "$results" || die "cannot create results dir $results"
results=$(cd "$results" && pwd -P)
case "$results" in
  *$'\n'*) die "results dir path must not contain a newline" ;;
esac
run=$results/vm-run
mkdir -p "$run"
rm -f "$run/exit_status" "$run/exit_status.tmp" "$run/error" "$run/job.sh" "$run/console.log"
: >"$run/output.log"
printf '%s\n' "$results" >"$run/host_path"

cwd=$(pwd -P)
{
  echo "# generated by tests/vm/run_in_vm.sh; runs inside the VM's chroot of the host root"
  # A small allow-list of the caller's environment (not all of it: no secrets in files).
  while IFS= read -r var; do
    case "$var" in
      PATH|HOME|USER|LOGNAME|LANG|LANGUAGE|TZ|LC_*|GTEST_*|ZEROG_*|CTEST_*|ASAN_OPTIONS|UBSAN_OPTIONS|LSAN_OPTIONS|TSAN_OPTIONS)
        printf 'export %s=%q\n' "$var" "${!var}" ;;
    esac
  done < <(compgen -e)
  echo "export ZEROG_IN_VM=1 ZEROG_CAN_IFACE=vcan0"
  printf 'cd %q || { echo "%s: cannot cd to %s in the VM" >&2; exit 125; }\n' "$cwd" "$PROG" "$cwd"
  printf 'exec'
  printf ' %q' "$@"
  printf ' >>%q 2>&1 </dev/null\n' "$run/output.log"
} >"$run/job.sh"

# ---------------------------------------------------------------- boot

note "booting $kernel (TCG, timeout ${timeout_s}s) for: $*"
start=$(date +%s.%N)
# `timeout` is a backstop in case this script itself is killed (SIGKILL) mid-run.
# tsc=reliable: the guest kernel otherwise finds the two emulated CPUs' TSCs "unsynchronized" and
# falls back to the emulated HPET, and every clock_gettime becomes a system call that reads it
# (the most frequent and costly call of a hardware-in-the-loop run, measured with strace -c).
timeout -k 5 $((timeout_s + 30)) "$qemu" -accel tcg -machine pc -cpu max -smp 2 -m 1024 \
  -nographic -no-reboot -nic none -no-user-config \
  -kernel "$kernel" -initrd "$initrd" \
  -append "console=ttyS0 panic=-1 quiet loglevel=4 tsc=reliable" \
  -virtfs "local,path=/,mount_tag=hostroot,security_model=none,readonly=on,multidevs=remap" \
  -virtfs "local,path=$results,mount_tag=results,security_model=none,multidevs=remap" \
  </dev/null >"$run/console.log" 2>&1 &
qemu_pid=$!
# Stream COMMAND's output while it runs (the file lives in the results share).
tail -n +1 -s 0.2 -F --pid="$qemu_pid" "$run/output.log" 2>/dev/null &
tail_pid=$!
sleep "$timeout_s" &
sleep_pid=$!

timed_out=0
finished=
wait -n -p finished "$qemu_pid" "$sleep_pid" || true
if [ "$finished" = "$sleep_pid" ]; then
  timed_out=1
  sleep_pid=
  kill "$qemu_pid" 2>/dev/null || true
  for _ in 1 2 3 4 5 6 7 8 9 10; do kill -0 "$qemu_pid" 2>/dev/null || break; sleep 0.5; done
  kill -9 "$qemu_pid" 2>/dev/null || true
  wait "$qemu_pid" 2>/dev/null || true
else
  kill "$sleep_pid" 2>/dev/null || true
  wait "$sleep_pid" 2>/dev/null || true
  sleep_pid=
fi
qemu_pid=
wait "$tail_pid" 2>/dev/null || true
tail_pid=
elapsed=$(awk -v s="$start" -v e="$(date +%s.%N)" 'BEGIN { printf "%.1f", e - s }')

show_console() {
  echo "---- last lines of the VM console ($run/console.log) ----" >&2
  tail -n 25 "$run/console.log" | sed 's/\x1b\[[0-9;?]*[A-Za-z]//g; s/\x1bc//g' >&2 || true
  echo "----" >&2
}

if [ "$timed_out" = 1 ]; then
  show_console
  note "ERROR: TIMEOUT: no result after ${timeout_s}s; qemu killed (raise --timeout? TCG is slow)"
  exit "$E_TIMEOUT"
fi
if [ -f "$run/exit_status" ]; then
  status=$(cat "$run/exit_status")
  [[ "$status" =~ ^[0-9]+$ ]] || die "garbled exit status '$status' in $run/exit_status"
  note "VM finished in ${elapsed}s, command exit status $status"
  exit "$status"
fi
show_console
if [ -s "$run/error" ]; then
  die "VM setup failed: $(cat "$run/error")"
fi
if grep -q 'ZEROG-VM-FATAL:' "$run/console.log"; then
  die "VM setup failed: $(grep -m1 'ZEROG-VM-FATAL:' "$run/console.log" | sed 's/.*ZEROG-VM-FATAL: *//' | tr -d '\r')"
fi
panic=$(grep -a -m1 'Kernel panic' "$run/console.log" | tr -d '\r' || true)
[ -z "$panic" ] || die "the VM crashed after ${elapsed}s: ${panic#*\] }"
die "the VM ended after ${elapsed}s without running the command (did not boot, or crashed); see the console above"
