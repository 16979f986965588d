#!/usr/bin/env bash
# Per-window benchmark of issue 13 item 5, every figure a ratio measured in this one run:
#   - WindowAnalyzer::analyze() (raw, TDA, PTDA) against the KissFFT forward transform alone (dsp_bench);
#   - `ptda monitor` per window (decode + slicer + analysis + decision) against a NumPy one-FFT PTDA
#     per window written below (rfft, |R| = ||X| - a|, rms by Parseval, entropy of |R|^2).
# Both for a "before" and an "after" build (e.g. main at f134bc3 built from a `git worktree`, and HEAD).
#
# Usage: scripts/bench.sh BEFORE_BUILD_DIR AFTER_BUILD_DIR [OUT_DIR]
#   *_BUILD_DIR: release build trees holding cli/ptda and dsp/bench/dsp_bench (the KissFFT anchor is
#   taken from AFTER's dsp_bench; KissFFT is the same library in both). A "before" tree can also be
#   just those two binaries copied from a build of the older commit (mkdir -p B/cli B/dsp/bench; cp).
#   PTDA_BENCH_BEFORE_LABEL names the before build in the tables (default: f134bc3).
# Needs /usr/bin/python3 with numpy (python3-numpy). Cost: ~2 min on the 2-core development host.
set -euo pipefail
before=${1:?before build dir}
after=${2:?after build dir}
out=${3:-$(mktemp -d)}
root=$(cd "$(dirname "$0")/.." && pwd)
py=/usr/bin/python3
mkdir -p "$out"
ptda_after=$after/cli/ptda

# 1. Recordings: 600 s at constant speed (the gfd_like simulator preset moved to 25.6 kHz, 20 plateaus
#    of 30 s), cut into back-to-back windows of N = 12800 (config/examples/gfd.toml with window_len and
#    hop = 12800): the monitor's per-window time then includes decoding each sample once, as in
#    issue 13's measurement. Trained on 120 s of another seed.
cfg=$out/bench.toml
if [[ ! -f $out/baseline.bin ]]; then
  scen() {  # $1 = seed, $2 = duration_s, $3 = file
    sed -e "s/^seed *=.*/seed = $1/" -e "s/^duration_s *=.*/duration_s = $2/" \
      -e "s/^fs_hz = 64500/fs_hz = 25600/" "$root/config/scenarios/gfd_like.toml" >"$3"
  }
  scen 11 120.0 "$out/train.toml"
  scen 12 600.0 "$out/mon.toml"
  scen 12 5.0 "$out/short.toml"
  sed -e 's/^window_len *=.*/window_len = 12800/' -e 's/^hop *=.*/hop = 12800/' \
    "$root/config/examples/gfd.toml" >"$cfg"
  "$ptda_after" simulate --scenario "$out/train.toml" --out "$out/train" >/dev/null
  "$ptda_after" simulate --scenario "$out/mon.toml" --out "$out/mon" >/dev/null
  "$ptda_after" simulate --scenario "$out/short.toml" --out "$out/short" >/dev/null
  "$ptda_after" train --recording "$out/train" --config "$cfg" --out "$out/baseline.bin" >/dev/null
fi

# All times are CPU time (user + sys), not wall time: the host's 2 cores are shared.
# 2. ptda monitor per window, best of 3, before and after (same baseline and recording): the child's
#    user + sys CPU time from getrusage (microsecond resolution) over the JSONL's window count.
#    $3 = recording (default mon). With `short` (5 s, 9 windows) the figure is mostly the process's
#    start-up; the marginal cost of one window is (T(mon) - T(short)) / (windows(mon) - windows(short)).
monitor_us() {  # $1 = ptda binary, $2 = tag[, $3 = recording]; prints "CPU µs per window, windows"
  "$py" - "$1" "$out" "$cfg" "$2" "${3:-mon}" <<'PY'
import resource, subprocess, sys
ptda, out, cfg, tag, rec = sys.argv[1:6]
best = None
for _ in range(3):
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([ptda, "monitor", "--recording", f"{out}/{rec}", "--config", cfg, "--baseline",
                    f"{out}/baseline.bin", "--method", "ptda", "--jsonl", f"{out}/{tag}.jsonl"],
                   check=True, stdout=subprocess.DEVNULL)
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    windows = sum(1 for _ in open(f"{out}/{tag}.jsonl"))
    us = cpu * 1e6 / windows
    best = us if best is None else min(best, us)
print(f"{best:.2f} {windows}")
PY
}

