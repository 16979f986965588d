#!/usr/bin/env bash
# The measured-data study of docs/results-gfd.md: the SpectraQuest gearbox data (../shared/data/gfd),
# healthy (h30hz<load>) against one broken tooth (b30hz<load>), loads 0-80 %, accelerometers a1-a4.
# Per load and channel: `ptda import` both files (--rate 64500, --shaft-speed 30Hz), `ptda train` on the
# first half of the healthy windows, `ptda monitor` the second half and the whole broken-tooth file with
# raw, TDA and PTDA, and `ptda evaluate` each method. Writes markdown tables and SVG figures.
#
# Usage: scripts/gfd_study.sh [build_dir] [out_dir]
#   build_dir  where `cli/ptda` was built (default build/release)
#   out_dir    outputs (default out/gfd-study): tables.md (the full table), summary.md (win counts),
#              figures/*.svg (AUC against load per channel and feature), work/ (recordings, JSONL).
# Environment: PTDA_GFD_DATA (data dir, default ../shared/data/gfd next to the checkout),
#              PTDA_GFD_CONFIG (pipeline config, default config/examples/gfd.toml),
#              PTDA_GFD_WINDOW_LEN (optional: window_len = hop override, written to out_dir/study.toml).
# To refresh the docs: scripts/gfd_study.sh build/release out/gfd-study && cp out/gfd-study/figures/*.svg docs/figures/gfd/
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build/release}
out=${2:-$root/out/gfd-study}
data=${PTDA_GFD_DATA:-$root/../shared/data/gfd}
config=${PTDA_GFD_CONFIG:-$root/config/examples/gfd.toml}
window_len=${PTDA_GFD_WINDOW_LEN:-}
ptda=$build/cli/ptda
rate_hz=64500
loads="0 20 40 60 80"
channels="a1 a2 a3 a4"
methods="raw tda ptda"

[[ -x "$ptda" ]] || { echo "gfd_study: $ptda not found: build the ptda target first" >&2; exit 1; }
[[ -d "$data" ]] || { echo "gfd_study: data directory $data not found" >&2; exit 1; }

work=$out/work
rm -rf "$out"
mkdir -p "$work" "$out/figures" "$out/results"

if [[ -n "$window_len" ]]; then
  # The same configuration with another window length (= hop): a derived copy in the output dir.
  sed -e "s/^window_len = .*/window_len = $window_len/" -e "s/^hop = .*/hop = $window_len/" "$config" \
    >"$out/study.toml"
  config=$out/study.toml
fi

tables=$out/tables.md
{
  echo "Sample rate assumed: $rate_hz Hz; configuration: ${config#"$root"/} (window_len $(sed -n "s/^window_len = //p" "$config")); train: healthy windows 0:0.5;"
  echo "test: healthy windows 0.5:1 (h) against every broken-tooth window (f)."
  echo
} >"$tables"
header_done=0

for load in $loads; do
  for ch in $channels; do
    case_dir=$work/load${load}_$ch
    mkdir -p "$case_dir"
    echo "== load $load %, channel $ch" >&2
    "$ptda" import --csv "$data/h30hz$load.csv.gz" --column "$ch" --rate "$rate_hz" --shaft-speed 30Hz --force \
      --out "$case_dir/healthy" >"$case_dir/import_healthy.txt"
    "$ptda" import --csv "$data/b30hz$load.csv.gz" --column "$ch" --rate "$rate_hz" --shaft-speed 30Hz --force \
      --out "$case_dir/broken" >"$case_dir/import_broken.txt"
    "$ptda" train --recording "$case_dir/healthy" --config "$config" --out "$case_dir/baseline.bin" \
      --windows 0:0.5 >"$case_dir/train.txt"
    for m in $methods; do
      "$ptda" monitor --recording "$case_dir/healthy" --config "$config" --baseline "$case_dir/baseline.bin" \
        --method "$m" --windows 0.5:1 --quiet --jsonl "$case_dir/healthy.$m.jsonl" >/dev/null
      "$ptda" monitor --recording "$case_dir/broken" --config "$config" --baseline "$case_dir/baseline.bin" \
        --method "$m" --quiet --jsonl "$case_dir/broken.$m.jsonl" >/dev/null
      hdr=()
      [[ $header_done == 1 ]] && hdr=(--no-header)
      "$ptda" evaluate --healthy "$case_dir/healthy.$m.jsonl" --faulty "$case_dir/broken.$m.jsonl" \
        --label "$load %, $ch" --x "$load" --json "$case_dir/eval.$m.json" --markdown "${hdr[@]}" >>"$tables"
      header_done=1
      cat "$case_dir/eval.$m.json" >>"$out/results/$ch.jsonl"
      # case, method, RMS AUC, entropy AUC, alarm on healthy, alarm on broken (full precision, for the counts)
      j=$(cat "$case_dir/eval.$m.json")
      printf '%s\t%s\t%s\t%s\t%s\t%s\n' "$load %, $ch" "$m" \
        "$(sed -E 's/.*"rms_res":\{[^}]*"auc":([^,}]*).*/\1/' <<<"$j")" \
        "$(sed -E 's/.*"entropy_res":\{[^}]*"auc":([^,}]*).*/\1/' <<<"$j")" \
        "$(sed -E 's/.*"healthy":\{[^}]*"alarm":(true|false).*/\1/' <<<"$j")" \
        "$(sed -E 's/.*"faulty":\{[^}]*"alarm":(true|false).*/\1/' <<<"$j")" >>"$out/results/auc.tsv"
    done
  done
