#!/usr/bin/env bash
# ptdad against real Linux kernels: boots Debian 12's own kernel under qemu (software emulation, TCG) with
# a small initramfs, runs ptdad on SocketCAN (vcan0) and, on aarch64, on the PL061 GPIO chip of qemu's
# virt machine, and checks the verdict frames on the bus (and the GPIO line) against the recording's
# fault onset. What each test does and asserts, and the measured numbers: docs/vm-tests.md.
#
# Usage: scripts/vm_test.sh <x86_64|aarch64|all>
# Needs (scripts/bootstrap.sh base cross vm): qemu-system-x86, qemu-system-arm, busybox-static, cpio,
# iproute2, can-utils, gpiod, dpkg-dev, apt with the arm64 architecture added, the aarch64 cross compiler.
# Environment:
#   PTDA_VM_TIMEOUT_S   kill a guest after this many seconds (default 180)
#   PTDA_SYSROOTS_DIR   where scripts/sysroot.sh keeps the arm64 sysroot (default build/sysroots)
#   PTDA_VM_KEEP=1      keep the guests' initramfs trees
#   PTDA_VM_HOST_BUILD, PTDA_VM_AARCH64_BUILD   build directories to take ptda/ptdad from (default
#                       build/release and build/aarch64-release when newer than every source file, else
#                       our own build/h-vm and build/h-vm-aarch64)
# Outputs: build/vm/<arch>/ (serial.log, the files the guest sent back in out/, result.txt).
set -euo pipefail

root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
vm="$root/build/vm"
cache="$vm/cache"
timeout_s="${PTDA_VM_TIMEOUT_S:-180}"
sysroots="${PTDA_SYSROOTS_DIR:-$root/build/sysroots}"

say() { echo "vm_test: $*"; }
die() {
  echo "vm_test: FAIL: $*" >&2
  exit 1
}
need() {  # command package [why]
  command -v "$1" > /dev/null 2>&1 ||
    die "'$1' not found: install the Debian package '$2'${3:+ ($3)} (scripts/bootstrap.sh vm does it)"
}

case "${1:-}" in
  x86_64) arches=(x86_64) ;;
  aarch64) arches=(aarch64) ;;
  all) arches=(x86_64 aarch64) ;;
  *)
    echo "usage: scripts/vm_test.sh <x86_64|aarch64|all>" >&2
    exit 2
    ;;
esac

for t in cpio gzip base64 readelf dpkg-deb apt-get apt-cache awk timeout cmake; do
  case "$t" in
    cpio) need cpio cpio ;;
    readelf) need readelf binutils "it lists the libraries the guest binaries need" ;;
    dpkg-deb) need dpkg-deb dpkg ;;
    apt-get | apt-cache) need "$t" apt "the kernels come from Debian's archive" ;;
    *) need "$t" coreutils ;;
  esac
done
mkdir -p "$vm" "$cache"

# ---------------------------------------------------------------- the binaries
# A build another stage made (the CI's release and aarch64 stages) is used when it is newer than every
# source file; otherwise (or when absent) we build our own copy, incrementally.
newest_source="$(find CMakeLists.txt cmake common config dsp formats sim drivers daemon cli gap \
  -type f \( -name '*.cpp' -o -name '*.hpp' -o -name '*.h' -o -name CMakeLists.txt -o -name '*.cmake' \) \
  -printf '%T@\n' 2> /dev/null | sort -g | tail -n 1)"
