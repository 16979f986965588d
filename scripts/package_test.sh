#!/usr/bin/env bash
# The Debian packages, built with CPack and put through their life cycle in a Debian 12 chroot
# (docs/packaging.md). Run as root (debootstrap, chroot, mounts): scripts/test.sh package.
#
# Usage: scripts/package_test.sh [build-dir]        (default build/release; configured and built if missing)
#
#  1. builds ptda and ptdad in build-dir and runs `cpack -G DEB` -> build-dir/packages/
#  2. checks the control fields: architecture, hand-written Depends against the binaries' DT_NEEDED and
#     against dpkg-shlibdeps (amd64); the same for the arm64/armhf packages of the cross build
#     directories when they exist (PTDA_PACKAGE_CROSS_DIRS, default build/aarch64-release
#     build/armhf-release; cpack is run there when their binaries are built)
#  3. a minbase bookworm chroot (debootstrap, cached in build/pkgtest/) without systemd:
#     install -> user made by the adduser fallback, check-config
#  4. a fresh copy with systemd (the path a robot takes): install with dependencies from the mirror,
#     files, owners, user, enablement, `ptdad --check-config`, `ptda --help`, a short daemon run;
#     then edit the conffile, add a drop-in and a fake baseline; upgrade (same conffile: no prompt;
#     changed conffile: --force-confold keeps the edit); remove (configuration and baseline kept);
#     reinstall; purge (conffile, baseline and enablement gone, user kept)
#
# Environment: PTDA_DEBIAN_MIRROR (default http://deb.debian.org/debian), PTDA_PKGTEST_DIR (default
# build/pkgtest), PTDA_JOBS (default nproc), PTDA_PKGTEST_REFRESH=1 (rebuild the cached chroot).
set -euo pipefail

cd "$(dirname "$0")/.."
src="$(pwd)"
t_start=$SECONDS

build_dir="${1:-build/release}"
mirror="${PTDA_DEBIAN_MIRROR:-http://deb.debian.org/debian}"
work="${PTDA_PKGTEST_DIR:-$src/build/pkgtest}"
jobs="${PTDA_JOBS:-$(nproc 2> /dev/null || echo 2)}"
cross_dirs="${PTDA_PACKAGE_CROSS_DIRS:-build/aarch64-release build/armhf-release}"

say() { echo "package_test: $*"; }
phase() { echo "=== package_test: $* ($((SECONDS - t_start)) s)"; }
ok() { echo "  ok   $*"; }
fail() {
  echo "  FAIL $*" >&2
  exit 1
}
# check "what was checked" command...: runs the command quietly, prints ok or fails with the message.
check() {
  local what="$1"
  shift
  if "$@" > /dev/null 2>&1; then ok "$what"; else fail "$what"; fi
}

[ "$(id -u)" -eq 0 ] || fail "must run as root (debootstrap, chroot, mount)"
for tool in cmake cpack dpkg-deb dpkg-shlibdeps debootstrap readelf file chroot mount umount sha256sum; do
  command -v "$tool" > /dev/null || fail "'$tool' not found: run scripts/bootstrap.sh base pkg"
done

