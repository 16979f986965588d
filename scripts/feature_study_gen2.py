#!/usr/bin/python3
"""Feature study for issue 12 (docs/method.md §8, "Session 11"): do features beyond the paper's two
(residual RMS and spectral entropy) separate a small local defect from a healthy new day?

For each machine directory (as written by scripts/detection_study_gen2.py --train-days D, or any
directory with the same layout) this script
  1. takes the window positions `ptda monitor --jsonl` reported (t_start, segment = class) for every
     recording (it runs `ptda monitor` itself on the training days, in-sample, only for the positions);
  2. recomputes in numpy, per window, the level-referred PTDA residual of docs/method.md §2 (class mean
     magnitude over all training windows, line groups, line gains, floor gain, referral clamped to
     [1/2, 2]) and candidate features of it:
       rms       residual RMS (the shipped feature, as a check of this re-implementation)
       entropy   spectral entropy of the residual (shipped feature)
       kurt      kurtosis of the time-domain residual
       crest     crest factor of the time-domain residual
       sb        residual power at +-1..3 input-shaft orders around every line group's peak, over the
                 residual floor power (log ratio)
       comb      residual power on the input-shaft comb (bins within 1 of m f_in, m >= 1) over the rest
       env       envelope spectrum of the residual above the first line group: amplitude at 1..3 f_in
                 over the envelope spectrum's median up to 10 f_in (log ratio)
       b0..b31   ln energy of the residual in 32 equal bands of 1..N/2 (--clean-bands: only floor bins
                 whose healthy mean is within 6 dB of its local floor, i.e. not a line's skirt)
  3. standardises each feature per class against the training windows (leave-one-out residuals):
     z = (v - mean) / sd_total with sd_total^2 = within-window variance + between-day variance of the
     training-day means (floored at 0.3 within, like [thresholds] day_sd_floor);
  4. reports per set (the first set is the healthy new day): per-machine median z, per-window AUC against
     the healthy set, machines alarmed by a one-sided CUSUM (k = 0.5, --h) on each feature's z, and the
     band detector: one CUSUM per band (--k-band, --h-band, --h-sweep), alarm when any band's exceeds h.

  scripts/feature_study_gen2.py --ptda build/release/cli/ptda --dirs out/dev2-3d/m20* --work out/feat \
      --clean-bands --k-band 1 --h-band 10
  (default --sets healthy=healthy.jsonl,q=faulty_0.25.jsonl,h=faulty_0.5.jsonl,f=faulty_1.jsonl: the layout
  of scripts/detection_study_gen2.py; scripts/detection_study.sh machines: --sets
  healthy=healthy.jsonl,q=faulty.jsonl with the job's config linked as config.toml; GFD:
  scripts/feature_study_gfd.sh, --split-train). Writes WORK/features.json (every z per window).

Needs python3-numpy. Development seeds only; the evaluation seeds are never run with this script.
"""

import argparse
import json
import math
import os
import subprocess
import sys
import struct

import numpy as np

FEATURES = ["rms", "entropy", "kurt", "crest", "sb", "comb", "env"]
NB = 32  # bands of the band-energy features
BANDS = [f"b{b}" for b in range(NB)]
K_BAND = 0.5
CLEAN_BANDS = False  # --clean-bands: band energies over floor bins outside the lines' skirts only


def toml_value(text, section, key, default=None):
    cur = None
    for line in text.splitlines():
        s = line.strip()
        if s.startswith("["):
            cur = s.strip("[]")
        elif cur == section and "=" in s and s.split("=")[0].strip() == key:
            v = s.split("=", 1)[1].split("#")[0].strip().strip('"')
            return v
    return default