fresh() {  # binary... -> 0 when each exists and is newer than every source file
  local b
  for b in "$@"; do
    [ -x "$b" ] || return 1
    awk -v b="$(stat -c %Y "$b")" -v s="${newest_source:-0}" 'BEGIN {exit !(b >= s)}' || return 1
  done
}
build_own() {  # dir log what cmake-args... -- targets...
  local dir="$1" log="$2" what="$3"
  shift 3
  local args=()
  while [ "$1" != -- ]; do
    args+=("$1")
    shift
  done
  shift
  say "building $* in ${dir#"$root"/}"
  {
    cmake -S . -B "$dir" -DPTDA_WERROR=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo -DPTDA_BUILD_TESTS=OFF "${args[@]}" &&
      cmake --build "$dir" -j2 --target "$@"
  } > "$log" 2>&1 || {
    tail -n 30 "$log" >&2
    die "$what failed (log: $log)"
  }
}
# Host: ptda (recording, baseline, reference) and the x86_64 guest's ptdad.
host_build="${PTDA_VM_HOST_BUILD:-$root/build/release}"
if ! fresh "$host_build/cli/ptda" "$host_build/daemon/ptdad"; then
  host_build="$root/build/h-vm"
  build_own "$host_build" "$vm/build-host.log" "the host build" -- ptda ptdad
fi
ptda="$host_build/cli/ptda"
say "host ptda/ptdad: ${host_build#"$root"/}"

# ---------------------------------------------------------------- the recording and the baseline
rec="$vm/rec"
tests/vm/make_recording.sh "$ptda" "$rec" > "$vm/recording.log" 2>&1 || {
  cat "$vm/recording.log" >&2
  die "could not make the test recording (tests/vm/make_recording.sh)"
}
say "$(tail -n 1 "$vm/recording.log")"
# The windows `ptda monitor` cuts and judges on the host: the reference for the daemon in the guest.
"$ptda" monitor --recording "$rec/recording" --config config/examples/joint_rotation.toml \
  --baseline "$rec/baseline.bin" --jsonl "$rec/host.jsonl" --quiet > "$rec/host_monitor.txt" 2>&1 ||
  die "ptda monitor failed on the test recording: $(cat "$rec/host_monitor.txt")"

# dpkg's architecture list, asked for up to 30 s: a dpkg run elsewhere on the machine (a package
# install/remove test) hid it for several seconds at a time here.
has_arm64() {
  local _
  for _ in $(seq 1 15); do
    dpkg --print-foreign-architectures 2> /dev/null | grep -qx arm64 && return 0
    sleep 2
  done
  return 1
}

