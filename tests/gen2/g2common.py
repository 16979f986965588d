"""Shared pieces of the second generator family (tests/gen2, docs/gap.md "Bench"): file writers for the
recording format (docs/recording-format.md), random numbers, filters in the frequency domain and the
truth/manifest files. Written independently of sim/src: nothing here ports the project simulator's
formulas; the only shared facts are the file formats and the meaning of the effect parameters that the
bench compares (location_matches() in gap/src/bench.cpp).
"""

import json
import os
import struct

import numpy as np

TRUTH_FORMAT = "ptda-gap-truth"
CORPUS_FORMAT = "ptda-gap-corpus"


def rng_for(seed, salt):
    """Independent numpy generator per (seed, purpose)."""
    return np.random.default_rng([int(seed), int(salt)])


# ---------------------------------------------------------------------------------------------- WAV
def write_wav_pcm(path, codes, fs_hz, bits):
    """PCM WAV (16 or 24 bit), mono, from integer codes (already saturated)."""
    codes = np.asarray(codes, dtype=np.int64)
    n = codes.size
    width = bits // 8
    if bits == 16:
        data = codes.astype("<i2").tobytes()
    elif bits == 24:
        c = (codes & 0xFFFFFF).astype("<u4").view(np.uint8).reshape(-1, 4)[:, :3]
        data = c.tobytes()
    else:
        raise ValueError("bits must be 16 or 24")
    hdr = b"RIFF" + struct.pack("<I", 36 + len(data)) + b"WAVE"
    hdr += b"fmt " + struct.pack("<IHHIIHH", 16, 1, 1, int(fs_hz), int(fs_hz) * width, width, bits)
    hdr += b"data" + struct.pack("<I", len(data))
    with open(path, "wb") as f:
        f.write(hdr)
        f.write(data)
    return n


def quantise(x_ms2, range_ms2, bits):
    """ADC: codes = round(x / lsb), saturated at the converter's full scale. Returns (codes, lsb)."""
    lsb = range_ms2 / float(2 ** (bits - 1))
    codes = np.rint(x_ms2 / lsb)
    lo, hi = -(2 ** (bits - 1)), 2 ** (bits - 1) - 1
    return np.clip(codes, lo, hi).astype(np.int64), lsb


def read_wav(path):
    """Mono or multi-channel WAV reader for the formats we write or `ptda import` writes (PCM16/24,
    float32). Returns (samples of channel 0 as float64 codes, fs, format tag, bits)."""
    with open(path, "rb") as f:
        b = f.read()
    if b[:4] != b"RIFF" or b[8:12] != b"WAVE":
        raise ValueError(f"{path}: not a RIFF/WAVE file")
    pos = 12
    fmt = None
    while pos + 8 <= len(b):
        cid = b[pos:pos + 4]
        size = struct.unpack("<I", b[pos + 4:pos + 8])[0]
        body = b[pos + 8:pos + 8 + size]
        if cid == b"fmt ":
            tag, ch, fs, _br, align, bits = struct.unpack("<HHIIHH", body[:16])
            fmt = (tag, ch, fs, align, bits)
        elif cid == b"data":
            if fmt is None:
                raise ValueError(f"{path}: data before fmt")
            tag, ch, fs, align, bits = fmt
            if tag == 3 and bits == 32:
                x = np.frombuffer(body, dtype="<f4").reshape(-1, ch)[:, 0].astype(np.float64)
            elif tag == 1 and bits == 16:
                x = np.frombuffer(body, dtype="<i2").reshape(-1, ch)[:, 0].astype(np.float64)
            elif tag == 1 and bits == 24:
                raw = np.frombuffer(body, dtype=np.uint8).reshape(-1, ch, 3)[:, 0, :].astype(np.int32)
                v = raw[:, 0] | (raw[:, 1] << 8) | (raw[:, 2] << 16)
                v = np.where(v >= 1 << 23, v - (1 << 24), v)
                x = v.astype(np.float64)
            else:
                raise ValueError(f"{path}: unsupported WAV format tag {tag} / {bits} bits")
            return x, fs, tag, bits
        pos += 8 + size + (size & 1)
    raise ValueError(f"{path}: no data chunk")


def write_wav_float(path, x, fs_hz):
    """IEEE float32 mono WAV (format tag 3, with a fact chunk)."""
    data = np.asarray(x, dtype="<f4").tobytes()
    n = len(data) // 4
    fmt = struct.pack("<HHIIHHH", 3, 1, int(fs_hz), int(fs_hz) * 4, 4, 32, 0)
    body = b"WAVE" + b"fmt " + struct.pack("<I", len(fmt)) + fmt
    body += b"fact" + struct.pack("<II", 4, n) + b"data" + struct.pack("<I", len(data)) + data
    with open(path, "wb") as f:
        f.write(b"RIFF" + struct.pack("<I", len(body)) + body)


