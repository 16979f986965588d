#!/usr/bin/env bash
# Builds a cross-compilation sysroot from Debian 12 packages of the target architecture, without
# installing anything into the host: the dependency closure of the project's -dev packages (plus any
# extra packages named on the command line) is fetched with `apt-get download` and unpacked with
# `dpkg -x`. Why not `apt-get install libfoo-dev:arm64`: Multi-Arch: same libraries must have the same
# version for every architecture, and a mirror whose arm64/armhf indexes lag the host's (seen: liblzma5,
# linux-libc-dev) makes that install impossible. docs/cross-build.md explains the whole setup.
#
# Usage: scripts/sysroot.sh <arm64|armhf> [extra-package...]
#   -> build/sysroots/<triplet>/            the sysroot (aarch64-linux-gnu, arm-linux-gnueabihf)
#      build/sysroots/<triplet>/.complete   stamp: the extra packages asked for, then every .deb unpacked
#      build/sysroots/debs-<arch>/          the downloaded .deb cache
# Extra packages accumulate: a later call without them keeps them (delete the sysroot to drop them).
# A run whose package set and versions match the stamp does nothing. Needs the foreign architecture
# (scripts/bootstrap.sh cross does `dpkg --add-architecture`); downloads need no root, an index refresh
# (apt-get update) uses sudo when not root.
set -euo pipefail

die() {
  echo "sysroot: error: $*" >&2
  exit 1
}
say() { echo "sysroot: $*"; }

arch="${1:-}"
case "$arch" in
  arm64 | aarch64) arch=arm64 triplet=aarch64-linux-gnu ;;
  armhf) triplet=arm-linux-gnueabihf ;;
  *) die "usage: scripts/sysroot.sh <arm64|armhf> [extra-package...]" ;;
esac
shift
requested_extra=("$@")

# The project's build and test dependencies for the target (the cross compiler brings its own
# libstdc++ headers and libgcc; libstdc++6 is the runtime the test binaries load under qemu-user).
BASE=(libspdlog-dev libfmt-dev libkissfft-dev libgpiod-dev libsystemd-dev libtomlplusplus-dev
  libgtest-dev libgmock-dev zlib1g-dev libc6-dev libstdc++6 libeigen3-dev libmosquitto-dev)

root="$(cd "$(dirname "$0")/.." && pwd)"
top="${PTDA_SYSROOTS_DIR:-$root/build/sysroots}"
sysroot="$top/$triplet"
cache="$top/debs-$arch"
stamp="$sysroot/.complete"
mkdir -p "$top" "$cache"

for tool in apt-get apt-cache dpkg dpkg-deb flock realpath; do
  command -v "$tool" > /dev/null || die "'$tool' not found (a Debian host with apt and dpkg is required)"
done
host_arch="$(dpkg --print-architecture)"
# (Captured first: `dpkg ... | grep -q` under pipefail fails now and then, when grep exits before dpkg
# has written everything and dpkg dies of SIGPIPE.)
foreign_archs="$(dpkg --print-foreign-architectures)"
if [ "$arch" != "$host_arch" ] && ! grep -qx "$arch" <<< "$foreign_archs"; then
  die "dpkg does not know the foreign architecture '$arch'; run: scripts/bootstrap.sh cross  (or: sudo dpkg --add-architecture $arch && sudo apt-get update)"
fi

# One run at a time per sysroot (several scripts and people share the tree).
exec 9> "$top/.$triplet.lock"
flock 9

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
APT_OPTS=(-q)
# As root apt drops to user _apt for downloads, which cannot write into our cache: say so up front
# instead of the per-file "unsandboxed" warning.
if [ "$(id -u)" -eq 0 ]; then APT_OPTS+=(-o APT::Sandbox::User=root); fi

updated="${PTDA_SYSROOT_UPDATED:-0}"  # set when this script re-ran itself after an update
apt_update() {
  [ "$updated" -eq 0 ] || return 0
  updated=1
  say "refreshing the package indexes (apt-get update)"
  # A mirror mid-sync can fail one index (seen: bookworm-security armhf, "File has unexpected size");
  # the others are still usable, and a package that is really missing fails below with its name.
  if ! $SUDO apt-get update -qq; then
    echo "sysroot: warning: apt-get update reported errors (see above); continuing with the indexes it got" >&2
  fi
}

