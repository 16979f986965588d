#!/usr/bin/python3
"""Detection study on the second, independently written generator (tests/gen2/g2detect.py; results in
docs/method.md §8 "Independent generator").

For every machine seed: write a healthy training recording, a healthy recording of another day and
faulty recordings of other days at each severity (one defect per machine, grown), train `ptda` on the
first with the machine's generated pipeline configuration, monitor the others, and record whether the
alarm was raised (first alarm window and detector) and how many windows were judged and abnormal.

  scripts/detection_study_gen2.py --ptda build/release/cli/ptda --seeds 2000-2009 \\
      --severities 0.25,0.5,1 --line-gain --floor-gain --out out/det-gen2 [--train-days 2]

--train-days D trains on D healthy days per machine: the commissioning day (train/) and D - 1 further
days (train2/, train3/, ...) with the generator's own day-to-day variation (the same exp(day_var N(0, 1))
factors on every harmonic level and the noise level as the test days), passed to `ptda train` as
repeated --recording, so the baseline can estimate the between-day spread (docs/method.md §5).
A --reuse directory must hold as many training days.

Output: OUT/results.tsv (seed, set, windows, abnormal, low, alarm, first alarm window, detector, exit
status) and OUT/summary.md (per set: machines alarmed, abnormal windows). Needs python3-numpy (apt).
Development seeds are 2000-2999; evaluation seeds are chosen once, at the end, and reported apart.
"""

import argparse
import json
import os
import subprocess
import sys
import time

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, "..", "tests", "gen2"))

import g2detect  # noqa: E402
import make_corpus  # noqa: E402


def run(cmd, log):
    with open(log, "w") as f:
        return subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT).returncode


