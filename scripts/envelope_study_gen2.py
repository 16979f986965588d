#!/usr/bin/python3
"""Envelope-periodicity study for issue 12's quarter-severity gap (docs/method.md §8, "Session 38").

The question: a local tooth defect knocks once per input-shaft revolution. The band detector sees that
knock only as extra energy in one band, which a healthy new day's level change (about +-2 dB) hides at
quarter severity. How much of a band's energy repeats at the input-shaft rate is a ratio: a day's gain
does not move it, and a healthy floor has none. Does it separate?

Per window (positions and classes from `ptda monitor --jsonl`, as scripts/feature_study_gen2.py does),
the level-referred PTDA residual is split into NBE equal bands of 1..N/2. For each band:
  z(t)  the band's analytic signal (its bins moved to baseband, one inverse FFT of a few hundred points)
  e(t)  = |z(t)|^2, mean removed, Hann-weighted
  c_m   = |DFT of e at m f_in|^2, m = 1..M (f_in the input-shaft frequency from the window's own speed)
  d_j   = the same at (m + 1/2) f_in, between the orders
  benv_b = ln(mean c_m / mean d_j)
Windows with fewer than --min-revs input-shaft revolutions give no value. Each band's value is
standardised per class against the training windows (within + between-day sd, as the band detector),
and a one-sided CUSUM per band (k, h as the band detector's defaults) alarms when any band exceeds h.
Pooled: per class and band, ln(sum of the on-order powers / sum of the between-order powers) over all of
a recording's windows, as a z against the training days' values (--pooled-z alarms).

  scripts/envelope_study_gen2.py --ptda build/release/cli/ptda --dirs out/d3/m20* --work out/env

Needs python3-numpy. Development seeds only; the evaluation seeds are never run with this script.
"""

import argparse
import math
import os
import sys
import warnings

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import feature_study_gen2 as F  # noqa: E402


def band_envelope_features(R, n, f_in_hz, fs, nbe, m_orders, min_revs):
    """(benv_b, on_b, off_b) for each of nbe bands of the residual spectrum R (one-sided, N/2 + 1 bins):
    on/off are the mean envelope powers at and between the orders; NaN when the window holds fewer than
    min_revs input-shaft revolutions."""
    out = np.full(nbe, np.nan)
    on_p = np.full(nbe, np.nan)
    off_p = np.full(nbe, np.nan)
    T = n / fs
    revs = f_in_hz * T
    if revs < min_revs:
        return out, on_p, off_p
    edges = np.linspace(1, R.size, nbe + 1).astype(int)
    for b in range(nbe):
        k0, k1 = edges[b], edges[b + 1]
        width = k1 - k0
        m_top = min(m_orders, int(0.5 * width / max(revs, 1e-9)))
        if m_top < 1:
            continue
        L = 1
        while L < 2 * width:
            L *= 2
        Z = np.zeros(L, complex)
        Z[:width] = R[k0:k1]
        z = np.fft.ifft(Z)
        e = np.abs(z) ** 2
        e = e - e.mean()
        t = np.arange(L) / L  # fraction of the window
        w = 0.5 - 0.5 * np.cos(2 * np.pi * (np.arange(L) + 0.5) / L)
        ew = e * w
        on = np.arange(1, m_top + 1) * revs
        off = (np.arange(1, m_top + 1) + 0.5) * revs
        def power(cycles):
            ph = np.exp(-2j * np.pi * np.outer(cycles, t))
            return np.abs(ph @ ew) ** 2
        c = power(on).mean()
        d = power(off).mean()
        on_p[b], off_p[b] = c, d
        if c > 0 and d > 0:
            out[b] = math.log(c / d)
    return out, on_p, off_p