# The names to resolve: architecture-all packages (libeigen3-dev, googletest...) go by their plain
# name, everything else as name:<arch>.
qualify() {  # names... -> qualified names on stdout
  local info
  info="$(apt-cache show --no-all-versions "$@" 2> /dev/null |
    awk '/^Package:/ {p = $2} /^Architecture:/ {print p, $2}')" || true
  local n a
  for n in "$@"; do
    a="$(awk -v n="$n" '$1 == n {print $2; exit}' <<< "$info")"
    if [ "$a" = all ]; then echo "$n"; else echo "$n:$arch"; fi
  done
}

# Extras recorded by earlier runs stay in.
extra=()
if [ -f "$stamp" ]; then
  read -r -a extra <<< "$(sed -n 's/^# extra: *//p' "$stamp" | head -n1)"
fi
for p in "${requested_extra[@]}"; do
  [[ " ${extra[*]} " == *" $p "* ]] || extra+=("$p")
done
mapfile -t extra < <(printf '%s\n' "${extra[@]}" | sed '/^$/d' | sort -u)

# Fast path: resolving the closure costs several apt calls (seconds); when the package indexes and the
# names asked for are those of the last successful run, the sysroot is up to date.
index_key() {
  {
    echo "${BASE[*]} | ${extra[*]}"
    find /var/lib/apt/lists -maxdepth 1 -name "*_binary-${arch}_Packages*" -printf '%f %s %T@\n' | sort
  } | sha256sum | cut -d' ' -f1
}
key_file="$top/.$triplet.key"
key="$(index_key)"
if [ -f "$stamp" ] && [ -f "$key_file" ] && [ "$(cat "$key_file")" = "$key" ]; then
  say "$sysroot is up to date ($(grep -vc '^#' "$stamp") packages; indexes unchanged)"
  exit 0
fi

resolve() {  # -> sets $plan: "file uri size" lines of every .deb to unpack, sorted by file
  local wanted deps_err
  mapfile -t wanted < <(qualify "${BASE[@]}" "${extra[@]}")
  deps_err="$(mktemp)"
  local closure
  if ! closure="$(apt-cache depends --recurse --no-recommends --no-suggests --no-conflicts --no-breaks \
    --no-replaces --no-enhances "${wanted[@]}" 2> "$deps_err")"; then
    local msg
    msg="$(cat "$deps_err")"
    rm -f "$deps_err"
    echo "$msg" >&2
    return 1
  fi
  rm -f "$deps_err"
  # Real packages of the target architecture, and plain names (architecture all or the host's: the
  # .deb file name tells, below). <name> lines are virtual packages; their providers are listed too.
  local names
  mapfile -t names < <(grep -v '^ ' <<< "$closure" | grep -v '^<' |
    awk -v a="$arch" -F: 'NF == 1 || $2 == a' | sort -u)
  local uris
  uris="$(apt-get download --print-uris "${names[@]}" 2>&1)" || {
    echo "$uris" >&2
    return 1
  }
  plan="$(sed -n "s/^'\([^']*\)' \([^ ]*\) \([0-9]*\) .*/\2 \1 \3/p" <<< "$uris" |
    grep -E "_($arch|all)\.deb " | sort -u)"
  [ -n "$plan" ] || {
    echo "no packages resolved for $arch" >&2
    return 1
  }
}

plan=""
if ! resolve 2> "$top/.resolve-$arch.err"; then
  say "could not resolve the packages from the current indexes:"
  sed 's/^/  /' "$top/.resolve-$arch.err" >&2
  apt_update
  resolve 2> "$top/.resolve-$arch.err" || {
    sed 's/^/  /' "$top/.resolve-$arch.err" >&2
    die "cannot resolve the $arch packages (the lines above name the package apt could not find)"
  }
fi
rm -f "$top/.resolve-$arch.err"

new_stamp="$(
  echo "# ptda sysroot $arch ($triplet), made by scripts/sysroot.sh"
  echo "# extra: ${extra[*]}"
  cut -d' ' -f1 <<< "$plan"
)"
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$new_stamp" ]; then
  say "$sysroot is up to date ($(grep -vc '^#' "$stamp") packages)"
  index_key > "$key_file"
  exit 0
fi

