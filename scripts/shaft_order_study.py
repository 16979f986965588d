#!/usr/bin/python3
"""Shaft-synchronous features of the PTDA residual and of the mesh (docs/method.md §8, "Session 18";
prototype, numpy).

A local tooth defect repeats once per revolution of the shaft that carries the tooth. On the second
generator (tests/gen2/g2robot.py `tooth_defect`) that is the input pinion: once per input-shaft
revolution the mesh dips and slips in phase and the tooth's entry knocks a structural mode. The
product's features (residual RMS, spectral entropy, 32 band energies) average over the window and do
not ask whether the residual's energy comes back once per input-shaft revolution. This script asks.

Input-shaft frequency of a window (cycloidal gearbox, eq. 1, config/include/ptda/config/
pipeline_config.hpp `cycloidal_ratio`): ratio R = 1 + z_spur / z_in * z_pin (or [gearbox] ratio),
f_in_hz = R * |speed_rad_s| / (2 pi), with speed_rad_s the window's region mean joint speed from the
CAN speed frames (the `speed_rad_s` of `ptda monitor --jsonl`). The window holds
n_rev = f_in_hz * window_len / fs input-shaft revolutions.

Per machine directory (the layout of scripts/detection_study_gen2.py --train-days D):
  1. window positions and classes from `ptda monitor --jsonl` (t_start, segment, speed_rad_s); the
     training days are monitored here once, in-sample, only for their positions (cached in WORK);
  2. the level-referred PTDA residual spectrum R[k] of docs/method.md §2 (class mean magnitude of all
     training windows, line groups, line gains, floor gain, referral clamped to [1/2, 2]; training
     windows leave themselves out of the mean), from scripts/feature_study_gen2.py, which agrees with
     `ptda monitor` to 4 digits (§8, session 11);
  3. per window and per band (all floor bins, and NB_ENV equal bands of 1..N/2, floor bins only: outside
     every line group) the band-passed residual b[n] = IDFT(R restricted to the band), its analytic
     signal via the FFT (Hilbert), and the squared envelope e[n] = |b + j H b|^2. Features:
       mi    ln of the shaft-order modulation index of e: mean over m = 1..3 of
             |sum_n w[n] (e[n] - mean e) exp(-j 2 pi m f_in n / fs)| / sum_n w[n] e[n] (Hann w),
             i.e. the envelope spectrum at exactly m f_in (not at the nearest bin) over its DC
       ac    autocorrelation of e - mean e at a lag of one input-shaft revolution (and of two, where the
             window holds three; --max-lags), normalised by the zero-lag value: near 0 for a
             stationary residual, towards 1 for a burst that comes back every revolution
       sync  ln peak-to-mean of the synchronous average of e over the window's whole input-shaft
             revolutions (32 angle bins per revolution)
       kurt  ln kurtosis of b (impulsiveness)
       am, pm  (not residual features) the mesh's own amplitude and phase modulation: per mesh harmonic
             h <= 6 that is a line of the class mean (GMF = z_in f_in), the window's spectrum over
             (h -+ 1/2) GMF gives an analytic signal; its envelope over its mean minus 1 (am) and its
             detrended unwrapped phase / h (pm), averaged over the harmonics; feature: their
             autocorrelation at one (two) revolutions, as ac (mesh_demodulation)
     Shaft features (mi, ac, sync, am, pm) need n_rev >= MIN_REV (--min-rev); windows with fewer
     revolutions are not scored for them (the report lists n_rev per class).
     Control: --f-scale F takes F f_in for every lag and shaft harmonic (am/pm keep the true GMF); a
     feature that still detects at a wrong rate does not see the shaft rate.
  4. standardisation per machine, class and band from the training days only: z = (v - mean) / sd over
     all training windows of the class (leave-one-out residuals; sd pooled over the days, so it holds the
     between-day spread the training days show);
  5. per set (healthy new day, faulty days): per-window AUC against the healthy new day of the window's
     largest band z ("max" rows) or of the all-floor band ("all" rows), and machines alarmed by a
     one-sided CUSUM S <- max(0, S + z - k), alarm when S > h (k = 1, h = 10 as the band detector of
     docs/method.md §6), one CUSUM per band (any band alarms) for "max" rows. Every healthy alarm is
     counted. The product's own verdicts (results.tsv of the detection study) are tabulated beside.

  /usr/bin/python3 scripts/shaft_order_study.py --ptda build/release/cli/ptda \
      --dirs out/dev_a/m20* out/dev_b/m20* --work out/shaft2 [--results out/dev_a/results.tsv,...]
      [--sets healthy=healthy.jsonl,q=faulty_0.25.jsonl,h=faulty_0.5.jsonl] [--from-json WORK/features.json]
  /usr/bin/python3 scripts/shaft_order_study.py --self-check

Needs python3-numpy. Development seeds only; the evaluation seeds are never run with this script.
"""

