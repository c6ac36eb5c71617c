#!/bin/bash
# Runs socketcan_vm_tests against a real Linux CAN stack: boots a stock Debian kernel under QEMU
# (software emulation, no KVM needed) with a throw-away initramfs holding static busybox, the CAN
# kernel modules, can-utils and the test binary with its shared libraries, on a fresh vcan0.
#
#   tests/vm/run-vm-tests.sh path/to/socketcan_vm_tests [extra gtest args...]
#
# Exit status: 0 all tests passed; 1 tests failed or the VM did not report a result; 2 the set-up
# failed (kernel download, missing busybox-static/cpio...); 77 QEMU cannot run here at all (CTest
# counts that as skipped).
#
# Environment:
#   FLEETGW_VM_CACHE    kernel download/extraction cache (default ~/.cache/fleetgw-vm); the
#                       kernel package is downloaded once and reused.
#   FLEETGW_VM_WORKDIR  where the initramfs and the console log go (default: a temp dir)
#   FLEETGW_VM_TIMEOUT  seconds before the VM is killed (default 300)
#   FLEETGW_VM_KERNEL_PKG  kernel package to use (default: what linux-image-amd64 depends on)
set -euo pipefail

die() { echo "run-vm-tests: $*" >&2; exit 2; }
log() { echo "run-vm-tests: $*" >&2; }

[[ $# -ge 1 ]] || die "usage: $0 path/to/socketcan_vm_tests [gtest args...]"
TEST_ARG=$1; shift
GTEST_ARGS=("$@")
TEST_BIN=$(readlink -f "$TEST_ARG" || true)
[[ -n $TEST_BIN && -f $TEST_BIN && -x $TEST_BIN ]] ||
  die "test binary '$TEST_ARG' not found or not executable"

QEMU=${QEMU:-qemu-system-x86_64}
if ! command -v "$QEMU" >/dev/null 2>&1 || ! "$QEMU" --version >/dev/null 2>&1; then
  echo "run-vm-tests: SKIPPED: $QEMU is not installed or cannot run (apt-get install qemu-system-x86)" >&2
  exit 77
fi
for tool in cpio gzip dpkg-deb tar xz ldd; do
  command -v "$tool" >/dev/null || die "'$tool' is required to build the VM image"
done
BUSYBOX=${BUSYBOX:-/bin/busybox}
[[ -x $BUSYBOX ]] || die "static busybox not found at $BUSYBOX (apt-get install busybox-static)"
if ldd "$BUSYBOX" >/dev/null 2>&1; then
  die "$BUSYBOX is dynamically linked; install busybox-static"
fi

CACHE=${FLEETGW_VM_CACHE:-$HOME/.cache/fleetgw-vm}
TIMEOUT=${FLEETGW_VM_TIMEOUT:-300}
mkdir -p "$CACHE"
if [[ -n ${FLEETGW_VM_WORKDIR:-} ]]; then
  WORK=$FLEETGW_VM_WORKDIR
  rm -rf "$WORK"
  mkdir -p "$WORK"
else
  WORK=$(mktemp -d /tmp/fleetgw-vm.XXXXXX)
  trap 'rm -rf "$WORK"' EXIT
fi

# --- kernel: download and extract once (serialised: two builds may run this concurrently) -----
prepare_kernel() {
  local pkg=${FLEETGW_VM_KERNEL_PKG:-}
  if [[ -z $pkg ]]; then
    pkg=$(apt-cache depends linux-image-amd64 2>/dev/null |
          awk '/Depends: linux-image-[0-9]/ {print $2; exit}') || true
  fi
  if [[ -z $pkg ]]; then
    # No apt metadata (offline, no apt-get update): fall back to whatever is cached.
    local cached
    cached=$(ls "$CACHE"/linux-image-*-amd64_*.deb 2>/dev/null | sort -V | tail -n1 || true)
    [[ -n $cached ]] || die "cannot determine the kernel package (apt-cache depends linux-image-amd64 found nothing; run apt-get update)"
    pkg=$(basename "$cached" | cut -d_ -f1)
  fi
  local kdir=$CACHE/$pkg
  if [[ -f $kdir/.complete ]]; then
    KERNEL_DIR=$kdir
    return
  fi
  local deb
  deb=$(ls "$CACHE"/"${pkg}"_*.deb 2>/dev/null | sort -V | tail -n1 || true)
  if [[ -z $deb ]]; then
    log "downloading $pkg (once; cached in $CACHE)"
    (cd "$CACHE" && apt-get download "$pkg" >&2) || die "apt-get download $pkg failed"
    deb=$(ls "$CACHE"/"${pkg}"_*.deb | sort -V | tail -n1)
  fi
  log "extracting kernel and CAN modules from $(basename "$deb")"
  rm -rf "$kdir.tmp"
  mkdir -p "$kdir.tmp/x"
  dpkg-deb --fsys-tarfile "$deb" |
    tar -x -C "$kdir.tmp/x" --wildcards '*/boot/vmlinuz-*' '*/kernel/net/can/*' \
        '*/kernel/drivers/net/can/*' || die "extracting $deb failed"
  cp "$kdir.tmp"/x/boot/vmlinuz-* "$kdir.tmp/vmlinuz"
  mkdir -p "$kdir.tmp/modules"
  # busybox insmod cannot read compressed modules: store them plain.
  while IFS= read -r -d '' ko; do
    local base
    base=$(basename "$ko")
    case $base in
      *.ko.xz) xz -dc "$ko" > "$kdir.tmp/modules/${base%.xz}" ;;
      *.ko.zst) zstd -dcq "$ko" > "$kdir.tmp/modules/${base%.zst}" ;;
      *.ko.gz) gzip -dc "$ko" > "$kdir.tmp/modules/${base%.gz}" ;;
      *.ko) cp "$ko" "$kdir.tmp/modules/$base" ;;
    esac
  done < <(find "$kdir.tmp/x" -name '*.ko*' -print0)
  rm -rf "$kdir.tmp/x"
  for m in can can-raw vcan; do
    [[ -f $kdir.tmp/modules/$m.ko ]] || die "module $m.ko not found in $pkg"
  done
  touch "$kdir.tmp/.complete"
  rm -rf "$kdir"
  mv "$kdir.tmp" "$kdir"
  KERNEL_DIR=$kdir
}