# ---------------------------------------------------------------------------------------------------
# Mounts and cleanup: every mount made here is recorded and undone on exit, before anything under a
# chroot is deleted.
mounts=()
umount_all() {
  local i
  for ((i = ${#mounts[@]} - 1; i >= 0; i--)); do
    umount "${mounts[$i]}" 2> /dev/null || umount -l "${mounts[$i]}" 2> /dev/null || true
  done
  mounts=()
}
# Scratch space for extracted and repacked packages (mktemp_dir runs in $(...) subshells, so the
# directories live below one parent that this shell removes).
tmp_root="$(mktemp -d)"
cleanup() {
  local rc=$?
  umount_all
  rm -rf "$tmp_root"
  if [ $rc -ne 0 ]; then
    echo "package_test: FAILED after $((SECONDS - t_start)) s (logs and chroots in $work)" >&2
  fi
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# Mounts left below a chroot directory by an earlier run that was killed (SIGKILL, a lost session).
umount_stale() {
  local real m
  real="$(realpath "$1")"
  awk -v d="$real" 'index($2, d "/") == 1 { print $2 }' /proc/mounts | sort -r | while read -r m; do
    say "unmounting $m (left by an earlier run)"
    umount "$m" 2> /dev/null || umount -l "$m"
  done
}
# Refuses to delete a directory that still has something mounted below it.
safe_rm_root() {
  local dir="$1"
  [ -e "$dir" ] || return 0
  local real
  real="$(realpath "$dir")"
  if awk -v d="$real" '$2 == d || index($2, d "/") == 1 { found = 1 } END { exit !found }' /proc/mounts; then
    fail "$dir still has mounts below it (see /proc/mounts); not deleting"
  fi
  rm -rf --one-file-system "$dir"
}

mktemp_dir() { mktemp -d -p "$tmp_root"; }

# ---------------------------------------------------------------------------------------------------
phase "build and cpack in $build_dir"
if [ ! -f "$build_dir/CMakeCache.txt" ]; then
  if [ "$build_dir" = build/release ]; then
    cmake --preset release > /dev/null
  else
    cmake -S . -B "$build_dir" -DPTDA_WERROR=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo > /dev/null
  fi
fi
# cpack builds the `preinstall` target (= all) first anyway: build it here with the job limit.
mkdir -p "$work"
cmake --build "$build_dir" -j "$jobs" > "$work/build.log" 2>&1 ||
  {
    tail -30 "$work/build.log" >&2
    fail "build of $build_dir (log: $work/build.log)"
  }

run_cpack() { # build-dir: (re)creates build-dir/packages/*.deb
  local dir="$1"
  rm -rf "$dir/packages"
  (cd "$dir" && cpack -G DEB > packages.log 2>&1) || {
    cat "$dir/packages.log" >&2
    fail "cpack in $dir"
  }
}
run_cpack "$build_dir"
pkgs="$(realpath "$build_dir/packages")"
deb_of() { # package-name dir -> the one .deb
  local f
  f="$(find "$2" -maxdepth 1 -name "$1_*.deb" | sort | tail -1)"
  [ -n "$f" ] || fail "no $1_*.deb in $2"
  echo "$f"
}
ptdad_deb="$(deb_of ptdad "$pkgs")"
tools_deb="$(deb_of ptda-tools "$pkgs")"
common_deb="$(deb_of ptda-common "$pkgs")"
version="$(dpkg-deb -f "$ptdad_deb" Version)"
say "packages $version:"
# shellcheck disable=SC2012 # CPack's file names, listed for the log
ls -l "$pkgs"/*.deb "$pkgs"/*.ddeb | awk '{printf "  %9d  %s\n", $5, $NF}'

# ---------------------------------------------------------------------------------------------------
# Control fields. The Depends are written by hand (identical for every architecture); they must
# cover every library the binaries load.
soname_pkg() { # DT_NEEDED soname -> Debian 12 package
  case "$1" in
    libc.so.6 | libm.so.6 | libpthread.so.0 | libdl.so.2 | librt.so.1 | ld-linux*.so.*) echo libc6 ;;
    libgcc_s.so.1) echo libgcc-s1 ;;
    libstdc++.so.6) echo libstdc++6 ;;
    libfmt.so.9) echo libfmt9 ;;
    libspdlog.so.1.10) echo libspdlog1.10 ;;
    libkissfft-float.so.131) echo libkissfft-float131 ;;
    libtomlplusplus.so.3) echo libtomlplusplus3 ;;
    libgpiod.so.2) echo libgpiod2 ;;
    libsystemd.so.0) echo libsystemd0 ;;
    libmosquitto.so.1) echo libmosquitto1 ;;
    libz.so.1) echo zlib1g ;;
    *) echo "" ;;
  esac
}
# depends_constraint "Depends field" package -> the "(op version)" of that package ('-' if none,
# empty if absent); the package may be one alternative of a|b.
depends_constraint() {
  echo "$1" | tr ',' '\n' | tr '|' '\n' | sed 's/^ *//; s/ *$//' |
    awk -v p="$2" '$1 == p { c = $0; sub(/^[^ ]+ */, "", c); print (c == "" ? "-" : c); exit }'
}

check_debs() { # dir expected-arch
  local dir="$1" arch="$2" deb pkg field got bin needed so dep x c
  say "control fields of $dir ($arch)"
  for pkg in ptdad ptda-tools ptda-common; do
    deb="$(deb_of "$pkg" "$dir")"
    got="$(dpkg-deb -f "$deb" Architecture)"
    if [ "$pkg" = ptda-common ]; then
      [ "$got" = all ] || fail "$pkg: Architecture $got, expected all"
      ok "$pkg: Architecture all"
      continue
    fi
    [ "$got" = "$arch" ] || fail "$pkg: Architecture $got, expected $arch"
    ok "$pkg: Architecture $arch"
    field="$(dpkg-deb -f "$deb" Depends)"
    c="$(depends_constraint "$field" libkissfft-float131)"
    x="${c#(>= }"
    x="${x%)}"
    if [ "$c" = "" ] || [ "$c" = "-" ] || ! dpkg --compare-versions "$x" ge 131.1.0-4.1~deb12u1; then
      fail "$pkg: Depends must have libkissfft-float131 (>= 131.1.0-4.1~deb12u1) (CVE fixes), has '${c}'"
    fi
    ok "$pkg: libkissfft-float131 $c (the CVE-2025-34297/CVE-2026-41445 fix)"
    x="$(mktemp_dir)"
    dpkg-deb -x "$deb" "$x"
    for bin in "$x"/usr/bin/*; do
      needed="$(readelf -d "$bin" | sed -n 's/.*(NEEDED).*\[\(.*\)\]/\1/p')"
      [ -n "$needed" ] || fail "$pkg: $(basename "$bin") has no DT_NEEDED entries"
      for so in $needed; do
        dep="$(soname_pkg "$so")"
        [ -n "$dep" ] || fail "$pkg: $(basename "$bin") needs $so, which package_test.sh does not know: add it to soname_pkg and to the Depends in cmake/ptda_package.cmake"
        [ -n "$(depends_constraint "$field" "$dep")" ] ||
          fail "$pkg: $(basename "$bin") needs $so, but Depends has no $dep: $field"
      done
      ok "$pkg: Depends covers DT_NEEDED of $(basename "$bin") ($(echo "$needed" | tr '\n' ' '))"
      # Symbol versions (any architecture): the newest GLIBC_x.y needed must be within libc6's
      # constraint, the newest GLIBCXX within GCC 12's libstdc++6 (3.4.30, bookworm's).
      local glibc glibcxx have_libc
      glibc="$(readelf -V --wide "$bin" | grep -o 'GLIBC_[0-9.]*' | sed 's/GLIBC_//' | sort -uV | tail -1)"
      have_libc="$(depends_constraint "$field" libc6)"
      have_libc="${have_libc#(>= }"
      have_libc="${have_libc%)}"
      dpkg --compare-versions "$have_libc" ge "$glibc" ||
        fail "$pkg: $(basename "$bin") needs GLIBC_$glibc, Depends has libc6 (>= $have_libc)"
      glibcxx="$(readelf -V --wide "$bin" | grep -o 'GLIBCXX_[0-9.]*' | sed 's/GLIBCXX_//' | sort -uV | tail -1)"
      [ -z "$glibcxx" ] || dpkg --compare-versions "$glibcxx" le 3.4.30 ||
        fail "$pkg: $(basename "$bin") needs GLIBCXX_$glibcxx, newer than Debian 12's libstdc++6"
      ok "$pkg: $(basename "$bin") needs at most GLIBC_$glibc (libc6 >= $have_libc) and GLIBCXX_${glibcxx:-none}"
      file "$bin" | grep -q "not stripped" && fail "$pkg: $(basename "$bin") is not stripped"
      ok "$pkg: $(basename "$bin") stripped (symbols in $pkg-dbgsym)"
    done
    # amd64 (the build host): what dpkg-shlibdeps computes, with versions, must be implied.
    if [ "$arch" = "$(dpkg --print-architecture)" ]; then
      mkdir -p "$x/debian"
      printf 'Source: ptda\n\nPackage: %s\nArchitecture: any\n' "$pkg" > "$x/debian/control"
      local shl
      shl="$(cd "$x" && dpkg-shlibdeps --warnings=0 -O usr/bin/* 2> /dev/null | sed -n 's/^shlibs:Depends=//p')"
      [ -n "$shl" ] || fail "$pkg: dpkg-shlibdeps computed nothing"
      while read -r dep; do
        [ -n "$dep" ] || continue
        local name="${dep%% *}" need="" have
        [[ "$dep" == *"(>= "* ]] && need="${dep#*(>= }" && need="${need%)}"
        have="$(depends_constraint "$field" "$name")"
        [ -n "$have" ] || fail "$pkg: dpkg-shlibdeps wants '$dep'; Depends has no $name: $field"
        if [ -n "$need" ]; then
          [[ "$have" == "(>= "* ]] || fail "$pkg: dpkg-shlibdeps wants '$dep', Depends has $name $have"
          have="${have#(>= }"
          have="${have%)}"
          dpkg --compare-versions "$have" ge "$need" ||
            fail "$pkg: dpkg-shlibdeps wants '$dep', Depends has only $name (>= $have)"
        fi
      done < <(echo "$shl" | tr ',' '\n' | sed 's/^ *//')
      ok "$pkg: Depends implies dpkg-shlibdeps: $shl"
    fi
  done
  deb="$(deb_of ptdad "$dir")"
  check "ptdad: conffiles lists /etc/ptda/ptda.toml" sh -c "dpkg-deb -I '$deb' conffiles | grep -qx /etc/ptda/ptda.toml"
  for x in postinst prerm postrm; do
    check "ptdad: $x is executable and passes sh -n" sh -c "dpkg-deb -I '$deb' $x > /dev/null && dpkg-deb --ctrl-tarfile '$deb' | tar -tvf - ./$x | grep -q '^-rwxr-xr-x' && dpkg-deb -I '$deb' $x | sh -n"
  done
}

phase "control fields"
check_debs "$pkgs" "$(dpkg --print-architecture)"
for d in $cross_dirs; do
  case "$d" in
    *aarch64* | *arm64*) a=arm64 ;;
    *armhf*) a=armhf ;;
    *) a="" ;;
  esac
  if [ -n "$a" ] && [ -f "$d/CPackConfig.cmake" ] && [ -x "$d/daemon/ptdad" ] && [ -x "$d/cli/ptda" ]; then
    run_cpack "$d"
    check_debs "$(realpath "$d/packages")" "$a"
  else
    say "no built cross directory $d: its packages not checked"
  fi
