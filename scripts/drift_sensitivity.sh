#!/usr/bin/env bash
# How much healthy drift the shipped detector tolerates (docs/benchmarks.md, "Drift soak"): train on
# 40 cycles of the joint-4 rotation job (config/examples/joint_rotation.toml, default bands and 3-of-5
# decision), then monitor 40 fresh healthy cycles whose mesh amplitude or noise level is changed by a
# constant factor through the simulator's [drift] table (a load cycle frozen at its crest or trough, or a
# coldness frozen at 1), and 40 cycles with a spur-tooth defect of growing severity at nominal load.
# Then the same with a baseline trained across the load range (5 recordings of 8 cycles at mesh amplitude
# factors 0.7, 0.85, 1, 1.15, 1.3). Prints two markdown tables: abnormal windows of 80 and whether the
# alarm was raised.
#
# Usage: scripts/drift_sensitivity.sh [build_dir] [out_dir]     (~40 s)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build/release}
out=${2:-$root/out/drift-sensitivity}
ptda=$build/cli/ptda
config=${PTDA_SENSITIVITY_CONFIG:-$root/config/examples/joint_rotation.toml}
[[ -x "$ptda" ]] || { echo "drift_sensitivity: $ptda not found: build the ptda target first" >&2; exit 1; }
rm -rf "$out"
mkdir -p "$out"

# scenario NAME SEED DRIFT_LINES [SEVERITY [CYCLES]]: joint_rotation_healthy.toml with 40 cycles (or
# CYCLES), a [drift] table and, with SEVERITY, the faulty preset's spur-tooth defect.
scenario() {
  sed -e "s/^cycles = 20 .*/cycles = ${5:-40}/" -e "s/^seed = .*/seed = $2/" \
    "$root/config/scenarios/joint_rotation_healthy.toml" >"$out/$1.toml"
  printf '\n[drift]\n%b\n' "$3" >>"$out/$1.toml"
  if [[ -n ${4:-} ]]; then
    printf '\n[[fault]]\nkind = "spur_tooth"\nseverity = %s\nimpulse_amplitude_ms2 = 5.0\nresonance_hz = 3000.0\ndamping_ratio = 0.05\nam_depth = 0.15\n' \
      "$4" >>"$out/$1.toml"
  fi
  rm -rf "${out:?}/$1"
  "$ptda" simulate --scenario "$out/$1.toml" --out "$out/$1" >/dev/null
}

scenario train 501 "load_period_s = 1e9"
"$ptda" train --recording "$out/train" --config "$config" --out "$out/baseline.bin" >"$out/train.txt"

row() {  # LABEL DRIFT_LINES [SEVERITY]
  scenario test 777 "$2" "${3:-}"
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
for sev in 0.1 0.25 0.5 1.0; do
  row "tooth defect, severity $sev (nominal load, warm)" "load_period_s = 1e9" "$sev"
done

# The same with a baseline trained across the load range: 5 recordings of 8 cycles each with the mesh
# amplitude frozen at 1 + 0.3 L, L = -1, -0.5, 0, 0.5, 1 (load_phase_rad = asin(L)).
recordings=()
i=0
for phase in -1.5707963267948966 -0.5235987755982989 0 0.5235987755982989 1.5707963267948966; do
  scenario "load$i" $((600 + i)) "load_period_s = 1e9\nload_phase_rad = $phase\nmesh_amplitude_rel = 0.3" "" 8
  recordings+=(--recording "$out/load$i")
  i=$((i + 1))
done
"$ptda" train "${recordings[@]}" --config "$config" --out "$out/baseline.bin" >"$out/train_load_range.txt"
echo
echo "| baseline trained across the load range (mesh x0.7 .. x1.3) | abnormal windows | alarm |"
echo "|---|---:|---|"
row "none" "load_period_s = 1e9"
row "mesh amplitude +30 %" "load_period_s = 1e9\nload_phase_rad = 1.5707963267948966\nmesh_amplitude_rel = 0.3"
row "mesh amplitude -30 %" "load_period_s = 1e9\nload_phase_rad = -1.5707963267948966\nmesh_amplitude_rel = 0.3"
for sev in 0.25 0.5 1.0; do
  row "tooth defect, severity $sev (nominal load, warm)" "load_period_s = 1e9" "$sev"
done
