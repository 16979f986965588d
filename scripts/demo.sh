#!/usr/bin/env bash
# The end-to-end demo of the offline tool: install what is missing, build, simulate a healthy job and a
# developing gearbox fault, train the baseline on the healthy recording, monitor the faulty one (windows,
# features, thresholds and the alarm on the terminal) and write an HTML report comparing raw, TDA and PTDA.
# Usage: scripts/demo.sh            (outputs in out/demo/)
set -euo pipefail
cd "$(dirname "$0")/.."

scripts/bootstrap.sh
cmake --preset release
cmake --build --preset release -j"$(nproc 2>/dev/null || echo 2)"

PTDA=build/release/cli/ptda
OUT=out/demo
CONFIG=config/examples/joint_rotation.toml
rm -rf "$OUT"
mkdir -p "$OUT"

step() { printf '\n\033[1m== %s\033[0m\n' "$*"; }

step "1. Simulate 20 healthy cycles of the joint-4 rotation job (training data)"
"$PTDA" simulate --scenario config/scenarios/joint_rotation_healthy.toml --out "$OUT/healthy_train" --seed 101

step "2. Simulate 20 more healthy cycles with another seed (a fresh healthy check)"
"$PTDA" simulate --scenario config/scenarios/joint_rotation_healthy.toml --out "$OUT/healthy_fresh" --seed 202

step "3. Simulate a developing spur-tooth fault (healthy cycles 0-7, then growing over 10 cycles)"
"$PTDA" simulate --scenario config/scenarios/demo_developing_fault.toml --out "$OUT/developing_fault"

step "4. Train the baseline: segment classes, TDA/PTDA averages, thresholds per method"
"$PTDA" train --recording "$OUT/healthy_train" --config "$CONFIG" --out "$OUT/baseline.bin"

step "5. Monitor the fresh healthy recording with PTDA (expect no alarm)"
"$PTDA" monitor --recording "$OUT/healthy_fresh" --config "$CONFIG" --baseline "$OUT/baseline.bin" --quiet \
  --jsonl "$OUT/healthy_fresh.ptda.jsonl"

step "6. Monitor the developing fault with PTDA: every window, its features against the bands, the alarm"
"$PTDA" monitor --recording "$OUT/developing_fault" --config "$CONFIG" --baseline "$OUT/baseline.bin" \
  --jsonl "$OUT/developing_fault.ptda.jsonl"

step "7. The same with TDA and raw residuals, for comparison (summaries only)"
for method in tda raw; do
  "$PTDA" monitor --recording "$OUT/developing_fault" --config "$CONFIG" --baseline "$OUT/baseline.bin" \
    --method "$method" --quiet --jsonl "$OUT/developing_fault.$method.jsonl"
done

step "8. HTML report: raw vs TDA vs PTDA on the healthy and the faulty recording"
"$PTDA" report --recording "$OUT/healthy_fresh" --label healthy --recording "$OUT/developing_fault" \
  --label developing-fault --config "$CONFIG" --baseline "$OUT/baseline.bin" --html "$OUT/report.html"

echo
echo "Report: $(pwd)/$OUT/report.html"
echo "Per-window JSONL: $(pwd)/$OUT/*.jsonl"