done

# ---------------------------------------------------------------------------------------------------
# The chroot. The cached base is a bare `debootstrap --variant=minbase` with fresh apt lists; every
# run installs the packages into a new copy of it. Downloaded .debs are kept in $work/apt-archives.
base="$work/bookworm-minbase"
archives="$work/apt-archives"
mkdir -p "$archives/partial"
if [ "${PTDA_PKGTEST_REFRESH:-0}" = 1 ] || [ ! -f "$base/.complete" ]; then
  phase "debootstrap --variant=minbase bookworm (cached in $base)"
  safe_rm_root "$base"
  t0=$SECONDS
  debootstrap --variant=minbase bookworm "$base" "$mirror" > "$work/debootstrap.log" 2>&1 ||
    {
      tail -20 "$work/debootstrap.log" >&2
      fail "debootstrap (log: $work/debootstrap.log)"
    }
  echo "deb $mirror bookworm main" > "$base/etc/apt/sources.list"
  cp /etc/resolv.conf "$base/etc/resolv.conf"
  chroot "$base" apt-get -q update > "$work/apt-update.log" 2>&1 || fail "apt-get update in the base chroot"
  rm -f "$base"/var/cache/apt/archives/*.deb
  date -u +%FT%TZ > "$base/.complete"
  say "debootstrap + apt-get update took $((SECONDS - t0)) s"
fi

root="" # the current chroot
enter_root() { # name: fresh copy of the base, /proc and the apt archive cache mounted
  umount_all
  root="$work/$1"
  [ ! -d "$root" ] || umount_stale "$root"
  safe_rm_root "$root"
  cp -a "$base" "$root"
  cp /etc/resolv.conf "$root/etc/resolv.conf"
  # No service of any package may start in the chroot (invoke-rc.d / deb-systemd-invoke ask this).
  printf '#!/bin/sh\nexit 101\n' > "$root/usr/sbin/policy-rc.d"
  chmod 0755 "$root/usr/sbin/policy-rc.d"
  mount -t proc proc "$root/proc"
  mounts+=("$root/proc")
  mount --bind "$archives" "$root/var/cache/apt/archives"
  mounts+=("$root/var/cache/apt/archives")
  mkdir -p "$root/tmp/debs"
}
in_root() {
  chroot "$root" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin HOME=/root LC_ALL=C.UTF-8 \
    DEBIAN_FRONTEND=noninteractive ${http_proxy:+http_proxy=$http_proxy} "$@" < /dev/null
}
# apt_get log-name args...: apt-get with stdin closed (a conffile prompt would fail, not hang); on
# failure one retry after an index refresh (the cached lists may name superseded versions).
apt_get() {
  local log="$work/$1.log"
  shift
  if ! in_root apt-get -y -q -o Dpkg::Use-Pty=0 --no-install-recommends "$@" > "$log" 2>&1; then
    if grep -qE "404|Unable to fetch|Failed to fetch" "$log"; then
      say "apt-get failed to fetch; refreshing the index"
      in_root apt-get -q update >> "$log" 2>&1 || true
      cp -a "$root/var/lib/apt/lists/." "$base/var/lib/apt/lists/" 2> /dev/null || true
      in_root apt-get -y -q -o Dpkg::Use-Pty=0 --no-install-recommends "$@" >> "$log" 2>&1 && return 0
    fi
    tail -40 "$log" >&2
    fail "apt-get $* (log: $log)"
  fi
  if grep -qiE "Configuration file .* ==> |\*\*\* .* \(Y/I/N/O/D/Z\)" "$log"; then
    fail "dpkg asked about a conffile during apt-get $* (log: $log)"
  fi
}
# owner:group mode of a path, with the chroot's user database
perms() { in_root stat -c '%U:%G %a' "$1" 2> /dev/null || echo "missing"; }
# shellcheck disable=SC2016 # ${Status} and ${Version} are dpkg-query fields
status_of() { in_root dpkg-query -W -f='${Status}' "$1" 2> /dev/null || true; }
# shellcheck disable=SC2016
version_of() { in_root dpkg-query -W -f='${Version}' "$1" 2> /dev/null || true; }

# repack in.deb out.deb new-version [text appended to the conffile]: the same package with another
# version (and the exact-version Depends on ptda-common moved along).
repack() {
  local in="$1" out="$2" new="$3" append="${4:-}" d old
  d="$(mktemp_dir)"
  dpkg-deb -R "$in" "$d"
  old="$(sed -n 's/^Version: //p' "$d/DEBIAN/control")"
  sed -i "s/^Version: .*/Version: $new/; s/(= $old)/(= $new)/g" "$d/DEBIAN/control"
  if [ -n "$append" ]; then
    printf '%s\n' "$append" >> "$d/etc/ptda/ptda.toml"
    (cd "$d" && sed -i "s|^[0-9a-f]*  etc/ptda/ptda.toml\$|$(md5sum etc/ptda/ptda.toml | cut -d' ' -f1)  etc/ptda/ptda.toml|" DEBIAN/md5sums)
  fi
  dpkg-deb --root-owner-group -Zxz -b "$d" "$out" > /dev/null
}