def judge(jsonl):
    rows = []
    if os.path.exists(jsonl):
        with open(jsonl) as f:
            rows = [json.loads(line) for line in f if line.strip()]
    scored = [r for r in rows if r.get("status") == "scored"]
    abnormal = sum(1 for r in scored if r.get("abnormal"))
    low = sum(1 for r in scored if r.get("rms_low"))
    first = next((r for r in rows if r.get("alarm")), None)
    zr = sorted(r["z_rms"] for r in scored if isinstance(r.get("z_rms"), (int, float)))
    ze = sorted(r["z_entropy"] for r in scored if isinstance(r.get("z_entropy"), (int, float)))
    med = lambda v: v[len(v) // 2] if v else float("nan")  # noqa: E731
    return {"windows": len(scored), "abnormal": abnormal, "low": low, "alarm": first is not None,
            "first": first["n"] if first else None, "detector": first.get("detector", "k_of_n") if first else "-",
            "z_rms": med(zr), "z_entropy": med(ze), "cusum_max": max((r.get("cusum_max", 0.0) for r in rows),
                                                                  default=0.0)}


def edit_config(text, assignments):
    """Applies SECTION.KEY=VALUE assignments to a TOML text: replaces the key inside its section, or adds
    it right after the section header (the section is appended when missing)."""
    for a in assignments:
        key_path, value = a.split("=", 1)
        section, key = key_path.rsplit(".", 1)
        lines = text.split("\n")
        header = f"[{section}]"
        if header not in lines:
            lines += ["", header]
        start = lines.index(header) + 1
        end = next((i for i in range(start, len(lines)) if lines[i].startswith("[")), len(lines))
        hit = next((i for i in range(start, end) if lines[i].split("=")[0].strip() == key), None)
        if hit is None:
            lines.insert(start, f"{key} = {value}")
        else:
            lines[hit] = f"{key} = {value}"
        text = "\n".join(lines)
    return text


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ptda", required=True)
    ap.add_argument("--seeds", required=True, help="e.g. 2000-2009 or 2000,2003")
    ap.add_argument("--severities", default="0.25,0.5,1")
    ap.add_argument("--out", required=True)
    ap.add_argument("--train-cycles", type=int, default=24)
    ap.add_argument("--test-cycles", type=int, default=24)
    ap.add_argument("--day-var", type=float, default=0.05)
    ap.add_argument("--line-gain", action="store_true", help="[monitor] line_gain = true in every config")
    ap.add_argument("--floor-gain", action="store_true", help="[monitor] floor_gain = true in every config")
    ap.add_argument("--train-days", type=int, default=1, help="healthy training days per machine (default 1)")
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                    help="set a key in every machine's configuration (repeatable), e.g. thresholds.method=\"gaussian\"")
    ap.add_argument("--reuse", default="", help="take the recordings of an earlier run's OUT (same seeds, "
                    "severities and lengths) instead of writing them again")
    a = ap.parse_args()
    seeds = make_corpus.seed_list(a.seeds)
    sevs = [float(s) for s in a.severities.split(",") if s]
    os.makedirs(a.out, exist_ok=True)
    res_path = os.path.join(a.out, "results.tsv")
    results = []
    t_start = time.time()
    for seed in seeds:
        mdir = os.path.join(a.out, f"m{seed}")
        t0 = time.time()
        src = os.path.join(a.reuse, f"m{seed}") if a.reuse else mdir
        info = g2detect.make_machine(seed, mdir, 1.0, a.train_cycles, a.test_cycles, a.day_var,
                                     sets=() if a.reuse else
                                     ("train",) + tuple(f"train{d}" for d in range(2, a.train_days + 1)) +
                                     ("healthy",), line_gain=a.line_gain)
        cfg = os.path.join(mdir, "config.toml")
        with open(cfg) as f:
            text = f.read()
        if a.floor_gain:
            text = text.replace("\nline_gain = ", "\nfloor_gain = true\nline_gain = ", 1)
        with open(cfg, "w") as f:
            f.write(edit_config(text, a.set))
        base = os.path.join(mdir, "baseline.bin")
        train_cmd = [a.ptda, "train", "--config", cfg, "--out", base]
        for d in range(1, a.train_days + 1):
            train_cmd += ["--recording", os.path.join(src, "train" if d == 1 else f"train{d}")]
        rc = run(train_cmd, os.path.join(mdir, "train.txt"))
        sets = [("healthy", os.path.join(src, "healthy"))]
        for s in sevs:
            if not a.reuse:
                g2detect.make_machine(seed, os.path.join(mdir, f"sev{s:g}"), s, a.train_cycles, a.test_cycles,
                                      a.day_var, sets=("faulty",), line_gain=a.line_gain)
            sets.append((f"faulty {s:g}", os.path.join(src, f"sev{s:g}", "faulty")))
        for name, rec in sets:
            if rc != 0:
                r = {"windows": 0, "abnormal": 0, "low": 0, "alarm": False, "first": None, "detector": "-",
                     "exit": f"train failed ({rc})"}
            else:
                tag = name.replace(" ", "_")
                jsonl = os.path.join(mdir, f"{tag}.jsonl")
                code = run([a.ptda, "monitor", "--recording", rec, "--config", cfg, "--baseline", base,
                            "--jsonl", jsonl], os.path.join(mdir, f"{tag}.txt"))
                r = judge(jsonl)
                r["exit"] = str(code)
            r.update({"seed": seed, "set": name})
            results.append(r)
        print(f"machine {seed}: fs {info['fs_hz']} z {info['z']} program {info['program']} window "
              f"{info['window_len']} ({time.time() - t0:.0f} s): " +
              "; ".join(f"{r['set']} {r['abnormal']}/{r['windows']}{' ALARM' if r['alarm'] else ''}"
                        for r in results if r["seed"] == seed), flush=True)
    with open(res_path, "w") as f:
        f.write("seed\tset\twindows\tabnormal\tlow\talarm\tfirst\tdetector\texit\tz_rms_median\t"
                "z_entropy_median\tcusum_max\n")
        for r in results:
            f.write(f"{r['seed']}\t{r['set']}\t{r['windows']}\t{r['abnormal']}\t{r['low']}\t"
                    f"{'yes' if r['alarm'] else 'no'}\t{r['first'] if r['first'] is not None else '-'}\t"
                    f"{r['detector']}\t{r['exit']}\t{r.get('z_rms', float('nan')):.3f}\t"
                    f"{r.get('z_entropy', float('nan')):.3f}\t{r.get('cusum_max', 0.0):.2f}\n")
    lines = ["| set | machines alarmed | abnormal windows | first alarm by |", "|---|---|---|---|"]
    for name in ["healthy"] + [f"faulty {s:g}" for s in sevs]:
        rs = [r for r in results if r["set"] == name]
        n_al = sum(1 for r in rs if r["alarm"])
        w = sum(r["windows"] for r in rs)
        ab = sum(r["abnormal"] for r in rs)
        dets = {}
        for r in rs:
            if r["alarm"]:
                dets[r["detector"]] = dets.get(r["detector"], 0) + 1
        lines.append(f"| {name} | {n_al} of {len(rs)} | {ab} / {w} ({100.0 * ab / max(1, w):.1f} %) | "
                     + (", ".join(f"{k} {v}" for k, v in sorted(dets.items())) or "-") + " |")
    summary = "\n".join(lines) + (f"\n\nseeds {a.seeds}; training days {a.train_days}; "
                                   f"{time.time() - t_start:.0f} s\n")
    with open(os.path.join(a.out, "summary.md"), "w") as f:
        f.write(summary)
    print(summary)


if __name__ == "__main__":
    main()
