#!/usr/bin/env bash
# Drift soak (issue 12 item 4; docs/benchmarks.md, "Drift soak"): HOURS of healthy operation of the
# joint-4 rotation job with slow drift (config/scenarios/drift_soak.toml: 8-hour load/temperature cycle
# with mesh amplitude +-30 %, cold start with lubricant warm-up, a 15-minute program pause every hour),
# replayed through `ptdad` at fast pace with the shipped configuration (config/examples/ptdad.toml).
#
# Streaming: the day is simulated in 10-minute pieces (240 cycles, ~52 MB each), one after the other;
# each piece continues the drift of the previous one (time_offset_s, initial_coldness from its
# truth.toml), is replayed through a fresh `ptdad --exit-at-end` (WAV + candump replay, pace "fast") and
# through `ptda monitor --jsonl` (the per-window timeline; the daemon equals the monitor window for window,
# tests/golden/daemon_replay_test.cpp), then deleted. So memory stays flat whatever HOURS is. The
# alarm state (k-of-n, latch) starts afresh in each piece: an alarm counts once per piece at most.
#
# Baseline (PTDA_SOAK_TRAIN, config/examples/joint_rotation.toml):
#   "day" (default since session 9): commissioning over a whole *other* simulated day (seeds from
#        PTDA_SOAK_TRAIN_SEED, never the evaluation's): PTDA_SOAK_TRAIN_PIECES (default 8) healthy pieces of
#        PTDA_SOAK_TRAIN_CYCLES (default PTDA_SOAK_CHUNK_CYCLES: 10 minutes) spread evenly over that day's 24 h (so over its
#        three 8-hour load cycles: every load phase), the first right after the cold start and one with a
#        program pause in its middle (the cooled restart). Each piece is the same scenario and drift law
#        as the evaluation, at the drift time and coldness the day's schedule gives it (one pause per
#        hour, cooling and warm-up as in the simulator's closed form). Each piece is its own
#        `--recording`, so the between-recording spread sizes the bands and the CUSUM allowance
#        (docs/method.md sections 5-6).
#   "short" (the recipe up to session 6): a short healthy run of a warm machine (40 cycles, ~100 s,
#        drift time 0: nominal load, coldness 0.02).
#   PTDA_SOAK_BASELINE=FILE skips training and uses FILE (e.g. out/drift-soak-healthy/work/baseline.bin of
#   an earlier run with the same recipe and drift setting).
#
# Usage: scripts/drift_soak.sh [hours] [mode] [build_dir] [out_dir]
#   hours      simulated hours (default 24; fractions allowed, e.g. 0.05 = 3 minutes)
#   mode       "healthy" (default) or "fault": a spur-tooth defect whose severity grows linearly from 0
#              at PTDA_SOAK_FAULT_ONSET_H (default hours/4) to 1 at PTDA_SOAK_FAULT_FULL_H (default
#              3 hours/4), constant within a piece (the value at its middle)
#   build_dir  default build/release (needs cli/ptda and daemon/ptdad)
#   out_dir    default out/drift-soak-<mode>: pieces.tsv (one row per piece), summary.md
# Environment: PTDA_SOAK_CHUNK_CYCLES (cycles per piece, default 240), PTDA_SOAK_SEED (default 1; piece i
#              uses seed SEED + i), PTDA_SOAK_TRAIN ("day" or "short"), PTDA_SOAK_TRAIN_SEED (default
#              900001; training piece j uses TRAIN_SEED + j), PTDA_SOAK_TRAIN_PIECES, PTDA_SOAK_TRAIN_CYCLES,
#              PTDA_SOAK_BASELINE (see Baseline above), PTDA_SOAK_CONFIG (pipeline config for train and
#              monitor; default config/examples/joint_rotation.toml),
#              PTDA_SOAK_PTDAD_DROPIN (a TOML file added to ptdad's drop-ins, e.g. `[decision] band_cusum = true`
#              to match PTDA_SOAK_CONFIG), PTDA_SOAK_PAUSE_EVERY_CYCLES (a program pause every N cycles in
#              every piece, for long pieces: 1440 with PTDA_SOAK_CHUNK_CYCLES=14000 gives the hourly pause of
#              the default schedule and 12-hour pieces, so the detectors' state runs on for 12 h),
#              PTDA_SOAK_KEEP_JSONL=1 (keep each piece's `ptda monitor --jsonl` as out_dir/pieceN.jsonl.gz),
#              PTDA_SOAK_NO_DRIFT=1 (reference run: load cycle and warm-up off, pauses kept),
#              PTDA_SOAK_SUMMARY_ONLY=WALL_S (only rewrite out_dir/summary.md from its pieces.tsv, e.g. of an
#              interrupted run; WALL_S is the wall time to report).
# Cost (session 9): about 10 s of simulation and 2 s of replay per 10-minute piece (~29 min per simulated
# day on the shared 2-core machine under load); the day recipe's training adds 8 pieces and a train of
# ~2 min. Peak RSS of the simulator (streaming) ~7 MB, of ptdad ~9.4 MB.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
hours=${1:-24}
mode=${2:-healthy}
build=${3:-$root/build/release}
out=${4:-$root/out/drift-soak-$mode}
ptda=$build/cli/ptda
ptdad=$build/daemon/ptdad
template=$root/config/scenarios/drift_soak.toml
pipeline=${PTDA_SOAK_CONFIG:-$root/config/examples/joint_rotation.toml}
chunk_cycles=${PTDA_SOAK_CHUNK_CYCLES:-240}
seed0=${PTDA_SOAK_SEED:-1}
pause_every_chunks=6        # one program pause per hour (every 6th 10-minute piece)
pause_s=900                 # 15 minutes
start_unix=1700000000       # UNIX time of the soak's start (the recordings' clock)

