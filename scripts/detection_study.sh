#!/usr/bin/env bash
# Detection study on simulated machines (docs/method.md, "Thresholds and evidence accumulation"): per
# job preset and seed ("machine"), train on a healthy recording (seed S), monitor an independent healthy
# recording (seed S+500) and a faulty one at reduced severity (seed S+1000), and report for each
# whether the alarm was raised (and by which detector) and the abnormal fraction.
#
# Usage: scripts/detection_study.sh BUILD_DIR OUT_DIR SEVERITY SEED...
#   e.g. scripts/detection_study.sh build/release out/det 0.25 1001 1002 1003
# Environment: PTDA_STUDY_JOBS (default "joint_rotation spot_welding arc_welding"),
#              PTDA_STUDY_CONFIG_DIR (default config/examples; a job's config is <dir>/<job>.toml).
# Output: OUT_DIR/results.tsv (job, seed, set, windows, abnormal, alarm, first alarm window, detector)
# and a per-job summary on stdout.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=$1
out=$2
severity=$3
shift 3
ptda=$build/cli/ptda
jobs=${PTDA_STUDY_JOBS:-joint_rotation spot_welding arc_welding}
cfgdir=${PTDA_STUDY_CONFIG_DIR:-$root/config/examples}
mkdir -p "$out"
res=$out/results.tsv
: >"$res"
for job in $jobs; do
  cfg=$cfgdir/$job.toml
  sed -E "s/^severity = .*/severity = $severity/" "$root/config/scenarios/${job}_faulty.toml" >"$out/${job}_faulty.toml"
  for seed in "$@"; do
    w=$out/$job/$seed
    mkdir -p "$w"
    "$ptda" simulate --scenario "$root/config/scenarios/${job}_healthy.toml" --seed "$seed" --out "$w/train" >/dev/null
    "$ptda" simulate --scenario "$root/config/scenarios/${job}_healthy.toml" --seed $((seed + 500)) --out "$w/healthy" >/dev/null
    "$ptda" simulate --scenario "$out/${job}_faulty.toml" --seed $((seed + 1000)) --out "$w/faulty" >/dev/null
    "$ptda" train --recording "$w/train" --config "$cfg" --out "$w/baseline.bin" >"$w/train.txt"
    for set in healthy faulty; do
      "$ptda" monitor --recording "$w/$set" --config "$cfg" --baseline "$w/baseline.bin" --jsonl "$w/$set.jsonl" \
        >"$w/$set.txt" || true
      python3 - "$job" "$seed" "$set" "$w/$set.jsonl" >>"$res" <<'PY'
import json, sys
job, seed, s, path = sys.argv[1:5]
rows = [json.loads(l) for l in open(path)]
scored = [r for r in rows if r.get("status") == "scored"]
ab = sum(1 for r in scored if r.get("abnormal"))
first = next((r for r in rows if r.get("alarm")), None)
det = first.get("detector", "k_of_n") if first else "-"
print("\t".join([job, seed, s, str(len(scored)), str(ab), "yes" if first else "no",
                 str(first["n"]) if first else "-", det]))
PY
    done
  done
done
python3 - "$res" <<'PY'
import sys, collections
rows = [l.rstrip("\n").split("\t") for l in open(sys.argv[1])]
by = collections.defaultdict(lambda: collections.Counter())
for job, seed, s, n, ab, alarm, first, det in rows:
    c = by[(job, s)]
    c["machines"] += 1; c["alarm"] += alarm == "yes"; c["windows"] += int(n); c["abnormal"] += int(ab)
    if alarm == "yes": c["det_" + det] += 1
for (job, s), c in sorted(by.items()):
    dets = ", ".join(f"{k[4:]} {v}" for k, v in sorted(c.items()) if k.startswith("det_"))
    print(f"{job:15s} {s:8s} alarm on {c['alarm']:2d} of {c['machines']:2d} machines; abnormal windows "
          f"{c['abnormal']}/{c['windows']} ({100.0*c['abnormal']/max(1,c['windows']):.1f} %)"
          + (f"; first alarm by: {dets}" if dets else ""))
PY
