"""Second generator family, robot joints (docs/gap.md "Bench", corpus `gen2`).

An independently written model of a robot joint with an RV-type reducer, used to check `ptda gap` on
recordings the project simulator did not make. Own parameterisation and own formulas:

- motion: a robot program of moves, each starting from rest (rest before every move), with raised-cosine
  speed blends, one or two cruise speeds per move, back and forth (2 or 3 moves per program cycle);
- mesh: a waveform defined over the mesh angle (cosine series with random phases per machine, its own
  convention), tabulated on an angle grid and read at the instantaneous mesh angle of every sample
  (angle-domain synthesis resampled to time); amplitude ~ |speed|^beta with beta drawn per machine;
- floor: Gaussian noise with a gentle spectral tilt;
- effects in real-machine forms (see EFFECT_SLOTS) and two forms outside the effect library;
- CAN: the controller's own free-running clock, speed/angle frames in the scenario's layout, other traffic.

The nominal scenario is written only from what a user of the machine knows (tooth counts, program,
speeds, approximate blends, sample rate, CAN layout, typical harmonic levels and noise), never from the
generator's exact internals. The truth file records everything.
"""

import math
import os

import numpy as np

import g2common as C

GEARBOXES = [(28, 23, 40), (24, 30, 40), (32, 20, 50), (30, 26, 44), (26, 22, 38)]
RATES = [25600, 20480, 32000]

LIBRARY = ["transfer_path", "speed_ripple", "mesh_modulation", "impacts", "electrical_interference",
           "adc_clipping", "sample_clock_error", "speed_latency", "other_axis", "load_dependence",
           "noise_color"]
OUT_OF_LIBRARY = ["sensor_nonlinearity", "loose_mount_rattle"]
CONTROLS = ["none", "amplitudes_off", "noise_off", "blend_off"]
SLOTS = LIBRARY + OUT_OF_LIBRARY + CONTROLS


def slot_of(seed):
    return SLOTS[seed % len(SLOTS)]


def U(r, a, b):
    return float(r.uniform(a, b))


def logU(r, a, b):
    return float(math.exp(r.uniform(math.log(a), math.log(b))))


# ---------------------------------------------------------------------------------------------- motion
class Program:
    """A robot program: moves (signed distance, list of (distance share, cruise speed)) with a rest
    before each, blends of `blend_s`."""

    def __init__(self, r, max_speed):
        self.kind = ["two", "three", "approach"][int(r.integers(3))]
        self.blend_s = U(r, 0.08, 0.22)
        self.rest_s = U(r, 0.3, 0.6)
        self.rest_jitter_s = U(r, 0.04, 0.15)
        vmax = max_speed

        def speed():
            return U(r, 0.35, 1.0) * vmax

        def dist(v):  # long enough for >= 0.35 s of cruise
            return max(U(r, 0.5, 1.5), v * (0.4 + self.blend_s))

        if self.kind == "two":
            v1, v2 = speed(), speed()
            a = max(dist(v1), dist(v2))
            self.moves = [(+a, [(1.0, v1)]), (-a, [(1.0, v2)])]
        elif self.kind == "three":
            v1, v2, v3 = speed(), speed(), speed()
            b = max(dist(v2), dist(v3))
            a = b + max(dist(v3), 0.4)
            # 0 -> a -> a - b -> 0 : the last move covers a - b
            c = a - b
            if c < v3 * (0.4 + self.blend_s):
                a = b + v3 * (0.45 + self.blend_s)
                c = a - b
            a = max(a, v1 * (0.4 + self.blend_s))
            c = a - b
            self.moves = [(+a, [(1.0, v1)]), (-b, [(1.0, v2)]), (-c, [(1.0, v3)])]
        else:  # fast move with a slow approach at its end, one return speed
            v1, v3 = U(r, 0.7, 1.0) * vmax, speed()
            v2 = U(r, 0.25, 0.5) * v1
            a = max(U(r, 1.0, 1.6), v1 * (0.4 + self.blend_s) + v2 * (0.4 + self.blend_s) + 0.2,
                    v3 * (0.4 + self.blend_s))
            share = U(r, 0.55, 0.75)
            self.moves = [(+a, [(share, v1), (1.0 - share, v2)]), (-a, [(1.0, v3)])]

    def speeds(self):
        return [v for _, legs in self.moves for _, v in legs]


def move_profile(distance, legs, blend_s):
    """Breakpoints of one move starting at time 0 from rest: list of (t0, t1, va, vb) pieces, blends
    raised-cosine from va to vb, cruises va = vb. Signed by the move direction."""
    s = 1.0 if distance >= 0 else -1.0
    D = abs(distance)
    speeds = [v for _, v in legs]
    shares = [d for d, _ in legs]
    # Distance of the blends: each blend between va and vb covers (va + vb) / 2 * T.
    pieces = []
    t = 0.0
    prev = 0.0
    covered = 0.0
    for i, (share, v) in enumerate(zip(shares, speeds)):
        pieces.append((t, t + blend_s, s * prev, s * v))
        covered += 0.5 * (prev + v) * blend_s
        t += blend_s
        if i < len(speeds) - 1:
            target = sum(shares[: i + 1]) * D - 0.5 * (v + speeds[i + 1]) * blend_s * 0.5
            cruise = max(0.05, (target - covered) / v)
        else:
            cruise = max(0.05, (D - covered - 0.5 * v * blend_s) / v)
        pieces.append((t, t + cruise, s * v, s * v))
        covered += v * cruise
        t += cruise
        prev = v
    pieces.append((t, t + blend_s, s * prev, 0.0))
    return pieces