[[ -x "$ptda" && -x "$ptdad" ]] || { echo "drift_soak: build ptda and ptdad first ($build)" >&2; exit 1; }
[[ "$mode" == healthy || "$mode" == fault ]] || { echo "drift_soak: mode must be healthy or fault" >&2; exit 2; }
total_s=$(awk -v h="$hours" 'BEGIN { if (h + 0 <= 0) exit 1; printf "%.3f", h * 3600 }') ||
  { echo "drift_soak: hours must be > 0, not '$hours'" >&2; exit 2; }
onset_h=${PTDA_SOAK_FAULT_ONSET_H:-$(awk -v h="$hours" 'BEGIN { print h / 4 }')}
full_h=${PTDA_SOAK_FAULT_FULL_H:-$(awk -v h="$hours" 'BEGIN { print 3 * h / 4 }')}

# summarize MODE OUT_DIR WALL_S: summary.md from OUT_DIR/pieces.tsv.
summarize() {
  local mode=$1 out=$2 wall=$3
  awk -F'\t' -v mode="$mode" -v onset="$onset_h" -v full="$full_h" -v wall="$wall" '
  NR == 1 { next }
  {
    ++pieces; hours = $3; win += $8; sc += $9; ab += $10; al += $11; alw += $12
    if ($11 > 0) ++alarm_pieces
    sim += $15; dae += $16; if ($17 > rss) rss = $17; if ($18 > simrss) simrss = $18
    if ($6 == "yes") { if ($17 > prss) prss = $17 } else { if ($17 > nrss) nrss = $17 }
    healthy = (mode == "healthy" || $7 + 0 == 0)
    if (healthy) { h_al += $11; h_ab += $10; h_sc += $9; h_hours += $3 - $2 }
    if (!healthy && fw == "" && $13 != "-") { fw = $13; fw_sev = $7 }
    if (!healthy && fa == "" && $14 != "-") { fa = $14; fa_sev = $7 }
  }
  END {
    printf "| quantity | value |\n|---|---:|\n"
    printf "| simulated hours | %.2f (%d pieces) |\n", hours, pieces
    printf "| windows cut / scored / abnormal | %d / %d / %d (%.2f %%) |\n", win, sc, ab, (sc ? 100 * ab / sc : 0)
    printf "| alarms raised by ptdad (at most one per 10-minute piece) | %d (in %d pieces) |\n", al, alarm_pieces
    if (mode == "healthy") {
      printf "| false alarms per day | %.1f |\n", (hours > 0 ? al * 24 / hours : 0)
      printf "| abnormal windows per day (warnings) | %.0f |\n", (hours > 0 ? ab * 24 / hours : 0)
    } else {
      printf "| healthy part (severity 0): hours / abnormal windows / alarms | %.2f / %d of %d / %d |\n", h_hours, h_ab, h_sc, h_al
      printf "| fault: severity 0 until %s h, 1 at %s h (linear, per piece) | |\n", onset, full
      printf "| first warning (abnormal window) in a faulty piece, hours since the start | %s h (severity %s) |\n", fw == "" ? "none" : fw, fw_sev
      printf "| first alarm (k-of-n or CUSUM) in a faulty piece, hours since the start | %s h (severity %s) |\n", fa == "" ? "none" : fa, fa_sev
      if (fw != "" && fa != "") printf "| warning ahead of the alarm | %.2f h |\n", fa - fw
    }
    printf "| peak RSS of ptdad: pieces without / with a 15-minute pause | %.1f MB / %.1f MB |\n", nrss / 1024, prss / 1024
    printf "| peak RSS of the simulator (one piece) | %.0f MB |\n", simrss / 1024
    printf "| wall time: simulation / ptdad replay / total | %.0f s / %.0f s / %.0f s |\n", sim, dae, wall
    printf "| ptdad replay speed | %.0f x real time |\n", (dae > 0 ? hours * 3600 / dae : 0)
  }' "$out/pieces.tsv" >"$out/summary.md"
}

