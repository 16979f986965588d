#!/usr/bin/python3
"""Band-aggregate study for issue 12 (docs/method.md §8, "Session 24"): would one-sided CUSUMs on the
*mean* standardised band energy of groups of adjacent bands (and of all 32 bands) find the
quarter-severity defect on more machines than one CUSUM per band?

Reuses scripts/feature_study_gen2.py (its residual, clean bands and per-class training statistics) on
machine directories of scripts/detection_study_gen2.py --train-days D. Per class: each band's mean and
total sd (within-window and between-day, the sd of the day means floored at 0.3 of the within sd) from
the training days' leave-one-out band energies; then the same for each aggregate of the training
windows' band z. Per judged recording: every window's band z and aggregate z. The report counts
machines alarmed per set and rule (CUSUM max over the recording above h).

  scripts/band_aggregate_study.py --ptda build/release/cli/ptda --dirs out/dev2-3d/m20* --work out/agg
  scripts/band_aggregate_study.py --report out/agg/agg.json

Development seeds only: never run on the evaluation seeds (4001-4020, 4101-4120). Needs python3-numpy.
"""
import argparse, importlib.util, json, math, os, sys
import numpy as np

_spec = importlib.util.spec_from_file_location(
    "fsg", os.path.join(os.path.dirname(os.path.abspath(__file__)), "feature_study_gen2.py"))
fsg = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fsg)
NB = fsg.NB


def agg_defs(width):
    d = {}
    for j in range(0, NB, width):
        d[f"g{width}_{j}"] = list(range(j, min(NB, j + width)))
    return d


def machine(args, d, aggs):
    mach = fsg.Machine(d, args.work)
    fs, n = mach.fs, mach.n
    train = mach.train_windows(args.ptda)
    classes = sorted({w[0] for ws in train.values() for w in ws})
    models = {c: fsg.ClassModel([w[2] for ws in train.values() for w in ws if w[0] == c], n) for c in classes}
    f_in = mach.f_in
    bands = fsg.BANDS
    tb = {t: [(w[0], np.array([fsg.features(models[w[0]], w[2], f_in(w[1]), fs, loo=True)[b] for b in bands]))
              for w in ws] for t, ws in train.items()}
    bstat, astat = {}, {}
    for c in classes:
        per = {t: np.array([v for cc, v in tb[t] if cc == c]) for t in tb}
        bstat[c] = [fsg.day_stats([per[t][:, b] for t in per if per[t].size]) for b in range(NB)]
        mu = np.array([s[0] for s in bstat[c]]); sd = np.array([s[1] for s in bstat[c]])
        zt = {t: (per[t] - mu) / sd for t in per if per[t].size}
        astat[c] = {a: fsg.day_stats([zt[t][:, idx].mean(axis=1) for t in zt]) for a, idx in aggs.items()}
    result = {}
    for name, specs in args.sets:
        rec = os.path.join(d, fsg.name_to_dir(d, name, specs))
        ws = fsg.windows(rec, os.path.join(d, specs), fs, n)
        zb, za = [], {a: [] for a in aggs}
        for c, v, x, _ in ws:
            if c not in models:
                continue
            fv = fsg.features(models[c], x, f_in(v), fs)
            mu = np.array([s[0] for s in bstat[c]]); sd = np.array([s[1] for s in bstat[c]])
            z = (np.array([fv[b] for b in bands]) - mu) / sd
            zb.append(z.tolist())
            for a, idx in aggs.items():
                m, s = astat[c][a]
                za[a].append((float(z[idx].mean()) - m) / s)
        result[name] = {"bands": zb, "aggs": za}
    return mach.tag, result


def cusum_max(z, k):
    s = top = 0.0
    for v in z:
        s = max(0.0, s + v - k)
        top = max(top, s)
    return top


def report(path):
    data = json.load(open(path))
    tags = sorted(data)
    sets = list(data[tags[0]].keys())

    def band_max(r, k):
        b = np.array(r["bands"])
        return max((cusum_max(b[:, j], k) for j in range(b.shape[1])), default=0.0) if b.size else 0.0

    def group_max(r, k):
        return max(cusum_max(v, k) for a, v in r["aggs"].items() if a != "all")

    def all_max(r, k):
        return cusum_max(r["aggs"]["all"], k)

    rules = [(f"per band, k = {k}", band_max, k, 10.0) for k in (1.0, 0.75, 0.5)]
    for k, h in ((1.0, 10.0), (0.75, 10.0), (0.5, 10.0), (0.5, 15.0), (1.0, 5.0)):
        rules.append((f"groups of adjacent bands, k = {k}, h = {h:g}", group_max, k, h))
        rules.append((f"all bands, k = {k}, h = {h:g}", all_max, k, h))
    print(f"machines: {len(tags)} ({', '.join(tags)})")
    print("| rule (alarm: CUSUM max > h; h = 10 unless said) | " + " | ".join(sets) + " |")
    print("|---|" + "---|" * len(sets))
    for name, f, k, h in rules:
        print(f"| {name} | " + " | ".join(f"{sum(f(data[t][s], k) > h for t in tags)} of {len(tags)}"
                                          for s in sets) + " |")
    print()
    for k in (1.0, 0.75, 0.5):
        hv = sorted(band_max(data[t][sets[0]], k) for t in tags)
        print(f"per band, k = {k}: largest {sets[0]} statistic {hv[-1]:.1f}; " +
              "; ".join(f"{s} sorted " + ", ".join(f"{band_max(data[t][s], k):.1f}" for t in
                                                     sorted(tags, key=lambda t: band_max(data[t][s], k)))
                        for s in sets[1:2]))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ptda")
    ap.add_argument("--dirs", nargs="+")
    ap.add_argument("--work")
    ap.add_argument("--sets", default="healthy=healthy.jsonl,q=faulty_0.25.jsonl,h=faulty_0.5.jsonl,f=faulty_1.jsonl")
    ap.add_argument("--width", type=int, default=4, help="bands per group (default 4)")
    ap.add_argument("--report", metavar="AGG_JSON", help="only print the tables of an earlier run")
    args = ap.parse_args()
    if args.report:
        report(args.report)
        return
    if not (args.ptda and args.dirs and args.work):
        ap.error("--ptda, --dirs and --work are required (or --report AGG_JSON)")
    fsg.CLEAN_BANDS = True
    args.sets = [s.split("=", 1) for s in args.sets.split(",")]
    aggs = agg_defs(args.width)
    aggs["all"] = list(range(NB))
    os.makedirs(args.work, exist_ok=True)
    path = os.path.join(args.work, "agg.json")
    out = json.load(open(path)) if os.path.exists(path) else {}
    for d in args.dirs:
        tag = os.path.basename(os.path.normpath(d))
        if tag in out:
            continue
        if not os.path.exists(os.path.join(d, "baseline.bin")):
            sys.exit(f"band_aggregate_study: {d}: no baseline.bin (an unfinished machine directory?)")
        tag, res = machine(args, d, aggs)
        out[tag] = res
        json.dump(out, open(path, "w"))
        print(tag, "done", file=sys.stderr, flush=True)
    report(path)


if __name__ == "__main__":
    main()