# ---------------------------------------------------------------------------------------------------
phase "chroot A: minbase without systemd (adduser fallback)"
enter_root root-adduser
cp "$ptdad_deb" "$common_deb" "$root/tmp/debs/"
t0=$SECONDS
apt_get a-install install /tmp/debs/"$(basename "$ptdad_deb")" /tmp/debs/"$(basename "$common_deb")"
say "install with dependencies: $((SECONDS - t0)) s"
[ "$(status_of ptdad)" = "install ok installed" ] || fail "ptdad not installed: $(status_of ptdad)"
ok "ptdad $version installed with its dependencies (no systemd in the chroot)"
check "systemd-sysusers absent, so postinst used adduser" sh -c "! chroot '$root' sh -c 'command -v systemd-sysusers'"
check "user ptda (adduser): home /var/lib/ptda, shell /usr/sbin/nologin" \
  sh -c "chroot '$root' getent passwd ptda | grep -q ':/var/lib/ptda:/usr/sbin/nologin\$'"
check "user ptda is in groups ptda and ptda-hw" sh -c "chroot '$root' id -nG ptda | tr ' ' '\n' | sort | tr '\n' ' ' | grep -qx 'ptda ptda-hw '"
check "/var/lib/ptda is ptda:ptda 0750" test "$(perms /var/lib/ptda)" = "ptda:ptda 750"
# A fresh install has no baseline: --check-config opens every path (issue 17), so the shipped
# configuration is ready for field training (--train: the baseline's directory must exist) and plain
# --check-config names the missing baseline.
out="$(in_root ptdad --config /etc/ptda/ptda.toml --check-config --train 2>&1)" || fail "ptdad --config /etc/ptda/ptda.toml --check-config --train: $out"
ok "ptdad --config /etc/ptda/ptda.toml --check-config --train: $out"
if out="$(in_root ptdad --config /etc/ptda/ptda.toml --check-config 2>&1)"; then
  fail "ptdad --check-config without a baseline said valid: $out"