def read_recording(rec):
    with open(os.path.join(rec, "recording.toml")) as f:
        t = f.read()
    start = float(toml_value(t, "vibration", "start_time"))
    scale = float(toml_value(t, "vibration", "scale", "1"))
    with open(os.path.join(rec, toml_value(t, "vibration", "file")), "rb") as f:
        blob = f.read()
    if blob[:4] != b"RIFF" or blob[8:12] != b"WAVE":
        raise SystemExit(f"{rec}: not a RIFF/WAVE file")
    pos, fmt, data = 12, None, None
    while pos + 8 <= len(blob):
        cid, size = blob[pos:pos + 4], struct.unpack("<I", blob[pos + 4:pos + 8])[0]
        if cid == b"fmt ":
            fmt = struct.unpack("<HHIIHH", blob[pos + 8:pos + 24])
        elif cid == b"data":
            data = blob[pos + 8:pos + 8 + size]
        pos += 8 + size + (size & 1)
    tag, ch, rate, _, _, bits = fmt
    if tag == 0xFFFE:
        tag = struct.unpack("<H", blob[blob.index(b"fmt ") + 32:blob.index(b"fmt ") + 34])[0]
    raw = np.frombuffer(data, dtype=np.uint8)
    if tag == 3 and bits == 32:
        v = raw.view("<f4").astype(float)
    elif tag == 3 and bits == 64:
        v = raw.view("<f8").astype(float)
    elif tag == 1 and bits == 24:
        b = raw[:raw.size // 3 * 3].reshape(-1, 3).astype(np.int32)
        v = b[:, 0] | (b[:, 1] << 8) | (b[:, 2] << 16)
        v = np.where(v >= 1 << 23, v - (1 << 24), v)
    elif tag == 1 and bits == 16:
        v = raw.view("<i2").astype(np.int32)
    elif tag == 1 and bits == 32:
        v = raw.view("<i4").astype(np.int64)
    else:
        raise SystemExit(f"{rec}: WAV format {tag} with {bits} bits not supported")
    v = v.reshape(-1, ch)[:, int(toml_value(t, "vibration", "channel", "0"))]
    return start, v.astype(float) * scale, float(rate)


def monitor_once(ptda, d, rec_name, cfg_path, jsonl):
    """`ptda monitor` of machine dir d's recording rec_name against its baseline.bin into jsonl (once:
    an existing jsonl is reused). Gives the window positions of a recording, training days included."""
    if not os.path.exists(jsonl):
        subprocess.run([ptda, "monitor", "--recording", os.path.join(d, rec_name), "--config", cfg_path,
                        "--baseline", os.path.join(d, "baseline.bin"), "--jsonl", jsonl],
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)


def windows(rec, jsonl, fs, n):
    start, x, wav_fs = read_recording(rec)
    fs = fs or wav_fs
    out = []
    with open(jsonl) as f:
        for line in f:
            if not line.strip():
                continue
            r = json.loads(line)
            if r.get("status") != "scored":
                continue
            i0 = int(round((r["t_start"] - start) * fs))
            if i0 < 0 or i0 + n > x.size:
                continue
            out.append((r["segment"], r["speed_rad_s"], x[i0:i0 + n], r))
    return out


def line_groups(a):
    """dsp::find_line_groups: a[k] > 4 x median of a over 65 bins centred on k (k >= 1), widened by one."""
    m = a.size
    floor = np.empty(m)
    for k in range(m):
        lo, hi = max(1, k - 32), min(m, k + 33)
        floor[k] = np.median(a[lo:hi])
    line = a > 4.0 * floor
    line[0] = False
    line_groups.last_floor = floor
    wide = line.copy()
    wide[1:] |= line[:-1]
    wide[:-1] |= line[1:]
    wide[0] = False
    groups, k = [], 1
    while k < m:
        if wide[k]:
            j = k
            while j + 1 < m and wide[j + 1]:
                j += 1
            groups.append((k, j + 1))
            k = j + 1
        else:
            k += 1
    return groups


class ClassModel:
    def __init__(self, wins, n):
        mags = np.array([np.abs(np.fft.rfft(w)) for w in wins])
        self.a = mags.mean(axis=0)
        self.sum = mags.sum(axis=0)
        self.m = mags.shape[0]
        self.groups = line_groups(self.a)
        self.in_group = np.zeros(self.a.size, bool)
        for g0, g1 in self.groups:
            self.in_group[g0:g1] = True
        self.floor_bins = ~self.in_group
        self.floor_bins[0] = False
        # "Clean" floor bins: the mean magnitude within 2x (6 dB) of its local floor, i.e. not in the
        # leakage skirt of a line, whose level moves with the line from day to day.
        self.clean = self.floor_bins & (self.a <= 2.0 * line_groups.last_floor)
        self.n = n


def residual_spectrum(cm, x, loo=False):
    """loo: x is one of the class's training windows; its own magnitude is left out of the mean (as
    training's leave-one-out residuals do; the line groups stay those of the full mean)."""
    X = np.fft.rfft(x)
    mag = np.abs(X)
    ph = np.where(mag > 0, X / np.where(mag > 0, mag, 1), 1.0)
    a = (cm.sum - mag) / (cm.m - 1) if loo and cm.m > 1 else cm.a
    D = a.copy()
    R = np.zeros_like(X)
    clamp = lambda g: min(2.0, max(0.5, g))  # noqa: E731
    for g0, g1 in cm.groups:
        aa, xx = a[g0:g1], mag[g0:g1]
        g = float(aa @ xx / (aa @ aa)) if aa @ aa > 0 else 1.0
        R[g0:g1] = (xx - g * aa) * ph[g0:g1] / clamp(g)
    fb = cm.floor_bins & (a > 0)
    gf = float(np.median(mag[fb] / a[fb])) if fb.any() else 1.0
    if gf <= 0:
        gf = 1.0
    R[cm.floor_bins] = (mag[cm.floor_bins] - gf * a[cm.floor_bins]) * ph[cm.floor_bins] / clamp(gf)
    R[0] = (mag[0] - a[0]) * ph[0]
    del D
    return R


def features(cm, x, f_in_hz, fs, loo=False):
    n = x.size
    R = residual_spectrum(cm, x, loo)
    r = np.fft.irfft(R, n)
    p = np.abs(R) ** 2
    out = {"rms": math.log(max(1e-30, float(np.sqrt(np.mean(r ** 2)))))}
    q = p[1:] / max(1e-300, p[1:].sum())
    q = q[q > 0]
    out["entropy"] = float(-(q * np.log(q)).sum() / math.log(p.size - 1))
    rc = r - r.mean()
    s2 = float(np.mean(rc ** 2))
    out["kurt"] = float(np.mean(rc ** 4) / (s2 * s2)) if s2 > 0 else 0.0
    out["crest"] = float(np.max(np.abs(rc)) / math.sqrt(s2)) if s2 > 0 else 0.0
    df = fs / n
    o = f_in_hz / df  # input-shaft order in bins
    floor_p = float(np.mean(p[cm.floor_bins])) if cm.floor_bins.any() else 1.0
    # Sidebands +-1..3 shaft orders around each line group's peak.
    sb_bins = set()
    for g0, g1 in cm.groups:
        c = g0 + int(np.argmax(cm.a[g0:g1]))
        for m in (1, 2, 3):
            for sgn in (-1, 1):
                k = int(round(c + sgn * m * o))
                for kk in (k - 1, k, k + 1):
                    if 1 <= kk < p.size and not cm.in_group[kk]:
                        sb_bins.add(kk)
    sb = np.array(sorted(sb_bins), int)
    out["sb"] = math.log(max(1e-30, float(p[sb].mean()) / floor_p)) if sb.size and floor_p > 0 else 0.0
    # Shaft-order comb over the floor bins.
    k = np.arange(p.size)
    frac = np.abs(k / o - np.round(k / o)) * o if o > 0 else np.full(p.size, 99.0)
    on = (frac <= 1.0) & cm.floor_bins & (k / max(o, 1e-9) >= 0.5)
    off = (frac > 1.5) & cm.floor_bins
    out["comb"] = (math.log(max(1e-30, float(p[on].mean())) / max(1e-30, float(p[off].mean())))
                   if on.any() and off.any() and o >= 4 else 0.0)
    # Envelope of the residual above the first line group.
    lo = cm.groups[0][1] if cm.groups else 1
    B = R.copy()
    B[:lo] = 0
    b = np.fft.irfft(B, n)
    H = -1j * B
    h = np.fft.irfft(H, n)
    env = np.sqrt(b * b + h * h)
    env -= env.mean()
    E = np.abs(np.fft.rfft(env)) * 2 / n
    top = int(min(E.size - 1, round(10 * o)))
    med = float(np.median(E[1:top + 1])) if top >= 2 else 0.0
    lines = []
    for m in (1, 2, 3):
        kk = int(round(m * o))
        if 1 <= kk < E.size - 1:
            lines.append(float(E[max(1, kk - 1):kk + 2].max()))
    out["env"] = math.log(max(1e-30, np.mean(lines)) / med) if lines and med > 0 else 0.0
    # Band energies: ln of the referred residual's energy in NB equal bands of 1..N/2.
    edges = np.linspace(1, p.size, NB + 1).astype(int)
    pc = np.where(cm.clean, p, 0.0) if CLEAN_BANDS else p
    for b in range(NB):
        out[f"b{b}"] = math.log(max(1e-30, float(pc[edges[b]:edges[b + 1]].sum())))
    return out


def auc(neg, pos):
    neg, pos = np.asarray(neg), np.asarray(pos)
    if not neg.size or not pos.size:
        return float("nan")
    allv = np.concatenate([neg, pos])
    ranks = allv.argsort().argsort() + 1.0
    rp = ranks[neg.size:].sum()
    return float((rp - pos.size * (pos.size + 1) / 2) / (neg.size * pos.size))


def cusum_alarm(z, k=0.5, h=5.0):
    return cusum_max(z, k) > h


def cusum_max(z, k=0.5):
    s, top = 0.0, 0.0
    for v in z:
        s = max(0.0, s + v - k)
        top = max(top, s)
    return top


def band_cusum_max(res, k=None):
    """Largest one-sided CUSUM over the bands of one recording's band z (the band detector's statistic)."""
    return max(cusum_max(res[b], K_BAND if k is None else k) for b in BANDS)


class Machine:
    """A machine directory's configuration (DIR/config.toml) and its work directory WORK/<tag> (created)."""

    def __init__(self, d, work):
        self.dir = d
        self.cfg_path = os.path.join(d, "config.toml")
        with open(self.cfg_path) as f:
            cfg = f.read()
        self.fs = float(toml_value(cfg, "acquisition", "fs_hz", "0"))
        self.n = int(toml_value(cfg, "extraction", "window_len"))
        z_in, z_spur, z_pin = (int(toml_value(cfg, "gearbox", k, "0")) for k in ("z_in", "z_spur", "z_pin"))
        ratio = toml_value(cfg, "gearbox", "ratio")
        self.ratio = float(ratio) if ratio else (1.0 + z_spur / z_in * z_pin if z_in and z_pin else 1.0)
        self.tag = os.path.basename(os.path.normpath(d))
        self.work = os.path.join(work, self.tag)
        os.makedirs(self.work, exist_ok=True)

    def train_windows(self, ptda):
        """The windows of every DIR/train* recording, by recording name (`ptda monitor` once each)."""
        d = self.dir
        names = sorted(x for x in os.listdir(d) if x.startswith("train") and os.path.isdir(os.path.join(d, x)))
        train = {}
        for t in names:
            j = os.path.join(self.work, t + ".jsonl")
            monitor_once(ptda, d, t, self.cfg_path, j)
            train[t] = windows(os.path.join(d, t), j, self.fs, self.n)
        return train

    def f_in(self, speed_rad_s):
        """Input-shaft rotation frequency in Hz at a joint speed."""
        return self.ratio * abs(speed_rad_s) / (2 * math.pi)


def day_stats(per_day):
    """(mean, total sd) of one feature's training values given per training day: within sd of all values,
    between-day sd of the day means floored at 0.3 within (like [thresholds] day_sd_floor)."""
    allv = np.concatenate([np.asarray(x) for x in per_day if len(x)])
    sd_w = float(np.std(allv, ddof=1)) if allv.size > 1 else 1.0
    means = [np.mean(x) for x in per_day if len(x)]
    sd_b = float(np.std(means, ddof=1)) if len(means) > 1 else 0.0
    sd_b = max(sd_b, 0.3 * sd_w)
    return float(allv.mean()), math.sqrt(sd_w ** 2 + sd_b ** 2) or 1.0


def machine(args, d):
    m = Machine(d, args.work)
    fs, n, tag = m.fs, m.n, m.tag
    first_set = None
    if args.split_train:
        # One recording: its first half (in time) trains, its second half is the first set.
        name, spec = args.sets[0]
        ws = windows(os.path.join(d, name_to_dir(d, name, spec)), os.path.join(d, spec), fs, n)
        half = len(ws) // 2
        train = {"train": ws[:half]}
        first_set = ws[half:]
        fs = fs or read_recording(os.path.join(d, name_to_dir(d, name, spec)))[2]
    else:
        train = m.train_windows(args.ptda)
    classes = sorted({w[0] for ws in train.values() for w in ws})
    models = {c: ClassModel([w[2] for ws in train.values() for w in ws if w[0] == c], n) for c in classes}
    f_in = m.f_in
    feats = {}
    for t, ws in train.items():
        feats[t] = [(w[0], features(models[w[0]], w[2], f_in(w[1]), fs, loo=True)) for w in ws]
    stats = {}
    for c in classes:
        stats[c] = {}
        for f in FEATURES + BANDS:
            stats[c][f] = day_stats([[v[f] for cc, v in feats[t] if cc == c] for t in train])
    result = {}
    for name, spec in args.sets:
        rec_jsonl = os.path.join(d, spec)
        rec = os.path.join(d, name_to_dir(d, name, spec))
        ws = first_set if (first_set is not None and name == args.sets[0][0]) else windows(rec, rec_jsonl, fs, n)
        z = {f: [] for f in FEATURES + BANDS}
        for c, v, x, _ in ws:
            if c not in models:
                continue
            fv = features(models[c], x, f_in(v), fs)
            for f in FEATURES + BANDS:
                mu, sd = stats[c][f]
                z[f].append((fv[f] - mu) / sd)
        result[name] = z
    return tag, result


def name_to_dir(d, name, spec):
    """The recording directory of a set: healthy.jsonl -> healthy/, faulty_S.jsonl -> sevS/faulty/."""
    base = os.path.basename(spec)[:-len(".jsonl")]
    if base.startswith("faulty_"):
        return os.path.join("sev" + base[len("faulty_"):], "faulty")
    return base


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ptda", required=True)
    ap.add_argument("--dirs", nargs="+", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--sets", default="healthy=healthy.jsonl,q=faulty_0.25.jsonl,h=faulty_0.5.jsonl,"
                    "f=faulty_1.jsonl")
    ap.add_argument("--h", type=float, default=5.0, help="CUSUM decision interval on z (k = 0.5)")
    ap.add_argument("--h-band", type=float, default=10.0, help="decision interval of the per-band CUSUMs")
    ap.add_argument("--split-train", action="store_true",
                    help="no train*/ recordings: train on the first half of the first set's windows and "
                         "judge its second half (GFD: one healthy recording per case)")
    ap.add_argument("--h-sweep", default="10,15,20,25,30,40",
                    help="decision intervals of the band detector to tabulate")
    ap.add_argument("--clean-bands", action="store_true",
                    help="band energies over floor bins whose mean is within 6 dB of the local floor")
    ap.add_argument("--k-band", type=float, default=0.5, help="reference value k of the per-band CUSUMs")
    args = ap.parse_args()
    global CLEAN_BANDS, K_BAND
    CLEAN_BANDS, K_BAND = args.clean_bands, args.k_band
    args.h_sweep = [float(x) for x in args.h_sweep.split(",")]
    args.sets = [s.split("=", 1) for s in args.sets.split(",")]
    allres = {}
    for d in args.dirs:
        tag, res = machine(args, d)
        allres[tag] = res
        print(tag, " ".join(f"{s}:{f}={np.median(res[s][f]):+.2f}" for s, _ in args.sets[:2]
                            for f in ("rms", "sb", "env", "kurt")), file=sys.stderr, flush=True)
    with open(os.path.join(args.work, "features.json"), "w") as f:
        json.dump(allres, f)
    report(allres, args)


def report(allres, args):
    sets = [s for s, _ in args.sets]
    ref = sets[0]
    tags = sorted(allres)
    print(f"machines {len(tags)}; z against training days (within + between-day sd); CUSUM k=0.5 h={args.h}")
    print("| feature | " + " | ".join(f"{s}: median z (range)" for s in sets) + " | "
          + " | ".join(f"{s}: AUC vs {ref} (median)" for s in sets[1:]) + " | "
          + " | ".join(f"{s}: CUSUM alarms" for s in sets) + " |")
    print("|---" * (1 + 3 * len(sets) - 1) + "|")
    for f in FEATURES:
        cells = []
        for s in sets:
            meds = [float(np.median(allres[t][s][f])) for t in tags if allres[t][s][f]]
            cells.append(f"{np.median(meds):+.2f} ({min(meds):+.2f}..{max(meds):+.2f})")
        for s in sets[1:]:
            cells.append(f"{np.median([auc(allres[t][ref][f], allres[t][s][f]) for t in tags]):.2f}")
        for s in sets:
            cells.append(str(sum(cusum_alarm(allres[t][s][f], 0.5, args.h) for t in tags)))
        print(f"| {f} | " + " | ".join(cells) + " |")
    # Band detector: per window the largest band z; per recording the largest per-band CUSUM.
    for t in tags:
        for s in sets:
            allres[t][s]["bandmax"] = list(np.max(np.array([allres[t][s][b] for b in BANDS]), axis=0))
    cells = []
    for s in sets:
        meds = [float(np.median(allres[t][s]["bandmax"])) for t in tags]
        cells.append(f"{np.median(meds):+.2f} ({min(meds):+.2f}..{max(meds):+.2f})")
    for s in sets[1:]:
        cells.append(f"{np.median([auc(allres[t][ref]['bandmax'], allres[t][s]['bandmax']) for t in tags]):.2f}")
    for s in sets:
        cells.append(str(sum(band_cusum_max(allres[t][s]) > args.h_band for t in tags)))
    print("| band max (CUSUM per band, k = %g, h = %g) | " % (K_BAND, args.h_band) + " | ".join(cells) + " |")
    print()
    print("band detector: machines alarmed per decision interval h")
    print("| h | " + " | ".join(sets) + " |")
    print("|---" * (1 + len(sets)) + "|")
    for h in args.h_sweep:
        print(f"| {h:g} | " + " | ".join(str(sum(band_cusum_max(allres[t][s]) > h for t in tags)) for s in sets)
              + " |")
    print()
    print(f"largest per-band CUSUM per machine (k = {K_BAND}):")
    print("| machine | " + " | ".join(sets) + " |")
    print("|---" * (1 + len(sets)) + "|")
    for t in tags:
        print(f"| {t} | " + " | ".join(f"{band_cusum_max(allres[t][s]):.1f}" for s in sets) + " |")


if __name__ == "__main__":
    main()
