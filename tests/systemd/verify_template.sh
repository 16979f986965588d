#!/bin/sh
# ptdad@.service (generated from ptdad.service by cmake/ptda_units.cmake) as systemd reads it:
#   1. `systemd-analyze verify` of an instance (ptdad@joint4.service) reports nothing. The daemon is not
#      installed on a build machine, so ExecStart's binary is replaced by /bin/true (arguments kept);
#   2. the check can fail: the same unit with a misspelt setting must be reported;
#   3. the hardening score of the template stays <= 2.0 (security_check.sh, which also proves it can fail).
# Usage: verify_template.sh TEMPLATE_UNIT SECURITY_CHECK_SCRIPT
set -eu
unit="$1"
security="$2"
command -v systemd-analyze >/dev/null || { echo "FAIL: systemd-analyze not found (apt install systemd)"; exit 1; }
grep -q '^ExecStart=/usr/bin/ptdad --config /etc/ptda/%i.toml ' "$unit" || { echo "FAIL: $unit: unexpected ExecStart"; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mkdir "$tmp/good" "$tmp/bad"
sed 's|^ExecStart=/usr/bin/ptdad |ExecStart=/bin/true |' "$unit" >"$tmp/good/ptdad@.service"
out=$(cd "$tmp/good" && systemd-analyze verify --man=no "$tmp/good/ptdad@joint4.service" 2>&1) || {
  echo "$out"
  echo "FAIL: systemd-analyze verify ptdad@joint4.service failed"
  exit 1
}
[ -z "$out" ] || { echo "$out"; echo "FAIL: systemd-analyze verify reported problems"; exit 1; }
echo "ok: systemd-analyze verify ptdad@joint4.service: nothing reported"
sed 's|^NoNewPrivileges=yes|NoNewPrivilege=yes|' "$tmp/good/ptdad@.service" >"$tmp/bad/ptdad@.service"
bad=$(cd "$tmp/bad" && systemd-analyze verify --man=no "$tmp/bad/ptdad@joint4.service" 2>&1 || true)
case "$bad" in
  *NoNewPrivilege*) echo "ok: a misspelt setting is reported" ;;
  *) echo "$bad"; echo "FAIL: verify did not report a misspelt setting: the check cannot fail"; exit 1 ;;
esac
sh "$security" "$unit"
