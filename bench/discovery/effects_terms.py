"""Additive catalogue effects: a deterministic term added to the output (unit u: g or deg/s).

Ranges (per kind) cover a QA-2000-class quartz accelerometer, a tactical FOG and an MHD angular
rate sensor from datasheet level up to roughly ten times worse (a degraded or mis-installed
unit), down to a floor below which the coefficient is immaterial for that class.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np
from scipy.ndimage import median_filter
from scipy.signal import lombscargle

from bench.discovery.data import Record
from bench.discovery.effects_base import Effect, Param, Params, guess_kind
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
#: Most lines one sinusoidal_interference effect holds — a practical cap: what a bench picks up
#: is mains (its fundamental and a harmonic) and one machine (a pump, a fan, a table's or a
#: dither's line). Each line is three parameters in every joint refit; the lines of a record with
#: more are left in its innovations and reported as unexplained spectral structure at their
#: frequencies.
MAX_LINES = 3
#: Two periodogram peaks closer than this many Fourier bins (1/T each) are one line's start: a
#: Hann window's main lobe spans two bins either side of a line, so a peak inside it is the
#: line's own leakage. Lines of a record closer than 3/T are one line to the starts.
LINE_SEPARATION_BINS = 3


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


def line_names(k: int) -> tuple[str, str, str]:
    """Names of line ``k``'s (1-based) amplitude, frequency and phase: the first line's carry no
    number (``amplitude``, ``freq_hz``, ``phase_rad``), the others' do (``amplitude_2``,
    ``freq_2_hz``, ``phase_2_rad``)."""
    return ("amplitude", "freq_hz", "phase_rad") if k == 1 else (f"amplitude_{k}", f"freq_{k}_hz", f"phase_{k}_rad")


def line_of(name: str) -> int:
    """The line (1-based) a parameter name belongs to."""
    parts = name.split("_")
    return int(parts[1]) if len(parts) > 1 and parts[1].isdigit() else 1


def _line_slots(unit: str, amp_high: float, floor: float, freq_high: float) -> tuple[Param, ...]:
    """Amplitude (0 … amp_high, with a physical floor), frequency (1e-4 … freq_high Hz) and phase
    (±π) of each of the :data:`MAX_LINES` lines."""
    out: list[Param] = []
    for k in range(1, MAX_LINES + 1):
        a, f, ph = line_names(k)
        out += [Param(a, unit, 0.0, amp_high, floor=floor), Param(f, "Hz", 1e-4, freq_high, log=True),
                Param(ph, "rad", -math.pi, math.pi)]
    return tuple(out)


#: One line: (amplitude, freq_hz, phase_rad).
Line = tuple[float, float, float]


class SinusoidalInterference(Effect):
    id = "sinusoidal_interference"
    description = ("periodic disturbances: mains pick-up, a pump or fan, a table's or dither's line — "
                   f"up to {MAX_LINES} lines, each an amplitude, a frequency and a phase")
    form = ("y += Σ_k amplitude_k · sin(2π·freq_k_hz·(t − t[0]) + phase_k_rad) (the first line's names carry no "
            "number); amplitude_k = 0: no line")
    inputs = ("t",)
    main_param = "amplitude"
    signature = "frequency: a spectral line at each freq_hz; time: present throughout"
    ranges = {
        "accelerometer": _line_slots("g", 1e-2, 1e-8, 1e4),
        "gyro": _line_slots("deg/s", 1.0, 1e-6, 1e4),
        "mhd": _line_slots("deg/s", 10.0, 1e-4, 1e5),
    }

    # ---- the lines ---------------------------------------------------------------------
    def lines(self, p: Mapping[str, float]) -> list[Line]:
        """(amplitude, freq_hz, phase_rad) of each used line (non-zero amplitude), in slot order."""
        out = []
        for k in range(1, MAX_LINES + 1):
            a, f, ph = line_names(k)
            if p.get(a, 0.0) != 0.0:
                out.append((float(p[a]), float(p[f]), float(p[ph])))
        return out

    def with_lines(self, p: Mapping[str, float], lines: Sequence[Line]) -> Params:
        """``p`` with ``lines`` in the first slots and the others unused (amplitude 0, the
        frequency at the bottom of its range, phase 0: values nothing reads)."""
        if len(lines) > MAX_LINES:
            raise ValueError(f"{len(lines)} lines; allowed: at most {MAX_LINES}")
        out = dict(p)
        for k in range(1, MAX_LINES + 1):
            a, f, ph = line_names(k)
            out[a], out[f], out[ph] = lines[k - 1] if k <= len(lines) else (0.0, self.param(f).low, 0.0)
        return out

    def count(self, p: Mapping[str, float]) -> int:
        """Number of lines (non-zero amplitudes)."""
        return len(self.lines(p))

    def check_params(self, p: Mapping[str, object], kind: str | None = None) -> Params:
        """As every effect checks them; a line whose three parameters are all absent is unused (a
        model file written with one line reads as that line)."""
        full = dict(p)
        for k in range(2, MAX_LINES + 1):
            names = line_names(k)
            if not any(n in full for n in names):
                full |= dict(zip(names, (0.0, self.param(names[1]).low, 0.0)))
        return super().check_params(full, kind)

    # ---- the term ----------------------------------------------------------------------
    def term(self, p, rec):
        tt = rec.t_s - rec.t_s[0]
        out = np.zeros(rec.n)
        for a, f, ph in self.lines(p):
            out += a * np.sin(2 * np.pi * f * tt + ph)
        return out

    def term_gradient(self, p: Mapping[str, float], rec: Record, names: Sequence[str]) -> list[np.ndarray]:
        tt = rec.t_s - rec.t_s[0]
        cache: dict[int, tuple[np.ndarray, np.ndarray]] = {}

        def sin_cos(k: int) -> tuple[np.ndarray, np.ndarray]:  # once per line for its three names
            if k not in cache:
                _, f, ph = line_names(k)
                arg = 2 * np.pi * p[f] * tt + p[ph]
                cache[k] = np.sin(arg), np.cos(arg)
            return cache[k]

        out = []
        for name in names:
            k = line_of(name)
            a = p[line_names(k)[0]]
            s, c = sin_cos(k)
            out.append(s if name.startswith("amplitude") else a * c if name.startswith("phase")
                       else a * c * (2 * np.pi * tt))
        return out

    # ---- what the search and the criterion ask -------------------------------------------
    def free_params(self, p: Mapping[str, float], kind: str, rec: Record,
                    rows: np.ndarray | None = None) -> tuple[Param, ...]:
        """Amplitude, frequency and phase of each used line (the first always)."""
        used = {1} | {k for k in range(2, MAX_LINES + 1) if p.get(line_names(k)[0], 0.0) != 0.0}
        return tuple(q for q in self.params_for(kind) if line_of(q.name) in used)

    def components(self, p: Mapping[str, float]) -> list[Params]:
        """Each line alone (in the first slot): the criterion charges every line as a line added
        by itself (:func:`.criterion.penalty`)."""
        lines = self.lines(p)
        return [dict(p)] if len(lines) <= 1 else [self.with_lines(p, [line]) for line in lines]

    def search_cells(self, p: Mapping[str, float], rec: Record) -> float:
        """Each line's frequency was chosen among the record's n/2 Fourier bins."""
        return max(rec.n / 2.0, 1.0) ** max(self.count(p), 1)

    def identity_params(self, p: Params) -> Params:
        return self.with_lines(p, [])

    def prefixes(self, p: Mapping[str, float]) -> list[Params]:
        """The j strongest lines of ``p`` (j = 1 … count − 1), strongest first: the number of
        lines is the criterion's to choose."""
        strongest = sorted(self.lines(p), key=lambda line: -abs(line[0]))
        return [self.with_lines(p, strongest[:j]) for j in range(1, len(strongest))]

    def aliases(self, p: Mapping[str, float], block_rate_hz: float, rate_hz: float,
                shift_s: float = 0.0) -> list[Params]:
        """Every frequency |f + k·f_b| below the record's Nyquist frequency of the first line (``p``
        first), each with the phase a line there has for block means of ``m = rate/f_b`` samples
        to show ``p``: on means whose first time is ``shift_s`` after the record's (``p``'s phase
        referenced to the record's first sample) a line at ``f + k·f_b`` reads as one at ``f``
        shifted by ``2π·k·f_b·shift_s``, by π more where the block average's gain
        ``sin(π·f·m/rate)/(m·sin(π·f/rate))`` is negative, mirrored when ``f + k·f_b < 0``. A fit of
        several lines is asked one line at a time (:meth:`components`, :meth:`joined`)."""
        f0, fb = float(p["freq_hz"]), float(block_rate_hz)
        m = max(round(rate_hz / fb), 1)
        k = int(math.ceil(0.5 * rate_hz / fb)) + 1
        out = []
        for j in range(-k, k + 1):
            fk = f0 + j * fb
            if j == 0 or not 0 < abs(fk) < 0.5 * rate_hz or abs(fk) == f0:
                continue
            ph = float(p["phase_rad"]) - 2 * math.pi * j * fb * float(shift_s)
            if math.sin(math.pi * fk * m / rate_hz) * math.sin(math.pi * fk / rate_hz) < 0:
                ph += math.pi
            if fk < 0:  # sin(−2π|f|t + φ) = sin(2π|f|t − φ + π)
                ph = math.pi - ph
            out.append({**p, "freq_hz": abs(fk), "phase_rad": (ph + math.pi) % (2 * math.pi) - math.pi})
        return [dict(p)] + sorted(out, key=lambda q: q["freq_hz"])

    def joined(self, p: Mapping[str, float], parts: Sequence[Mapping[str, float]]) -> Params:
        """The lines of ``parts`` (each a line in the first slot), in that order."""
        return self.with_lines(p, [(float(q["amplitude"]), float(q["freq_hz"]), float(q["phase_rad"])) for q in parts])

    def time_shifted(self, p: Mapping[str, float], shift_s: float) -> Params:
        """The phases at a start ``shift_s`` earlier (negative: later): each line has 2π·f·shift
        less phase there (wrapped to ±π)."""
        out = dict(p)
        for k in range(1, MAX_LINES + 1):
            _, f, ph = line_names(k)
            v = p[ph] - 2 * np.pi * p[f] * float(shift_s)
            out[ph] = float((v + np.pi) % (2 * np.pi) - np.pi)
        return out

    def reference_params(self, rec: Record, kind: str) -> Params:
        """One line (the geometric mean of the resolvable frequencies); the others unused."""
        out = super().reference_params(rec, kind)
        return self.with_lines(out, [(out["amplitude"], out["freq_hz"], out["phase_rad"])])

    def draw_others(self, rng: np.random.Generator, rec: Record, kind: str) -> Params:
        """One line's frequency and phase, uniform over their resolvable ranges (log-uniform for
        the frequency); the other lines unused."""
        out: Params = {}
        for q in self.params_for(kind):
            if q.name == self.main_param or line_of(q.name) != 1:
                continue
            lo, hi = self.drawable_range(q, rec, kind)
            out[q.name] = math.exp(rng.uniform(math.log(lo), math.log(hi))) if q.log else rng.uniform(lo, hi)
        return self.with_lines(out, [(0.0, out["freq_hz"], out["phase_rad"])])

    def drawable_range(self, q, rec, kind):
        if q.name.startswith("freq"):  # at least 20 cycles in the record, below 0.4 × the sample rate
            return max(q.low, 20.0 / rec.duration_s), min(q.high, 0.4 * rec.rate_hz)
        return q.low, q.high

    def fit_range(self, q, rec, kind):
        if q.name.startswith("freq"):  # two cycles in the record up to the Nyquist frequency
            return 2.0 / rec.duration_s, 0.5 * rec.rate_hz
        return q.low, q.high

    def fit_starts(self, rec, residual, *, kind=None, rows=None, held_out=None):
        """One start: the :data:`MAX_LINES` strongest periodogram lines of the residual on ``rows``
        (others zero; uniform records: FFT with a Hann window; else a Lomb-Scargle grid), at
        least :data:`LINE_SEPARATION_BINS` bins apart, strongest first, each judged against the
        periodogram's running median over :data:`LINE_BACKGROUND_BINS` bins around it (a line
        stands out of its neighbourhood; beside a red process the strongest bins are its low
        frequencies, not the line), amplitudes and phases by one least-squares fit of them all on
        ``rows``. How many of them the record holds is the criterion's to say (:meth:`prefixes`).

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
        used: list[int] = []  # the strongest lines, apart: as many as may be ranked
        for i in order:
            if not any(abs(i - j) < LINE_SEPARATION_BINS for j in used):
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
        chosen = used[:MAX_LINES]
        coef, *_ = np.linalg.lstsq(np.column_stack([columns(i) for i in chosen]), r, rcond=None)
        lines = [(float(math.hypot(coef[2 * j], coef[2 * j + 1])), float(np.clip(f[i], qf.low, qf.high)),
                  float(math.atan2(coef[2 * j + 1], coef[2 * j]))) for j, i in enumerate(chosen)]
        return [self.with_lines({}, lines)]