def build_timeline(r, prog, cycles, lead_in_s, blend_scale=1.0):
    """All pieces of the recording: rest before every move (program rest + random extra)."""
    pieces = []
    t = lead_in_s
    moves = []
    for c in range(cycles):
        for m, (dist, legs) in enumerate(prog.moves):
            t += prog.rest_s + U(r, 0.0, prog.rest_jitter_s)
            p = move_profile(dist, legs, prog.blend_s * blend_scale)
            t0 = t
            for a, b, va, vb in p:
                pieces.append((t0 + a, t0 + b, va, vb))
            t = t0 + p[-1][1]
            moves.append({"cycle": c, "move": m, "start_s": t0, "stop_s": t,
                          "cruise": [(t0 + a, t0 + b, va) for a, b, va, vb in p if va == vb]})
    end = t + prog.rest_s + 0.2
    return pieces, moves, end


def speed_at(pieces, t):
    """Joint speed (rad/s) at times t (array)."""
    v = np.zeros_like(t)
    starts = np.array([p[0] for p in pieces])
    idx = np.searchsorted(starts, t, side="right") - 1
    for i, (a, b, va, vb) in enumerate(pieces):
        sel = (idx == i) & (t < b)
        if not np.any(sel):
            continue
        if va == vb:
            v[sel] = va
        else:
            u = (t[sel] - a) / (b - a)
            v[sel] = va + (vb - va) * 0.5 * (1.0 - np.cos(np.pi * u))
    return v


def accel_at(pieces, t):
    a_out = np.zeros_like(t)
    starts = np.array([p[0] for p in pieces])
    idx = np.searchsorted(starts, t, side="right") - 1
    for i, (a, b, va, vb) in enumerate(pieces):
        if va == vb:
            continue
        sel = (idx == i) & (t < b)
        u = (t[sel] - a) / (b - a)
        a_out[sel] = (vb - va) * 0.5 * np.pi / (b - a) * np.sin(np.pi * u)
    return a_out


# ---------------------------------------------------------------------------------------------- machine
class Machine:
    def __init__(self, seed):
        r = C.rng_for(seed, 1)
        self.seed = seed
        self.z_in, self.z_spur, self.z_pin = GEARBOXES[int(r.integers(len(GEARBOXES)))]
        self.ratio = 1.0 + self.z_spur / self.z_in * self.z_pin
        self.fs = RATES[int(r.integers(len(RATES)))]
        n_orders = int(r.integers(4, 7))
        orders = sorted(set([1] + list(r.choice(np.arange(2, 10), size=n_orders - 1, replace=False))))
        self.orders = [int(k) for k in orders]
        self.levels = {k: (U(r, 0.6, 1.4) if k == 1 else U(r, 0.15, 0.9)) for k in self.orders}
        self.phases = {k: U(r, -math.pi, math.pi) for k in self.orders}
        self.beta = U(r, 0.9, 1.2)
        self.move_jitter = 0.02
        self.noise_rms = U(r, 0.15, 0.5)
        self.noise_tilt_db_dec = U(r, -2.0, 2.0)
        self.noise_move_jitter = 0.05
        # top joint speed such that the highest order stays below 0.42 fs
        gmf_per_rad_s = self.z_in * self.ratio / (2 * math.pi)
        vmax_alias = 0.42 * self.fs / (max(self.orders) * gmf_per_rad_s)
        self.vmax = min(U(r, 1.8, 3.2), vmax_alias)
        self.prog = Program(r, self.vmax)
        self.cycles = 6 if len(self.prog.moves) == 2 else 5
        self.lead_in_s = 0.3
        self.range_ms2 = 50.0
        self.can_id = [0x184, 0x184, 0x1A4][int(r.integers(3))]
        self.can_period_s = 0.004
        self.can_delay_s = U(r, 0.0003, 0.0009)
        self.can_jitter_s = U(r, 0.00005, 0.0003)
        self.can_clock_ppm = U(r, -30, 30)
        self.start_time = 1.75e9 + float(r.integers(0, 10 ** 7))
        self.ref_speed = self.prog.speeds()[0]

    def gmf_hz(self, speed_rad_s):
        return self.z_in * self.ratio * abs(speed_rad_s) / (2 * math.pi)


