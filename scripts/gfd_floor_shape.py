#!/usr/bin/env python3
"""The GFD rig's own noise-floor shape, for the nominal's [vibration] noise_shape_hz / noise_shape_db
(config/scenarios/gfd_gap.toml; docs/gap.md, "Real data: the rig's floor shape").

Reads healthy recordings' channel (default a1 of the five healthy loads h30hz0,20,40,60,80), estimates
each one's PSD (Welch: Hann, 16384 samples, half overlap, at the assumed 64.5 kHz) and prints, per
third-octave band from 80 Hz to 25.6 kHz, the *lower quartile* of the band's bins in dB: it skips the
band's few line bins, so this is the broadband floor under the lines. Levels are relative (the
simulator refers the shape to its value at the tilt's pivot, and `ptda gap` calibrates the level).

Usage: scripts/gfd_floor_shape.py [--data ../shared/data/gfd] [--files h30hz0,h30hz20,...] [--channel a1]
"""
import argparse
import csv
import gzip
import os
import sys

import numpy as np

FS_HZ = 64500.0


def floor_db(path, channel):
    try:
        with gzip.open(path, "rt") as f:
            r = csv.reader(f)
            head = next(r)
            if channel not in head:
                sys.exit("gfd_floor_shape: %s: no column '%s' (header %s)" % (path, channel, ",".join(head)))
            col = head.index(channel)
            x = np.array([float(row[col]) for row in r])
    except (OSError, ValueError, StopIteration) as e:
        sys.exit("gfd_floor_shape: %s: %s" % (path, e))
    n = 16384
    if len(x) < 4 * n:
        sys.exit("gfd_floor_shape: %s: %d samples, need at least %d" % (path, len(x), 4 * n))
    w = np.hanning(n)
    segs = [x[i:i + n] * w for i in range(0, len(x) - n + 1, n // 2)]
    p = np.mean([np.abs(np.fft.rfft(s)) ** 2 for s in segs], axis=0) * 2.0 / (FS_HZ * np.sum(w ** 2))
    f = np.fft.rfftfreq(n, 1.0 / FS_HZ)
    hz, db = [], []
    for k in range(31):
        c = 25.0 * 2.0 ** (k / 3.0)
        lo, hi = c * 2.0 ** (-1.0 / 6.0), c * 2.0 ** (1.0 / 6.0)
        m = (f >= lo) & (f < hi)
        if m.sum() < 5 or hi > 0.45 * FS_HZ:
            continue
        hz.append(c)
        db.append(10.0 * np.log10(np.percentile(p[m], 25.0)))
    return hz, db, len(x)


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default=os.path.join(here, "..", "..", "shared", "data", "gfd"))
    ap.add_argument("--files", default="h30hz0,h30hz20,h30hz40,h30hz60,h30hz80")
    ap.add_argument("--channel", default="a1")
    a = ap.parse_args()
    per_file = []
    total = 0
    for name in a.files.split(","):
        hz, db, n_samples = floor_db(os.path.join(a.data, name + ".csv.gz"), a.channel)
        per_file.append(db)
        total += n_samples
    db = list(np.median(np.array(per_file), axis=0))
    ref = db[0]
    print("# %s %s, %d samples at %.0f Hz: third-octave lower-quartile floor, median over the files, dB re the %.0f Hz band" %
          (a.files, a.channel, total, FS_HZ, hz[0]))
    print("noise_shape_hz = [" + ", ".join("%.0f" % v for v in hz) + "]")
    print("noise_shape_db = [" + ", ".join("%.1f" % (v - ref) for v in db) + "]")


if __name__ == "__main__":
    main()
