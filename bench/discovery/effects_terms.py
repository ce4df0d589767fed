"""Additive catalogue effects: a deterministic term added to the output (unit u: g or deg/s).

Ranges (per kind) cover a QA-2000-class quartz accelerometer, a tactical FOG and an MHD angular
rate sensor from datasheet level up to roughly ten times worse (a degraded or mis-installed
unit), down to a floor below which the coefficient is immaterial for that class.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from scipy.ndimage import median_filter
from scipy.signal import lombscargle

from bench.discovery.data import Record
from bench.discovery.effects_base import Effect, Param, guess_kind
from bench.discovery.effects_linalg import base_regressors, project_out

#: Reference temperature of the temperature effects, degC: a model file's coefficients then
#: mean the same on any record (the record's first temperature would tie them to one run);
#: the constant part at the record's temperatures is absorbed by bias / scale factor.
T_REF_C = 25.0
#: Width (bins) of the running median a sinusoid's start line is judged against.
LINE_BACKGROUND_BINS = 31
#: A fold pattern's spectral lines (its power above this fraction of its peak) are starts of a
#: sine's fold fit only as the strongest line (:meth:`SinusoidalInterference.fit_starts`).
FOLD_ALIAS_LEVEL = 0.01
#: Beside a clip a sine's fold fit ranks this many of the strongest lines by how much of the
#: training rows each explains (:meth:`SinusoidalInterference.fit_starts`).
FOLD_LINES_RANKED = 8


def _time_range(rec: Record, lo: float, hi: float, min_samples: float = 3.0, frac: float = 0.25):
    return max(lo, min_samples * rec.dt_s), max(min(hi, frac * rec.duration_s), max(lo, min_samples * rec.dt_s) * 1.01)


class WarmupExponential(Effect):
    id = "warmup_exponential"
    description = "start-up transient of the bias after power-on (thermal settling of the sensor and electronics)"
    form = "y += amplitude · exp(−t_on / tau_s)"
    inputs = ("t_on",)
    main_param = "amplitude"
    signature = ("time: a decaying offset at the start of the record (early segments), Allan: slope near tau; "
                 "correlates with t_on")
    separating = {
        "temperature_bias": "vary temperature independently of time since power-on (soak at a second "
                            "temperature, or power-cycle at a stable temperature)",
        "linear_drift": "record longer after power-on (an exponential settles, a drift keeps going) or power-cycle",
    }
    kinds = ("accelerometer", "gyro", "mhd")
    ranges = {  # QA-2000 start-up tens of µg over minutes; FOG up to ~1000 deg/h; MHD electronics offset
        "accelerometer": (Param("amplitude", "g", -1e-2, 1e-2, linear=True, floor=1e-7),
                          Param("tau_s", "s", 1.0, 1e5, log=True)),
        "gyro": (Param("amplitude", "deg/s", -0.3, 0.3, linear=True, floor=1e-6),
                 Param("tau_s", "s", 1.0, 1e5, log=True)),
        "mhd": (Param("amplitude", "deg/s", -1.0, 1.0, linear=True, floor=1e-4),
                Param("tau_s", "s", 0.1, 1e5, log=True)),
    }

    def term(self, p, rec):
        return p["amplitude"] * np.exp(-rec.column("t_on") / p["tau_s"])

    def term_gradient(self, p, rec, names):
        t = rec.column("t_on")
        e = np.exp(-t / p["tau_s"])
        d = {"amplitude": lambda: e, "tau_s": lambda: p["amplitude"] * e * t / p["tau_s"] ** 2}
        return [d[k]() for k in names]

    def drawable_range(self, q, rec, kind):
        if q.name == "tau_s":  # resolvable: a few samples up to a quarter of the record
            return _time_range(rec, q.low, q.high, 5.0, 0.2)
        return q.low, q.high

    def fit_range(self, q, rec, kind):
        if q.name == "tau_s":  # beyond half the record the decay is a straight line: linear_drift's job
            return rec.dt_s, 0.5 * rec.duration_s
        return q.low, q.high

    def identifiable(self, p, rec):
        """A time constant beyond the record's t_on span is not resolvable on it (as a two-node's
        slow node): the decay is a straight line there — a drift's, or another term's misfit (a
        warm-up at the top of its amplitude range with τ = 87 s on a 6-s record took a
        high-pass's misfit)."""
        t = rec.column("t_on")
        return p.get("tau_s", 0.0) <= float(t.max() - t.min())


class LinearDrift(Effect):
    id = "linear_drift"
    description = "bias changing at a constant rate over the record (ageing, slow thermal drift)"
    form = "y += slope_per_s · (t − t[0])"
    inputs = ("t",)
    main_param = "slope_per_s"
    signature = ("time: a ramp across the whole record; Allan: +1 slope at the longest tau; spectrum: 1/f² at the "
                 "lowest bins")
    separating = {
        "temperature_bias": "hold temperature constant for a long record, or ramp it down as well as up",
        "rate_random_walk": "repeat the record: a drift repeats with the same slope, a random walk does not",
    }
    ranges = {
        "accelerometer": (Param("slope_per_s", "g/s", -1e-6, 1e-6, linear=True, floor=1e-12),),
        "gyro": (Param("slope_per_s", "deg/s/s", -1e-4, 1e-4, linear=True, floor=1e-10),),
        "mhd": (Param("slope_per_s", "deg/s/s", -1e-3, 1e-3, linear=True, floor=1e-8),),
    }

    def term(self, p, rec):
        return p["slope_per_s"] * (rec.t_s - rec.t_s[0])


class TemperatureBias(Effect):
    id = "temperature_bias"
    description = "bias temperature sensitivity, linear with an optional quadratic term"
    form = f"y += coef_per_c·ΔT + coef_per_c2·ΔT², ΔT = temp − {T_REF_C} °C (fixed reference)"
    inputs = ("temp",)
    main_param = "coef_per_c"
    signature = "input: residual correlates with temp (and temp²); time: follows the temperature profile"
    separating = {"temperature_scale_factor": "change temperature at zero input and at a large input"}
    ranges = {  # QA-2000 sheet < 30 µg/°C; FOG ~0.1-10 deg/h/°C (1e-2 deg/h/°C = 2.8e-6 deg/s/°C)
        "accelerometer": (Param("coef_per_c", "g/degC", -1e-4, 1e-4, linear=True, floor=1e-8),
                          Param("coef_per_c2", "g/degC^2", -1e-6, 1e-6, linear=True)),
        "gyro": (Param("coef_per_c", "deg/s/degC", -3e-3, 3e-3, linear=True, floor=1e-7),
                 Param("coef_per_c2", "deg/s/degC^2", -1e-4, 1e-4, linear=True)),
        "mhd": (Param("coef_per_c", "deg/s/degC", -1e-2, 1e-2, linear=True, floor=1e-5),
                Param("coef_per_c2", "deg/s/degC^2", -1e-3, 1e-3, linear=True)),
    }

    def term(self, p, rec):
        dt = rec.column("temp") - T_REF_C
        return p["coef_per_c"] * dt + p["coef_per_c2"] * dt * dt

    def draw_others(self, rng, rec, kind):
        return {"coef_per_c2": 0.0}

    def identity_params(self, p):
        return {"coef_per_c": 0.0, "coef_per_c2": 0.0}

    def finish_draw(self, rng, rec, kind, p):
        # quadratic part at most 30 % of the linear one over the record's temperature swing
        dt = rec.column("temp") - T_REF_C
        span = max(float(np.ptp(dt)), 1.0) + abs(float(np.mean(dt)))
        q = self.param("coef_per_c2", kind)
        p["coef_per_c2"] = float(np.clip(rng.uniform(-0.3, 0.3) * abs(p["coef_per_c"]) / span, q.low, q.high))
        return p


class TemperatureScaleFactor(Effect):
    id = "temperature_scale_factor"
    description = "scale-factor temperature sensitivity"
    form = f"y += sf_coef_per_c · (temp − {T_REF_C} °C) · input"
    inputs = ("input", "temp")
    main_param = "sf_coef_per_c"
    signature = "input: residual ∝ input·ΔT (grows with |input| and with the temperature change)"
    ranges = {  # QA-2000 SF TC < 180 ppm/°C; FOG SF TC tens to hundreds of ppm/°C
        "accelerometer": (Param("sf_coef_per_c", "1/degC", -1e-3, 1e-3, linear=True, floor=1e-8),),
        "gyro": (Param("sf_coef_per_c", "1/degC", -1e-3, 1e-3, linear=True, floor=1e-8),),
        "mhd": (Param("sf_coef_per_c", "1/degC", -1e-2, 1e-2, linear=True, floor=1e-6),),
    }

    def term(self, p, rec):
        return p["sf_coef_per_c"] * (rec.column("temp") - T_REF_C) * rec.input


class K2Nonlinearity(Effect):
    id = "k2_nonlinearity"
    description = "second-order (even) scale-factor non-linearity"
    form = "y += k2_per_u · input²"
    inputs = ("input",)
    main_param = "k2_per_u"
    competitors = ("scale_factor_asymmetry",)  # input² and |input| differ only in shape
    signature = "input: residual ∝ input² (same sign for ±input)"
    separating = {"scale_factor_asymmetry": "apply inputs of both signs with equal magnitudes (k2 is even, "
                                            "asymmetry is odd)"}
    ranges = {  # QA-2000 sheet < 20 µg/g²; FOG: 100 ppm of 490 deg/s full scale ≈ 2e-7 /(deg/s)
        "accelerometer": (Param("k2_per_u", "1/g", -1e-3, 1e-3, linear=True, floor=1e-8),),
        "gyro": (Param("k2_per_u", "1/(deg/s)", -1e-4, 1e-4, linear=True, floor=1e-10),),
        "mhd": (Param("k2_per_u", "1/(deg/s)", -1e-3, 1e-3, linear=True, floor=1e-8),),
    }

    def term(self, p, rec):
        return p["k2_per_u"] * rec.input ** 2


class K3Nonlinearity(Effect):
    id = "k3_nonlinearity"
    description = "third-order (odd) scale-factor non-linearity"
    form = "y += k3_per_u2 · input³"
    inputs = ("input",)
    main_param = "k3_per_u2"
    signature = "input: residual ∝ input³ minus its linear part (S-shaped against input)"
    separating = {"saturation": "step the input towards full range: saturation clips abruptly, k3 bends smoothly"}
    ranges = {  # FOG cubic n·FS·(ω/FS)³: n = 100 ppm at 490 deg/s -> 4e-10 /(deg/s)²
        "accelerometer": (Param("k3_per_u2", "1/g^2", -1e-4, 1e-4, linear=True, floor=1e-9),),
        "gyro": (Param("k3_per_u2", "1/(deg/s)^2", -1e-6, 1e-6, linear=True, floor=1e-14),),
        "mhd": (Param("k3_per_u2", "1/(deg/s)^2", -1e-5, 1e-5, linear=True, floor=1e-12),),
    }

    def term(self, p, rec):
        return p["k3_per_u2"] * rec.input ** 3


class ScaleFactorAsymmetry(Effect):
    id = "scale_factor_asymmetry"
    description = "different scale factors for positive and negative input (SF+ − SF− = asymmetry·SF)"
    form = "y += (asymmetry / 2) · |input|"
    inputs = ("input",)
    main_param = "asymmetry"
    competitors = ("k2_nonlinearity",)
    signature = "input: residual ∝ |input| (V-shaped against input)"
    ranges = {  # FOG asymmetry tens of ppm (limit 100 ppm); pendulous accelerometers ~ppm
        "accelerometer": (Param("asymmetry", "1", -1e-3, 1e-3, linear=True, floor=1e-7),),
        "gyro": (Param("asymmetry", "1", -1e-2, 1e-2, linear=True, floor=1e-7),),
        "mhd": (Param("asymmetry", "1", -5e-2, 5e-2, linear=True, floor=1e-6),),
    }

    def term(self, p, rec):
        return 0.5 * p["asymmetry"] * np.abs(rec.input)


class Misalignment(Effect):
    id = "misalignment"
    description = "input axis tilted toward a cross axis: part of the cross-axis input is sensed"
    form = "y += angle_rad · cross_input"
    inputs = ("cross_input",)
    main_param = "angle_rad"
    signature = "input: residual correlates with cross_input"
    ranges = {  # QA-2000 sheet < 70 µrad (mounting adds mrad); FOG/MHD mounting up to tens of mrad
        "accelerometer": (Param("angle_rad", "rad", -5e-3, 5e-3, linear=True, floor=1e-7),),
        "gyro": (Param("angle_rad", "rad", -5e-2, 5e-2, linear=True, floor=1e-6),),
        "mhd": (Param("angle_rad", "rad", -5e-2, 5e-2, linear=True, floor=1e-6),),
    }

    def term(self, p, rec):
        return p["angle_rad"] * rec.column("cross_input")


class GSensitivity(Effect):
    id = "g_sensitivity"
    description = ("gyro bias proportional to the specific force along its input axis (logged as the "
                   "`accel` column, g): orientation in gravity or a sustained acceleration")
    form = "y += coef_per_g · accel"
    inputs = ("accel",)
    main_param = "coef_per_g"
    signature = "input: residual correlates with the specific force column `accel`"
    separating = {"temperature_bias": "change orientation (specific force) at constant temperature"}
    kinds = ("gyro",)
    ranges = {  # FOG g-sensitivity ≲ 1-100 deg/h/g (1 deg/h/g = 2.8e-4 deg/s/g)
        "gyro": (Param("coef_per_g", "deg/s/g", -0.03, 0.03, linear=True, floor=3e-7),),
    }

    def term(self, p, rec):
        return p["coef_per_g"] * rec.column("accel")


class VibrationRectification(Effect):
    id = "vibration_rectification"
    description = "bias shift under vibration (rectification of the vibration by non-linearities)"
    form = "y += coef_per_g2 · vib²"
    inputs = ("vib",)
    main_param = "coef_per_g2"
    signature = "input/time: offset during vibration segments ∝ vib² (g rms)"
    separating = {"linear_drift": "switch vibration on and off during the record"}
    kinds = ("accelerometer", "gyro")
    ranges = {  # QA-2000-class VRE tens of µg/g²; FOG vibration rectification ≲ 100 deg/h/g²
        "accelerometer": (Param("coef_per_g2", "g/g^2", -1e-3, 1e-3, linear=True, floor=1e-8),),
        "gyro": (Param("coef_per_g2", "deg/s/g^2", -0.03, 0.03, linear=True, floor=3e-7),),
    }

    def term(self, p, rec):
        return p["coef_per_g2"] * rec.column("vib") ** 2


def _explained_first(lines: list[int], columns: Callable[[int], np.ndarray], r: np.ndarray) -> list[int]:
    """``lines`` (periodogram bins) ordered by how much of ``r`` (zero off the rows it is read
    on) a sine at each explains by least squares, most first (``columns(i)``: the sine and
    cosine at bin ``i``, zero off the rows). A sine at the true line explains all the line
    leaves on the rows and a sideband of it less; beside a clip the periodogram of a fold's
    training rows ranked the line's sidebands by the fold pattern above it (0.1167 Hz on blocks
    of 6.25 s, 17 % clipped: its sideband at 0.1967 Hz stood 35 to 23 over it and fold 0 never
    started at the line)."""
    gains = []
    for i in lines:
        m = columns(i)
        coef, *_ = np.linalg.lstsq(m, r, rcond=None)
        gains.append(float(np.sum((m @ coef) ** 2)))
    return [lines[k] for k in np.argsort(gains, kind="stable")[::-1]]


def _runs_demeaned(x: np.ndarray, runs: np.ndarray, seen: np.ndarray) -> np.ndarray:
    """``x`` with each contiguous run of ``runs`` less the mean of its ``seen`` samples, zero off
    ``seen`` (a run's samples a clip hides are neither in its mean nor in the answer)."""
    out = np.zeros_like(x)
    edges = np.flatnonzero(np.diff(np.r_[0, runs.astype(np.int8), 0]))
    for a, b in zip(edges[::2], edges[1::2]):
        s = seen[a:b]
        if s.any():
            out[a:b] = np.where(s, x[a:b] - x[a:b][s].mean(), 0.0)
    return out


class SinusoidalInterference(Effect):
    id = "sinusoidal_interference"
    description = "a periodic disturbance: mains pick-up, a pump or fan, a table's or dither's line"
    form = "y += amplitude · sin(2π·freq_hz·(t − t[0]) + phase_rad)"
    inputs = ("t",)
    main_param = "amplitude"
    signature = "frequency: a spectral line at freq_hz; time: present throughout"
    ranges = {
        "accelerometer": (Param("amplitude", "g", 0.0, 1e-2, floor=1e-8), Param("freq_hz", "Hz", 1e-4, 1e4, log=True),
                          Param("phase_rad", "rad", -math.pi, math.pi)),
        "gyro": (Param("amplitude", "deg/s", 0.0, 1.0, floor=1e-6), Param("freq_hz", "Hz", 1e-4, 1e4, log=True),
                 Param("phase_rad", "rad", -math.pi, math.pi)),
        "mhd": (Param("amplitude", "deg/s", 0.0, 10.0, floor=1e-4), Param("freq_hz", "Hz", 1e-4, 1e5, log=True),
                Param("phase_rad", "rad", -math.pi, math.pi)),
    }

    def term(self, p, rec):
        return p["amplitude"] * np.sin(2 * np.pi * p["freq_hz"] * (rec.t_s - rec.t_s[0]) + p["phase_rad"])

    def aliases(self, p, block_rate_hz, rate_hz):
        """Every frequency |f + k·f_b| below the record's Nyquist frequency (``p``'s first): block
        means fold a line of any of them onto f."""
        f0, fb = float(p["freq_hz"]), float(block_rate_hz)
        k = int(math.ceil(0.5 * rate_hz / fb)) + 1
        fs = sorted({abs(f0 + j * fb) for j in range(-k, k + 1)} - {f0})
        return [dict(p)] + [{**p, "freq_hz": f} for f in fs if 0 < f < 0.5 * rate_hz]

    def time_shifted(self, p, shift_s):
        """The phase at a start ``shift_s`` earlier (negative: later): the line has 2π·f·shift less
        phase there (wrapped to ±π)."""
        ph = p["phase_rad"] - 2 * np.pi * p["freq_hz"] * float(shift_s)
        return {**p, "phase_rad": float((ph + np.pi) % (2 * np.pi) - np.pi)}

    def term_gradient(self, p, rec, names):
        tt = rec.t_s - rec.t_s[0]
        ph = 2 * np.pi * p["freq_hz"] * tt + p["phase_rad"]
        a_cos = p["amplitude"] * np.cos(ph) if {"phase_rad", "freq_hz"} & set(names) else None  # once for both
        d = {"amplitude": lambda: np.sin(ph), "phase_rad": lambda: a_cos,
             "freq_hz": lambda: a_cos * (2 * np.pi * tt)}
        return [d[k]() for k in names]

    def search_cells(self, p, rec):
        """The line's frequency was chosen among the record's n/2 Fourier bins."""
        return max(rec.n / 2.0, 1.0)

    def drawable_range(self, q, rec, kind):
        if q.name == "freq_hz":  # at least 20 cycles in the record, below 0.4 × the sample rate
            return max(q.low, 20.0 / rec.duration_s), min(q.high, 0.4 * rec.rate_hz)
        return q.low, q.high

    def fit_range(self, q, rec, kind):
        if q.name == "freq_hz":  # two cycles in the record up to the Nyquist frequency
            return 2.0 / rec.duration_s, 0.5 * rec.rate_hz
        return q.low, q.high

    def fit_starts(self, rec, residual, *, kind=None, rows=None, held_out=None):
        """The three strongest periodogram lines of the residual on ``rows`` (others zero; uniform
        records: FFT with a Hann window; else a Lomb-Scargle grid), each judged against the
        periodogram's running median over :data:`LINE_BACKGROUND_BINS` bins around it (a line
        stands out of its neighbourhood; beside a red process the strongest bins are its low
        frequencies, not the line), amplitude and phase by least squares on ``rows``.

        On part of the record (a fold's training blocks), zeroing the held-out blocks modulates
        a red process's level by the fold pattern and puts false lines at the pattern's odd
        harmonics (blocks of 6.25 s: 0.08, 0.24 … Hz); a sine fitted at one is sign-flipped on
        the held-out blocks by construction — beside a random walk such a start out-fitted the
        true 0.157-Hz line on the training blocks (sum of squares 0.0158 vs 0.0172) and scored
        −0.6 held out. So from the pattern's first line up, lines are judged with each
        contiguous run's own mean removed (what the modulated level leaves), and a line on the
        pattern (its power above :data:`FOLD_ALIAS_LEVEL` of its peak) is a start only as the
        strongest line. ``held_out`` (the fold's held-out samples) gives the pattern; ``rows`` may
        miss more (a clip's samples), which is no pattern of the fold's — and then of the fold's
        :data:`FOLD_LINES_RANKED` strongest lines the starts are those that explain most of the
        rows (:func:`_explained_first`). Not without a clip: there each block's mean removed
        (what the demeaned periodogram reads) is part of what a line explains, and a line slower
        than the blocks explains less of them than the structure other terms leave (an 82-s line
        of 74 σ ranked below such lines on blocks of 62.5 s and the sine was never named).
        """
        kind = kind or guess_kind(rec)
        part = rows is not None and not np.all(rows)
        r = np.asarray(residual, float) if rows is None else np.where(rows, residual, 0.0)
        r = project_out(r, base_regressors(rec))
        if part:
            r = np.where(rows, r, 0.0)
        f_lo, f_hi = self.drawable_range(self.param("freq_hz", kind), rec, kind)
        tt = rec.t_s - rec.t_s[0]
        uniform = rec.is_uniform()
        grid = None if uniform else np.geomspace(f_lo, f_hi, 4000)

        def line_ratio(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            if uniform:
                spec = np.abs(np.fft.rfft(x * np.hanning(rec.n)))
                freq = np.fft.rfftfreq(rec.n, rec.dt_s)
            else:
                freq, spec = grid, lombscargle(tt, x, 2 * np.pi * grid)
            power = spec ** 2
            background = median_filter(power, size=LINE_BACKGROUND_BINS, mode="nearest")
            return freq, power / np.maximum(background, np.finfo(float).tiny)
        f, ratio = line_ratio(r)
        alias = np.zeros(f.size, bool)
        blocks = seen = None
        if held_out is not None and np.any(held_out) and uniform:
            blocks = ~np.asarray(held_out, bool)
            w_blocks = blocks.astype(float)
            pattern = np.abs(np.fft.rfft((w_blocks - w_blocks.mean()) * np.hanning(rec.n))) ** 2
            alias = pattern > FOLD_ALIAS_LEVEL * pattern.max()
            # from the pattern's first line up, lines judged with each block's own mean removed
            above = np.arange(f.size) >= np.argmax(alias)
            seen = blocks if rows is None else np.asarray(rows, bool)
            ratio = np.where(above, line_ratio(_runs_demeaned(r, blocks, seen))[1], ratio)
        ok = (f >= f_lo * 0.5) & (f <= min(f_hi * 1.25, 0.5 * rec.rate_hz))
        idx = np.flatnonzero(ok)
        if idx.size == 0:
            return []
        order = idx[np.argsort(ratio[idx], kind="stable")[::-1]]
        # the fold pattern's lines: a start only as the strongest line
        order = np.r_[order[:1], [i for i in order[1:] if not alias[i]]].astype(int)
        used: list[int] = []  # the strongest lines, three bins apart: as many as may be ranked
        for i in order:
            if not any(abs(i - j) < 3 for j in used):
                used.append(int(i))
                if len(used) == FOLD_LINES_RANKED:
                    break
        qf = self.param("freq_hz", kind)

        def columns(i: int) -> np.ndarray:
            fr = float(np.clip(f[i], qf.low, qf.high))
            m = np.column_stack([np.sin(2 * np.pi * fr * tt), np.cos(2 * np.pi * fr * tt)])
            return m * np.asarray(rows, float)[:, None] if part else m  # r is zero off the rows
        if blocks is not None and not np.array_equal(seen, blocks):  # a fold beside a clip
            used = _explained_first(used[:FOLD_LINES_RANKED], columns, r)
        starts = []
        for i in used[:3]:
            m = columns(i)
            (a, b), *_ = np.linalg.lstsq(m, r, rcond=None)
            starts.append({"amplitude": float(math.hypot(a, b)), "freq_hz": float(np.clip(f[i], qf.low, qf.high)),
                           "phase_rad": float(math.atan2(b, a))})
        return starts