if [[ -n ${PTDA_SOAK_SUMMARY_ONLY:-} ]]; then  # re-summarise an existing (e.g. interrupted) run
  [[ -f "$out/pieces.tsv" ]] || { echo "drift_soak: no $out/pieces.tsv" >&2; exit 1; }
  summarize "$mode" "$out" "$PTDA_SOAK_SUMMARY_ONLY"
  cat "$out/summary.md"
  exit 0
fi
rm -rf "$out"
mkdir -p "$out/work"
work=$out/work
tsv=$out/pieces.tsv

# scenario TEMPLATE OUT key=value...: the template with [drift]/top-level keys replaced, plus an
# optional fault (FAULT_SEVERITY > 0).
make_scenario() {
  local dst=$1 cycles=$2 seed=$3 start=$4 offset=$5 cold=$6 pause_every=$7 severity=$8
  sed -e "s/^cycles = .*/cycles = $cycles/" -e "s/^seed = .*/seed = $seed/" \
    -e "s/^start_time_s = .*/start_time_s = $start/" -e "s/^time_offset_s = .*/time_offset_s = $offset/" \
    -e "s/^initial_coldness = .*/initial_coldness = $cold/" \
    -e "s/^pause_every_cycles = .*/pause_every_cycles = $pause_every/" \
    -e "s/^pause_s = .*/pause_s = $([[ $pause_every -gt 0 ]] && echo $pause_s || echo 0.0)/" \
    -e "s/^lead_in_s = .*/lead_in_s = 0.0/" "$template" >"$dst"
  if [[ ${PTDA_SOAK_NO_DRIFT:-0} == 1 ]]; then
    sed -i -e "s/^load_period_s = .*/load_period_s = 0.0/" -e "s/^mesh_amplitude_rel = .*/mesh_amplitude_rel = 0.0/" \
      -e "s/^resonance_shift_rel = .*/resonance_shift_rel = 0.0/" -e "s/^warmup_tau_s = .*/warmup_tau_s = 0.0/" \
      -e "s/^initial_coldness = .*/initial_coldness = 1.0/" -e "s/^cold_amplitude_rel = .*/cold_amplitude_rel = 0.0/" \
      -e "s/^cold_noise_rel = .*/cold_noise_rel = 0.0/" -e "s/^cooldown_tau_s = .*/cooldown_tau_s = 0.0/" "$dst"
  fi
  if awk -v s="$severity" 'BEGIN { exit !(s > 0) }'; then
    cat >>"$dst" <<EOF

[[fault]]
kind = "spur_tooth"
severity = $severity
impulse_amplitude_ms2 = 5.0
resonance_hz = 3000.0
damping_ratio = 0.05
am_depth = 0.15
EOF
  fi
}
truth_value() { sed -n "s/^$2 = //p" "$1/truth.toml" | head -1; }

# --- baseline ----------------------------------------------------------------------------------------
train_recipe=${PTDA_SOAK_TRAIN:-day}
if [[ -n ${PTDA_SOAK_BASELINE:-} ]]; then
  [[ -f $PTDA_SOAK_BASELINE ]] || { echo "drift_soak: PTDA_SOAK_BASELINE: no file $PTDA_SOAK_BASELINE" >&2; exit 2; }
  cp "$PTDA_SOAK_BASELINE" "$work/baseline.bin"
  echo "baseline: $PTDA_SOAK_BASELINE (not trained here)" >"$out/train.txt"
