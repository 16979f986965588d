#!/usr/bin/env bash
# Builds the gap-bench corpora for given seeds into one directory (docs/gap.md "Bench"):
#   OUT/gen2/           second, independently written generator (tests/gen2/g2robot.py)
#   OUT/gfd-injected/   healthy GFD recordings with injected effects (tests/gen2/g2gfd.py)
#   OUT/project-simulator.conf   the project simulator corpus: `ptda gap-bench --cases N --seed S --jobs ...`
#                                generates its cases itself; this file records N, S and the jobs.
# Usage:
#   scripts/gap_corpus.sh --out DIR [--gen2-seeds A-B] [--gfd-seeds A-B] [--sim-seed S] [--sim-cases N]
#                         [--sim-jobs A.toml,B.toml] [--ptda PATH] [--gfd DATA_DIR]
# Seeds: development 1000-1999; evaluation seeds are chosen once, at the end, and never developed on.
# Example (the development corpus): scripts/gap_corpus.sh --out /work/corpora/dev --gen2-seeds 1000-1019 \
#   --gfd-seeds 1000-1009
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
out="" gen2_seeds="" gfd_seeds="" sim_seed="" sim_cases=26 sim_jobs=""
ptda="${here}/build/release/cli/ptda"
gfd="${here}/../shared/data/gfd"
while [[ $# -gt 0 ]]; do
  case "$1" in
    --out) out="$2"; shift 2 ;;
    --gen2-seeds) gen2_seeds="$2"; shift 2 ;;
    --gfd-seeds) gfd_seeds="$2"; shift 2 ;;
    --sim-seed) sim_seed="$2"; shift 2 ;;
    --sim-cases) sim_cases="$2"; shift 2 ;;
    --sim-jobs) sim_jobs="$2"; shift 2 ;;
    --ptda) ptda="$2"; shift 2 ;;
    --gfd) gfd="$2"; shift 2 ;;
    -h|--help) sed -n '2,13p' "$0"; exit 0 ;;
    *) echo "gap_corpus: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
[[ -n "$out" ]] || { echo "gap_corpus: --out DIR is required" >&2; exit 2; }
[[ -n "$gen2_seeds$gfd_seeds$sim_seed" ]] || { echo "gap_corpus: give --gen2-seeds, --gfd-seeds or --sim-seed" >&2; exit 2; }
# Debian's interpreter carries python3-numpy (scripts/bootstrap.sh); PYTHON overrides.
py="${PYTHON:-}"
if [[ -z "$py" ]]; then py=python3; [[ -x /usr/bin/python3 ]] && py=/usr/bin/python3; fi
"$py" -c 'import numpy' 2>/dev/null || { echo "gap_corpus: $py has no numpy (scripts/bootstrap.sh installs python3-numpy)" >&2; exit 1; }
mkdir -p "$out"
if [[ -n "$gen2_seeds" ]]; then
  "$py" "${here}/tests/gen2/make_corpus.py" gen2 --seeds "$gen2_seeds" --out "$out/gen2"
fi
if [[ -n "$gfd_seeds" ]]; then
  [[ -x "$ptda" ]] || { echo "gap_corpus: $ptda not built (cmake --build --preset release --target ptda)" >&2; exit 1; }
  [[ -d "$gfd" ]] || { echo "gap_corpus: GFD data not found at $gfd (--gfd DIR)" >&2; exit 1; }
  "$py" "${here}/tests/gen2/make_corpus.py" gfd --seeds "$gfd_seeds" --out "$out/gfd-injected" --gfd "$gfd" --ptda "$ptda"
fi
if [[ -n "$sim_seed" ]]; then
  jobs="${sim_jobs:-${here}/config/scenarios/palletizing_healthy.toml,${here}/config/scenarios/deburring_healthy.toml}"
  printf 'cases=%s\nseed=%s\njobs=%s\n' "$sim_cases" "$sim_seed" "$jobs" > "$out/project-simulator.conf"
fi
echo "gap_corpus: wrote $out ($(git -C "$here" rev-parse --short HEAD 2>/dev/null || echo '?'))"