import argparse
import json
import math
import os
import sys

import numpy as np

sys.dont_write_bytecode = True  # no scripts/__pycache__ from the import below
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import feature_study_gen2 as fs2  # noqa: E402  (recording reader, window positions, PTDA residual)

NB_ENV = 8          # equal bands of 1..N/2 for the band-passed envelope
MIN_REV = 2.0       # shaft features need at least this many input-shaft revolutions in the window
F_SCALE = 1.0       # control (--f-scale): the shaft frequency multiplied by a wrong factor
MAX_LAGS = 2        # ac: lags of 1..MAX_LAGS revolutions (each with at least one revolution of overlap)
SYNC_BINS = 32      # angle bins per revolution of the synchronous average
HARMONICS = (1, 2, 3)
FAMILIES = ["mi", "ac", "sync", "kurt", "am", "pm"]
BANDS = ["all"] + [f"e{b}" for b in range(NB_ENV)]
K, H = 1.0, 10.0


def band_masks(floor_bins, nbins):
    masks = {"all": floor_bins.copy()}
    edges = np.linspace(1, nbins, NB_ENV + 1).astype(int)
    for b in range(NB_ENV):
        m = np.zeros(nbins, bool)
        m[edges[b]:edges[b + 1]] = True
        masks[f"e{b}"] = m & floor_bins
    return masks


def squared_envelope(R, mask, n):
    """Band-passed residual b[n] and its squared envelope |b + j H b|^2 (Hilbert via the FFT)."""
    B = np.where(mask, R, 0.0)
    b = np.fft.irfft(B, n)
    h = np.fft.irfft(-1j * B, n)  # Hilbert transform of b (one-sided spectrum times -j)
    return b, b * b + h * h


def ac_at_revolutions(x, f_in_hz, fs):
    """Autocorrelation of x - mean x at lags of 1..MAX_LAGS input-shaft revolutions (each with at least
    one revolution of overlap), unbiased per lag, over the zero-lag mean square; their mean."""
    n = x.size
    xc = x - x.mean()
    nfft = 1 << int(math.ceil(math.log2(2 * n)))
    E = np.fft.rfft(xc, nfft)
    acf = np.fft.irfft(E * np.conj(E), nfft)[:n]
    lags = [int(round(m * fs / f_in_hz)) for m in range(1, MAX_LAGS + 1) if m * fs / f_in_hz <= n - fs / f_in_hz]
    if not lags or acf[0] <= 0:
        return float("nan")
    return float(np.mean([float(acf[lag] / (n - lag)) / float(acf[0] / n) for lag in lags]))


