#!/bin/sh
# A shipped drop-in example applied to a unit (issue 15: the MQTT drop-in opens IP to the broker):
#   1. `systemd-analyze verify` of the unit with the drop-in in its .d directory reports nothing
#      (ExecStart's binary replaced by /bin/true: the daemon is not installed on a build machine);
#   2. the hardening score of the unit with the drop-in's settings stays <= 2.0 (security_check.sh on the
#      unit followed by the drop-in's [Service] lines: `--offline` reads one file, and a later section of
#      the same name continues it, as a drop-in does; the check also proves it can fail).
# Usage: dropin_check.sh UNIT_FILE DROPIN_FILE SECURITY_CHECK_SCRIPT
set -eu
unit="$1"
dropin="$2"
security="$3"
command -v systemd-analyze >/dev/null || { echo "FAIL: systemd-analyze not found (apt install systemd)"; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
name=$(basename "$unit")
mkdir "$tmp/v" "$tmp/v/$name.d"
sed 's|^ExecStart=/usr/bin/ptdad |ExecStart=/bin/true |' "$unit" >"$tmp/v/$name"
cp "$dropin" "$tmp/v/$name.d/30-test.conf"
instance="$name"
case "$name" in *@.service) instance="${name%@.service}@joint4.service" ;; esac
out=$(cd "$tmp/v" && systemd-analyze verify --man=no "$tmp/v/$instance" 2>&1) || {
  echo "$out"
  echo "FAIL: systemd-analyze verify $instance with $(basename "$dropin") failed"
  exit 1
}
[ -z "$out" ] || { echo "$out"; echo "FAIL: systemd-analyze verify reported problems"; exit 1; }
echo "ok: systemd-analyze verify $instance with $(basename "$dropin"): nothing reported"
{ cat "$unit"; echo; grep -v '^#' "$dropin"; } >"$tmp/$name"
sh "$security" "$tmp/$name"