# ---------------------------------------------------------------- kernels
# Debian's kernel image package: the one linux-image-<arch> depends on (the version moves with security
# updates), fetched with apt-get download, only vmlinuz and the four CAN modules unpacked.
fetch_kernel() {  # debarch -> sets kdir
  local debarch="$1" meta pkg deb
  if [ "$debarch" = amd64 ]; then meta=linux-image-amd64; else meta="linux-image-$debarch:$debarch"; fi
  pkg="$(apt-cache depends "$meta" 2> /dev/null | awk '/Depends: linux-image-[0-9]/ {print $2; exit}')"
  if [ -z "$pkg" ]; then
    if [ "$debarch" != amd64 ] && ! has_arm64; then
      die "apt does not know the $debarch architecture, so the $debarch kernel cannot be downloaded: run scripts/bootstrap.sh vm (dpkg --add-architecture $debarch && apt-get update)"
    fi
    die "apt-cache depends $meta names no kernel image package (run apt-get update; is $meta in the configured Debian 12 sources?)"
  fi
  pkg="${pkg%%:*}"
  deb="$(ls "$cache/${pkg}_"*"_$debarch.deb" 2> /dev/null | head -n 1 || true)"
  if [ -z "$deb" ]; then
    say "downloading $pkg ($debarch)"
    local opts=(-q)
    [ "$(id -u)" -ne 0 ] || opts+=(-o APT::Sandbox::User=root)
    (cd "$cache" && apt-get "${opts[@]}" download "$pkg:$debarch") > "$cache/download-$pkg.log" 2>&1 ||
      die "apt-get download $pkg:$debarch failed: $(tail -n 3 "$cache/download-$pkg.log")"
    deb="$(ls "$cache/${pkg}_"*"_$debarch.deb" | head -n 1)"
  fi
  kdir="$vm/kernel/$pkg"
  # .complete-2: the module list grew (can-bcm); an older unpacking is redone.
  if [ ! -f "$kdir/.complete-2" ]; then
    rm -rf "$kdir"
    mkdir -p "$kdir"
    dpkg-deb --fsys-tarfile "$deb" | tar -x -C "$kdir" --wildcards './boot/vmlinuz-*' \
      './lib/modules/*/kernel/net/can/can.ko*' './lib/modules/*/kernel/net/can/can-raw.ko*' \
      './lib/modules/*/kernel/net/can/can-bcm.ko*' \
      './lib/modules/*/kernel/drivers/net/can/dev/can-dev.ko*' './lib/modules/*/kernel/drivers/net/can/vcan.ko*' ||
      die "cannot unpack vmlinuz and the CAN modules from $deb"
    # x86_64: the uncompressed kernel boots in about a third of the time (the xz decompressor is slow
    # under emulation: 15-17 s to /init with vmlinuz, 5-6 s with vmlinux). qemu starts an ELF vmlinux
    # through its PVH entry note, which Debian's kernel has (CONFIG_PVH=y).
    if [ "$debarch" = amd64 ]; then
      local z off
      z="$(ls "$kdir"/boot/vmlinuz-* | head -n 1)"
      off="$(LC_ALL=C grep -obUaP '\xfd7zXZ\x00' "$z" | head -n 1 | cut -d: -f1)"
      if [ -n "$off" ] && tail -c +$((off + 1)) "$z" | xz -dc > "$kdir/boot/vmlinux" 2> /dev/null ||
        [ -s "$kdir/boot/vmlinux" ]; then
        readelf -nW "$kdir/boot/vmlinux" 2> /dev/null | grep -q 'Xen.*(0x00000012)' || rm -f "$kdir/boot/vmlinux"
      else
        rm -f "$kdir/boot/vmlinux"
      fi
      [ -s "$kdir/boot/vmlinux" ] || say "note: no PVH vmlinux from $z (xz missing?); booting vmlinuz (slower)"
    fi
    touch "$kdir/.complete-2"
  fi
  kver="${pkg#linux-image-}"
}

