#!/usr/bin/env bash
# Runs `ptda gap-bench` on every corpus of a directory made by scripts/gap_corpus.sh and writes the
# markdown tables (summary per corpus, confusion matrices, per-case tables) and the JSON:
#   DIR/bench/<tag>.md, DIR/bench/<tag>.json, DIR/bench/<tag>.log (per-case lines)
# Usage: scripts/gap_eval.sh --dir DIR [--tag NAME] [--threads N] [--ptda PATH] [--only gen2,gfd-injected,simulator]
# One bench process; each case's diagnosis runs in a child process (peak RSS per case).
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
dir="" tag="bench" threads=1 only="gen2,gfd-injected,simulator"
ptda="${here}/build/release/cli/ptda"
while [[ $# -gt 0 ]]; do
  case "$1" in
    --dir) dir="$2"; shift 2 ;;
    --tag) tag="$2"; shift 2 ;;
    --threads) threads="$2"; shift 2 ;;
    --ptda) ptda="$2"; shift 2 ;;
    --only) only="$2"; shift 2 ;;
    -h|--help) sed -n '2,7p' "$0"; exit 0 ;;
    *) echo "gap_eval: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
[[ -n "$dir" ]] || { echo "gap_eval: --dir DIR is required" >&2; exit 2; }
[[ -x "$ptda" ]] || { echo "gap_eval: $ptda not built" >&2; exit 1; }
args=(gap-bench --threads "$threads")
if [[ ",$only," == *",simulator,"* && -f "$dir/project-simulator.conf" ]]; then
  cases="$(sed -n 's/^cases=//p' "$dir/project-simulator.conf")"
  seed="$(sed -n 's/^seed=//p' "$dir/project-simulator.conf")"
  jobs="$(sed -n 's/^jobs=//p' "$dir/project-simulator.conf")"
  args+=(--cases "$cases" --seed "$seed" --jobs "$jobs" --work "$dir/bench/sim-work")
fi
for c in gen2 gfd-injected; do
  if [[ ",$only," == *",$c,"* && -f "$dir/$c/corpus.json" ]]; then args+=(--corpus "$dir/$c"); fi
done
[[ ${#args[@]} -gt 3 ]] || { echo "gap_eval: no corpus found in $dir" >&2; exit 1; }
mkdir -p "$dir/bench"
echo "gap_eval: $ptda ${args[*]}" | tee "$dir/bench/$tag.log"
"$ptda" "${args[@]}" --json "$dir/bench/$tag.json" --markdown "$dir/bench/$tag.md" \
  > "$dir/bench/$tag.txt" 2>> "$dir/bench/$tag.log"
cat "$dir/bench/$tag.txt"
echo "gap_eval: tables in $dir/bench/$tag.md (code $(git -C "$here" rev-parse --short HEAD 2>/dev/null || echo '?'))"
