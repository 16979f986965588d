#!/usr/bin/env python3
"""Self-checks of the second generator family (ctest gen2_selfcheck): the helpers whose output the truth
files describe do what the truth says, each against a closed form. Exits non-zero on the first failure.

- resample_clock: a tone at f in true time, sampled by a clock e fast, appears at f / (1 + e);
- the structural mode of `transfer_path`: gain 10^(G/20) at fn on white noise, half-power width fn / Q;
- quantise: the ADC's full scale clips at the truth's level_ms2;
- a generated case: the CAN frames decode to the program's speeds, and the WAV has the case's rate
  and length.
"""

import math
import os
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import g2common as C  # noqa: E402
import g2robot  # noqa: E402

failures = []


def check(cond, what):
    print(("ok    " if cond else "FAIL  ") + what)
    if not cond:
        failures.append(what)


def tone_frequency(x, fs):
    """Frequency of a pure tone by a Hann-windowed FFT peak with parabolic interpolation of log power."""
    n = x.size
    X = np.abs(np.fft.rfft(x * np.hanning(n)))
    k = int(np.argmax(X[1:-1])) + 1
    a, b, c = np.log(X[k - 1:k + 2] ** 2)
    d = 0.5 * (a - c) / (a - 2 * b + c)
    return (k + d) * fs / n


def main():
    fs = 25600.0
    t = np.arange(int(4 * fs)) / fs
    f0 = 1234.5
    for ppm in (+2500.0, -800.0):
        y = C.resample_clock(np.sin(2 * math.pi * f0 * t), 1.0 / (1.0 + ppm * 1e-6))
        got = tone_frequency(y[: int(3.5 * fs)], fs)
        want = f0 / (1 + ppm * 1e-6)
        check(abs(got - want) < 0.02, f"clock {ppm:+.0f} ppm: tone {f0} Hz reads {got:.4f}, expected {want:.4f}")

    r = np.random.default_rng(5)
    w = r.standard_normal(1 << 20)
    fn, zeta, gain_db = 3000.0, 0.05, 14.0
    k = 10 ** (gain_db / 20) - 1
    y = w + k * C.fft_filter(w, fs, C.mode_response(fn, zeta))
    seg = 8192
    f = np.fft.rfftfreq(seg, 1 / fs)

    def psd(v):
        return np.mean([np.abs(np.fft.rfft(v[i:i + seg] * np.hanning(seg))) ** 2
                        for i in range(0, v.size - seg, seg)], axis=0)
    ratio = psd(y) / psd(w)
    at_fn = 10 * np.log10(np.mean(ratio[np.abs(f - fn) < 6]))
    check(abs(at_fn - gain_db) < 0.5, f"mode: gain at fn {at_fn:.2f} dB, expected {gain_db} dB")
    # half-power points of the modal part |k H|^2 (H(fn) = 1): width fn / Q, Q = 1 / (2 zeta)
    modal = psd(y - w) / psd(w)
    above = f[modal > 0.5 * k * k]
    width = above.max() - above.min()
    check(abs(width - 2 * zeta * fn) < 0.1 * 2 * zeta * fn,
          f"mode: half-power width {width:.1f} Hz, expected fn/Q = {2 * zeta * fn:.1f} Hz")

    level = 3.7
    codes, lsb = C.quantise(np.array([-10.0, -3.0, 0.0, 3.0, 10.0]), level * 32768 / 32767, 16)
    vals = codes * lsb
    check(abs(vals.max() - level) < 1e-9 and abs(vals.min() + level * 32768 / 32767) < 1e-9,
          f"adc: full scale clips at {vals.max():.6f} (level {level})")

    with tempfile.TemporaryDirectory() as d:
        info = g2robot.make_case(1005, d, kind="none", short_s=True)
        check(info["category"] == "control", "case 1005 'none' is a control")
        x, wav_fs, _tag, bits = C.read_wav(os.path.join(d, "rec", "vibration.wav"))
        m = g2robot.Machine(1005)
        check(wav_fs == m.fs and bits == 24, f"wav: {wav_fs} Hz, {bits} bit")
        speeds = []
        with open(os.path.join(d, "rec", "can.log")) as f:
            for line in f:
                _ts, _iface, frame = line.split()
                cid, data = frame.split("#")
                if int(cid, 16) == m.can_id:
                    speeds.append(int.from_bytes(bytes.fromhex(data[:8]), "little", signed=True) * 1e-4)
        speeds = np.array(speeds)
        want = sorted(set(round(v, 3) for v in m.prog.speeds()))
        top_pos = speeds.max()
        top_neg = -speeds.min()
        check(any(abs(top_pos - v) < 2e-3 for v in want) and any(abs(top_neg - v) < 2e-3 for v in want),
              f"can: top speeds +{top_pos:.4f} / -{top_neg:.4f} rad/s are program speeds {want}")
        check(abs(x.size / wav_fs - (speeds.size * m.can_period_s)) < 0.1,
              f"wav length {x.size / wav_fs:.2f} s matches the CAN span {speeds.size * m.can_period_s:.2f} s")

    if failures:
        print(f"{len(failures)} check(s) failed")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