done

for ch in $channels; do
  for f in rms_res entropy_res; do
    "$ptda" evaluate --plot "$out/figures/auc_${f}_$ch.svg" --results "$out/results/$ch.jsonl" --feature "$f" \
      --title "$f ROC AUC, accelerometer $ch (broken tooth vs healthy)" --x-label "load [%]" >/dev/null
  done
done

# Counts over the load/channel pairs, from results/auc.tsv (the AUCs at full precision; a tie counts
# for PTDA). Separability = max(AUC, 1 - AUC).
awk -F'\t' '
  function sep(a) { return a >= 0.5 ? a : 1 - a }
  {
    c = $1; m = $2; rms[c, m] = $3 + 0; ent[c, m] = $4 + 0; clean[c, m] = ($5 == "false" && $6 == "true")
    if (!(c in seen)) { seen[c] = 1; order[++n] = c }
  }
  END {
    split("raw tda ptda", ms, " ")
    for (i = 1; i <= n; ++i) {
      c = order[i]
      if (rms[c, "ptda"] >= rms[c, "tda"] && rms[c, "ptda"] >= rms[c, "raw"]) r_b++
      if (sep(rms[c, "ptda"]) >= sep(rms[c, "tda"]) && sep(rms[c, "ptda"]) >= sep(rms[c, "raw"])) rs_b++
      if (ent[c, "ptda"] >= ent[c, "tda"] && ent[c, "ptda"] >= ent[c, "raw"]) e_b++
      if (sep(ent[c, "ptda"]) >= sep(ent[c, "tda"]) && sep(ent[c, "ptda"]) >= sep(ent[c, "raw"])) es_b++
      for (j = 1; j <= 3; ++j) {
        m = ms[j]
        if (rms[c, m] >= 0.9) r9[m]++
        if (rms[c, m] > 0.5) rhi[m]++
        if (sep(rms[c, m]) >= 0.9) rs9[m]++
        if (sep(ent[c, m]) >= 0.9) es9[m]++
        if (clean[c, m]) cl[m]++
      }
    }
    printf "| claim | load/channel pairs of %d |\n|---|---:|\n", n
    printf "| PTDA RMS AUC >= TDA and raw RMS AUC | %d |\n", r_b
    printf "| PTDA RMS separability >= TDA and raw | %d |\n", rs_b
    printf "| PTDA entropy AUC >= TDA and raw | %d |\n", e_b
    printf "| PTDA entropy separability >= TDA and raw | %d |\n", es_b
    printf "| RMS AUC > 0.5 (broken higher): raw / TDA / PTDA | %d / %d / %d |\n", rhi["raw"], rhi["tda"], rhi["ptda"]
    printf "| RMS AUC >= 0.9: raw / TDA / PTDA | %d / %d / %d |\n", r9["raw"], r9["tda"], r9["ptda"]
    printf "| RMS separability >= 0.9: raw / TDA / PTDA | %d / %d / %d |\n", rs9["raw"], rs9["tda"], rs9["ptda"]
    printf "| entropy separability >= 0.9: raw / TDA / PTDA | %d / %d / %d |\n", es9["raw"], es9["tda"], es9["ptda"]
    printf "| alarm on the broken tooth and not on healthy: raw / TDA / PTDA | %d / %d / %d |\n", cl["raw"], cl["tda"], cl["ptda"]
  }' "$out/results/auc.tsv" >"$out/summary.md"

cat "$out/summary.md"
echo "gfd_study: tables in $tables, figures in $out/figures" >&2