# ---------------------------------------------------------------------------------------------- effects
def draw_effect(kind, r, m, peak_hint):
    fs = m.fs
    g1 = m.gmf_hz(m.prog.speeds()[0])
    if kind == "transfer_path":
        return {"fn_hz": logU(r, 800, 0.38 * fs), "zeta": U(r, 0.04, 0.12), "gain_db": U(r, 8, 20)}
    if kind == "speed_ripple":
        return {"mesh_rms_rad": U(r, 0.25, 0.8), "periodic_share": U(r, 0.3, 0.7),
                "periodic_order": int(r.integers(1, 4)), "periodic_phase": U(r, 0, 6.28),
                "random_band_hz": logU(r, 5, 50)}
    if kind == "mesh_modulation":
        return {"rate_order": U(r, 0.6, 3.0), "am": U(r, 0.15, 0.5),
                "pm_rad": 0.0 if r.uniform() < 0.5 else U(r, 0.05, 0.3), "phase": U(r, 0, 6.28)}
    if kind == "impacts":
        fn = logU(r, 1000, 0.38 * fs)
        return {"amplitude_ms2": U(r, 3, 15), "fn_hz": fn, "zeta": U(r, 0.03, 0.1),
                "fn2_hz": min(fn * U(r, 1.3, 2.2), 0.45 * fs), "second_share": U(r, 0.2, 0.5),
                "max_delay_s": U(r, 0.005, 0.03)}
    if kind == "electrical_interference":
        mains = 50.0 if r.uniform() < 0.6 else 60.0
        pwm = [f for f in (4000.0, 5000.0, 8000.0, 10000.0, 12000.0) if f < 0.45 * fs]
        return {"mains_hz": mains, "drift_rel": U(r, 1e-4, 6e-4), "amplitude_ms2": U(r, 0.05, 0.4),
                "harmonic_levels": [1.0] + [U(r, 0.05, 0.7) * (1.0 if k % 2 else 0.4) for k in range(3, 9)],
                "pwm_hz": float(pwm[int(r.integers(len(pwm)))]), "pwm_ms2": U(r, 0.05, 0.3),
                "pwm_side_hz": U(r, 40, 300)}
    if kind == "adc_clipping":
        return {"level_rel_peak": U(r, 0.5, 0.8)}
    if kind == "sample_clock_error":
        e = U(r, 300, 3000)
        return {"ppm": e if r.uniform() < 0.5 else -e}
    if kind == "speed_latency":
        return {"delay_s": U(r, 0.01, 0.05), "jitter_s": U(r, 0.0, 0.002)}
    if kind == "other_axis":
        ratio = 1.0
        while abs(ratio - round(ratio)) < 0.1:
            ratio = U(r, 0.35, 2.5)
        return {"ratio": ratio, "amplitude_ms2": U(r, 0.3, 1.0), "speed_rad_s": U(r, 0.8, 2.5),
                "dist_rad": U(r, 0.8, 1.8), "rest_s": U(r, 0.2, 1.0), "offset_s": U(r, 0.0, 1.5),
                "blend_s": U(r, 0.08, 0.2), "gmf_hz": ratio * g1}
    if kind == "load_dependence":
        g = U(r, 0.2, 0.5)
        return {"target_gain": g if r.uniform() < 0.5 else -g, "tau0": U(r, 0.2, 0.6),
                "inertia": U(r, 0.01, 0.04), "gravity_wobble": U(r, 0.0, 0.15),
                "q0": U(r, 0, 6.28)}
    if kind == "noise_color":
        return {"corner_hz": logU(r, 30, 500), "rms_rel_floor": U(r, 0.6, 2.0)}
    if kind == "sensor_nonlinearity":
        return {"sat_rel_peak": U(r, 0.45, 0.8), "quadratic": U(r, 0.03, 0.12)}
    if kind == "loose_mount_rattle":
        return {"threshold_rel_peak": U(r, 0.35, 0.6), "fn_hz": logU(r, 1500, 0.35 * fs),
                "zeta": U(r, 0.05, 0.12), "gain": U(r, 1.5, 4.0), "dead_s": U(r, 0.01, 0.03)}
    raise ValueError(kind)


def ring(fs, fn, zeta, fn2=None, share2=0.0):
    """Impulse response of a knock ringing one or two structural modes (unit peak-ish)."""
    t = np.arange(int(fs * min(0.2, 8.0 / (zeta * 2 * math.pi * fn)))) / fs
    w = 2 * math.pi * fn
    h = np.exp(-zeta * w * t) * np.sin(w * math.sqrt(1 - zeta * zeta) * t)
    if fn2:
        w2 = 2 * math.pi * fn2
        h += share2 * np.exp(-zeta * w2 * t) * np.sin(w2 * math.sqrt(1 - zeta * zeta) * t)
    return h