elif [[ $train_recipe == short ]]; then  # a short healthy run of a warm machine
  make_scenario "$work/train.toml" 40 $((seed0 + 100000)) $((start_unix - 86400)) 0.0 0.02 0 0
  "$ptda" simulate --scenario "$work/train.toml" --out "$work/train" >/dev/null
  "$ptda" train --recording "$work/train" --config "$pipeline" --out "$work/baseline.bin" >"$out/train.txt"
elif [[ $train_recipe == day ]]; then  # pieces spread over another simulated day
  train_seed=${PTDA_SOAK_TRAIN_SEED:-900001}
  train_pieces=${PTDA_SOAK_TRAIN_PIECES:-8}
  train_cycles=${PTDA_SOAK_TRAIN_CYCLES:-$chunk_cycles}
  [[ $train_pieces =~ ^[0-9]+$ && $train_pieces -ge 3 && $train_cycles =~ ^[0-9]+$ && $train_cycles -ge 8 ]] ||
    { echo "drift_soak: PTDA_SOAK_TRAIN_PIECES must be >= 3 and PTDA_SOAK_TRAIN_CYCLES >= 8" >&2; exit 2; }
  # The evaluation uses seeds SEED .. SEED + (pieces of HOURS); training must not share any.
  awk -v a="$train_seed" -v n="$train_pieces" -v s="$seed0" -v h="$hours" 'BEGIN {
    e = s + int(h * 3600 / 600) + 10; exit !(a + n <= s || a > e) }' ||
    { echo "drift_soak: PTDA_SOAK_TRAIN_SEED $train_seed overlaps the evaluation's seeds (from $seed0)" >&2; exit 2; }
  # The training day's schedule, as the evaluation's: pieces of train_cycles, the 6th of each hour with a
  # 15-minute pause in its middle; piece k's drift time and coldness from the drift law's closed form
  # (warm-up e^{-t/900 s} while working, cooling 1 - (1 - c) e^{-t/3600 s} in a pause; drift_soak.toml).
  # Pieces chosen: index round(j * P / N) for j = 0..N-1 of the P pieces of 24 h; if none is a pause
  # piece, the middle one moves to the nearest pause piece.
  awk -v n="$train_pieces" -v cyc="$train_cycles" -v every="$pause_every_chunks" -v ps="$pause_s" \
    -v tw="$(sed -n 's/^warmup_tau_s = \([0-9.e+-]*\).*/\1/p' "$template")" \
    -v tc="$(sed -n 's/^cooldown_tau_s = \([0-9.e+-]*\).*/\1/p' "$template")" '
  BEGIN {
    per = cyc * 2.525; t = 0; c = 1; P = 0
    while (t < 86400 - 5) {
      T[P] = t; C[P] = c; pz = ((P + 1) % every == 0)
      if (pz) { w = per / 2; c *= exp(-w / tw); c = 1 - (1 - c) * exp(-ps / tc); c *= exp(-w / tw); t += per + ps }
      else { c *= exp(-per / tw); t += per }
      Z[P] = pz; ++P
    }
    any = 0
    for (j = 0; j < n; ++j) { I[j] = int(j * P / n + 0.5); if (Z[I[j]]) any = 1 }
    if (!any) { m = int(n / 2); k = I[m]; while (!Z[k]) ++k; I[m] = k }
    for (j = 0; j < n; ++j) printf "%d %.3f %.6f %d\n", I[j], T[I[j]], C[I[j]], Z[I[j]]
  }' >"$work/train_pieces.txt"
  train_args=()
  j=0
  printf 'day_piece\tdrift_time_h\tload\tcoldness\tpause\tseed\n' >"$out/train_pieces.tsv"
  while read -r idx t_s c_start pz; do
    pe=0; [[ $pz -eq 1 ]] && pe=$((train_cycles / 2))
    make_scenario "$work/train$j.toml" "$train_cycles" $((train_seed + j)) \
      "$(awk -v s="$start_unix" -v t="$t_s" 'BEGIN { printf "%.6f", s - 86400 + t }')" "$t_s" "$c_start" "$pe" 0
    rm -rf "$work/train$j"
    "$ptda" simulate --scenario "$work/train$j.toml" --out "$work/train$j" >/dev/null
    train_args+=(--recording "$work/train$j")
    printf '%d\t%.3f\t%.3f\t%s\t%s\t%d\n' "$idx" "$(awk -v t="$t_s" 'BEGIN { print t / 3600 }')" \
      "$(awk -v t="$t_s" 'BEGIN { print sin(2 * 3.141592653589793 * t / 28800) }')" "$c_start" \
      "$([[ $pz -eq 1 ]] && echo yes || echo no)" $((train_seed + j)) >>"$out/train_pieces.tsv"
    j=$((j + 1))
  done <"$work/train_pieces.txt"
  "$ptda" train "${train_args[@]}" --config "$pipeline" --out "$work/baseline.bin" >"$out/train.txt"
  for ((i = 0; i < j; ++i)); do rm -rf "$work/train$i"; done
