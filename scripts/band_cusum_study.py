#!/usr/bin/python3
"""The shipped band CUSUM (`[decision] band_cusum = true`, docs/method.md §6 "Band detector") against the
shipped detectors (k-of-n + feature CUSUM) on recordings already laid out by the earlier studies
(docs/method.md §8, "Session 12: shipped as opt-in"). Everything runs through `ptda train` / `ptda monitor`.

Layouts:
  gen2 (scripts/detection_study_gen2.py --train-days D): DIR/config.toml, DIR/train, DIR/train2.., DIR/healthy,
       DIR/sevS/faulty (or DIR/faulty: scripts/detection_study.sh machines with the job's config as
       config.toml). Trained on every train* recording; judged: healthy and each faulty set.
  gfd  (scripts/feature_study_gfd.sh): DIR/config.toml, DIR/healthy, DIR/broken. Trained on the first half of
       the healthy windows (--windows 0:0.5); judged: the healthy second half (--windows 0.5:1), the broken file.

Per machine and set: alarm by the shipped detectors (kofn_alarm or seq_alarm in any window), by the band
detector (band_alarm in any window), and the largest band statistic. Prints a table of machines alarmed per set.

  scripts/band_cusum_study.py --ptda build/release/cli/ptda --layout gen2 --dirs out/dev2-3d/m20* --work out/band
  extra config lines: --decision "band_cusum_k = 1.5" (repeatable)

Development seeds only: never run it on the evaluation seeds (4001-4020, 4101-4120).
"""

import argparse
import json
import os
import subprocess
import sys


def with_band(cfg_text, extra):
    lines = cfg_text.splitlines()
    add = ["band_cusum = true"] + extra
    for i, line in enumerate(lines):
        if line.strip() == "[decision]":
            return "\n".join(lines[:i + 1] + add + lines[i + 1:]) + "\n"
    return cfg_text.rstrip("\n") + "\n\n[decision]\n" + "\n".join(add) + "\n"


def judge(jsonl):
    shipped = band = False
    top = 0.0
    first_band = None
    windows = 0
    with open(jsonl) as f:
        for line in f:
            if not line.strip():
                continue
            r = json.loads(line)
            windows += 1
            shipped = shipped or r.get("kofn_alarm", False) or r.get("seq_alarm", False)
            if r.get("band_alarm", False):
                if not band:
                    first_band = (r["n"], r.get("band"), r.get("band_hz"))
                band = True
            top = max(top, r.get("band_cusum_max", 0.0))
    return windows, shipped, band, top, first_band


def run(cmd, log):
    with open(log, "w") as f:
        code = subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT).returncode
    return code


def machine(a, d):
    tag = os.path.basename(os.path.normpath(d))
    wd = os.path.join(a.work, tag)
    os.makedirs(wd, exist_ok=True)
    with open(a.config or os.path.join(d, "config.toml")) as f:
        cfg = with_band(f.read(), a.decision)
    cfg_path = os.path.join(wd, "config.toml")
    with open(cfg_path, "w") as f:
        f.write(cfg)
    base = os.path.join(wd, "baseline.bin")
    sets = []
    if a.layout == "gen2":
        trains = sorted(x for x in os.listdir(d) if x.startswith("train") and os.path.isdir(os.path.join(d, x)))
        cmd = [a.ptda, "train", "--config", cfg_path, "--out", base]
        for t in trains:
            cmd += ["--recording", os.path.join(d, t)]
        sets.append(("healthy", os.path.join(d, "healthy"), []))
        for s in sorted(x for x in os.listdir(d) if x.startswith("sev")):
            sets.append((s[3:], os.path.join(d, s, "faulty"), []))
        if os.path.isdir(os.path.join(d, "faulty")):  # scripts/detection_study.sh machines
            sets.append(("faulty", os.path.join(d, "faulty"), []))
    else:
        cmd = [a.ptda, "train", "--config", cfg_path, "--out", base, "--recording", os.path.join(d, "healthy"),
               "--windows", "0:0.5"]
        sets.append(("healthy", os.path.join(d, "healthy"), ["--windows", "0.5:1"]))
        sets.append(("broken", os.path.join(d, "broken"), []))
    if run(cmd, os.path.join(wd, "train.txt")) != 0:
        sys.exit(f"{tag}: training failed, see {wd}/train.txt")
    out = {}
    for name, rec, extra in sets:
        j = os.path.join(wd, name + ".jsonl")
        run([a.ptda, "monitor", "--recording", rec, "--config", cfg_path, "--baseline", base, "--quiet",
             "--jsonl", j] + extra, os.path.join(wd, name + ".txt"))
        out[name] = judge(j)
    return tag, out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ptda", required=True)
    ap.add_argument("--layout", choices=["gen2", "gfd"], required=True)
    ap.add_argument("--dirs", nargs="+", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--config", help="configuration of every machine (default DIR/config.toml)")
    ap.add_argument("--decision", action="append", default=[], help="extra [decision] line, e.g. band_cusum_k = 1.5")
    a = ap.parse_args()
    res = {}
    for d in a.dirs:
        tag, out = machine(a, d)
        res[tag] = out
        print(tag, " ".join(f"{s}:{'S' if v[1] else '-'}{'B' if v[2] else '-'}{v[3]:.1f}" for s, v in out.items()),
              file=sys.stderr, flush=True)
    with open(os.path.join(a.work, "results.tsv"), "w") as f:
        f.write("machine\tset\twindows\tshipped_alarm\tband_alarm\tband_cusum_max\tfirst_band_alarm\n")
        for tag, out in sorted(res.items()):
            for s, (w, sh, b, top, first) in out.items():
                f.write(f"{tag}\t{s}\t{w}\t{int(sh)}\t{int(b)}\t{top:.2f}\t{json.dumps(first)}\n")
    sets = list(next(iter(res.values())).keys())
    n = len(res)
    print(f"machines {n}; extra [decision]: {a.decision or 'none'}")
    print("| set | shipped (k-of-n + CUSUM) | band CUSUM | either | largest band statistic (median, max) |")
    print("|---|---|---|---|---|")
    for s in sets:
        sh = sum(res[t][s][1] for t in res)
        b = sum(res[t][s][2] for t in res)
        e = sum(res[t][s][1] or res[t][s][2] for t in res)
        tops = sorted(res[t][s][3] for t in res)
        print(f"| {s} | {sh} of {n} | {b} of {n} | {e} of {n} | {tops[len(tops) // 2]:.1f}, {tops[-1]:.1f} |")


if __name__ == "__main__":
    main()