fi
echo "$out" | grep -q "baseline: /var/lib/ptda/baseline.bin" || fail "ptdad --check-config without a baseline: $out"
ok "ptdad --check-config without a baseline: exit 1, $out"
apt_get a-purge purge ptdad ptda-common
[ -z "$(version_of ptdad)" ] || fail "ptdad still known to dpkg after purge: $(status_of ptdad)"
ok "purged"
umount_all

# ---------------------------------------------------------------------------------------------------
phase "chroot B: minbase + systemd (not running): the full life cycle"
enter_root root-systemd
cp "$ptdad_deb" "$tools_deb" "$common_deb" "$root/tmp/debs/"
apt_get b-systemd install systemd
t0=$SECONDS
apt_get b-install install /tmp/debs/"$(basename "$ptdad_deb")" /tmp/debs/"$(basename "$tools_deb")" \
  /tmp/debs/"$(basename "$common_deb")"
say "install with dependencies: $((SECONDS - t0)) s"
for p in ptdad ptda-tools ptda-common; do
  [ "$(status_of "$p")" = "install ok installed" ] || fail "$p not installed: $(status_of "$p")"
  [ "$(version_of "$p")" = "$version" ] || fail "$p: version $(version_of "$p"), expected $version"
done
ok "ptdad, ptda-tools, ptda-common $version installed with their dependencies"

echo "  -- files"
for f in /usr/bin/ptdad /usr/bin/ptda; do
  check "$f: root:root 0755" test "$(perms "$f")" = "root:root 755"