def mesh_demodulation(X, cm, f_in_hz, fs, n, z_in):
    """am, pm: the mesh's own amplitude and phase modulation at the input-shaft rate. Per mesh harmonic h
    (GMF = z_in f_in; h GMF inside a line group of the class mean, (h + 1/2) GMF below fs/2, h <= 6)
    the window's spectrum X over (h - 1/2 .. h + 1/2) GMF (carrier and sidebands; the raw window, not
    the residual) gives an analytic signal z_h; am_h = |z_h| / mean |z_h| - 1, pm_h = (unwrapped phase,
    linear trend removed) / h. am, pm average them over the harmonics, and the features are their
    autocorrelation at one (two) revolutions (ac_at_revolutions). Gain-invariant. NaN below MIN_REV."""
    nan = {"am": float("nan"), "pm": float("nan")}
    if z_in <= 0 or f_in_hz / F_SCALE * n / fs < MIN_REV:
        return nan
    gmf, df = z_in * f_in_hz / F_SCALE, fs / n  # the control (--f-scale) moves the lag, not the mesh
    ams, pms = [], []
    t = np.arange(n)
    for h in range(1, 7):
        if (h + 0.5) * gmf >= 0.5 * fs:
            break
        kc = int(round(h * gmf / df))
        if not cm.in_group[max(1, kc - 1):kc + 2].any():
            continue
        lo, hi = int(round((h - 0.5) * gmf / df)), int(round((h + 0.5) * gmf / df))
        Z = np.zeros(n, complex)
        Z[max(1, lo):hi] = X[max(1, lo):hi]
        z = np.fft.ifft(Z)
        a = np.abs(z)
        if a.mean() <= 0:
            continue
        ams.append(a / a.mean() - 1.0)
        ph = np.unwrap(np.angle(z))
        ph = ph - np.polyval(np.polyfit(t, ph, 1), t)
        pms.append(ph / h)
    if not ams:
        return nan
    return {"am": ac_at_revolutions(np.mean(ams, axis=0), f_in_hz, fs),
            "pm": ac_at_revolutions(np.mean(pms, axis=0), f_in_hz, fs)}


def shaft_features(b, e, f_in_hz, fs):
    """mi, ac, sync, kurt of one band-passed residual b with squared envelope e (dict; shaft features
    are NaN when the window holds fewer than MIN_REV input-shaft revolutions)."""
    n = b.size
    out = {}
    bc = b - b.mean()
    s2 = float(np.mean(bc * bc))
    out["kurt"] = math.log(max(1e-12, float(np.mean(bc ** 4)) / (s2 * s2))) if s2 > 0 else float("nan")
    n_rev = f_in_hz * n / fs
    if n_rev < MIN_REV or not np.isfinite(n_rev) or float(e.mean()) <= 0:
        out.update({"mi": float("nan"), "ac": float("nan"), "sync": float("nan")})
        return out
    t = np.arange(n) / fs
    w = 0.5 - 0.5 * np.cos(2 * math.pi * (np.arange(n) + 0.5) / n)
    ec = e - e.mean()
    mis = [abs(np.sum(w * ec * np.exp(-2j * math.pi * m * f_in_hz * t))) / np.sum(w * e) for m in HARMONICS]
    out["mi"] = math.log(max(1e-12, float(np.mean(mis))))
    # Autocorrelation at one (and two) revolutions, by the FFT (zero-padded: linear, not circular).
    out["ac"] = ac_at_revolutions(e, f_in_hz, fs)
    # Synchronous average of e over the whole revolutions the window holds.
    whole = int(math.floor(n_rev))
    nn = int(round(whole * fs / f_in_hz))
    ang = (np.arange(nn) * f_in_hz / fs) % 1.0
    idx = np.minimum(SYNC_BINS - 1, (ang * SYNC_BINS).astype(int))
    prof = np.bincount(idx, weights=e[:nn], minlength=SYNC_BINS) / np.maximum(1, np.bincount(idx, minlength=SYNC_BINS))
    out["sync"] = math.log(max(1e-12, float(prof.max() / prof.mean()))) if prof.mean() > 0 else float("nan")
    return out


def window_features(cm, masks, x, f_in_hz, fs, z_in, loo=False):
    n = x.size
    R = fs2.residual_spectrum(cm, x, loo)
    out = {f"{k}_all": v for k, v in mesh_demodulation(np.fft.fft(x), cm, f_in_hz, fs, n, z_in).items()}
    for name, mask in masks.items():
        if not mask.any():
            continue
        b, e = squared_envelope(R, mask, n)
        for f, v in shaft_features(b, e, f_in_hz, fs).items():
            out[f"{f}_{name}"] = v
    return out