# ---------------------------------------------------------------------------------------------- gear fault
def tooth_defect(m, fault, theta_in, phi, w, mesh, fs):
    """A local defect on one tooth of the input pinion (detection study, g2detect.py), in this family's
    own terms: once per input-shaft revolution, while the damaged tooth is in mesh (an angle span of
    `contact` tooth pitches centred on `angle_rad`), the mesh loses part of its amplitude and slips in
    phase (a Hann-shaped dip of depth `depth` and `slip_rad`), and the tooth's entry knocks a structural
    mode (`knock_ms2` at the reference speed, scaled by (speed / ref)^beta). `severity` scales all three.
    Returns the mesh signal with the defect."""
    s = fault["severity"]
    pitch = 2 * math.pi / m.z_in
    half = 0.5 * fault["contact"] * pitch
    # Signed angle of the shaft from the damaged tooth's centre, in (-pi, pi].
    d = np.mod(theta_in - fault["angle_rad"] + math.pi, 2 * math.pi) - math.pi
    bump = np.where(np.abs(d) < half, 0.5 * (1.0 + np.cos(math.pi * d / half)), 0.0)
    out = mesh * (1.0 - s * fault["depth"] * bump)
    # The phase slip: the mesh waveform read slightly late where the tooth bends. A first-order
    # correction (d mesh / d phi * slip) is enough for slips of a few tenths of a radian.
    dmesh = np.gradient(mesh) / np.maximum(np.abs(np.gradient(phi)), 1e-9)
    out = out - dmesh * s * fault["slip_rad"] * bump
    # Knocks where the damaged tooth enters the mesh: the shaft angle crosses the span's leading edge
    # (angle - half going forward, angle + half going backward).
    fwd = np.flatnonzero(np.diff(np.floor((theta_in - fault["angle_rad"] + half) / (2 * math.pi))) > 0)
    bwd = np.flatnonzero(np.diff(np.floor((theta_in - fault["angle_rad"] - half) / (2 * math.pi))) < 0)
    cross = np.concatenate([fwd, bwd])
    h = ring(fs, fault["fn_hz"], fault["zeta"])
    lvl = (np.abs(w) / m.ref_speed) ** m.beta
    for i0 in cross:
        a = s * fault["knock_ms2"] * lvl[i0]
        seg = h[: max(0, min(h.size, out.size - i0))]
        out[i0:i0 + seg.size] += a * seg
    return out


def draw_tooth_defect(m, r, severity):
    """Defect parameters of a machine at full severity (drawn once per machine; severity scales)."""
    return {"severity": severity, "angle_rad": U(r, -math.pi, math.pi), "contact": U(r, 1.3, 1.8),
            "depth": U(r, 0.3, 0.6), "slip_rad": U(r, 0.1, 0.3),
            "knock_ms2": U(r, 0.5, 1.5) * m.levels[1], "fn_hz": logU(r, 1500, 0.35 * m.fs),
            "zeta": U(r, 0.03, 0.08)}


