"""Real recordings with injected effects (docs/gap.md "Bench", corpus `gfd-injected`).

A healthy GFD test-rig recording (../shared/data/gfd, channel a1, load from the seed) is converted with
`ptda import` (the same conversion docs/gap.md "Real data" uses: fs 64.5 kHz assumed, 12 Hz output
speed) and one effect is added to its vibration by code written here, independently of sim/src:
clipping, a soft sensor non-linearity (outside the effect library), mains pickup with harmonics and
drive PWM lines, sample-clock error by resampling, a structural mode in the path, knocks at random
times (the rig runs at constant speed: no torque reversals), coloured noise; or nothing (control).
The nominal is config/scenarios/gfd_gap.toml, copied into the case.
"""

import math
import os
import shutil
import subprocess

import numpy as np

import g2common as C

FS = 64500
LOADS = [0, 20, 40, 60, 80]
SLOTS = ["transfer_path", "impacts", "electrical_interference", "adc_clipping", "sample_clock_error",
         "noise_color", "sensor_nonlinearity", "none"]
NOMINAL = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "config", "scenarios",
                       "gfd_gap.toml")


def U(r, a, b):
    return float(r.uniform(a, b))


def logU(r, a, b):
    return float(math.exp(r.uniform(math.log(a), math.log(b))))


def slot_of(seed):
    return SLOTS[seed % len(SLOTS)]