def machine(args, d):
    cfg_path = os.path.join(d, "config.toml")
    with open(cfg_path) as f:
        cfg = f.read()
    fs = float(fs2.toml_value(cfg, "acquisition", "fs_hz", "0"))
    n = int(fs2.toml_value(cfg, "extraction", "window_len"))
    z_in, z_spur, z_pin = (int(fs2.toml_value(cfg, "gearbox", k, "0")) for k in ("z_in", "z_spur", "z_pin"))
    ratio = fs2.toml_value(cfg, "gearbox", "ratio")
    ratio = float(ratio) if ratio else 1.0 + z_spur / z_in * z_pin
    tag = os.path.basename(os.path.normpath(d))
    wd = os.path.join(args.work, tag)
    os.makedirs(wd, exist_ok=True)
    train_dirs = sorted(x for x in os.listdir(d) if x.startswith("train") and os.path.isdir(os.path.join(d, x)))
    train = {}
    for t in train_dirs:
        j = os.path.join(wd, t + ".jsonl")
        fs2.monitor_once(args.ptda, d, t, cfg_path, j)
        train[t] = fs2.windows(os.path.join(d, t), j, fs, n)
    classes = sorted({w[0] for ws in train.values() for w in ws})
    models = {c: fs2.ClassModel([w[2] for ws in train.values() for w in ws if w[0] == c], n) for c in classes}
    masks = {c: band_masks(models[c].floor_bins, models[c].a.size) for c in classes}
    f_in = lambda v: F_SCALE * ratio * abs(v) / (2 * math.pi)  # noqa: E731
    tr = [(w[0], window_features(models[w[0]], masks[w[0]], w[2], f_in(w[1]), fs, z_in, loo=True))
          for ws in train.values() for w in ws]
    stats = {}
    for c in classes:
        rows = [v for cc, v in tr if cc == c]
        stats[c] = {}
        for key in rows[0]:
            vals = np.array([r[key] for r in rows if np.isfinite(r.get(key, np.nan))])
            if vals.size >= 5:
                sd = float(np.std(vals, ddof=1))
                stats[c][key] = (float(vals.mean()), sd if sd > 0 else 1.0)
    speeds = {c: float(np.median([abs(w[1]) for ws in train.values() for w in ws if w[0] == c])) for c in classes}
    info = {"fs": fs, "n": n, "ratio": ratio, "z": [z_in, z_spur, z_pin],
            "classes": {str(c): {"speed_rad_s": speeds[c], "f_in_hz": f_in(speeds[c]),
                                 "n_rev": f_in(speeds[c]) * n / fs, "train_windows": sum(1 for cc, _ in tr if cc == c)}
                        for c in classes}}
    result = {}
    for name, spec in args.sets:
        rec = os.path.join(d, fs2.name_to_dir(d, name, spec))
        ws = fs2.windows(rec, os.path.join(d, spec), fs, n)
        z = {}  # key -> list of z per window (NaN where the feature is not defined)
        for c, v, x, _ in ws:
            if c not in models:
                continue
            fv = window_features(models[c], masks[c], x, f_in(v), fs, z_in)
            for key in set(fv) | set(stats[c]):
                mu_sd = stats[c].get(key)
                val = fv.get(key, float("nan"))
                z.setdefault(key, []).append((val - mu_sd[0]) / mu_sd[1] if mu_sd and np.isfinite(val)
                                             else float("nan"))
        # keys that appear late get leading NaNs
        nw = max((len(v) for v in z.values()), default=0)
        for key in z:
            z[key] = [float("nan")] * (nw - len(z[key])) + z[key]
        result[name] = z
    return tag, result, info


def cusum_max(z, k=K):
    s, top = 0.0, 0.0
    for v in z:
        if not np.isfinite(v):
            continue
        s = max(0.0, s + v - k)
        top = max(top, s)
    return top


def finite(v):
    v = np.asarray(v, float)
    return v[np.isfinite(v)]


def per_window_max(res, fam):
    keys = [f"{fam}_{b}" for b in BANDS[1:] if f"{fam}_{b}" in res]
    if not keys:
        return []
    a = np.array([res[k] for k in keys])
    with np.errstate(all="ignore"):
        m = np.nanmax(np.where(np.isfinite(a), a, -np.inf), axis=0)
    return [float(x) if np.isfinite(x) else float("nan") for x in m]