# ---------------------------------------------------------------------------------------------- synthesis
def synthesise(m, kind, p, control, r, fault=None):
    """Returns (acceleration at the true-time grid m/fs (m/s^2), t grid, speed, motion info).
    fault: None, or a local tooth defect on the input pinion (see tooth_defect(); detection study)."""
    fs = m.fs
    blend_scale = control.get("blend_scale", 1.0)
    pieces, moves, end = build_timeline(C.rng_for(m.seed, 2), m.prog, m.cycles, m.lead_in_s, blend_scale)
    n = int(end * fs)
    t = np.arange(n) / fs
    w = speed_at(pieces, t)
    q = np.cumsum(w) / fs
    theta_in = m.ratio * q
    info = {"pieces": pieces, "moves": moves, "end_s": end, "t": t, "w": w, "q": q}

    # Mesh angle (mesh periods in radians) with ripple.
    phi = m.z_in * theta_in + U(r, 0, 6.28)
    if kind == "speed_ripple":
        rr = C.rng_for(m.seed, 11)
        a_per = math.sqrt(2.0 * p["periodic_share"]) * p["mesh_rms_rad"]
        rnd = C.band_noise(rr, n, fs, 0.5, p["random_band_hz"]) * math.sqrt(1 - p["periodic_share"]) * \
            p["mesh_rms_rad"]
        phi = phi + a_per * np.sin(p["periodic_order"] * theta_in + p["periodic_phase"]) + rnd
    if kind == "mesh_modulation":
        phi = phi + p["pm_rad"] * np.sin(p["rate_order"] * theta_in + p["phase"] + 1.0)

    # Angle-domain table of one mesh period, per move (a few % amplitude variation move to move).
    grid = 2048
    ang = np.arange(grid + 1) * (2 * math.pi / grid)
    move_of = np.full(n, -1)
    for i, mv in enumerate(moves):
        a, b = int(mv["start_s"] * fs), min(n, int(mv["stop_s"] * fs) + 1)
        move_of[a:b] = i
    mesh = np.zeros(n)
    rj = C.rng_for(m.seed, 3)
    pos = np.mod(phi, 2 * math.pi) / (2 * math.pi) * grid
    for i in range(len(moves)):
        sel = move_of == i
        table = np.zeros(grid + 1)
        for k in m.orders:
            a_k = m.levels[k] * math.exp(m.move_jitter * rj.standard_normal())
            table += a_k * np.cos(k * ang + m.phases[k])
        mesh[sel] = np.interp(pos[sel], np.arange(grid + 1), table)
    amp = (np.abs(w) / m.ref_speed) ** m.beta
    if fault is not None:
        mesh = tooth_defect(m, fault, theta_in, phi, w, mesh, fs)
    if kind == "mesh_modulation":
        amp = amp * (1.0 + p["am"] * np.cos(p["rate_order"] * theta_in + p["phase"]))
    if kind == "load_dependence":
        alpha = accel_at(pieces, t)
        grav = 1.0 * (1.0 + p["gravity_wobble"] * np.sin(q + p["q0"]))
        g = p["target_gain"]
        # lifting vs lowering: |gravity + friction| vs |gravity - friction|; the friction share sets the
        # direction ratio (1+g)/(1-g); sign of the gravity torque sets which way is louder.
        fric = (1.0 + p["tau0"]) * abs(g)
        sign_g = 1.0 if g > 0 else -1.0
        tau = sign_g * grav + fric * np.sign(w) + p["inertia"] * alpha
        factor = (np.abs(tau) + p["tau0"]) / (1.0 + p["tau0"])
        amp = amp * factor
        info["load_factor"] = factor
    x = mesh * amp

    # Floor noise with a tilt, level varying from move to move.
    rn = C.rng_for(m.seed, 4)
    tilt = m.noise_tilt_db_dec

    def tilt_shape(f):
        return (np.maximum(f, 20.0) / 1000.0) ** (tilt / 20.0)

    floor = C.colour_noise(rn, n, fs, tilt_shape) * m.noise_rms
    for i in range(len(moves)):
        sel = move_of == i
        floor[sel] *= math.exp(m.noise_move_jitter * rn.standard_normal())
    x = x + floor
    mech_peak = float(np.max(np.abs(x)))

    if kind == "impacts":
        h = ring(fs, p["fn_hz"], p["zeta"], p["fn2_hz"], p["second_share"])
        rk = C.rng_for(m.seed, 12)
        knocks = []
        for mv in moves:
            for t0 in (mv["start_s"], mv["stop_s"]):
                tk = t0 + rk.uniform(0, p["max_delay_s"])
                knocks.append(tk)
                a = p["amplitude_ms2"] * rk.uniform(0.6, 1.2) * (1 if rk.uniform() < 0.5 else -1)
                i0 = int(tk * fs)
                seg = h[: max(0, min(h.size, n - i0))]
                x[i0:i0 + seg.size] += a * seg
        info["knocks_s"] = knocks
    if kind == "other_axis":
        # Another joint on its own schedule: moves back and forth at its own speed and rests.
        pieces_o = []
        tt = p["offset_s"]
        sgn = 1.0
        while tt < end:
            pr = move_profile(sgn * p["dist_rad"], [(1.0, p["speed_rad_s"])], p["blend_s"])
            for a, b, va, vb in pr:
                pieces_o.append((tt + a, tt + b, va, vb))
            tt += pr[-1][1] + p["rest_s"] * (0.7 + 0.6 * r.uniform())
            sgn = -sgn
        w_o = speed_at(pieces_o, t)
        phi_o = np.cumsum(w_o) / fs * (2 * math.pi * p["gmf_hz"] / p["speed_rad_s"]) + U(r, 0, 6.28)
        a_o = p["amplitude_ms2"] * np.abs(w_o) / p["speed_rad_s"]
        x = x + a_o * (np.cos(phi_o) + 0.35 * np.cos(2 * phi_o + 0.7))
        info["other_axis_moving_share"] = float(np.mean(np.abs(w_o) > 0.02))
    if kind == "noise_color":
        rc = C.rng_for(m.seed, 13)
        fc = p["corner_hz"]
        red = C.colour_noise(rc, n, fs, lambda f: 1.0 / np.sqrt(1.0 + (f / fc) ** 4))
        x = x + red * p["rms_rel_floor"] * m.noise_rms
    if kind == "loose_mount_rattle":
        # A loose bracket lifts when the vibration exceeds a threshold and knocks back.
        thr = p["threshold_rel_peak"] * mech_peak
        h = ring(fs, p["fn_hz"], p["zeta"])
        over = np.flatnonzero(np.abs(x) > thr)
        last = -1e9
        hits = 0
        base = x.copy()
        for i0 in over:
            if (i0 - last) / fs < p["dead_s"]:
                continue
            last = i0
            hits += 1
            a = p["gain"] * (abs(base[i0]) - thr + 0.2 * thr) * np.sign(base[i0])
            seg = h[: max(0, min(h.size, n - i0))]
            x[i0:i0 + seg.size] += a * seg
        info["rattles"] = hits
    if kind == "transfer_path":
        k = 10 ** (p["gain_db"] / 20.0) - 1.0
        mode = C.mode_response(p["fn_hz"], p["zeta"])
        x = x + k * C.fft_filter(x, fs, mode)
    if kind == "electrical_interference":
        re = C.rng_for(m.seed, 14)
        drift = 1.0 + p["drift_rel"] * C.band_noise(re, n, fs, 0.02, 0.3)
        ph = 2 * math.pi * p["mains_hz"] * np.cumsum(drift) / fs
        el = np.zeros(n)
        levels = p["harmonic_levels"]
        harmonics = [1, 3, 4, 5, 6, 7, 8]  # 2nd omitted (symmetric mains), 3rd strongest of the rest
        for lvl, h_k in zip(levels, harmonics):
            if h_k * p["mains_hz"] < 0.45 * fs:
                el += lvl * np.sin(h_k * ph + re.uniform(0, 6.28))
        el *= p["amplitude_ms2"]
        # drive PWM carrier with sidebands, switching noise of the servo amplifier
        tp = t
        el += p["pwm_ms2"] * (np.sin(2 * math.pi * p["pwm_hz"] * tp) +
                              0.5 * np.sin(2 * math.pi * (p["pwm_hz"] - p["pwm_side_hz"]) * tp) +
                              0.5 * np.sin(2 * math.pi * (p["pwm_hz"] + p["pwm_side_hz"]) * tp))
        x = x + el
    if kind == "sensor_nonlinearity":
        L = p["sat_rel_peak"] * mech_peak
        x = L * np.tanh(x / L) + p["quadratic"] * x * x / L
    return x, info


