#!/usr/bin/env bash
# Installs the Debian 12 packages ptda builds and tests with. Idempotent: apt runs only when something
# is missing. Needs root (or sudo) on a fresh machine; nothing is downloaded from outside Debian.
# Usage: scripts/bootstrap.sh [base] [cross] [vm] [pkg] [fuzz]     (base is always included)
#   base  - includes chromium: the report test renders `ptda report` headless (ctest -L report), and
#           prometheus for promtool (the fleet rules and textfile checks, ctest -L fleet)
#   cross - aarch64/armhf cross compilers, qemu-user, the foreign architectures for apt-get download
#           (the target libraries go into a sysroot: scripts/sysroot.sh)
#   vm    - qemu-system for the x86_64 and aarch64 kernel tests, busybox, cpio
#   pkg   - what the .deb build and the install/upgrade/remove test need
#   fuzz  - clang and its libFuzzer runtime (scripts/fuzz.sh, tests/fuzz)
set -euo pipefail

BASE=(
  build-essential cmake pkgconf clang-format clang-tidy git
  libeigen3-dev libkissfft-dev libspdlog-dev libfmt-dev libtomlplusplus-dev zlib1g-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libgpiod-dev libsystemd-dev can-utils systemd
  libmosquitto-dev mosquitto mosquitto-clients openssl
  python3-numpy
  chromium
  prometheus
)
CROSS=(g++-aarch64-linux-gnu g++-arm-linux-gnueabihf qemu-user dpkg-dev)
VM=(qemu-system-x86 qemu-system-arm busybox-static cpio iproute2 can-utils gpiod dpkg-dev xz-utils)
PKG=(dpkg-dev fakeroot debootstrap file)
FUZZ=(clang-14 libclang-rt-14-dev)

groups=("$@")
packages=("${BASE[@]}")
foreign=()
for g in "${groups[@]}"; do
  case "$g" in
    base) ;;
    cross) packages+=("${CROSS[@]}"); foreign+=(arm64 armhf) ;;
    vm) packages+=("${VM[@]}"); foreign+=(arm64) ;;
    pkg) packages+=("${PKG[@]}") ;;
    fuzz) packages+=("${FUZZ[@]}") ;;
    *) echo "bootstrap: unknown group '$g' (base, cross, vm, pkg, fuzz)" >&2; exit 2 ;;
  esac
done
packages+=(${PTDA_EXTRA_PACKAGES:-})

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive

# Foreign architectures let `apt-get download pkg:arm64` work (scripts/sysroot.sh, the VM tests).
need_update=0
for a in "${foreign[@]}"; do
  if ! dpkg --print-foreign-architectures | grep -qx "$a"; then
    echo "bootstrap: dpkg --add-architecture $a"
    $SUDO dpkg --add-architecture "$a"
    need_update=1
  fi
done

missing=()
for p in "${packages[@]}"; do
  # Captured first: `dpkg-query | grep -q` under pipefail fails when grep's early exit SIGPIPEs dpkg.
  status="$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)"
  [ "$status" = "install ok installed" ] || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ] || [ $need_update -eq 1 ]; then
  # A mirror that is mid-sync can fail one foreign index (seen: bookworm-security armhf); the other
  # indexes are still usable, and a package that really is missing fails the install below.
  if ! $SUDO apt-get update -qq; then
    echo "bootstrap: warning: apt-get update reported errors (see above); continuing with the indexes it got" >&2
  fi
fi
if [ ${#missing[@]} -eq 0 ]; then
  echo "bootstrap: all ${#packages[@]} packages present"
  exit 0
fi
echo "bootstrap: installing ${missing[*]}"
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