def report(allres, allinfo, sets, product):
    tags = sorted(allres)
    ref = sets[0]
    lines = []
    lines.append(f"machines {len(tags)}; k = {K:g}, h = {H:g}; z per class and band against the training days")
    lines.append("")
    head = ("| feature | " + " | ".join(f"{s}: machines alarmed" for s in sets) + " | "
            + " | ".join(f"{s}: AUC vs {ref} (median; range)" for s in sets[1:])
            + f" | largest {ref} statistic | machines scored |")
    lines.append(head)
    lines.append("|---" * (head.count("|") - 1) + "|")
    rows = {}
    for fam in FAMILIES:
        for variant in ("all", "max"):
            alarms, aucs, scored = {s: 0 for s in sets}, {s: [] for s in sets[1:]}, 0
            per_machine = {}
            for t in tags:
                r = allres[t]
                if variant == "all":
                    key = f"{fam}_all"
                    if key not in r[ref] or not finite(r[ref][key]).size:
                        continue
                    stat = {s: cusum_max(r[s].get(key, [])) for s in sets}
                    win = {s: finite(r[s].get(key, [])) for s in sets}
                else:
                    keys = [f"{fam}_{b}" for b in BANDS[1:]
                            if f"{fam}_{b}" in r[ref] and finite(r[ref][f"{fam}_{b}"]).size]
                    if not keys:
                        continue
                    stat = {s: max(cusum_max(r[s].get(k, [])) for k in keys) for s in sets}
                    win = {s: finite(per_window_max(r[s], fam)) for s in sets}
                scored += 1
                per_machine[t] = stat
                for s in sets:
                    alarms[s] += stat[s] > H
                for s in sets[1:]:
                    if win[ref].size and win[s].size:
                        aucs[s].append(fs2.auc(win[ref], win[s]))
            if not scored:
                continue
            name = f"{fam} ({'all floor bins' if variant == 'all' else f'largest of {NB_ENV} bands'})"
            if fam in ("am", "pm"):
                name = f"{fam} (mesh harmonics demodulated)"
            rows[(fam, variant)] = (alarms, aucs, scored, per_machine)
            cells = [f"{alarms[s]}" for s in sets]
            cells += [f"{np.median(aucs[s]):.2f} ({min(aucs[s]):.2f}-{max(aucs[s]):.2f})" if aucs[s] else "-"
                      for s in sets[1:]]
            top = max((pm[ref] for pm in per_machine.values()), default=0.0)
            lines.append(f"| {name} | " + " | ".join(cells) + f" | {top:.1f} | {scored} of {len(tags)} |")
    if product:
        cells = [str(sum(1 for t in tags if product.get((t, s)) == "yes")) for s in sets]
        lines.append("| product (k-of-n, feature CUSUM, band CUSUM; results.tsv) | " + " | ".join(cells)
                     + " |" + " - |" * (len(sets) - 1) + f" - | {len(tags)} of {len(tags)} |")
    lines.append("")
    # Union with the product: machines alarmed by the product or by the feature.
    if product:
        lines.append("Product or feature (union), machines alarmed:")
        lines.append("| feature | " + " | ".join(sets) + " |")
        lines.append("|---" * (1 + len(sets)) + "|")
        for (fam, variant), (alarms, aucs, scored, pm) in rows.items():
            cells = []
            for s in sets:
                cells.append(str(sum(1 for t in tags if product.get((t, s)) == "yes" or pm.get(t, {}).get(s, 0) > H)))
            lines.append(f"| {fam} {variant} | " + " | ".join(cells) + " |")
        lines.append("")
    # Combinations: a machine is alarmed when any of the named detectors alarms (each its own CUSUM).
    combos = [[("pm", "all"), ("am", "all")], [("pm", "all"), ("am", "all"), ("ac", "max")]]
    lines.append("Combinations (any detector alarms), machines alarmed; with the product too in brackets:")
    lines.append("| detectors | " + " | ".join(sets) + " |")
    lines.append("|---" * (1 + len(sets)) + "|")
    for combo in combos:
        if not all(c in rows for c in combo):
            continue
        cells = []
        for s_ in sets:
            alone = [t for t in tags if any(rows[c][3].get(t, {}).get(s_, 0) > H for c in combo)]
            withp = [t for t in tags if t in alone or product.get((t, s_)) == "yes"]
            cells.append(f"{len(alone)} ({len(withp)})" if product else f"{len(alone)}")
        lines.append("| " + " + ".join(f"{f} {v}" for f, v in combo) + " | " + " | ".join(cells) + " |")
    lines.append("")
    # Per-machine detail: revolutions per window and the largest CUSUM of each set.
    lines.append("Per machine: input-shaft revolutions per window by class; largest CUSUM (max over bands) "
                 "per set for ac / sync / mi / kurt; product verdict")
    lines.append("| machine | n_rev per class | " + " | ".join(f"{fam} {s}" for fam in FAMILIES for s in sets)
                 + " | product |")
    lines.append("|---" * (2 + len(FAMILIES) * len(sets) + 1) + "|")
    for t in tags:
        nrev = ", ".join(f"{c['n_rev']:.1f}" for c in allinfo[t]["classes"].values())
        cells = []
        for fam in FAMILIES:
            pm = rows.get((fam, "max"), rows.get((fam, "all")))[3].get(t)
            cells += [f"{pm[s]:.1f}" if pm else "-" for s in sets]
        prod = "/".join(product.get((t, s), "?")[0] for s in sets) if product else "-"
        lines.append(f"| {t} | {nrev} | " + " | ".join(cells) + f" | {prod} |")
    return "\n".join(lines)