def make_case(seed, outdir, gfd_dir, ptda, kind=None):
    kind = kind or slot_of(seed)
    r = C.rng_for(seed, 101)
    load = LOADS[int(r.integers(len(LOADS)))]
    src = os.path.join(gfd_dir, f"h30hz{load}.csv.gz")
    rec = os.path.join(outdir, "rec")
    if os.path.exists(rec):
        shutil.rmtree(rec)
    os.makedirs(outdir, exist_ok=True)
    subprocess.run([ptda, "import", "--csv", src, "--column", "a1", "--rate", str(FS), "--shaft-speed", "12Hz",
                    "--out", rec], check=True, stdout=subprocess.DEVNULL)
    wav = os.path.join(rec, "vibration.wav")
    x, fs, tag, bits = C.read_wav(wav)
    if tag != 3:
        raise ValueError(f"{wav}: expected the float32 WAV `ptda import` writes")
    scale = _scale_of(os.path.join(rec, "recording.toml"))
    x = x * scale
    n = x.size
    sx = float(np.std(x))
    peak = float(np.max(np.abs(x)))
    p = {}
    category = "effect"
    lib = None
    ri = C.rng_for(seed, 102)
    if kind == "transfer_path":
        p = {"fn_hz": logU(ri, 1000, 0.38 * FS), "zeta": U(ri, 0.04, 0.12), "gain_db": U(ri, 8, 20)}
        k = 10 ** (p["gain_db"] / 20) - 1
        x = x + k * C.fft_filter(x, FS, C.mode_response(p["fn_hz"], p["zeta"]))
        lib = {"frequency_hz": p["fn_hz"], "gain_db": p["gain_db"], "q": 1 / (2 * p["zeta"])}
    elif kind == "impacts":
        fn = logU(ri, 1500, 0.35 * FS)
        p = {"amplitude_ms2": U(ri, 3, 8) * sx, "fn_hz": fn, "zeta": U(ri, 0.03, 0.1),
             "rate_hz": U(ri, 2, 8), "fn2_hz": min(fn * U(ri, 1.3, 2.0), 0.45 * FS), "second_share": U(ri, 0.2, 0.5)}
        t = 0.0
        tw = np.arange(int(FS * min(0.1, 8 / (p["zeta"] * 2 * math.pi * fn)))) / FS
        h = np.exp(-p["zeta"] * 2 * math.pi * fn * tw) * np.sin(2 * math.pi * fn * tw)
        h += p["second_share"] * np.exp(-p["zeta"] * 2 * math.pi * p["fn2_hz"] * tw) * \
            np.sin(2 * math.pi * p["fn2_hz"] * tw)
        times = []
        while True:
            t += ri.exponential(1.0 / p["rate_hz"])
            if t >= n / FS:
                break
            i0 = int(t * FS)
            seg = h[: n - i0]
            x[i0:i0 + seg.size] += p["amplitude_ms2"] * ri.uniform(0.6, 1.2) * seg
            times.append(t)
        p["knocks_s"] = times
        lib = {"amplitude_ms2": p["amplitude_ms2"], "resonance_hz": fn, "damping_ratio": p["zeta"],
               "rate_hz": p["rate_hz"]}
    elif kind == "electrical_interference":
        mains = 50.0 if ri.uniform() < 0.6 else 60.0
        p = {"mains_hz": mains, "amplitude_ms2": U(ri, 0.08, 0.4) * sx, "drift_rel": U(ri, 1e-4, 6e-4),
             "pwm_hz": float([8000.0, 10000.0, 12000.0, 16000.0][int(ri.integers(4))]),
             "pwm_rel": U(ri, 0.2, 0.6)}
        drift = 1 + p["drift_rel"] * C.band_noise(ri, n, FS, 0.3, 3.0)
        ph = 2 * math.pi * mains * np.cumsum(drift) / FS
        levels = {1: 1.0, 3: U(ri, 0.1, 0.6), 5: U(ri, 0.05, 0.4), 7: U(ri, 0.02, 0.2), 2: U(ri, 0.0, 0.15)}
        el = sum(v * np.sin(k * ph + ri.uniform(0, 6.28)) for k, v in levels.items())
        tt = np.arange(n) / FS
        el = el * p["amplitude_ms2"] + p["pwm_rel"] * p["amplitude_ms2"] * np.sin(2 * math.pi * p["pwm_hz"] * tt)
        x = x + el
        p["harmonic_levels"] = levels
        lib = {"frequency_hz": mains, "amplitude_ms2": p["amplitude_ms2"], "harmonics": 7,
               "harmonic_decay": levels[3]}
    elif kind == "adc_clipping":
        p = {"level_ms2": U(ri, 0.5, 0.8) * peak}
        x = np.clip(x, -p["level_ms2"], p["level_ms2"])
        lib = {"level_ms2": p["level_ms2"]}
    elif kind == "sample_clock_error":
        e = U(ri, 300, 3000) * (1 if ri.uniform() < 0.5 else -1)
        p = {"ppm": e}
        x = C.resample_clock(x, 1.0 / (1.0 + e * 1e-6))
        lib = {"ppm": e}
    elif kind == "noise_color":
        p = {"corner_hz": logU(ri, 50, 800), "rms_ms2": U(ri, 0.5, 1.5) * sx}
        fc = p["corner_hz"]
        x = x + p["rms_ms2"] * C.colour_noise(ri, n, FS, lambda f: 1 / np.sqrt(1 + (f / fc) ** 4))
        lib = {"rms_ms2": p["rms_ms2"], "corner_hz": fc}
    elif kind == "sensor_nonlinearity":
        category = "out_of_library"
        p = {"sat_ms2": U(ri, 0.45, 0.8) * peak, "quadratic": U(ri, 0.03, 0.12)}
        L = p["sat_ms2"]
        x = L * np.tanh(x / L) + p["quadratic"] * x * x / L
    elif kind == "none":
        category = "control"
    else:
        raise ValueError(kind)
    C.write_wav_float(wav, x / scale, FS)
    shutil.copyfile(NOMINAL, os.path.join(outdir, "nominal.toml"))
    gen = {"family": "gfd-injected", "seed": seed, "source": os.path.basename(src), "channel": "a1",
           "load_pct": load, "fs_hz_assumed": FS, "samples": int(x.size), "signal_rms": sx, "signal_peak": peak,
           "form": {k: v for k, v in p.items()}}
    effects = [{"kind": kind, "params": lib}] if lib else []
    if category == "effect":
        desc = f"{kind} on h30hz{load} a1 (" + ", ".join(f"{k}={v:.4g}" for k, v in lib.items()) + ")"
    elif category == "out_of_library":
        desc = f"out of library: {kind} on h30hz{load} a1"
    else:
        desc = f"none: h30hz{load} a1 as measured"
    C.write_json(os.path.join(outdir, "truth.json"),
                 C.truth_doc(category, effects, desc, gen,
                             unlisted={"kind": kind, "params": p} if category == "out_of_library" else None,
                             control=("none" if category == "control" else None)))
    return {"category": category, "kind": kind, "description": desc}


def _scale_of(path):
    with open(path) as f:
        for line in f:
            s = line.strip()
            if s.startswith("scale"):
                return float(s.split("=")[1])
    raise ValueError(f"{path}: no scale")
