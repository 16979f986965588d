#!/usr/bin/python3
"""Reference values for tests/unit/dsp/mesh_modulation_test.cpp: the session-18 prototype's full-rate
mesh demodulation (scripts/shaft_order_study.py mesh_demodulation, numpy) on the test's synthetic
windows. The C++ demodulator works at a decimated rate, so it agrees to a few hundredths, not exactly.

    /usr/bin/python3 scripts/mesh_reference.py
"""
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import feature_study_gen2 as fs2  # noqa: E402
import shaft_order_study as sos  # noqa: E402

FS, N, RATIO, ZIN = 25600.0, 12800, 40.0, 20
SPEED = 2 * math.pi * 10.0 / RATIO


def window(pm_rad=0.0, am=0.0, rate=1.0, noise=0.05, gain=1.0, speed=SPEED):
    """The C++ test's mesh_window(): three mesh harmonics, a once-per-`rate` bump, LCG noise."""
    f_in = RATIO * speed / (2 * math.pi)
    gmf = ZIN * f_in
    t = np.arange(N) / FS
    c = rate * f_in * t + 0.3
    c -= np.floor(c)
    bump = np.exp(-0.5 * ((c - 0.5) / 0.04) ** 2)
    v = np.zeros(N)
    for h, (a, p) in enumerate(zip((1.0, 0.6, 0.35), (0.3, 1.1, 2.0)), start=1):
        v += a * (1.0 - am * bump) * np.cos(2 * math.pi * h * gmf * t + p + h * pm_rad * bump)
    state, mask = 12345, (1 << 64) - 1
    r = np.empty(N)
    for i in range(N):
        state = (state * 6364136223846793005 + 1442695040888963407) & mask
        r[i] = (state >> 11) * (1.0 / 9007199254740992.0)
    v += noise * (2 * r - 1)
    return (gain * v).astype(np.float32).astype(np.float64)


class Mean:
    def __init__(self, x):
        a = np.abs(np.fft.rfft(x))
        self.in_group = np.zeros(a.size, bool)
        for g0, g1 in fs2.line_groups(a):
            self.in_group[g0:g1] = True


def main():
    cm = Mean(window())
    f_in = RATIO * SPEED / (2 * math.pi)
    for name, kw in (("steady", {}), ("slip 0.3", {"pm_rad": 0.3}), ("dip 0.3", {"am": 0.3}),
                     ("slip 0.3 at 1.37", {"pm_rad": 0.3, "rate": 1.37}),
                     ("slip 0.2 dip 0.1", {"pm_rad": 0.2, "am": 0.1})):
        x = window(**kw)
        r = sos.mesh_demodulation(np.fft.fft(x), cm, f_in, FS, N, ZIN)
        print(f"{name:18s} am {r['am']:.4f} pm {r['pm']:.4f}")


if __name__ == "__main__":
    main()