# 3. NumPy one-FFT PTDA per window (the reference of issue 13), N = 12800, on float32 windows.
#    Run twice: with glibc's allocator defaults, and with its trim and mmap thresholds at 1 GiB. With
#    the defaults this script page-faults its temporaries in again on every call (session 31, perf
#    stat: 94,127 page faults for the whole script against 5,554 with the thresholds raised, ~70 per
#    call); on a host where a page fault is dear (the session-31 VM) that, not NumPy's arithmetic, is
#    most of what gets timed (there: ~850 µs against ~95 µs per window). The fault-free figure is the
#    stricter reference and the one issue 13's target is judged on; both are reported.
numpy_us() {  # $@ = environment settings for the Python process
  env "$@" "$py" - <<'PY'
import time, numpy as np
n = 12800
rng = np.random.default_rng(1)
t = np.arange(n) / 25600.0
def window():
    ph = rng.uniform(0, 2 * np.pi, 2)
    return (1.4 * np.sin(2 * np.pi * 520 * t + ph[0]) + 0.9 * np.sin(2 * np.pi * 2600 * t + ph[1])
            + rng.standard_normal(n)).astype(np.float32)
a = np.mean([np.abs(np.fft.rfft(window())) for _ in range(8)], axis=0)
xs = [window() for _ in range(64)]
half = n // 2
def ptda(x):
    X = np.fft.rfft(x)
    e = (np.abs(X) - a) ** 2
    s = e[0] + 2.0 * e[1:half].sum() + e[half]
    rms = np.sqrt(s / n / n)
    p = e[1:] / e[1:].sum()
    p = p[p > 0]
    h = -(p * np.log(p)).sum() / np.log(half)
    return rms, h
best = 1e9
for _ in range(5):
    t0 = time.process_time()
    for _ in range(4):
        for x in xs:
            ptda(x)
    best = min(best, (time.process_time() - t0) / (4 * len(xs)))
print(f"{best * 1e6:.2f}")
PY
}

# 4. dsp_bench: analyze() per method and the forward transform alone, N = 12800.
bench_json() {  # $1 = dsp_bench, $2 = filter, $3 = file
  "$1" --benchmark_filter="$2" --benchmark_repetitions=5 --benchmark_report_aggregates_only=true \
    --benchmark_format=json >"$3" 2>/dev/null
}
bench_json "$after/dsp/bench/dsp_bench" 'BM_RealFftForward/N:12800$' "$out/fft.json"
bench_json "$before/dsp/bench/dsp_bench" 'BM_Analyze/N:12800/' "$out/analyze_before.json"
bench_json "$after/dsp/bench/dsp_bench" 'BM_Analyze/N:12800/' "$out/analyze_after.json"
read -r mon_before win_long < <(monitor_us "$before/cli/ptda" before)
read -r mon_after _ < <(monitor_us "$ptda_after" after)
read -r short_before win_short < <(monitor_us "$before/cli/ptda" before_short short)
read -r short_after _ < <(monitor_us "$ptda_after" after_short short)
np_us=$(numpy_us)
np_kept_us=$(numpy_us MALLOC_TRIM_THRESHOLD_=1073741824 MALLOC_MMAP_THRESHOLD_=1073741824)

"$py" - "$out" "$mon_before" "$mon_after" "$np_us" "${PTDA_BENCH_BEFORE_LABEL:-f134bc3}" "$np_kept_us" \
  "$short_before" "$short_after" "$win_long" "$win_short" <<'PY'
import json, sys
out, mon_b, mon_a, np_us = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
label = sys.argv[5]
np_kept = float(sys.argv[6])
short_b, short_a, w_long, w_short = (float(v) for v in sys.argv[7:11])
def marginal(long_us, short_us):  # CPU per window past the start-up, from the two recordings
    return (long_us * w_long - short_us * w_short) / (w_long - w_short)
marg_b, marg_a = marginal(mon_b, short_b), marginal(mon_a, short_a)
def median(path, name_part):
    for b in json.load(open(f"{out}/{path}"))["benchmarks"]:
        if b.get("aggregate_name") == "median" and name_part in b["name"]:
            return b["cpu_time"]
    raise SystemExit(f"{name_part} not in {path}")
fft = median("fft.json", "BM_RealFftForward/N:12800")
print(f"| N = 12800 | before ({label}) | after | before / FFT | after / FFT |")
print("|---|---|---|---|---|")
print(f"| KissFFT forward alone | {fft:.1f} µs | {fft:.1f} µs | 1.00 | 1.00 |")
for m, name in ((0, "raw"), (1, "tda"), (2, "ptda")):
    b = median("analyze_before.json", f"BM_Analyze/N:12800/method:{m}")
    a = median("analyze_after.json", f"BM_Analyze/N:12800/method:{m}")
    print(f"| analyze() {name} | {b:.1f} µs | {a:.1f} µs | {b / fft:.2f} | {a / fft:.2f} |")
print()
print(f"| per window, N = 12800 | before ({label}) | after |")
print("|---|---|---|")
print(f"| `ptda monitor --method ptda` (best of 3) | {mon_b:.1f} µs | {mon_a:.1f} µs |")
print(f"| `ptda monitor` start-up (5 s recording, {w_short:.0f} windows: CPU in all) | "
      f"{short_b * w_short / 1e3:.1f} ms | {short_a * w_short / 1e3:.1f} ms |")
print(f"| `ptda monitor` past start-up, per window | {marg_b:.1f} µs | {marg_a:.1f} µs |")
print(f"| NumPy one-FFT PTDA, glibc allocator defaults | {np_us:.1f} µs | {np_us:.1f} µs |")
print(f"| NumPy one-FFT PTDA, temporaries kept mapped (stricter) | {np_kept:.1f} µs | {np_kept:.1f} µs |")
print(f"| NumPy (defaults) / `ptda monitor` | {np_us / mon_b:.2f}x | {np_us / mon_a:.2f}x |")
print(f"| NumPy (kept mapped) / `ptda monitor` | {np_kept / mon_b:.2f}x | {np_kept / mon_a:.2f}x |")
print(f"| NumPy (kept mapped) / `ptda monitor` past start-up | {np_kept / marg_b:.2f}x | {np_kept / marg_a:.2f}x |")
print(f"| `ptda monitor` / KissFFT forward | {mon_b / fft:.2f} | {mon_a / fft:.2f} |")
PY
