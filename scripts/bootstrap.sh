#!/usr/bin/env bash
# Installs the Debian 12 packages ptda builds and tests with. Idempotent: apt runs only when something
# is missing. Needs root (or sudo) on a fresh machine; nothing is downloaded from outside Debian.
set -euo pipefail

PACKAGES=(
  build-essential cmake pkgconf clang-format clang-tidy git
  libeigen3-dev libkissfft-dev libspdlog-dev libfmt-dev libtomlplusplus-dev zlib1g-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libgpiod-dev libsystemd-dev can-utils
  ${PTDA_EXTRA_PACKAGES:-}
)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "bootstrap: all ${#PACKAGES[@]} packages present"
  exit 0
fi
echo "bootstrap: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