def library_truth(kind, p, m, info, x_peak):
    """The effect in the library's parameter meaning (what location_matches() compares)."""
    if kind == "transfer_path":
        return {"frequency_hz": p["fn_hz"], "gain_db": p["gain_db"], "q": 1.0 / (2 * p["zeta"])}
    if kind == "speed_ripple":
        return {"jitter_rad": p["mesh_rms_rad"], "bandwidth_hz": p["random_band_hz"]}
    if kind == "mesh_modulation":
        return {"rate_order": p["rate_order"], "am_depth": p["am"], "pm_rad": p["pm_rad"]}
    if kind == "impacts":
        return {"amplitude_ms2": p["amplitude_ms2"], "resonance_hz": p["fn_hz"], "damping_ratio": p["zeta"],
                "rate_hz": 0.0}
    if kind == "electrical_interference":
        lv = p["harmonic_levels"]
        return {"frequency_hz": p["mains_hz"], "amplitude_ms2": p["amplitude_ms2"], "harmonics": 5,
                "harmonic_decay": float(np.clip(lv[1], 0.05, 0.95))}
    if kind == "adc_clipping":
        return {"level_ms2": p["level_ms2"]}
    if kind == "sample_clock_error":
        return {"ppm": p["ppm"]}
    if kind == "speed_latency":
        return {"delay_s": p["delay_s"], "jitter_s": p["jitter_s"]}
    if kind == "other_axis":
        # Its own program in the library's terms: its line while it moves, the share of time it moves,
        # its 2nd harmonic's level (0.35 below).
        return {"amplitude_ms2": p["amplitude_ms2"], "frequency_ratio": p["ratio"], "lag_s": 0.0,
                "own_frequency_hz": p["gmf_hz"], "duty": info["other_axis_moving_share"], "harmonic2": 0.35}
    if kind == "load_dependence":
        # Measured direction gain from the mean load factor on positive vs negative cruise.
        fac, w = info["load_factor"], info["w"]
        cruise = np.zeros(w.size, dtype=bool)
        for mv in info["moves"]:
            for a, b, _v in mv["cruise"]:
                cruise[int(a * m.fs):int(b * m.fs)] = True
        fp = float(np.mean(fac[cruise & (w > 0)]))
        fn = float(np.mean(fac[cruise & (w < 0)]))
        g = (fp - fn) / (fp + fn)
        p["measured_factors"] = [fp, fn]
        return {"direction_gain": g, "accel_gain": 0.0}
    if kind == "noise_color":
        return {"rms_ms2": p["rms_rel_floor"] * m.noise_rms, "corner_hz": p["corner_hz"]}
    raise ValueError(kind)