def machine(args, d):
    m = F.Machine(d, args.work)
    fs, n = m.fs, m.n
    train = m.train_windows(args.ptda)
    if args.train_days:
        train = {t: train[t] for t in sorted(train)[:args.train_days]}
    classes = sorted({w[0] for ws in train.values() for w in ws})
    models = {c: F.ClassModel([w[2] for ws in train.values() for w in ws if w[0] == c], n) for c in classes}

    def feat(c, v, x, loo):
        R = F.residual_spectrum(models[c], x, loo)
        return band_envelope_features(R, n, m.f_in(v), fs, args.bands, args.orders, args.min_revs)

    tv_all = {t: [(w[0], feat(w[0], w[1], w[2], True)) for w in ws] for t, ws in train.items()}
    tv = {t: [(c, f[0]) for c, f in rows] for t, rows in tv_all.items()}
    # Pooled: per class and band, ln(sum on / sum off) over a recording's windows.
    def pooled(rows):
        acc = {}
        for c, f in rows:
            a = acc.setdefault(c, [np.zeros(args.bands), np.zeros(args.bands), np.zeros(args.bands)])
            ok = np.isfinite(f[1]) & np.isfinite(f[2])
            a[0][ok] += f[1][ok]
            a[1][ok] += f[2][ok]
            a[2][ok] += 1
        return {c: (np.log(np.where((a[0] > 0) & (a[1] > 0), a[0] / np.where(a[1] > 0, a[1], 1), np.nan)),
                    a[2]) for c, a in acc.items()}
    train_pooled = {t: pooled(rows) for t, rows in tv_all.items()}
    stats = {}
    for c in classes:
        stats[c] = []
        for b in range(args.bands):
            per_day = [[v[b] for cc, v in tv[t] if cc == c and np.isfinite(v[b])] for t in train]
            if sum(len(x) for x in per_day) < 5:
                stats[c].append(None)
            else:
                stats[c].append(F.day_stats([x for x in per_day if x]))
    res = {}
    for name, spec in args.sets:
        rec = os.path.join(d, F.name_to_dir(d, name, spec))
        ws = F.windows(rec, os.path.join(d, spec), fs, n)
        zs = []  # per window: z per band (NaN where not scored)
        rows = []
        for c, v, x, _ in ws:
            if c not in models:
                continue
            full = feat(c, v, x, False)
            rows.append((c, full))
            fv = full[0]
            z = np.full(args.bands, np.nan)
            for b in range(args.bands):
                st = stats[c][b]
                if st is not None and np.isfinite(fv[b]):
                    z[b] = (fv[b] - st[0]) / st[1]
            zs.append((c, z))
        # Pooled z: against the training days' pooled ratios; sd = the exponential sums' own spread
        # (on: M terms per window, off: 2M; ln of a ratio of such sums) plus the days' spread.
        pz = -np.inf
        for c, (lr, cnt) in pooled(rows).items():
            days = [train_pooled[t][c][0] for t in train_pooled if c in train_pooled[t]]
            if not days:
                continue
            with warnings.catch_warnings():  # bands without a value on every day: NaN, not a warning
                warnings.simplefilter("ignore", RuntimeWarning)
                mu = np.nanmean(days, axis=0)
                sd_days = np.nanstd(days, axis=0, ddof=1) if len(days) > 1 else np.zeros(args.bands)
            sd_own = np.sqrt((1.0 + 0.5) / (args.orders * np.maximum(cnt, 1)))
            z = (lr - mu) / np.sqrt(sd_own ** 2 + sd_days ** 2)
            if np.isfinite(z).any():
                pz = max(pz, float(np.nanmax(z)))
        res[name] = (zs, pz)
    return m.tag, res


def cusum_top(zs, k, per_class):
    """Largest one-sided CUSUM over bands (and classes when per_class) of one recording."""
    top = 0.0
    keys = sorted({c for c, _ in zs}) if per_class else [None]
    for key in keys:
        rows = [z for c, z in zs if key is None or c == key]
        if not rows:
            continue
        a = np.array(rows)
        for b in range(a.shape[1]):
            s = 0.0
            for v in a[:, b]:
                if np.isfinite(v):
                    s = max(0.0, s + v - k)
                    top = max(top, s)
    return top


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ptda", required=True)
    ap.add_argument("--dirs", nargs="+", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--sets", default="healthy=healthy.jsonl,q=faulty_0.25.jsonl,h=faulty_0.5.jsonl")
    ap.add_argument("--bands", type=int, default=16)
    ap.add_argument("--orders", type=int, default=6)
    ap.add_argument("--min-revs", type=float, default=2.0)
    ap.add_argument("--k", type=float, default=1.0)
    ap.add_argument("--h", type=float, default=10.0)
    ap.add_argument("--pooled-z", type=float, default=4.0, help="alarm level of the pooled ratio's z")
    ap.add_argument("--train-days", type=int, default=0,
                    help="train on the first D of the machine's train* recordings only (default all)")
    args = ap.parse_args()
    args.sets = [s.split("=", 1) for s in args.sets.split(",")]
    names = [s for s, _ in args.sets]
    print("| machine | " + " | ".join(f"{s}: benv max CUSUM (largest band median z); pooled z" for s in names)
          + " |")
    print("|---" * (1 + len(names)) + "|")
    alarms = {s: 0 for s in names}
    pooled_alarms = {s: 0 for s in names}
    for d in args.dirs:
        tag, res = machine(args, d)
        cells = []
        for s in names:
            zs, pz = res[s]
            top = cusum_top(zs, args.k, True)
            alarms[s] += top > args.h
            pooled_alarms[s] += pz > args.pooled_z
            a = np.array([z for _, z in zs])
            med = np.nanmedian(a, axis=0) if a.size else np.array([np.nan])
            cells.append(f"{top:.1f} ({np.nanmax(med):+.2f}); {pz:+.1f}")
        print(f"| {tag} | " + " | ".join(cells) + " |", flush=True)
    print(f"machines alarmed, benv (k = {args.k}, h = {args.h}): "
          + ", ".join(f"{s} {alarms[s]} of {len(args.dirs)}" for s in names))
    print(f"machines alarmed, pooled (z > {args.pooled_z}): "
          + ", ".join(f"{s} {pooled_alarms[s]} of {len(args.dirs)}" for s in names))


if __name__ == "__main__":
    main()
