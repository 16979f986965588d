#!/usr/bin/env bash
# Cross-builds the unit suite for arm64 or armhf and runs it under qemu-user (docs/cross-build.md):
# the sysroot (scripts/sysroot.sh), then configure + build + ctest of the <arch>-release preset.
# Called by scripts/test.sh (stage aarch64; armhf on demand). Needs scripts/bootstrap.sh cross.
# Usage: scripts/cross_test.sh <aarch64|armhf|armhf-neon> [ctest args...]   e.g. -L dsp, -R Fft
#   PTDA_CROSS_JOBS  build and ctest parallelism (default: nproc)
#   PTDA_CROSS_GATEWAY_ONLY=1  build and run only the unit tests of the gateway's real-time path
#                    (not cli, gap, sim: scripts/test.sh's CI stage; default: the whole unit suite)
set -euo pipefail
cd "$(dirname "$0")/.."

die() {
  echo "cross_test: error: $*" >&2
  exit 1
}

target="${1:-}"
case "$target" in
  aarch64 | arm64) preset=aarch64-release deb_arch=arm64 triplet=aarch64-linux-gnu qemu=qemu-aarch64 ;;
  armhf) preset=armhf-release deb_arch=armhf triplet=arm-linux-gnueabihf qemu=qemu-arm ;;
  armhf-neon) preset=armhf-neon-release deb_arch=armhf triplet=arm-linux-gnueabihf qemu=qemu-arm ;;
  *) die "usage: scripts/cross_test.sh <aarch64|armhf|armhf-neon> [ctest args...]" ;;
esac
shift
jobs="${PTDA_CROSS_JOBS:-$(nproc 2> /dev/null || echo 2)}"

# What the build needs from the host, with the package that provides it.
missing=()
command -v "${triplet}-g++" > /dev/null || missing+=("${triplet}-g++ (package g++-${triplet})")
command -v "$qemu" > /dev/null || missing+=("$qemu (package qemu-user)")
command -v cmake > /dev/null || missing+=("cmake")
command -v pkg-config > /dev/null || missing+=("pkg-config (package pkgconf)")
if [ ${#missing[@]} -gt 0 ]; then
  die "missing on this host: ${missing[*]}; install with: scripts/bootstrap.sh cross"
fi

t0=$SECONDS
echo "=== cross_test $target: sysroot ==="
scripts/sysroot.sh "$deb_arch" || die "could not make the $deb_arch sysroot (scripts/sysroot.sh $deb_arch, message above)"
sysroot="$(realpath "${PTDA_SYSROOTS_DIR:-build/sysroots}")/$triplet"
[ -f "$sysroot/.complete" ] || die "$sysroot/.complete missing after scripts/sysroot.sh"

echo "=== cross_test $target: configure ($preset) ==="
mkdir -p "build/$preset"
# The sysroot just made, also when the build directory was configured with another one before.
all_tests=ON
[ "${PTDA_CROSS_GATEWAY_ONLY:-0}" = 1 ] && all_tests=OFF
cmake --preset "$preset" -DPTDA_SYSROOT="$sysroot" -DPTDA_CROSS_ALL_TESTS="$all_tests" > "build/$preset/cross_test-configure.log" 2>&1 || {
  cat "build/$preset/cross_test-configure.log" >&2
  die "configure of preset $preset failed (log above)"
}

echo "=== cross_test $target: build (-j$jobs) ==="
t_build=$SECONDS
cmake --build --preset "$preset" -j "$jobs" || die "build of preset $preset failed"
build_s=$((SECONDS - t_build))

echo "=== cross_test $target: ctest under $qemu (-j$jobs) ==="
t_test=$SECONDS
log="build/$preset/cross_test-ctest.log"
set +e
ctest --preset "$preset" -j "$jobs" "$@" 2>&1 | tee "$log"
rc=${PIPESTATUS[0]}
set -e
test_s=$((SECONDS - t_test))

summary="$(grep -E '^[0-9]+% tests passed' "$log" | tail -n1)"
skipped="$(grep -c '\*\*\*Skipped\|Not Run (Disabled)' "$log" || true)"
echo "=== cross_test $target: ${summary:-no ctest summary}; skipped: $skipped;" \
  "build ${build_s} s, ctest ${test_s} s (-j$jobs), total $((SECONDS - t0)) s ==="
[ "$rc" -eq 0 ] || die "ctest failed under $qemu (rc $rc): see $log"