# ---------------------------------------------------------------------------------------------- nominal
def nominal_toml(m, control, r):
    """Scenario in the project's language from what a user knows."""
    prog = m.prog
    amp_err_db = control.get("amp_err_db", 1.5)
    noise_err = control.get("noise_err", 0.1)
    speeds = prog.speeds()
    accel = float(np.mean(speeds)) / prog.blend_s  # "the controller's acceleration", v / blend time
    via = [0.0, 0.0]
    durs = [prog.rest_s + 0.5 * prog.rest_jitter_s + speeds[0] / (2 * accel)]
    pos = 0.0
    legs_flat = []
    for dist, legs in prog.moves:
        for share, v in legs:
            legs_flat.append((dist * share, v))
    for i, (d, v) in enumerate(legs_flat):
        pos += d
        via.append(pos)
        last = i == len(legs_flat) - 1
        if last:
            durs.append(abs(d) / v + v / (2 * accel))
        else:
            durs.append(abs(d) / v)
            # a rest follows when the next leg starts a new move (the next leg's sign or a move end)
        if not last:
            nxt = legs_flat[i + 1]
            # approach legs continue the same move: no rest between them
            same_move = _same_move(prog, i)
            if not same_move:
                via.append(pos)
                durs.append(prog.rest_s + 0.5 * prog.rest_jitter_s + v / (2 * accel) + nxt[1] / (2 * accel))
    levels = []
    kmax = max(m.orders)
    for k in range(1, kmax + 1):
        if k in m.orders:
            levels.append(m.levels[k] * 10 ** (U(r, -amp_err_db, amp_err_db) / 20.0))
        else:
            levels.append(0.0)
    phases = None
    if control.get("phases_given"):
        phases = [U(r, -3.14, 3.14) if k in m.orders else 0.0 for k in range(1, kmax + 1)]
    noise = m.noise_rms * (1.0 + (noise_err if r.uniform() < 0.5 else -noise_err) *
                           (1.0 if "noise_err" in control else r.uniform()))
    lines = [
        "# Nominal scenario written from what the machine's user knows (tests/gen2/g2robot.py): reducer",
        "# tooth counts, the robot program (moves, speeds, approximate blends and rests), sample rate, CAN",
        "# layout, typical harmonic levels and noise. Not the generator's internals.",
        f'name = "gen2_nominal_{m.seed}"',
        'description = "gen2 robot joint, nominal"',
        "seed = 1",
        f"start_time_s = {m.start_time:.1f}",
        "",
        "[motion]",
        'kind = "lspb"',
        f"via_points_rad = {C.fmt_list(via, 6)}",
        f"segment_durations_s = {C.fmt_list(durs, 6)}",
        f"accel_rad_s2 = {accel:.4g}",
        "dwell_s = 0.0",
        f"cycles = {m.cycles}",
        f"start_jitter_s = {prog.rest_jitter_s:.3g}",
        f"lead_in_s = {m.lead_in_s}",
        "",
        "[gearbox]",
        'kind = "cycloidal"',
        f"z_in = {m.z_in}",
        f"z_spur = {m.z_spur}",
        f"z_pin = {m.z_pin}",
        "",
        "[vibration]",
        f"gmf_amplitudes = {C.fmt_list(levels, 4)}",
    ]
    if phases:
        lines.append(f"gmf_phases_rad = {C.fmt_list(phases, 4)}")
    lines += [
        f"reference_speed_rad_s = {m.ref_speed:.6g}",
        "amplitude_speed_exponent = 1.0",
        f"noise_rms = {noise:.4g}",
        "cycle_amplitude_jitter_rel = 0.02",
        "cycle_noise_jitter_rel = 0.05",
        "",
        "[sensor]",
        f"fs_hz = {m.fs}",
        f"range_ms2 = {m.range_ms2}",
        'format = "pcm24"',
        "",
        "[can]",
        f"period_s = {m.can_period_s}",
        "delay_s = 0.0005",
        "jitter_s = 0.0002",
        "other_frames_per_s = 20",
    ]
    if m.can_id != 0x184:
        lines += ["", "[can.speed_frame]", f"id = 0x{m.can_id:X}"]
    return "\n".join(lines) + "\n", {"via": via, "durations": durs, "accel": accel, "levels": levels,
                                     "noise_rms": noise}


def _same_move(prog, leg_index):
    i = 0
    for _dist, legs in prog.moves:
        for j in range(len(legs)):
            if i == leg_index:
                return j < len(legs) - 1
            i += 1
    return False


def write_can_and_toml(recdir, m, info, rc, delay, jit, lsb):
    """CAN log (the controller's clock, speed/angle frames in the nominal's layout, other traffic) and
    recording.toml of a recording whose vibration.wav is written."""
    period = m.can_period_s * (1 + m.can_clock_ppm * 1e-6)
    t0 = rc.uniform(0, period)
    tk = np.arange(t0, info["end_s"] - 0.01, period)
    wk = np.interp(tk, info["t"], info["w"])
    qk = np.interp(tk, info["t"], info["q"])
    logt = m.start_time + tk + delay + rc.uniform(0, jit, tk.size)
    frames = []
    for ts, wv, qv in zip(logt, wk, qk):
        payload = int(round(wv / 1e-4)).to_bytes(4, "little", signed=True) + \
            int(round(qv / 1e-5)).to_bytes(4, "little", signed=True)
        frames.append((ts, m.can_id, payload))
    dur = info["end_s"]
    for _ in range(int(20 * dur)):
        ts = m.start_time + rc.uniform(0, dur)
        cid = [0x080, 0x201, 0x701][int(rc.integers(3))]
        pl = bytes(int(b) for b in rc.integers(0, 256, 0 if cid == 0x080 else (1 if cid == 0x701 else 8)))
        frames.append((ts, cid, pl))
    frames.sort(key=lambda f: f[0])
    with open(os.path.join(recdir, "can.log"), "w") as f:
        for ts, cid, pl in frames:
            f.write(C.candump_line(ts, "can0", cid, pl))
    C.write_recording_toml(recdir, "vibration.wav", m.start_time, lsb, "can.log")


