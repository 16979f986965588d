#!/usr/bin/env bash
# GFD corpus of the feature study (docs/method.md §8 "Session 11"): per load and channel, import the
# healthy and broken-tooth files like scripts/gfd_study.sh, train a baseline on the first half of the
# healthy windows (only so `ptda monitor` reports every window's position), monitor both whole files,
# then run scripts/feature_study_gen2.py --split-train (first healthy half trains, second half is the
# healthy set, the broken file the faulty set).
#
# Usage: scripts/feature_study_gfd.sh BUILD_DIR OUT_DIR [LOADS] [CHANNELS]
#   e.g. scripts/feature_study_gfd.sh build/release out/feat-gfd "0 20 40 60 80" "a1 a2 a3 a4"
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
ptda=$1/cli/ptda
out=$2
loads=${3:-0 20 40 60 80}
channels=${4:-a1 a2 a3 a4}
data=${PTDA_GFD_DATA:-$root/../shared/data/gfd}
config=$root/config/examples/gfd.toml
mkdir -p "$out"
dirs=()
for load in $loads; do
  for ch in $channels; do
    c=$out/load${load}_$ch
    mkdir -p "$c"
    cp "$config" "$c/config.toml"
    if [[ ! -f $c/broken.jsonl ]]; then
      "$ptda" import --csv "$data/h30hz$load.csv.gz" --column "$ch" --rate 64500 --shaft-speed 30Hz --force \
        --out "$c/healthy" >/dev/null
      "$ptda" import --csv "$data/b30hz$load.csv.gz" --column "$ch" --rate 64500 --shaft-speed 30Hz --force \
        --out "$c/broken" >/dev/null
      "$ptda" train --recording "$c/healthy" --config "$c/config.toml" --out "$c/baseline.bin" \
        --windows 0:0.5 >/dev/null
      "$ptda" monitor --recording "$c/healthy" --config "$c/config.toml" --baseline "$c/baseline.bin" \
        --quiet --jsonl "$c/healthy.jsonl" >/dev/null || true
      "$ptda" monitor --recording "$c/broken" --config "$c/config.toml" --baseline "$c/baseline.bin" \
        --quiet --jsonl "$c/broken.jsonl" >/dev/null || true
    fi
    dirs+=("$c")
  done
done
/usr/bin/python3 "$root/scripts/feature_study_gen2.py" --ptda "$ptda" --split-train --dirs "${dirs[@]}" \
  --work "$out/feat" --sets healthy=healthy.jsonl,broken=broken.jsonl
