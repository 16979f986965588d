"""Detection sets from the second generator family (docs/method.md §8, "Independent generator").

For one machine (a seed of g2robot.Machine: its own reducer, program, harmonic levels and phases, noise,
CAN layout) this writes three recordings of the same robot program:

  train/    healthy, `train_cycles` program cycles (the commissioning recording)
  healthy/  healthy, another day: new noise, new move-to-move jitter, harmonic levels and noise level
            moved by a day-to-day factor exp(day_var * N(0, 1)) each
  faulty/   the same kind of other day, with a local tooth defect (g2robot.tooth_defect) at `severity`
  trainD/   (D = 2, 3, ..., only when asked for) further healthy training days, `train_cycles` cycles
            each, with their own day-to-day factors like healthy/ (several days of commissioning)

and `config.toml`, the pipeline configuration a commissioning engineer would write from what they know:
sample rate, CAN id, tooth counts and the shortest constant-speed stretch of the program (window length).
The defect's form is drawn once per machine (its severity only scales it), so severities 0.25, 0.5 and
1 of one machine are the same defect grown.

Nothing here is shared with sim/src; the detector never sees the generator's parameters.
"""

import math
import os

import numpy as np

import g2common as C
import g2robot as R

# Recordings of one machine get independent random streams: the machine seed is kept for the machine's
# own parameters (Machine()), and its synthesis runs under seed + REALISATION_STRIDE * k.
REALISATION_STRIDE = 1_000_000
DAY_S = 86400.0


def smooth_length(limit):
    """Largest n <= limit with prime factors 2, 3 and 5 only, even (the FFT lengths ptda accepts)."""
    best = 0
    for n in range(4, int(limit) + 1, 2):
        k = n
        for p in (2, 3, 5):
            while k % p == 0:
                k //= p
        if k == 1:
            best = n
    return best


def shortest_cruise_s(m):
    """Shortest constant-speed stretch of the program (one cycle's timeline, without jitter)."""
    pieces, moves, _end = R.build_timeline(C.rng_for(m.seed, 2), m.prog, 1, m.lead_in_s)
    return min(b - a for mv in moves for a, b, _v in mv["cruise"])


def pipeline_config(m, window_len, min_duration_s, line_gain=False):
    return f"""# Written by tests/gen2/g2detect.py for machine {m.seed} from what its user knows.
[acquisition]
fs_hz = {m.fs}

[can.speed_frame]
id = 0x{m.can_id:X}

[extraction]
window_len = {window_len}
hop = {window_len}
max_windows_per_region = 1
speed_tol_rel = 0.02
speed_tol_abs_rad_s = 0.005
min_speed_rad_s = 0.05
max_speed_rad_s = 10.0
min_duration_s = {min_duration_s:.4f}
guard_s = 0.02
max_speed_gap_s = 0.05

[classes]
speed_tol_rel = 0.05
speed_tol_abs_rad_s = 0.02
min_regions = 3

[monitor]
method = "ptda"
line_gain = {"true" if line_gain else "false"}

[gearbox]
kind = "cycloidal"
z_in = {m.z_in}
z_spur = {m.z_spur}
z_pin = {m.z_pin}
"""


def write_recording(recdir, m, x, info, seed_salt):
    codes, lsb = C.quantise(x, m.range_ms2, 24)
    os.makedirs(recdir, exist_ok=True)
    C.write_wav_pcm(os.path.join(recdir, "vibration.wav"), codes, m.fs, 24)
    R.write_can_and_toml(recdir, m, info, C.rng_for(seed_salt, 8), m.can_delay_s, m.can_jitter_s, lsb)


def make_machine(seed, outdir, severity, train_cycles=24, test_cycles=24, day_var=0.05, sets=None,
                 line_gain=False):
    """Writes outdir/{train,healthy,faulty}/ and outdir/config.toml; returns a dict describing the
    machine (for the study's table). sets: which recordings to write (default all three; () writes
    the configuration only; "train2", "train3", ... are further healthy training days with their own
    day-to-day factors). line_gain: the configuration's [monitor] line_gain."""
    sets = ("train", "healthy", "faulty") if sets is None else sets
    base = R.Machine(seed)
    fault = R.draw_tooth_defect(base, C.rng_for(seed, 201), severity)
    cruise_s = shortest_cruise_s(base)
    # Window: the longest fast FFT length fitting the shortest plateau after the 20 ms guard and 30 ms
    # of margin for the plateau detection, at most 0.5 s.
    window_len = smooth_length(min(0.5, cruise_s - 0.05) * base.fs)
    min_duration_s = window_len / base.fs + 0.03
    os.makedirs(outdir, exist_ok=True)
    with open(os.path.join(outdir, "config.toml"), "w") as f:
        f.write(pipeline_config(base, window_len, min_duration_s, line_gain))
    plan = {"train": (1, train_cycles, False), "healthy": (2, test_cycles, False),
            "faulty": (3, test_cycles, True)}
    for name in sets:
        if name.startswith("train") and name != "train":
            # Further training days: realisation index 10 + D (never one of the test days).
            plan[name] = (10 + int(name[5:]), train_cycles, False)
        k, cycles, faulty = plan[name]
        m = R.Machine(seed)
        m.cycles = cycles
        m.seed = seed + REALISATION_STRIDE * k
        m.start_time = base.start_time + k * DAY_S
        if name != "train":
            rd = C.rng_for(m.seed, 202)
            m.levels = {o: v * math.exp(day_var * rd.standard_normal()) for o, v in m.levels.items()}
            m.noise_rms *= math.exp(day_var * rd.standard_normal())
        x, info = R.synthesise(m, None, {}, {}, C.rng_for(m.seed, 7), fault=fault if faulty else None)
        write_recording(os.path.join(outdir, name), m, x, info, m.seed)
    return {"seed": seed, "fs_hz": base.fs, "z": [base.z_in, base.z_spur, base.z_pin],
            "program": base.prog.kind, "speeds": base.prog.speeds(), "window_len": window_len,
            "shortest_cruise_s": cruise_s, "fault": fault}