def read_product(paths, sets):
    """(machine tag, set) -> 'yes'/'no' from detection_study_gen2.py results.tsv files."""
    names = {"healthy": "healthy"}
    for s, spec in sets:
        base = os.path.basename(spec)[:-len(".jsonl")]
        if base.startswith("faulty_"):
            names[f"faulty {base[len('faulty_'):]}"] = s
        else:
            names[base] = s
    out = {}
    for p in paths:
        with open(p) as f:
            hdr = f.readline().rstrip("\n").split("\t")
            for line in f:
                r = dict(zip(hdr, line.rstrip("\n").split("\t")))
                if r["set"] in names:
                    out[(f"m{r['seed']}", names[r["set"]])] = r["alarm"]
    return out


def self_check():
    """A synthetic residual: white noise, plus (second case) a decaying 3 kHz burst once per shaft
    revolution at 12 Hz. The shaft features must rise far above their noise-only values, and they must
    not change when the whole window is scaled (a new day's level)."""
    rng = np.random.default_rng(1)
    fs, n, f_in = 20480.0, 8192, 12.0
    t = np.arange(n) / fs
    noise = rng.normal(size=n)
    burst = np.zeros(n)
    h = np.exp(-0.05 * 2 * math.pi * 3000 * t[:400]) * np.sin(2 * math.pi * 3000 * t[:400])
    for i0 in (np.arange(0.013, n / fs, 1 / f_in) * fs).astype(int):
        seg = h[: n - i0]
        burst[i0:i0 + seg.size] += 10.0 * seg
    res = {}
    for name, x in (("noise", noise), ("burst", noise + burst), ("burst x3", 3 * (noise + burst))):
        X = np.fft.rfft(x)
        mask = np.ones(X.size, bool)
        mask[0] = False
        b, e = squared_envelope(X, mask, n)
        res[name] = shaft_features(b, e, f_in, fs)
        print(f"self-check {name}: " + ", ".join(f"{k} {v:+.3f}" for k, v in res[name].items()))
    ok = (res["burst"]["ac"] > res["noise"]["ac"] + 0.2 and res["burst"]["mi"] > res["noise"]["mi"] + 0.7
          and res["burst"]["sync"] > res["noise"]["sync"] + 0.5
          and all(abs(res["burst"][k] - res["burst x3"][k]) < 1e-9 for k in res["burst"]))
    # Mesh demodulation: a 24-tooth mesh at 12 Hz shaft rate whose amplitude dips by 30 % (or whose
    # phase slips by 0.3 rad) over 1.5 pitches once per revolution, in noise.
    cm = type("Cm", (), {})()
    gmf = 24 * f_in
    cm.in_group = np.zeros(n // 2 + 1, bool)
    kc = int(round(gmf * n / fs))
    cm.in_group[kc - 1:kc + 2] = True
    d = np.mod(2 * math.pi * f_in * t + math.pi, 2 * math.pi) - math.pi
    half = 0.75 * 2 * math.pi / 24
    bump = np.where(np.abs(d) < half, 0.5 * (1 + np.cos(math.pi * d / half)), 0.0)
    mesh = np.sin(2 * math.pi * gmf * t)
    slip = np.sin(2 * math.pi * gmf * t - 0.3 * bump)
    for name, x in (("mesh", mesh + 0.1 * noise), ("mesh with dip", mesh * (1 - 0.3 * bump) + 0.1 * noise),
                    ("mesh with slip", slip + 0.1 * noise)):
        res[name] = mesh_demodulation(np.fft.fft(x), cm, f_in, fs, n, 24)
        print(f"self-check {name}: " + ", ".join(f"{k} {v:+.3f}" for k, v in res[name].items()))
    ok = (ok and res["mesh with dip"]["am"] > res["mesh"]["am"] + 0.2
          and res["mesh with slip"]["pm"] > res["mesh"]["pm"] + 0.2)
    # Below MIN_REV revolutions the shaft features are not defined.
    b, e = squared_envelope(np.fft.rfft(noise), np.ones(n // 2 + 1, bool), n)
    ok = ok and not np.isfinite(shaft_features(b, e, 1.0, fs)["ac"])
    print("self-check", "passed" if ok else "FAILED")
    return ok


def main():
    global NB_ENV, MIN_REV, MAX_LAGS, BANDS, F_SCALE
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ptda")
    ap.add_argument("--dirs", nargs="+")
    ap.add_argument("--work")
    ap.add_argument("--sets", default="healthy=healthy.jsonl,q=faulty_0.25.jsonl,h=faulty_0.5.jsonl")
    ap.add_argument("--results", default="", help="comma-separated results.tsv of the detection study "
                    "(the product's verdicts on the same recordings)")
    ap.add_argument("--self-check", action="store_true")
    ap.add_argument("--from-json", default="", help="re-report WORK/features.json of an earlier run "
                    "(same --env-bands)")
    ap.add_argument("--env-bands", type=int, default=NB_ENV, help="equal bands of the envelope features (8)")
    ap.add_argument("--min-rev", type=float, default=MIN_REV, help="input-shaft revolutions a window needs (2)")
    ap.add_argument("--max-lags", type=int, default=MAX_LAGS, help="ac: lags of 1..L revolutions (2)")
    ap.add_argument("--f-scale", type=float, default=1.0, help="control: take F times the input-shaft "
                    "frequency (a wrong rate: a feature that still detects does not see the shaft rate)")
    args = ap.parse_args()
    NB_ENV, MIN_REV, MAX_LAGS, F_SCALE = args.env_bands, args.min_rev, args.max_lags, args.f_scale
    BANDS = ["all"] + [f"e{b}" for b in range(NB_ENV)]
    F_SCALE = 1.0  # the self-check runs at the true rate
    if not self_check():
        return 1
    F_SCALE = args.f_scale
    if args.self_check:
        return 0
    if not (args.work and (args.from_json or (args.ptda and args.dirs))):
        ap.error("--ptda, --dirs and --work are needed (or --self-check)")
    args.sets = [s.split("=", 1) for s in args.sets.split(",")]
    sets = [s for s, _ in args.sets]
    os.makedirs(args.work, exist_ok=True)
    allres, allinfo = {}, {}
    if args.from_json:  # re-report an earlier run's features.json (no recomputation)
        with open(args.from_json) as f:
            j = json.load(f)
        allres, allinfo = j["z"], j["info"]
        args.dirs = []
    for d in args.dirs:
        tag, res, info = machine(args, d)
        allres[tag], allinfo[tag] = res, info
        print(tag, "n_rev", [round(c["n_rev"], 1) for c in info["classes"].values()],
              " ".join(f"{s}:ac={max(cusum_max(v) for k, v in res[s].items() if k.startswith('ac_e')):.1f}"
                       for s in sets),
              file=sys.stderr, flush=True)
    if not args.from_json:
        with open(os.path.join(args.work, "features.json"), "w") as f:
            json.dump({"z": allres, "info": allinfo}, f)
    product = read_product([p for p in args.results.split(",") if p], args.sets) if args.results else {}
    text = report(allres, allinfo, sets, product)
    with open(os.path.join(args.work, "report.md"), "w") as f:
        f.write(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