else
  echo "drift_soak: PTDA_SOAK_TRAIN must be day or short, not '$train_recipe'" >&2; exit 2
fi

# --- ptdad drop-in: replay the current piece at fast pace -------------------------------------------
mkdir -p "$work/ptdad.d" "$work/status"
cat >"$work/ptdad.d/50-soak.toml" <<EOF
[daemon]
baseline = "$work/baseline.bin"
status_dir = "$work/status"
[adc]
backend = "wav"
recording = "$work/piece"
pace = "fast"
[can]
backend = "candump"
replay_file = ""
pace = "fast"
EOF
if [[ -n ${PTDA_SOAK_PTDAD_DROPIN:-} ]]; then
  [[ -f $PTDA_SOAK_PTDAD_DROPIN ]] || { echo "drift_soak: PTDA_SOAK_PTDAD_DROPIN: no file $PTDA_SOAK_PTDAD_DROPIN" >&2; exit 2; }
  cp "$PTDA_SOAK_PTDAD_DROPIN" "$work/ptdad.d/60-extra.toml"
fi

printf 'piece\tt0_h\tt1_h\tload_start\tcoldness_start\tpause\tseverity\twindows\tscored\tabnormal\tptdad_alarms\tmonitor_alarm_windows\tfirst_abnormal_h\tfirst_alarm_h\tsim_s\tptdad_s\tptdad_rss_kb\tsim_rss_kb\n' >"$tsv"
t=0.0
cold=1.0
piece=0
wall_start=$(date +%s.%N)
while awk -v t="$t" -v e="$total_s" 'BEGIN { exit !(t < e - 5) }'; do  # stop within two cycles of the end
  # The last piece is shortened to end near HOURS (whole cycles of ~2.5 s).
  cycles=$(awk -v t="$t" -v e="$total_s" -v c="$chunk_cycles" 'BEGIN { n = int((e - t) / 2.525 + 0.5); if (n > c) n = c; if (n < 4) n = 4; print n }')
  pause_every=0
  if [[ -n ${PTDA_SOAK_PAUSE_EVERY_CYCLES:-} ]]; then
    pause_every=$PTDA_SOAK_PAUSE_EVERY_CYCLES  # long pieces: a pause every N cycles inside each piece
  elif [[ $(((piece + 1) % pause_every_chunks)) -eq 0 && $cycles -gt 2 ]]; then pause_every=$((cycles / 2)); fi
  severity=0
  if [[ $mode == fault ]]; then
    severity=$(awk -v t="$t" -v c="$cycles" -v a="$onset_h" -v b="$full_h" 'BEGIN {
      m = (t + c * 2.525 / 2) / 3600; s = (b > a) ? (m - a) / (b - a) : (m >= a); if (s < 0) s = 0; if (s > 1) s = 1; printf "%.4f", s }')
  fi
  start=$(awk -v s="$start_unix" -v t="$t" 'BEGIN { printf "%.6f", s + t }')
  make_scenario "$work/piece.toml" "$cycles" $((seed0 + piece)) "$start" "$t" "$cold" "$pause_every" "$severity"
  rm -rf "$work/piece"
  /usr/bin/time -f "%e %M" -o "$work/sim.time" "$ptda" simulate --scenario "$work/piece.toml" --out "$work/piece" >/dev/null
  sim_stats=$(tail -1 "$work/sim.time")
  rm -f "$work/status/status.json"
  /usr/bin/time -f "%e %M" -o "$work/ptdad.time" "$ptdad" --config "$root/config/examples/ptdad.toml" \
    --config-dir "$work/ptdad.d" --exit-at-end --foreground >"$work/ptdad.out" 2>"$work/ptdad.err" || {
    echo "drift_soak: ptdad failed on piece $piece:" >&2; tail -5 "$work/ptdad.err" >&2; exit 1; }
  ptdad_stats=$(tail -1 "$work/ptdad.time")
  "$ptda" monitor --recording "$work/piece" --config "$pipeline" --baseline "$work/baseline.bin" --quiet \
    --jsonl "$work/piece.jsonl" >/dev/null
  if [[ ${PTDA_SOAK_KEEP_JSONL:-0} == 1 ]]; then gzip -c "$work/piece.jsonl" >"$out/piece$piece.jsonl.gz"; fi
  status=$(cat "$work/status/status.json")
  member() { sed -E "s/.*\"$1\":([0-9.]+).*/\\1/" <<<"$status"; }
  end_s=$(truth_value "$work/piece" time_end_s)
  [[ -n "$end_s" ]] || end_s=$(awk -v t="$t" -v d="$(truth_value "$work/piece" duration_s)" 'BEGIN { print t + d }')
  load_start=$(awk -v t="$t" 'BEGIN { printf "%.3f", sin(2 * 3.141592653589793 * t / 28800) }')
  cold_text=$(printf '%.4f' "$cold")
  if [[ ${PTDA_SOAK_NO_DRIFT:-0} == 1 ]]; then load_start="-" cold_text="-"; fi
  # Timeline from the monitor's windows: t_start is UNIX time; hours since the soak start.
  read -r windows scored abnormal alarm_windows first_abn first_alarm < <(awk -v s0="$start_unix" '
    { ++n; match($0, /"t_start":[0-9.e+]+/); t = (substr($0, RSTART + 10, RLENGTH - 10) - s0) / 3600 }
    /"status":"scored"/ { ++sc }
    /"abnormal":true/ { ++ab; if (fa == "") fa = sprintf("%.4f", t) }
    /"alarm":true/ { ++al; if (fl == "") fl = sprintf("%.4f", t) }
    END { printf "%d %d %d %d %s %s\n", n, sc, ab, al, (fa == "" ? "-" : fa), (fl == "" ? "-" : fl) }' "$work/piece.jsonl")
  printf '%d\t%.6f\t%.6f\t%s\t%s\t%s\t%s\t%d\t%d\t%d\t%d\t%d\t%s\t%s\t%s\t%s\t%s\t%s\n' "$piece" \
    "$(awk -v t="$t" 'BEGIN { print t / 3600 }')" "$(awk -v t="$end_s" 'BEGIN { print t / 3600 }')" "$load_start" \
    "$cold_text" "$([[ $pause_every -gt 0 ]] && echo yes || echo no)" "$severity" "$windows" \
    "$(member windows_scored)" "$(member windows_abnormal)" "$(member alarms_raised)" "$alarm_windows" \
    "$first_abn" "$first_alarm" ${sim_stats% *} ${ptdad_stats% *} ${ptdad_stats#* } ${sim_stats#* } >>"$tsv"
  # The daemon and the monitor judged the same windows.
  if [[ $(member windows_scored) != "$scored" || $(member windows_abnormal) != "$abnormal" ]]; then
    echo "drift_soak: piece $piece: ptdad scored/abnormal $(member windows_scored)/$(member windows_abnormal)" \
      "!= ptda monitor $scored/$abnormal" >&2
    exit 1
  fi
  t=$end_s
  cold=$(truth_value "$work/piece" coldness_at_end)
  [[ -n "$cold" ]] || cold=1.0  # no drift table (PTDA_SOAK_NO_DRIFT without pauses)
  piece=$((piece + 1))
  echo "drift_soak: piece $piece done, $(awk -v t="$t" 'BEGIN { printf "%.2f", t / 3600 }') h" >&2
done
rm -rf "$work/piece"
wall_end=$(date +%s.%N)

# --- summary -------------------------------------------------------------------------------------------
summarize "$mode" "$out" "$(awk -v a="$wall_start" -v b="$wall_end" 'BEGIN { print b - a }')"
cat "$out/summary.md"
