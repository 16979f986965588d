#!/usr/bin/env bash
# Time-domain vs order-domain PTDA under speed ripple (issue 16, docs/results-order.md): runs
# dsp/bench/order_bench for one seed set (one seed = one simulated machine) and prints, per ripple and
# domain, the mean and the minimum over machines of the window AUC of rms_res and of entropy_res, and
# the mean abnormal share of healthy and faulty windows.
#
# Usage: scripts/order_bench.sh BUILD_DIR OUT_CSV SEEDS [order_bench options...]
#   e.g. scripts/order_bench.sh build/release out/order-dev.csv 1-3
#        scripts/order_bench.sh build/release out/order-eval.csv 101-110
# Development seeds 1-3 were used to choose the fault amplitude; 101-110 are reported and never tuned on.
set -euo pipefail
build=$1
out=$2
seeds=$3
shift 3
mkdir -p "$(dirname "$out")"
"$build/dsp/bench/order_bench" --seeds "$seeds" "$@" > "$out"
/usr/bin/python3 - "$out" <<'PY'
import csv, sys
from collections import defaultdict
rows = list(csv.DictReader(open(sys.argv[1])))
g = defaultdict(list)
for r in rows:
    g[(float(r["ripple"]), r["domain"])].append(r)
print("| ripple | domain | machines | AUC rms mean (min) | AUC entropy mean (min) | healthy abnormal | faulty abnormal |")
print("|---|---|---|---|---|---|---|")
for (rip, dom), rs in sorted(g.items()):
    a = [float(r["auc_rms"]) for r in rs]
    e = [float(r["auc_entropy"]) for r in rs]
    ha = sum(float(r["healthy_abnormal"]) for r in rs) / len(rs)
    fa = sum(float(r["faulty_abnormal"]) for r in rs) / len(rs)
    print(f"| ±{rip*100:.0f} % | {dom} | {len(rs)} | {sum(a)/len(a):.3f} ({min(a):.3f}) | "
          f"{sum(e)/len(e):.3f} ({min(e):.3f}) | {ha*100:.1f} % | {fa*100:.1f} % |")
PY