# ---------------------------------------------------------------- initramfs
# copy_elf ROOT TRIPLET DEST PROGRAM...: copies each PROGRAM to DEST/usr/bin, with its interpreter and
# every shared library it needs, recursively (readelf's NEEDED entries, searched under ROOT the way the
# target's ld.so searches its multiarch directories), each library at its own path under ROOT.
copy_elf() {
  local sroot="$1" triplet="$2" dest="$3"
  shift 3
  local queue=() done_list=" " f rel interp lib p found
  for f in "$@"; do
    [ -e "$f" ] || die "$f not found"
    cp -L "$f" "$dest/usr/bin/$(basename "$f")"
    queue+=("$f")
  done
  while [ ${#queue[@]} -gt 0 ]; do
    f="${queue[0]}"
    queue=("${queue[@]:1}")
    case "$done_list" in *" $f "*) continue ;; esac
    done_list+="$f "
    case "$f" in
      "$sroot"/lib/* | "$sroot"/usr/lib/*)
        rel="${f#"$sroot"}"
        mkdir -p "$dest$(dirname "$rel")"
        cp -L "$f" "$dest$rel"
        ;;
    esac
    interp="$(readelf -lW "$f" 2> /dev/null | sed -n 's/.*Requesting program interpreter: \(.*\)]/\1/p')"
    if [ -n "$interp" ] && [ ! -e "$dest$interp" ]; then
      [ -e "$sroot$interp" ] || die "$f: interpreter $interp not found under ${sroot:-/}"
      mkdir -p "$dest$(dirname "$interp")"
      cp -L "$sroot$interp" "$dest$interp"
    fi
    for lib in $(readelf -dW "$f" 2> /dev/null | sed -n 's/.*(NEEDED).*\[\(.*\)\]/\1/p'); do
      found=""
      for p in "$sroot/lib/$triplet" "$sroot/usr/lib/$triplet" "$sroot/lib" "$sroot/usr/lib"; do
        if [ -e "$p/$lib" ]; then
          found="$p/$lib"
          break
        fi
      done
      [ -n "$found" ] || die "$f needs $lib, not found under ${sroot:-/}{,usr/}lib/$triplet"
      queue+=("$found")
    done
  done
}

make_initramfs() {  # arch sroot triplet busybox ptdad gpio(0|1) -> $work/initrd.cpio
  local arch="$1" sroot="$2" triplet="$3" busybox="$4" ptdad="$5" gpio="$6"
  local img="$work/root"
  rm -rf "$img"
  mkdir -p "$img"/{bin,sbin,usr/bin,usr/sbin,lib/modules,proc,sys,dev,tmp,run,test/conf.d}
  cp "$busybox" "$img/bin/busybox"
  # The applets of busybox-static (same version for both architectures in Debian 12).
  local a
  for a in $(busybox --list); do
    [ -e "$img/bin/$a" ] || ln -s busybox "$img/bin/$a"
  done
  local tools=()
  local t
  for t in ip candump cansend; do
    for p in "$sroot/usr/bin/$t" "$sroot/usr/sbin/$t" "$sroot/bin/$t" "$sroot/sbin/$t"; do
      if [ -e "$p" ] && [ ! -L "$p" ]; then
        tools+=("$p")
        break
      fi
    done
  done
  if [ "$gpio" = 1 ]; then
    for t in gpioinfo gpioget gpiodetect; do tools+=("$sroot/usr/bin/$t"); done
  fi
  [ ${#tools[@]} -ge 3 ] || die "iproute2's ip and can-utils' candump and cansend not all found under ${sroot:-/}"
  copy_elf "$sroot" "$triplet" "$img" "${tools[@]}" "$ptdad"
  cp "$work/canreplay" "$img/usr/bin/canreplay"
  if [ "$gpio" = 1 ]; then cp "$work/gpiowatch" "$img/usr/bin/gpiowatch"; fi
  local m
  for m in can can-raw can-bcm can-dev vcan; do
    local ko
    ko="$(find "$kdir/lib/modules" -name "$m.ko" | head -n 1)"
    [ -n "$ko" ] || die "$m.ko not in $kdir (compressed modules? the test expects plain .ko files)"
    cp "$ko" "$img/lib/modules/"
  done
  cp tests/vm/init.sh "$img/init"
  chmod 755 "$img/init"
  ln -sf busybox "$img/bin/sh"
  cp -r "$rec/recording" "$img/test/recording"
  cp "$rec/baseline.bin" "$img/test/baseline.bin"
  cp config/examples/joint_rotation.toml "$img/test/joint_rotation.toml"
  sed -e "s/@GPIO_ENABLED@/$([ "$gpio" = 1 ] && echo true || echo false)/" -e "s/@GPIO_LINE@/$gpio_line/" \
    tests/vm/ptdad-vm.toml > "$img/test/conf.d/10-vm.toml"
  cat > "$img/test/test.env" << EOF
GPIO=$gpio
GPIO_LINE=$gpio_line
GPIO_POLL_US=2000
LOG_IFACE=$(awk 'NR == 1 {print $2}' "$rec/recording/can.log")
START_UNIX=$(grep START_UNIX "$rec/truth.env" | cut -d= -f2)
ALARM_ID=3A0
CLEAR_FRAME=3A1#C1
CLEAR_FROM_S=$clear_from_s
CLEAR_PERIOD_S=1
PTDAD_LIMIT_S=$(awk -v e="$(grep END_UNIX "$rec/truth.env" | cut -d= -f2)" \
    -v s="$(grep START_UNIX "$rec/truth.env" | cut -d= -f2)" 'BEGIN {printf "%d", (e - s) * 2 + 20}')
EOF
  # Not compressed: the kernel would decompress it under emulation, which costs more than loading it.
  (cd "$img" && find . | LC_ALL=C sort | cpio -o -H newc --quiet) > "$work/initrd.cpio"
}

# ---------------------------------------------------------------- one guest
gpio_line=3
# Clear frames start once the alarm has been latched for a while (the condition is still there: refused)
# and go on every second; the first accepted one comes after the repaired part began and k-of-n went off.
clear_from_s=$(awk -v o="$(grep ONSET_UNIX "$rec/truth.env" | cut -d= -f2)" \
  -v s="$(grep START_UNIX "$rec/truth.env" | cut -d= -f2)" 'BEGIN {printf "%d", o - s + 8}')

run_guest() {  # arch
  local arch="$1"
  work="$vm/$arch"
  rm -rf "$work"
  mkdir -p "$work/out"
  local t_start debarch qemu sroot triplet busybox ptdad gpio console cc strip
  t_start=$(date +%s.%N)
  case "$arch" in
    x86_64)
      need qemu-system-x86_64 qemu-system-x86
      need busybox busybox-static
      need candump can-utils
      need ip iproute2
      debarch=amd64 sroot="" triplet=x86_64-linux-gnu gpio=0 console=ttyS0
      busybox="$(command -v busybox)"
      ! readelf -lW "$busybox" 2> /dev/null | grep -q 'program interpreter' ||
        die "$busybox is not statically linked: install busybox-static (the guest has no libraries for it)"
      ptdad="$host_build/daemon/ptdad"
      need gcc build-essential
      cc=gcc
      strip='strip'
      qemu=(qemu-system-x86_64 -cpu max -m 512 -smp 2)
      ;;
    aarch64)
      need qemu-system-aarch64 qemu-system-arm
      need aarch64-linux-gnu-gcc gcc-aarch64-linux-gnu "the cross compiler: scripts/bootstrap.sh cross"
      need busybox busybox-static "its applet list"
      debarch=arm64 triplet=aarch64-linux-gnu gpio=1 console=ttyAMA0
      has_arm64 ||
        die "dpkg has no arm64 architecture: the arm64 kernel and target tools cannot be downloaded (scripts/bootstrap.sh vm)"
      say "arm64 sysroot with the guest's tools (scripts/sysroot.sh arm64 iproute2 can-utils gpiod busybox-static)"
      # Once more after a pause when it fails: its check of dpkg's architectures can meet a dpkg run.
      {
        PTDA_SYSROOTS_DIR="$sysroots" scripts/sysroot.sh arm64 iproute2 can-utils gpiod busybox-static ||
          { sleep 20 && PTDA_SYSROOTS_DIR="$sysroots" scripts/sysroot.sh arm64 iproute2 can-utils gpiod busybox-static; }
      } > "$vm/sysroot-arm64.log" 2>&1 || {
        tail -n 20 "$vm/sysroot-arm64.log" >&2
        die "scripts/sysroot.sh arm64 failed (log: $vm/sysroot-arm64.log)"
      }
      sroot="$sysroots/aarch64-linux-gnu"
      busybox="$sroot/bin/busybox"
      [ -x "$busybox" ] || die "$busybox missing after scripts/sysroot.sh (busybox-static:arm64)"
      local xbuild="${PTDA_VM_AARCH64_BUILD:-$root/build/aarch64-release}"
      if ! fresh "$xbuild/daemon/ptdad"; then
        xbuild="$root/build/h-vm-aarch64"
        build_own "$xbuild" "$vm/build-aarch64.log" "the aarch64 cross build of ptdad" \
          -DCMAKE_TOOLCHAIN_FILE="$root/toolchains/aarch64-linux-gnu.cmake" -DPTDA_SYSROOT="$sroot" -- ptdad
      fi
      say "aarch64 ptdad: ${xbuild#"$root"/}"
      ptdad="$xbuild/daemon/ptdad"
      cc=aarch64-linux-gnu-gcc
      strip=aarch64-linux-gnu-strip
      qemu=(qemu-system-aarch64 -M virt -cpu cortex-a53 -m 512 -smp 2)
      ;;
  esac
  # The guest's two helpers, static: canreplay (the CAN log on the daemon's timeline), gpiowatch.
  "$cc" -static -O2 -Wall -Wextra -Werror -o "$work/canreplay" tests/vm/canreplay.c ||
    die "cannot build tests/vm/canreplay.c with $cc -static"
  if [ "$gpio" = 1 ]; then
    "$cc" -static -O2 -Wall -Wextra -Werror -o "$work/gpiowatch" tests/vm/gpiowatch.c ||
      die "cannot build tests/vm/gpiowatch.c with $cc -static"
  fi
  # Without its debug information (RelWithDebInfo: 22 MB -> 3 MB): a smaller initramfs boots faster.
  "$strip" --strip-debug -o "$work/ptdad" "$ptdad" || die "$strip failed on $ptdad"
  fetch_kernel "$debarch"
  make_initramfs "$arch" "$sroot" "$triplet" "$busybox" "$work/ptdad" "$gpio"
  local vmlinuz
  vmlinuz="$(ls "$kdir"/boot/vmlinux "$kdir"/boot/vmlinuz-* 2> /dev/null | head -n 1)"
  local t_prep
  t_prep=$(date +%s.%N)
  say "$arch: booting $kver (initramfs $(du -k "$work/initrd.cpio" | cut -f1) KiB), timeout ${timeout_s} s"
  # Each line of the serial console with the host's arrival time (boot-to-READY from qemu's start).
  local t_qemu rc=0
  t_qemu=$(date +%s.%N)
  set +e
  timeout --kill-after=5 "$timeout_s" "${qemu[@]}" -accel tcg -nographic -no-reboot -kernel "$vmlinuz" \
    -initrd "$work/initrd.cpio" -append "console=$console quiet panic=-1" < /dev/null 2>&1 |
    while IFS= read -r line; do printf '%s %s\n' "$EPOCHREALTIME" "${line%$'\r'}"; done > "$work/serial.log"
  rc=${PIPESTATUS[0]}
  set -e
  local t_end
  t_end=$(date +%s.%N)
  [ "${PTDA_VM_KEEP:-0}" = 1 ] || rm -rf "$work/root"
  # The files the guest sent between "@@VM BEGIN name" and "@@VM END name" (gzip + base64).
  awk -v dir="$work/out" '
    { sub(/^[0-9.]+ /, "") }
    /^@@VM BEGIN / { name = $3; file = dir "/" name ".b64"; printf "" > file; next }
    /^@@VM END / { close(file); name = ""; next }
    name != "" { print >> file }' "$work/serial.log"
  local f
  for f in "$work"/out/*.b64; do
    [ -e "$f" ] || continue
    if [ -s "$f" ]; then base64 -d "$f" 2> /dev/null | gunzip -c > "${f%.b64}" 2> /dev/null || true; fi
    rm -f "$f"
  done
  {
    echo "ARCH=$arch"
    echo "KERNEL=$kver"
    echo "QEMU_RC=$rc"
    echo "T_SCRIPT_START=$t_start"
    echo "T_QEMU_START=$t_qemu"
    echo "T_PREP_END=$t_prep"
    echo "T_END=$t_end"
  } > "$work/run.env"
  if [ "$rc" = 124 ] || [ "$rc" = 137 ]; then
    echo "qemu killed after the ${timeout_s} s limit (PTDA_VM_TIMEOUT_S)" > "$work/timeout"
  fi
  tests/vm/analyze.sh "$work" "$rec" "$ptda" config/examples/joint_rotation.toml > "$work/result.txt" 2>&1 || true
  cat "$work/result.txt"
  grep -q '^PASS' "$work/result.txt"
}

status=0
for a in "${arches[@]}"; do
  if ! run_guest "$a"; then status=1; fi
done
if [ $status -eq 0 ]; then say "PASS (${arches[*]})"; else say "FAIL (see build/vm/<arch>/result.txt and serial.log)"; fi
exit $status
