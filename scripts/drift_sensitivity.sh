#!/usr/bin/env bash
# How much healthy drift the shipped detector tolerates (docs/benchmarks.md, "Drift soak"): train on
# 40 cycles of the joint-4 rotation job (config/examples/joint_rotation.toml, default bands and 3-of-5
# decision), then monitor 40 fresh healthy cycles whose mesh amplitude or noise level is changed by a
# constant factor through the simulator's [drift] table (a load cycle frozen at its crest or trough, or a
# coldness frozen at 1). Prints a markdown table: abnormal windows of 80 and whether the alarm was raised.
#
# Usage: scripts/drift_sensitivity.sh [build_dir] [out_dir]     (~40 s)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build/release}
out=${2:-$root/out/drift-sensitivity}
ptda=$build/cli/ptda
config=$root/config/examples/joint_rotation.toml
[[ -x "$ptda" ]] || { echo "drift_sensitivity: $ptda not found: build the ptda target first" >&2; exit 1; }
rm -rf "$out"
mkdir -p "$out"

# scenario NAME SEED DRIFT_LINES: joint_rotation_healthy.toml with 40 cycles and a [drift] table.
scenario() {
  sed -e 's/^cycles = 20 .*/cycles = 40/' -e "s/^seed = .*/seed = $2/" \
    "$root/config/scenarios/joint_rotation_healthy.toml" >"$out/$1.toml"
  printf '\n[drift]\n%b\n' "$3" >>"$out/$1.toml"
  "$ptda" simulate --scenario "$out/$1.toml" --out "$out/$1" >/dev/null
}

scenario train 501 "load_period_s = 1e9"
"$ptda" train --recording "$out/train" --config "$config" --out "$out/baseline.bin" >"$out/train.txt"

row() {  # LABEL DRIFT_LINES
  scenario test 777 "$2"
  "$ptda" monitor --recording "$out/test" --config "$config" --baseline "$out/baseline.bin" --quiet \
    --jsonl "$out/test.jsonl" >/dev/null
  echo "| $1 | $(grep -c '"abnormal":true' "$out/test.jsonl") of $(grep -c '"status":"scored"' "$out/test.jsonl") |" \
    "$(grep -q '"alarm":true' "$out/test.jsonl" && echo yes || echo no) |"
  rm -rf "$out/test"
}

echo "| healthy change (constant over the 40 test cycles) | abnormal windows | alarm |"
echo "|---|---:|---|"
# L = sin(load_phase_rad) with an (effectively) infinite period: +-pi/2 freezes the crest or trough.
row "none" "load_period_s = 1e9"
for rel in 0.01 0.02 0.05 0.10 0.30; do
  row "mesh amplitude +$(awk -v r=$rel 'BEGIN { print r * 100 }') %" \
    "load_period_s = 1e9\nload_phase_rad = 1.5707963267948966\nmesh_amplitude_rel = $rel"
done
for rel in 0.05 0.30; do
  row "mesh amplitude -$(awk -v r=$rel 'BEGIN { print r * 100 }') %" \
    "load_period_s = 1e9\nload_phase_rad = -1.5707963267948966\nmesh_amplitude_rel = $rel"
done
# Coldness 1 that never warms up (tau 1e9 s): noise x (1 + rel).
for rel in 0.02 0.05 0.10 0.30; do
  row "noise +$(awk -v r=$rel 'BEGIN { print r * 100 }') %" "warmup_tau_s = 1e9\ncold_noise_rel = $rel"
done