# Download what the cache lacks. apt-get download takes name:arch=version; the file name carries both
# (the epoch's ':' is written %3a).
download() {  # file... -> downloads into $cache; returns non-zero and names the failing packages
  local specs=() f base name ver a
  for f in "$@"; do
    base="${f%.deb}"
    name="${base%%_*}"
    a="${base##*_}"
    ver="${base#*_}"
    ver="${ver%_*}"
    ver="${ver//%3a/:}"
    if [ "$a" = all ]; then specs+=("$name=$ver"); else specs+=("$name:$a=$ver"); fi
  done
  (cd "$cache" && apt-get "${APT_OPTS[@]}" download "${specs[@]}") && return 0
  # Find out which ones failed, one by one, so the message names them.
  local failed=()
  local s
  for s in "${specs[@]}"; do
    (cd "$cache" && apt-get "${APT_OPTS[@]}" download "$s" > /dev/null 2>&1) || failed+=("$s")
  done
  [ ${#failed[@]} -eq 0 ] && return 0
  echo "sysroot: download failed for: ${failed[*]}" >&2
  return 1
}

missing=()
while read -r file _ size; do
  if [ -f "$cache/$file" ] && [ "$(stat -c %s "$cache/$file")" = "$size" ]; then continue; fi
  rm -f "$cache/$file"
  missing+=("$file")
done <<< "$plan"
if [ ${#missing[@]} -gt 0 ]; then
  say "downloading ${#missing[@]} of $(wc -l <<< "$plan") packages into $cache"
  if ! download "${missing[@]}"; then
    # A stale index points at files the mirror no longer has: refresh once and start over.
    if [ "$updated" -eq 0 ]; then
      apt_update
      exec 9>&-
      PTDA_SYSROOT_UPDATED=1 exec "$0" "$arch" "${extra[@]}"
    fi
    die "could not download the packages named above (is the mirror reachable? 'apt-get download <pkg>' shows apt's own message)"
  fi
fi

# Only packages added (new extras, same versions of everything else): unpack them into the sysroot in
# place. Anything else: unpack into a fresh directory next to the old one, then swap, so a build using
# the old sysroot never sees a half-unpacked or half-removed tree.
to_unpack="$plan"
tmp="$top/.$triplet.new"
incremental=0
if [ -f "$stamp" ] && [ -d "$sysroot" ]; then
  if [ -z "$(comm -23 <(grep -v '^#' "$stamp" | sort) <(cut -d' ' -f1 <<< "$plan"))" ]; then
    incremental=1
    tmp="$sysroot"
    to_unpack="$(grep -v -x -F -f <(grep -v '^#' "$stamp") <(cut -d' ' -f1 <<< "$plan") || true)"
  fi
fi
if [ $incremental -eq 0 ]; then
  rm -rf "$tmp"
  mkdir -p "$tmp"
fi
say "unpacking $(grep -c . <<< "$to_unpack") packages into $sysroot$([ $incremental -eq 1 ] && echo " (adding to it)")"
while read -r file _; do
  [ -n "$file" ] || continue
  dpkg-deb -x "$cache/$file" "$tmp" || die "cannot unpack $cache/$file (delete it and re-run)"
done <<< "$to_unpack"

# Absolute symlinks (libz.so -> /lib/<triplet>/libz.so.1...) would point into the host: make them
# relative so they resolve inside the sysroot, wherever it lives.
fixed=0
while IFS= read -r -d '' link; do
  target="$(readlink "$link")"
  rel="$(realpath -m -s --relative-to="$(dirname "$link")" "$tmp$target")"
  ln -sfn "$rel" "$link"
  fixed=$((fixed + 1))
done < <(find "$tmp" -type l -lname '/*' -print0)

# Sanity: what the compiler, the linker and qemu-user need.
for f in "usr/lib/$triplet/crt1.o" "usr/lib/$triplet/libc.so" "usr/include/stdio.h" \
  "lib/$triplet/libc.so.6"; do
  [ -e "$tmp/$f" ] || die "unpacked sysroot lacks /$f (libc6-dev:$arch incomplete?)"
done

echo "$new_stamp" > "$tmp/.complete"
if [ $incremental -eq 0 ]; then
  old="$top/.$triplet.old"
  rm -rf "$old"
  if [ -d "$sysroot" ]; then mv "$sysroot" "$old"; fi
  mv "$tmp" "$sysroot"
  rm -rf "$old"
fi
index_key > "$key_file"
say "done: $sysroot ($(wc -l <<< "$plan") packages, $fixed absolute symlinks made relative, extra: ${extra[*]:-none})"