done
for f in /lib/systemd/system/ptdad.service /usr/lib/sysusers.d/ptda.conf /usr/lib/tmpfiles.d/ptda.conf \
  /lib/udev/rules.d/60-ptda.rules /etc/ptda/ptda.toml /usr/share/ptda/scenarios/joint_rotation_healthy.toml \
  /usr/share/ptda/examples/ptdad.toml /usr/share/ptda/examples/ptdad.d/10-joint_rotation.toml \
  /usr/share/ptda/examples/systemd/10-can0.conf /usr/share/ptda/examples/systemd/80-can0.network \
  /usr/share/ptda/examples/systemd/30-mqtt.conf.example \
  /usr/share/doc/ptda-common/docs/systemd.md; do
  check "$f: root:root 0644" test "$(perms "$f")" = "root:root 644"
done
check "/etc/ptda/conf.d exists (drop-ins)" test -d "$root/etc/ptda/conf.d"
check "80-can0.network is not active (no /etc/systemd/network/80-can0.network)" test ! -e "$root/etc/systemd/network/80-can0.network"
check "no can0 drop-in is active (/lib and /etc ptdad.service.d absent)" sh -c "[ ! -e '$root/lib/systemd/system/ptdad.service.d' ] && [ ! -e '$root/etc/systemd/system/ptdad.service.d' ]"
check "the unit's ExecStart reads /etc/ptda/ptda.toml" grep -qx 'ExecStart=/usr/bin/ptdad --config /etc/ptda/ptda.toml' "$root/lib/systemd/system/ptdad.service"
check "the unit's Documentation= file exists" sh -c "d=\$(sed -n 's|^Documentation=file:||p' '$root/lib/systemd/system/ptdad.service'); [ -n \"\$d\" ] && [ -f '$root'\"\$d\" ]"
check "dpkg registers /etc/ptda/ptda.toml as a conffile" sh -c "chroot '$root' dpkg-query -W -f='\${Conffiles}' ptdad | grep -q '^ /etc/ptda/ptda.toml '"
scen="$(sed -n 's/^scenario = "\([^"]*\)".*/\1/p' "$root/etc/ptda/ptda.toml")"
check "the conffile's simulator scenario ($scen) is installed" test -f "$root$scen"

echo "  -- user, directories, enablement"
check "systemd-sysusers present, so postinst used it" chroot "$root" sh -c 'command -v systemd-sysusers'
check "user ptda (sysusers): home /var/lib/ptda, shell /usr/sbin/nologin" \
  sh -c "chroot '$root' getent passwd ptda | grep -q ':/var/lib/ptda:/usr/sbin/nologin\$'"
check "user ptda is in groups ptda and ptda-hw" sh -c "chroot '$root' id -nG ptda | tr ' ' '\n' | sort | tr '\n' ' ' | grep -qx 'ptda ptda-hw '"
check "/var/lib/ptda is ptda:ptda 0750" test "$(perms /var/lib/ptda)" = "ptda:ptda 750"
wants="$root/etc/systemd/system/multi-user.target.wants/ptdad.service"
check "ptdad.service enabled (multi-user.target.wants symlink)" sh -c "[ \"\$(readlink '$wants')\" = /lib/systemd/system/ptdad.service ]"
check "deb-systemd-helper recorded the enablement" test -e "$root/var/lib/systemd/deb-systemd-helper-enabled/ptdad.service.dsh-also"

echo "  -- the programs"
# A fresh install has no baseline: --check-config opens every path (issue 17), so the shipped
# configuration is ready for field training (--train: the baseline's directory must exist) and plain
# --check-config names the missing baseline.
out="$(in_root ptdad --config /etc/ptda/ptda.toml --check-config --train 2>&1)" || fail "ptdad --config /etc/ptda/ptda.toml --check-config --train: $out"
ok "ptdad --config /etc/ptda/ptda.toml --check-config --train: $out"
if out="$(in_root ptdad --config /etc/ptda/ptda.toml --check-config 2>&1)"; then
  fail "ptdad --check-config without a baseline said valid: $out"
fi
echo "$out" | grep -q "baseline: /var/lib/ptda/baseline.bin" || fail "ptdad --check-config without a baseline: $out"
ok "ptdad --check-config without a baseline: exit 1, $out"
out="$(in_root ptdad --version 2>&1)" || fail "ptdad --version: $out"
[ "$out" = "ptdad ${version%-*}" ] || fail "ptdad --version says '$out', expected 'ptdad ${version%-*}'"
ok "ptdad --version: $out"
check "ptda --help" in_root ptda --help
check "ptda simulate --help" in_root ptda simulate --help
# The shipped configuration, as the service would run it (user ptda, the simulator, no baseline):
# it must come up and refuse monitoring for the missing baseline, not fail.
in_root install -d -o ptda -g ptda /tmp/ptda-status
chroot "$root" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin LC_ALL=C.UTF-8 \
  setpriv --reuid ptda --regid ptda --init-groups \
  ptdad --config /etc/ptda/ptda.toml --status-dir /tmp/ptda-status --foreground < /dev/null > "$work/b-run.log" 2>&1 &
daemon_pid=$! # chroot, env and setpriv exec: this is ptdad's pid
state=""
for _ in $(seq 1 100); do
  state="$(sed -n 's/^{"version":1,"state":"\([a-z]*\)".*/\1/p' "$root/tmp/ptda-status/status.json" 2> /dev/null || true)"
  [ -z "$state" ] || [ "$state" = configured ] || break
  kill -0 "$daemon_pid" 2> /dev/null || break
  sleep 0.2
done
kill -TERM "$daemon_pid" 2> /dev/null || true
rc=0
wait "$daemon_pid" || rc=$?
if [ "$state" != refused ] || [ $rc -ne 0 ]; then
  tail -20 "$work/b-run.log" >&2
  fail "ptdad with the shipped configuration as user ptda: state '$state', exit $rc after SIGTERM (expected refused, 0; log: $work/b-run.log)"
fi
ok "ptdad runs the shipped configuration as user ptda: status.json state refused (no baseline yet), SIGTERM -> exit 0"

echo "  -- local changes: conffile edit, drop-in, baseline"
sed -i 's/^log_level = "info"/log_level = "debug"  # site edit (package_test)/' "$root/etc/ptda/ptda.toml"
check "conffile edited" grep -q 'site edit (package_test)' "$root/etc/ptda/ptda.toml"
printf '# site drop-in (package_test)\n[daemon]\nstatus_period_s = 2.0\n' > "$root/etc/ptda/conf.d/50-site.toml"
head -c 65536 /dev/urandom > "$root/var/lib/ptda/baseline.bin"
in_root chown ptda:ptda /var/lib/ptda/baseline.bin
in_root chmod 0600 /var/lib/ptda/baseline.bin
baseline_sum="$(sha256sum < "$root/var/lib/ptda/baseline.bin")"
dropin_sum="$(sha256sum < "$root/etc/ptda/conf.d/50-site.toml")"
conf_sum="$(sha256sum < "$root/etc/ptda/ptda.toml")"
ok "wrote /etc/ptda/conf.d/50-site.toml and a fake /var/lib/ptda/baseline.bin (64 KiB, ptda:ptda 0600)"
out="$(in_root ptdad --config /etc/ptda/ptda.toml --check-config --train 2>&1)" || fail "check-config with the edit and the drop-in: $out"
ok "ptdad --check-config with the edit and the drop-in: $out"

local_state_kept() { # when
  [ "$(sha256sum < "$root/etc/ptda/ptda.toml")" = "$conf_sum" ] || fail "$1: the edited conffile changed"
  ok "$1: edited /etc/ptda/ptda.toml unchanged"
  [ "$(sha256sum < "$root/etc/ptda/conf.d/50-site.toml")" = "$dropin_sum" ] || fail "$1: the drop-in changed"
  ok "$1: /etc/ptda/conf.d/50-site.toml unchanged"
  [ "$(sha256sum < "$root/var/lib/ptda/baseline.bin")" = "$baseline_sum" ] || fail "$1: the baseline changed or vanished"
  [ "$(perms /var/lib/ptda/baseline.bin)" = "ptda:ptda 600" ] || fail "$1: baseline owner/mode changed"
  ok "$1: /var/lib/ptda/baseline.bin unchanged (content, ptda:ptda 0600)"
  check "$1: user ptda still exists" chroot "$root" getent passwd ptda
}

echo "  -- upgrade 1: new version, same conffile (no prompt expected)"
v1="${version}+pkgtest1"
up="$(mktemp_dir)"
repack "$ptdad_deb" "$up/ptdad_${v1}.deb" "$v1"
repack "$tools_deb" "$up/ptda-tools_${v1}.deb" "$v1"
repack "$common_deb" "$up/ptda-common_${v1}.deb" "$v1"
cp "$up"/*.deb "$root/tmp/debs/"
apt_get b-upgrade1 install "/tmp/debs/ptdad_${v1}.deb" "/tmp/debs/ptda-tools_${v1}.deb" "/tmp/debs/ptda-common_${v1}.deb"
[ "$(version_of ptdad)" = "$v1" ] || fail "upgrade 1: ptdad is $(version_of ptdad), expected $v1"
ok "upgrade 1: ptdad $version -> $v1, stdin closed, no conffile question"
local_state_kept "upgrade 1"
check "upgrade 1: no ptda.toml.dpkg-* left" sh -c "! ls '$root'/etc/ptda/ptda.toml.dpkg-* 2>/dev/null"
check "upgrade 1: still enabled" test -L "$wants"

echo "  -- upgrade 2: new version that changes the conffile, --force-confdef --force-confold"
v2="${version}+pkgtest2"
repack "$ptdad_deb" "$up/ptdad_${v2}.deb" "$v2" "# changed by the packager in $v2 (package_test)"
repack "$tools_deb" "$up/ptda-tools_${v2}.deb" "$v2"
repack "$common_deb" "$up/ptda-common_${v2}.deb" "$v2"
cp "$up"/*"$v2"*.deb "$root/tmp/debs/"
apt_get b-upgrade2 -o Dpkg::Options::=--force-confdef -o Dpkg::Options::=--force-confold \
  install "/tmp/debs/ptdad_${v2}.deb" "/tmp/debs/ptda-tools_${v2}.deb" "/tmp/debs/ptda-common_${v2}.deb"
[ "$(version_of ptdad)" = "$v2" ] || fail "upgrade 2: ptdad is $(version_of ptdad), expected $v2"
ok "upgrade 2: ptdad $v1 -> $v2"
local_state_kept "upgrade 2"
check "upgrade 2: the new default is beside it as ptda.toml.dpkg-dist" grep -q "changed by the packager in $v2" "$root/etc/ptda/ptda.toml.dpkg-dist"

echo "  -- remove (configuration and baseline stay)"
apt_get b-remove remove ptdad
[ "$(status_of ptdad)" = "deinstall ok config-files" ] || fail "remove: ptdad status '$(status_of ptdad)'"
ok "remove: ptdad in state config-files"
for f in /usr/bin/ptdad /lib/systemd/system/ptdad.service /lib/udev/rules.d/60-ptda.rules /usr/lib/sysusers.d/ptda.conf; do
  check "remove: $f gone" test ! -e "$root$f"
done
local_state_kept "remove"
check "remove: ptda-tools untouched" test -x "$root/usr/bin/ptda"
check "remove: enablement symlink kept (as debhelper does: a reinstall keeps the admin's choice)" test -L "$wants"

echo "  -- reinstall"
apt_get b-reinstall install "/tmp/debs/ptdad_${v2}.deb"
[ "$(status_of ptdad)" = "install ok installed" ] || fail "reinstall: ptdad status '$(status_of ptdad)'"
ok "reinstall: ptdad $v2 installed, no conffile question"
local_state_kept "reinstall"
check "reinstall: enabled again" sh -c "[ \"\$(readlink '$wants')\" = /lib/systemd/system/ptdad.service ]"
out="$(in_root ptdad --config /etc/ptda/ptda.toml --check-config --train 2>&1)" || fail "reinstall: check-config: $out"
ok "reinstall: ptdad --check-config: $out"

echo "  -- purge"
files_before="$(in_root dpkg -L ptdad ptda-tools ptda-common | sort -u)"
apt_get b-purge purge ptdad ptda-tools ptda-common
for p in ptdad ptda-tools ptda-common; do
  [ -z "$(version_of "$p")" ] || fail "purge: $p still known to dpkg: $(status_of "$p")"
done
ok "purge: ptdad, ptda-tools, ptda-common unknown to dpkg"
check "purge: /etc/ptda/ptda.toml and its .dpkg-dist gone" sh -c "! ls '$root'/etc/ptda/ptda.toml* 2>/dev/null"
check "purge: administrator drop-in /etc/ptda/conf.d/50-site.toml kept" test -f "$root/etc/ptda/conf.d/50-site.toml"
check "purge: /var/lib/ptda (baseline) gone" test ! -e "$root/var/lib/ptda"
check "purge: enablement symlink gone" test ! -e "$wants" -a ! -L "$wants"
check "purge: deb-systemd-helper state gone" test ! -e "$root/var/lib/systemd/deb-systemd-helper-enabled/ptdad.service.dsh-also"
check "purge: user ptda and group ptda-hw kept (Debian does not delete system accounts)" \
  sh -c "chroot '$root' getent passwd ptda && chroot '$root' getent group ptda-hw"
left=""
while read -r f; do
  [ -n "$f" ] || continue
  [ -e "$root$f" ] && [ ! -d "$root$f" ] && left="$left $f"
done <<< "$files_before"
[ -z "$left" ] || fail "purge: files of the packages left behind:$left"
ok "purge: no file of the three packages left"
umount_all

safe_rm_root "$work/root-adduser"
safe_rm_root "$work/root-systemd"
phase "all package checks passed"