exec 9>"$CACHE/.lock"
if command -v flock >/dev/null; then flock 9; fi
prepare_kernel
exec 9>&-

# --- initramfs ---------------------------------------------------------------------------------
ROOT=$WORK/root
mkdir -p "$ROOT"/{bin,dev,proc,sys,tmp,etc,lib/can}
ln -s bin "$ROOT/sbin"
mkdir -p "$ROOT/usr"
ln -s ../bin "$ROOT/usr/bin"
ln -s ../bin "$ROOT/usr/sbin"
cp "$BUSYBOX" "$ROOT/bin/busybox"
for applet in $("$BUSYBOX" --list); do
  [[ -e $ROOT/bin/$applet ]] || ln -s busybox "$ROOT/bin/$applet"
done
cp "$KERNEL_DIR"/modules/*.ko "$ROOT/lib/can/"

# Copies a dynamically linked program and every library ldd lists (plus the loader), keeping
# their absolute paths so the loader finds them without configuration.
copy_with_libs() {
  local bin=$1 dest=$2
  cp "$bin" "$ROOT/$dest"
  ldd "$bin" 2>/dev/null | grep -oE '/[^ ]+' | while read -r lib; do
    [[ -e $lib ]] || continue
    mkdir -p "$ROOT$(dirname "$lib")"
    [[ -e $ROOT$lib ]] || cp -L "$lib" "$ROOT$lib"
  done
}
copy_with_libs "$TEST_BIN" bin/socketcan_vm_tests
for tool in cansend candump; do
  if path=$(command -v $tool); then
    rm -f "$ROOT/bin/$tool"
    copy_with_libs "$path" "bin/$tool"
  else
    log "warning: $tool not installed (can-utils); the can-utils interop test will skip"
  fi
done
# /lib64 on merged-/usr systems is a symlink; make sure the loader path resolves.
if [[ -d /lib64 && ! -e $ROOT/lib64 ]]; then mkdir -p "$ROOT/lib64"; fi

printf '%q ' "${GTEST_ARGS[@]}" > "$ROOT/etc/gtest_args"
cat > "$ROOT/init" <<'EOF'
#!/bin/sh
export PATH=/bin
mount -t proc proc /proc
mount -t sysfs sysfs /sys
mount -t devtmpfs devtmpfs /dev
mount -t tmpfs tmpfs /tmp
# Module order matters: can-dev (drivers' helper, optional), vcan, then the protocol family.
for m in can-dev vcan can can-raw can-bcm; do
  if [ -f /lib/can/$m.ko ]; then insmod /lib/can/$m.ko || echo "init: insmod $m failed"; fi
done
ip link set lo up
ip link add dev vcan0 type vcan && ip link set up vcan0 || echo "init: cannot create vcan0"
echo "FLEETGW-VM-BEGIN kernel $(uname -r)"
export FLEETGW_REQUIRE_VCAN=1
eval "/bin/socketcan_vm_tests --gtest_color=no $(cat /etc/gtest_args)"
rc=$?
echo "FLEETGW-VM-RESULT rc=$rc"
# isa-debug-exit at port 0xf4: QEMU exits with (value << 1) | 1, so 1 = pass, 3 = fail.
if [ $rc -eq 0 ]; then code='\000'; else code='\001'; fi
printf "$code" | dd of=/dev/port bs=1 seek=244 count=1 2>/dev/null
poweroff -f
EOF
chmod +x "$ROOT/init"
(cd "$ROOT" && find . -print0 | cpio --null -o -H newc --quiet | gzip -1) > "$WORK/initramfs.cpio.gz"
log "initramfs $(du -h "$WORK/initramfs.cpio.gz" | cut -f1), kernel $(basename "$KERNEL_DIR")"

# --- boot ----------------------------------------------------------------------------------------
CONSOLE=$WORK/console.log
start=$(date +%s)
set +e
timeout --foreground -k 10 "$TIMEOUT" "$QEMU" -accel tcg -m 512 -smp 1 -nodefaults -no-user-config \
  -display none -serial stdio -no-reboot \
  -device isa-debug-exit,iobase=0xf4,iosize=0x01 \
  -kernel "$KERNEL_DIR/vmlinuz" -initrd "$WORK/initramfs.cpio.gz" \
  -append "console=ttyS0 panic=-1 quiet" < /dev/null | tee "$CONSOLE"
qemu_rc=${PIPESTATUS[0]}
set -e
log "VM finished in $(( $(date +%s) - start )) s (qemu exit $qemu_rc)"

if [[ $qemu_rc -eq 124 || $qemu_rc -eq 137 ]]; then
  log "FAIL: the VM did not finish within ${TIMEOUT} s"
  exit 1
fi
result=$(grep -a -oE 'FLEETGW-VM-RESULT rc=[0-9]+' "$CONSOLE" | tail -n1 | cut -d= -f2 || true)
if [[ -z $result ]]; then
  log "FAIL: no result marker on the VM console (kernel or init failure?); last lines:"
  tail -n 20 "$CONSOLE" >&2
  exit 1
fi
if [[ $result -ne 0 ]]; then
  log "FAIL: socketcan_vm_tests exited with $result inside the VM"
  exit 1
fi
if grep -a -q '\[  SKIPPED \]' "$CONSOLE"; then
  log "note: some tests skipped inside the VM:"
  grep -a '\[  SKIPPED \]' "$CONSOLE" >&2 || true
fi
log "PASS"
exit 0
