#!/bin/sh
# The unit's hardening, as systemd rates it (issue 14): `systemd-analyze security --offline` of
# systemd/ptdad.service must report an overall exposure of at most 2.0 ("OK"; docs/systemd.md lists
# what remains exposed and why). The check proves it can fail: the same unit stripped of its
# sandboxing directives must be rated above 2.0.
# Usage: security_check.sh UNIT_FILE
set -eu
unit="$1"
command -v systemd-analyze >/dev/null || { echo "FAIL: systemd-analyze not found (apt install systemd)"; exit 1; }
if ! out=$(systemd-analyze security --offline=true --threshold=20 "$unit" 2>&1); then
  echo "$out" | tail -30
  echo "FAIL: $unit: overall exposure above 2.0"
  exit 1
fi
echo "$out" | tail -1
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
grep -v -E '^(Protect|Private|Restrict|NoNewPrivileges|SystemCallFilter|SystemCallArchitectures|CapabilityBoundingSet|LockPersonality|MemoryDenyWriteExecute|DevicePolicy|DeviceAllow|IPAddressDeny|UMask|ProcSubset|RemoveIPC|KeyringMode|DynamicUser|User|Group)' \
  "$unit" >"$tmp/ptdad.service"
if systemd-analyze security --offline=true --threshold=20 "$tmp/ptdad.service" >/dev/null 2>&1; then
  echo "FAIL: the check passed a unit without sandboxing: it cannot fail"
  exit 1
fi
echo "ok: the unstripped unit passes, the stripped one ($(systemd-analyze security --offline=true "$tmp/ptdad.service" 2>&1 | tail -1 | sed 's/.*: //')) fails"