# ---------------------------------------------------------------------------------------------- CAN
def candump_line(t_s, iface, can_id, payload):
    us = int(round(t_s * 1e6))
    ident = f"{can_id:03X}" if can_id <= 0x7FF else f"{can_id:08X}"
    return f"({us // 1000000:010d}.{us % 1000000:06d}) {iface} {ident}#{payload.hex().upper()}\n"


def write_recording_toml(dirpath, wav_name, start_time, scale, can_name):
    with open(os.path.join(dirpath, "recording.toml"), "w") as f:
        f.write('format = "ptda-recording"\nversion = 1\n\n[vibration]\n')
        f.write(f'file = "{wav_name}"\nchannel = 0\nstart_time = {repr(float(start_time))}\n')
        f.write(f'scale = {repr(float(scale))}\nunit = "m/s^2"\n\n[can]\nfile = "{can_name}"\n')


# ---------------------------------------------------------------------------------------------- filters
def fft_filter(x, fs_hz, response):
    """Applies H(f) (complex, a function of a frequency array in Hz) to x by one long FFT (zero padded
    to twice the length, so the circular wrap of a ringing path stays in the padding)."""
    n = x.size
    m = 1 << int(np.ceil(np.log2(2 * n)))
    X = np.fft.rfft(x, m)
    f = np.fft.rfftfreq(m, 1.0 / fs_hz)
    return np.fft.irfft(X * response(f), m)[:n]


def mode_response(fn_hz, zeta):
    """Receptance-like structural mode seen by an accelerometer, normalised to 1 at its peak:
    H(f) = 2 j zeta r / (1 - r^2 + 2 j zeta r), r = f / fn (a band-pass resonance, two poles)."""
    def h(f):
        r = f / fn_hz
        return (2j * zeta * r) / (1.0 - r * r + 2j * zeta * r)
    return h


def colour_noise(rng, n, fs_hz, shape):
    """Gaussian noise with power spectrum |shape(f)|^2, unit variance."""
    w = rng.standard_normal(n)
    y = fft_filter(w, fs_hz, shape)
    return y / max(np.std(y), 1e-12)


def band_noise(rng, n, fs_hz, lo_hz, hi_hz):
    """Gaussian noise band-limited to [lo, hi] Hz, unit variance (a smooth random process)."""
    def shape(f):
        return ((f >= lo_hz) & (f <= hi_hz)).astype(float)
    return colour_noise(rng, n, fs_hz, shape)


def resample_clock(x, ratio):
    """Values of the band-limited signal x (grid n) at the points n * ratio: 4 x FFT upsampling, then
    cubic (Catmull-Rom) interpolation on the fine grid. Used for a sample clock that runs at
    fs / ratio in true time (ratio = 1 / (1 + e))."""
    up = 4
    n = x.size
    m = 1 << int(np.ceil(np.log2(n + 64)))
    X = np.fft.rfft(x, m)
    Y = np.zeros(up * m // 2 + 1, dtype=complex)
    Y[: X.size] = X
    xf = np.fft.irfft(Y, up * m) * up
    pos = np.arange(int(np.floor((n - 3) / ratio))) * ratio * up
    i = np.floor(pos).astype(np.int64)
    t = pos - i
    i = np.clip(i, 1, xf.size - 3)
    p0, p1, p2, p3 = xf[i - 1], xf[i], xf[i + 1], xf[i + 2]
    return p1 + 0.5 * t * (p2 - p0 + t * (2 * p0 - 5 * p1 + 4 * p2 - p3 + t * (3 * (p1 - p2) + p3 - p0)))


# ---------------------------------------------------------------------------------------------- truth
def truth_doc(category, effects, description, generator, unlisted=None, control=None):
    """Truth file. category: "effect" (effects: library kinds with the parameters the bench compares,
    in the library's meaning), "control" (no unmodelled effect; `control` says what differs from the
    nominal), "out_of_library" (`unlisted` describes an effect the library has no kind for)."""
    d = {"format": TRUTH_FORMAT, "version": 1, "category": category, "description": description,
         "effects": effects, "generator": generator}
    if unlisted is not None:
        d["out_of_library"] = unlisted
    if control is not None:
        d["control"] = control
    return d


def write_json(path, obj):
    with open(path, "w") as f:
        json.dump(obj, f, indent=1, sort_keys=False, default=_jsonable)
        f.write("\n")


def _jsonable(o):
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(str(type(o)))


def write_manifest(outdir, name, cases):
    """corpus.json: {format, version, name, cases: [{name, recording, nominal, truth}]} with paths
    relative to the corpus directory."""
    write_json(os.path.join(outdir, "corpus.json"),
               {"format": CORPUS_FORMAT, "version": 1, "name": name, "cases": cases})


def fmt_list(v, digits=4):
    return "[" + ", ".join(f"{float(a):.{digits}g}" for a in v) + "]"