# ---------------------------------------------------------------------------------------------- case
def make_case(seed, outdir, kind=None, short_s=None):
    """Writes outdir/rec (recording), outdir/nominal.toml, outdir/truth.json. kind overrides the slot.
    short_s: keep only this many seconds of program (smoke test)."""
    kind = kind or slot_of(seed)
    m = Machine(seed)
    if short_s:
        m.cycles = 2
    r = C.rng_for(seed, 5)
    control = {}
    category = "effect"
    if kind in CONTROLS:
        category = "control"
        if kind == "none":
            control = {"phases_given": True}
        elif kind == "amplitudes_off":
            control = {"amp_err_db": 6.0}
        elif kind == "noise_off":
            control = {"noise_err": U(r, 0.15, 0.3)}
        elif kind == "blend_off":
            control = {"blend_scale": U(r, 0.6, 0.8) if r.uniform() < 0.5 else U(r, 1.3, 1.6)}
    elif kind in OUT_OF_LIBRARY:
        category = "out_of_library"
    p = draw_effect(kind, C.rng_for(seed, 6), m, None) if kind in LIBRARY + OUT_OF_LIBRARY else {}
    eff_kind = kind if kind in LIBRARY + OUT_OF_LIBRARY else None
    x, info = synthesise(m, eff_kind, p, control, C.rng_for(seed, 7))
    fs = m.fs
    n_true = x.size
    # Sample clock error: the ADC really samples at fs (1 + e); the WAV says fs.
    e = p["ppm"] * 1e-6 if kind == "sample_clock_error" else 0.0
    if e != 0.0:
        x = C.resample_clock(x, 1.0 / (1.0 + e))
    bits = 24
    rng_ms2 = m.range_ms2
    if kind == "adc_clipping":
        level = p["level_rel_peak"] * float(np.max(np.abs(x)))
        p["level_ms2"] = level
        bits = 16
        rng_ms2 = level * 32768.0 / 32767.0  # codes saturate at +-32767 lsb = level
    codes, lsb = C.quantise(x, rng_ms2, bits)
    os.makedirs(os.path.join(outdir, "rec"), exist_ok=True)
    C.write_wav_pcm(os.path.join(outdir, "rec", "vibration.wav"), codes, fs, bits)

    delay = m.can_delay_s + (p["delay_s"] if kind == "speed_latency" else 0.0)
    jit = m.can_jitter_s + (p["jitter_s"] if kind == "speed_latency" else 0.0)
    write_can_and_toml(os.path.join(outdir, "rec"), m, info, C.rng_for(seed, 8), delay, jit, lsb)

    nominal, nominfo = nominal_toml(m, control, C.rng_for(seed, 9))
    with open(os.path.join(outdir, "nominal.toml"), "w") as f:
        f.write(nominal)

    gen = {"family": "gen2", "seed": seed, "slot": kind, "fs_hz": fs, "z": [m.z_in, m.z_spur, m.z_pin],
           "ratio": m.ratio, "orders": m.orders, "levels": [m.levels[k] for k in m.orders],
           "phases": [m.phases[k] for k in m.orders], "beta": m.beta, "noise_rms": m.noise_rms,
           "noise_tilt_db_per_decade": m.noise_tilt_db_dec, "program": m.prog.kind,
           "moves": m.prog.moves, "blend_s": m.prog.blend_s, "rest_s": m.prog.rest_s,
           "rest_jitter_s": m.prog.rest_jitter_s, "cycles": m.cycles, "duration_s": n_true / fs,
           "gmf_first_move_hz": m.gmf_hz(m.prog.speeds()[0]), "can_id": m.can_id,
           "can_delay_s": m.can_delay_s, "effect_form": p, "control": control, "nominal": nominfo,
           "moves_timeline": [{k: v for k, v in mv.items() if k != "cruise"} for mv in info["moves"]]}
    for key in ("knocks_s", "other_axis_moving_share", "rattles"):
        if key in info:
            gen[key] = info[key]
    effects = []
    unlisted = None
    if category == "effect":
        effects = [{"kind": kind, "params": library_truth(kind, p, m, info, None)}]
        desc = f"{kind} ({_short(effects[0]['params'])})"
    elif category == "out_of_library":
        unlisted = {"kind": kind, "params": {k: v for k, v in p.items()}}
        desc = f"out of library: {kind}"
    else:
        desc = f"{kind}"
    C.write_json(os.path.join(outdir, "truth.json"),
                 C.truth_doc(category, effects, desc, gen, unlisted=unlisted,
                             control=(kind if category == "control" else None)))
    return {"category": category, "kind": kind, "description": desc}


def _short(params):
    return ", ".join(f"{k}={v:.4g}" for k, v in params.items())
