"""Thermal catalogue effects beyond a bias proportional to temperature (``temperature_bias``):
a warm-up through two thermal time constants, a bias proportional to the rate of temperature
change, a bias that depends on whether the temperature last rose or fell (hysteresis), and a
bias and scale factor that follow the sensing element's temperature, which lags the logged
(case) temperature through a first-order lag (``thermal_lag``).

Units: the sensor unit u (g or deg/s), °C, s. The rate of temperature change is taken from the
logged column by a centred difference over ``rate_window`` samples (a logged temperature is
quantized: a one-sample difference of 0.01 °C steps would be mostly noise); the hysteresis is
the play (backlash) operator of the temperature history, started in the middle of its band;
the element's lag is the exact solution of ``τ·dT_e/dt = T − T_e`` for a logged temperature
linear between its samples (:func:`element_temperature`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import replace

import numba
import numpy as np

from bench.discovery.data import Record
from bench.discovery.effects_base import N_STARTS, Effect, Param, Params, guess_kind
from bench.discovery.effects_linalg import base_regressors, orthonormal, project_out, project_q, vdot
from bench.discovery.effects_terms import T_REF_C, WarmupExponential

#: A temperature that goes "up and down" (thermal_hysteresis) rises and falls by at least this.
MIN_REVERSAL_C = 0.5


#: A node of a transient is seen by a fit whose first row comes within this many of its time
#: constants of power-on (e^−2: 13.5 % of it left there): :func:`node_seen`.
NODE_SEEN = 2.0


def node_seen(rec: Record, rows: np.ndarray | None) -> float:
    """The shortest time constant a fit on ``rows`` sees of a transient from power-on: the first
    row's ``t_on`` / :data:`NODE_SEEN` (0 for rows from power-on, or all rows)."""
    if rows is None:
        return 0.0
    t = rec.column("t_on")[np.asarray(rows, bool)]
    return float(t.min()) / NODE_SEEN if t.size else 0.0


#: The slow node's share of a two-node transient the fit may take (an overshoot either way);
#: a fit at either end of it (within FRACTION_PINNED of the span) is a hump the range stopped
#: — two steps down on a 6-s rate table record took f = 3.0, τ 0.92/2.74 s — not two nodes.
FRACTION_RANGE = (-2.0, 3.0)
FRACTION_PINNED = 1e-3


class ThermalTwoNode(Effect):
    id = "thermal_two_node"
    description = ("start-up transient through two thermal time constants: the sensing element settles fast, "
                   "its case and mount slowly (a two-node thermal network)")
    form = ("y += amplitude · ((1 − fraction_slow)·exp(−t_on/tau_fast_s) + fraction_slow·exp(−t_on/tau_slow_s)), "
            "tau_slow_s > tau_fast_s")
    inputs = ("t_on",)
    main_param = "amplitude"
    signature = ("time: a decaying offset whose log-time shape is wider than one exponential (two humps in the "
                 "derivative against log t_on); correlates with t_on")
    separating = {"warmup_exponential": "record until the slow node settles (several tau_slow_s), or log the "
                                        "case temperature: one exponential leaves a hump in log t_on"}
    ranges = {  # as warmup_exponential's amplitudes; time constants from seconds (die) to hours (mount)
        "accelerometer": (Param("amplitude", "g", -1e-2, 1e-2, linear=True, floor=1e-7),
                          Param("fraction_slow", "1", *FRACTION_RANGE),
                          Param("tau_fast_s", "s", 1.0, 1e5, log=True), Param("tau_slow_s", "s", 1.0, 1e5, log=True)),
        "gyro": (Param("amplitude", "deg/s", -0.3, 0.3, linear=True, floor=1e-6),
                 Param("fraction_slow", "1", *FRACTION_RANGE),
                 Param("tau_fast_s", "s", 1.0, 1e5, log=True), Param("tau_slow_s", "s", 1.0, 1e5, log=True)),
        "mhd": (Param("amplitude", "deg/s", -1.0, 1.0, linear=True, floor=1e-4),
                Param("fraction_slow", "1", *FRACTION_RANGE),
                Param("tau_fast_s", "s", 0.1, 1e5, log=True), Param("tau_slow_s", "s", 0.1, 1e5, log=True)),
    }

    def term(self, p: Mapping[str, float], rec: Record) -> np.ndarray:
        t = rec.column("t_on")
        f = p["fraction_slow"]
        return p["amplitude"] * ((1 - f) * np.exp(-t / p["tau_fast_s"]) + f * np.exp(-t / p["tau_slow_s"]))

    def term_gradient(self, p: Mapping[str, float], rec: Record, names: Sequence[str]) -> list[np.ndarray]:
        t = rec.column("t_on")
        a, f, tf, ts = p["amplitude"], p["fraction_slow"], p["tau_fast_s"], p["tau_slow_s"]
        ef, es = np.exp(-t / tf), np.exp(-t / ts)
        d = {"amplitude": lambda: (1 - f) * ef + f * es, "fraction_slow": lambda: a * (es - ef),
             "tau_fast_s": lambda: a * (1 - f) * ef * t / tf ** 2, "tau_slow_s": lambda: a * f * es * t / ts ** 2}
        return [d[k]() for k in names]

    def free_params(self, p: Mapping[str, float], kind: str, rec: Record,
                    rows: np.ndarray | None = None) -> tuple[Param, ...]:
        """On ``rows`` that start after power-on, the fast node no faster than :func:`node_seen`
        (a faster one is not seen there: its amplitude would be extrapolated from noise)."""
        qs = self.params_for(kind)
        seen = node_seen(rec, rows)
        if seen <= 0:
            return qs
        return tuple(replace(q, low=min(max(q.low, seen), q.high / 4)) if q.name == "tau_fast_s" else q for q in qs)

    def reduced(self, p: Mapping[str, float], nested: str, kind: str) -> list[Params]:
        """A warm-up at either node (its share of the step, or the whole step) — the other node
        may be a process's wander the two-node followed."""
        if nested != "warmup_exponential":
            return []
        a, f = float(p["amplitude"]), float(p["fraction_slow"])
        amp = self.param("amplitude", kind)
        tau = self.param("tau_fast_s", kind)
        out = []
        for share, t in ((1.0 - f, p["tau_fast_s"]), (1.0, p["tau_fast_s"]), (f, p["tau_slow_s"])):
            out.append({"amplitude": float(np.clip(a * share, amp.low, amp.high)),
                        "tau_s": float(np.clip(t, tau.low, tau.high))})
        return out

    def identifiable(self, p: Mapping[str, float], rec: Record) -> bool:
        """Both nodes settle inside the record (the slow time constant at most the record's
        t_on span): a slower node is a straight line on it — a drift, not a node (a warm-up
        beside a wandering process was named two-node, its slow node 20 000 s on 3 000 s)."""
        t = rec.column("t_on")
        return p.get("tau_slow_s", 0.0) <= float(t.max() - t.min()) and p.get("tau_fast_s", 0.0) <= float(t.max())

    def drawable_range(self, q: Param, rec: Record, kind: str) -> tuple[float, float]:
        if q.name == "fraction_slow":
            return 0.3, 0.7
        if q.name == "tau_fast_s":  # five samples to a fortieth of the record
            lo = max(q.low, 5 * rec.dt_s)
            return lo, max(min(q.high, rec.duration_s / 40), lo * 1.01)
        if q.name == "tau_slow_s":
            lo = max(q.low, 20 * rec.dt_s)
            return lo, max(min(q.high, rec.duration_s / 4), lo * 1.01)
        return q.low, q.high

    def draw_others(self, rng: np.random.Generator, rec: Record, kind: str) -> Params:
        """tau_fast log-uniform in its range, tau_slow 4-30 times it (two separate nodes), the
        slow node's share 0.3-0.7."""
        lo, hi = self.drawable_range(self.param("tau_fast_s", kind), rec, kind)
        fast = math.exp(rng.uniform(math.log(lo), math.log(hi)))
        s_lo, s_hi = self.drawable_range(self.param("tau_slow_s", kind), rec, kind)
        slow = float(np.clip(fast * math.exp(rng.uniform(math.log(4.0), math.log(30.0))), s_lo, s_hi))
        return {"fraction_slow": float(rng.uniform(0.3, 0.7)), "tau_fast_s": fast, "tau_slow_s": max(slow, 2 * fast)}

    def reference_params(self, rec: Record, kind: str) -> Params:
        lo, hi = self.drawable_range(self.param("tau_fast_s", kind), rec, kind)
        fast = math.sqrt(lo * hi)
        return {"amplitude": 0.0, "fraction_slow": 0.5, "tau_fast_s": fast, "tau_slow_s": 10 * fast}

    def snr(self, p: Params, rec: Record, noise_sd: float) -> float:
        """The part of the transient one exponential cannot absorb (the best warm-up direction
        projected away): a two-node transient is only told from a warm-up by its second node."""
        y0 = self.reference_output(rec)
        q = orthonormal(base_regressors(rec))
        delta = project_q(self.apply(p, rec, y0) - y0, q)
        if np.any(delta):
            one = _ONE_NODE.direction_matching(delta, rec, q, guess_kind(rec))
            delta = project_q(delta, orthonormal(one[:, None]))
        return math.sqrt(vdot(delta, delta)) / noise_sd

    def fit_starts(self, rec: Record, residual: np.ndarray, *, kind: str | None = None,
                   rows: np.ndarray | None = None, held_out: np.ndarray | None = None) -> list[Params]:
        """A grid of (tau_fast, tau_slow ≥ 2·tau_fast) over five samples … half the record, the two
        amplitudes by least squares with the base regressors projected out; the three best.

        On ``rows`` that start after power-on (a fold's training blocks, the first held out) the
        grid starts at :func:`node_seen` (as the fit's range, :meth:`free_params`): a faster node
        has decayed below e^−2 before the rows begin, and what is left of it there is fitted as
        well by a large amplitude at a shorter time constant — the least squares took −0.27 °/s
        at 1.5 s on a gyro whose fast node was −0.02 °/s at 3.2 s (independent generator), and
        extrapolated it into the held-out first block: a held-out score of −3 for a two-node
        transient the full record fitted to within 6 % (0.74 with the bound)."""
        kind = kind or guess_kind(rec)
        rows = np.ones(rec.n, bool) if rows is None else np.asarray(rows, bool)
        a = base_regressors(rec)[rows]
        r = project_out(np.asarray(residual, float)[rows], a)
        t = rec.column("t_on")[rows]
        q_f, q_s = self.param("tau_fast_s", kind), self.param("tau_slow_s", kind)
        top = max(min(q_s.high, 0.5 * rec.duration_s), 10 * rec.dt_s)
        taus = np.geomspace(min(max(q_f.low, 5 * rec.dt_s, node_seen(rec, rows)), top / 4), top, 12)
        cands = []
        for i, tf in enumerate(taus):
            ef = project_out(np.exp(-t / tf), a)
            for ts in taus[i + 1:]:
                if ts < 2 * tf:
                    continue
                es = project_out(np.exp(-t / ts), a)
                m = np.column_stack([ef, es])
                (af, as_), *_ = np.linalg.lstsq(m, r, rcond=None)
                sse = float(np.sum((r - m @ np.array([af, as_])) ** 2))
                amp = float(af + as_)
                frac = float(as_ / amp) if abs(amp) > 1e-3 * (abs(af) + abs(as_)) else 0.5
                amp_q = self.param("amplitude", kind)
                cands.append((sse, {"amplitude": float(np.clip(amp, amp_q.low, amp_q.high)),
                                    "fraction_slow": float(np.clip(frac, -2.0, 3.0)),
                                    "tau_fast_s": float(tf), "tau_slow_s": float(ts)}))
        cands.sort(key=lambda c: c[0])
        return [c[1] for c in cands[:3]]


_ONE_NODE = WarmupExponential()


def temperature_rate(rec: Record, window: int | None = None) -> np.ndarray:
    """dT/dt (°C/s) of the logged temperature: a centred difference over ``window`` samples
    (default n/200, at least 1), one-sided at the ends."""
    temp = rec.column("temp")
    h = max(1, rec.n // 400) if window is None else max(1, int(window) // 2)
    n = rec.n
    i = np.arange(n)
    lo, hi = np.clip(i - h, 0, n - 1), np.clip(i + h, 0, n - 1)
    return (temp[hi] - temp[lo]) / (rec.t_s[hi] - rec.t_s[lo])


class TemperatureRate(Effect):
    id = "temperature_rate"
    description = ("bias proportional to the rate of temperature change: a thermal gradient across the sensing "
                   "element (the FOG's Shupe effect, a pendulum's differential expansion)")
    form = "y += coef_per_c_per_s · dT/dt (centred difference over n/200 samples of the logged temp)"
    inputs = ("temp",)
    main_param = "coef_per_c_per_s"
    signature = "input: residual correlates with d(temp)/dt (changes sign where the temperature turns)"
    separating = {"temperature_bias": "hold a temperature, then ramp it up and down at two rates: a rate effect "
                                      "vanishes at the hold and flips with the direction"}
    ranges = {  # FOG Shupe ~1-10 (deg/h)/(degC/min) ≈ 0.017-0.17 (deg/s)/(degC/s); µg per degC/min class
        "accelerometer": (Param("coef_per_c_per_s", "g/(degC/s)", -1e-1, 1e-1, linear=True, floor=1e-7),),
        "gyro": (Param("coef_per_c_per_s", "deg/s/(degC/s)", -10.0, 10.0, linear=True, floor=1e-5),),
        "mhd": (Param("coef_per_c_per_s", "deg/s/(degC/s)", -100.0, 100.0, linear=True, floor=1e-4),),
    }

    def term(self, p: Mapping[str, float], rec: Record) -> np.ndarray:
        return p["coef_per_c_per_s"] * temperature_rate(rec)


@numba.njit(cache=True)
def _play(x, half_width):  # pragma: no cover - compiled
    """Play (backlash) operator: y follows x within ±half_width, starting at x[0]."""
    y = np.empty_like(x)
    v = x[0]
    for k in range(x.size):
        if x[k] - v > half_width:
            v = x[k] - half_width
        elif v - x[k] > half_width:
            v = x[k] + half_width
        y[k] = v
    return y


def reversal_swings(temp: np.ndarray) -> tuple[float, float]:
    """(largest rise from an earlier minimum, largest fall from an earlier maximum), °C."""
    rise = float(np.max(temp - np.minimum.accumulate(temp)))
    fall = float(np.max(np.maximum.accumulate(temp) - temp))
    return rise, fall


class ThermalHysteresis(Effect):
    id = "thermal_hysteresis"
    description = ("bias that depends on whether the temperature last rose or fell (stress in the mount or "
                   "bonds relaxing with a lag): a backlash in temperature")
    form = ("y += half_gap · (P[temp] − temp)/(width_c/2), P the play operator of half-width width_c/2 started "
            "at the first temperature: −half_gap while heating, +half_gap while cooling, crossing over the "
            "first width_c °C after each turn")
    inputs = ("temp",)
    main_param = "half_gap"
    signature = ("input: residual against temp is a loop (two branches, heating and cooling); time: a step at "
                 "each temperature turn, spread over width_c of temperature")
    competitors = ("temperature_rate",)  # both follow the sign of dT/dt
    separating = {"temperature_rate": "ramp the temperature at two rates: hysteresis keeps its gap, a rate "
                                      "effect scales with the rate"}
    ranges = {
        "accelerometer": (Param("half_gap", "g", -1e-3, 1e-3, linear=True, floor=1e-8),
                          Param("width_c", "degC", 0.05, 20.0, log=True)),
        "gyro": (Param("half_gap", "deg/s", -0.1, 0.1, linear=True, floor=1e-6),
                 Param("width_c", "degC", 0.05, 20.0, log=True)),
        "mhd": (Param("half_gap", "deg/s", -1.0, 1.0, linear=True, floor=1e-4),
                Param("width_c", "degC", 0.05, 20.0, log=True)),
    }

    def term(self, p: Mapping[str, float], rec: Record) -> np.ndarray:
        temp = np.ascontiguousarray(rec.column("temp"), dtype=float)
        w = 0.5 * float(p["width_c"])
        return p["half_gap"] * (_play(temp, w) - temp) / w

    def applies_to(self, rec: Record) -> bool:
        """A temperature column that goes up and down (each by :data:`MIN_REVERSAL_C` at least)."""
        if not rec.logged("temp"):
            return False
        return min(reversal_swings(rec.column("temp"))) >= MIN_REVERSAL_C

    def free_params(self, p: Mapping[str, float], kind: str, rec: Record,
                    rows: np.ndarray | None = None) -> tuple[Param, ...]:
        """The width is fitted below the smaller of the record's rise and fall: a play wider than
        the swing never changes branch, and its output is then linear in temperature."""
        if not rec.logged("temp"):
            return self.params_for(kind)
        top = min(reversal_swings(rec.column("temp")))
        return tuple(replace(q, high=max(min(q.high, 0.8 * top), q.low * 1.01)) if q.name == "width_c" else q
                     for q in self.params_for(kind))

    def identifiable(self, p: Mapping[str, float], rec: Record) -> bool:
        """The play must change branch with room to spare: a width over half the smaller of the
        rise and fall is a temperature bias on this record."""
        return rec.logged("temp") and p.get("width_c", math.inf) <= 0.5 * min(reversal_swings(rec.column("temp")))

    def drawable_range(self, q: Param, rec: Record, kind: str) -> tuple[float, float]:
        if q.name == "width_c" and rec.logged("temp"):
            swing = min(reversal_swings(rec.column("temp")))
            hi = max(min(q.high, swing / 3), q.low * 1.01)
            return q.low, max(min(hi, q.high), min(1.0, hi))
        return q.low, q.high

    def main_grid_range(self, rec: Record, kind: str) -> tuple[float, float]:
        q = self.param("width_c", kind)
        return self.drawable_range(q, rec, kind)


#: Below this x = dt/τ the lag's ramp weight g(x) = 1 − (1 − e^−x)/x and its derivative are
#: summed as series (to x⁵: truncation 2x⁵/5040 ≈ 4e-14 relative); above it the closed form
#: loses only 2·eps/x to cancellation.
_SERIES_X = 1e-2


@numba.njit(cache=True)
def _lag_recursion(t, x, tau):  # pragma: no cover - compiled
    """(T_e, ∂T_e/∂τ): the first-order lag of x (linear between the samples t) started at x[0]."""
    n = x.size
    te = np.empty(n)
    dte = np.empty(n)
    te[0] = x[0]
    dte[0] = 0.0
    for k in range(1, n):
        z = (t[k] - t[k - 1]) / tau
        a = math.exp(-z)
        if z < _SERIES_X:
            g = z * (0.5 - z * (1.0 / 6 - z * (1.0 / 24 - z * (1.0 / 120 - z / 720))))
            dg = 0.5 - z * (1.0 / 3 - z * (1.0 / 8 - z * (1.0 / 30 - z / 144)))
        else:
            g = (z + math.expm1(-z)) / z
            dg = (-math.expm1(-z) - g) / z
        prev = te[k - 1] - x[k - 1]
        step = x[k] - x[k - 1]
        te[k] = x[k - 1] + a * prev + step * g
        # d/dτ: da/dτ = a·z/τ, dz/dτ = −z/τ
        dte[k] = a * dte[k - 1] + (a * z / tau) * prev - step * dg * z / tau
    return te, dte


def element_temperature(rec: Record, lag_s: float, *, gradient: bool = False):
    """The sensing element's temperature (°C) behind the logged (case) temperature through a
    first-order lag of time constant ``lag_s``: the exact solution of ``lag_s·dT_e/dt = T − T_e``
    for ``T`` linear between its (possibly non-uniform) samples, started at ``T_e[0] = T[0]`` (the
    element settled at the first logged value). Per interval h_k, z = h_k/lag_s:
    ``T_e[k] = T[k−1] + e^−z·(T_e[k−1] − T[k−1]) + (T[k] − T[k−1])·(1 − (1 − e^−z)/z)``.
    With ``gradient``: (T_e, ∂T_e/∂lag_s in °C/s)."""
    if not lag_s > 0:
        raise ValueError(f"lag_s = {lag_s!r}; allowed: > 0 s")
    t = np.ascontiguousarray(rec.t_s, dtype=float)
    temp = np.ascontiguousarray(rec.column("temp"), dtype=float)
    te, dte = _lag_recursion(t, temp, float(lag_s))
    return (te, dte) if gradient else te


#: A sensing element bonded inside its case lags the case by 5-10 min (the thermal-ramp
#: analysis's simulated units: case lag 2-10 min, docs/METHODS.md): drawn there when the record
#: resolves it.
LAG_DRAW_S = (300.0, 600.0)
def sweep_time(rec: Record) -> float:
    """The temperature's sweep time, s: its swing over the record divided by its fastest rate
    (:func:`temperature_rate`) — how fast the logged temperature crosses its range (inf when it
    does not move)."""
    rate = float(np.max(np.abs(temperature_rate(rec)))) if rec.logged("temp") else 0.0
    return float(np.ptp(rec.column("temp"))) / rate if rate > 0 else math.inf


#: A logged temperature's resolution (0.01 °C steps, as the module docstring says): a lag whose
#: signature in temperature, lag × the change of the temperature's rate, stays below it cannot
#: be read from the record.
TEMP_RESOLUTION_C = 0.01


class ThermalLag(Effect):
    id = "thermal_lag"
    description = ("bias (and scale factor) following the sensing element's temperature, which lags the logged "
                   "case temperature through a first-order lag (the sensor sits on the case)")
    form = (f"y += coef_per_c·(T_e − {T_REF_C} °C) + sf_coef_per_c·(T_e − {T_REF_C} °C)·input, "
            "lag_s·dT_e/dt = temp − T_e (temp linear between samples, exact), T_e[0] = temp[0]; "
            "sf_coef_per_c only when the input varies")
    inputs = ("temp",)
    main_param = "coef_per_c"
    signature = ("input: residual correlates with the temperature delayed and smoothed by lag_s (a loop against "
                 "temp: heating and cooling branches part by coef·lag·dT/dt); time: after a temperature step "
                 "the offset settles over several lag_s")
    competitors = ("temperature_bias",)  # at a lag of a few samples the element is the logged temperature
    # not the MHD sensor: its records last a minute over a few °C, and a lag it could resolve there
    # (seconds) is not told from temperature_bias inside the coefficient's range (distinct snr at
    # most 16 at the largest coefficient on the catalogue's experiment, against 15 to draw)
    kinds = ("accelerometer", "gyro")
    separating = {"temperature_bias": "a temperature step: the lagged response reaches its level only after "
                                      "several lag_s"}
    ranges = {  # coefficients as temperature_bias's and temperature_scale_factor's; lags from a die (s) to
        # a massive mount (a day)
        "accelerometer": (Param("coef_per_c", "g/degC", -1e-4, 1e-4, linear=True, floor=1e-8),
                          Param("sf_coef_per_c", "1/degC", -1e-3, 1e-3, linear=True, floor=1e-8),
                          Param("lag_s", "s", 1.0, 1e5, log=True)),
        "gyro": (Param("coef_per_c", "deg/s/degC", -3e-3, 3e-3, linear=True, floor=1e-7),
                 Param("sf_coef_per_c", "1/degC", -1e-3, 1e-3, linear=True, floor=1e-8),
                 Param("lag_s", "s", 1.0, 1e5, log=True)),
    }

    def term(self, p: Mapping[str, float], rec: Record) -> np.ndarray:
        d = element_temperature(rec, p["lag_s"]) - T_REF_C
        out = p["coef_per_c"] * d
        if p["sf_coef_per_c"] != 0.0 and rec.logged("input"):
            out = out + p["sf_coef_per_c"] * d * rec.column("input")
        return out

    def term_gradient(self, p: Mapping[str, float], rec: Record, names: Sequence[str]) -> list[np.ndarray]:
        if not names:
            return []
        te, dte = element_temperature(rec, p["lag_s"], gradient=True)
        d = te - T_REF_C
        u = rec.column("input") if rec.logged("input") else np.zeros(rec.n)
        grads = {"coef_per_c": lambda: d, "sf_coef_per_c": lambda: d * u,
                 "lag_s": lambda: (p["coef_per_c"] + p["sf_coef_per_c"] * u) * dte}
        return [grads[k]() for k in names]

    def identity_params(self, p: Params) -> Params:
        return {**p, "coef_per_c": 0.0, "sf_coef_per_c": 0.0}

    # ---- what the record resolves -----------------------------------------------------
    def fit_range(self, q: Param, rec: Record, kind: str) -> tuple[float, float]:
        if q.name == "lag_s":  # three sample intervals (below: a sub-sample shift of the logged
            # temperature, its rate term) up to the record's length (beyond: identifiable says no)
            return 3 * rec.dt_s, max(rec.duration_s, 3.03 * rec.dt_s)
        return q.low, q.high

    def free_params(self, p: Mapping[str, float], kind: str, rec: Record,
                    rows: np.ndarray | None = None) -> tuple[Param, ...]:
        """The lag inside :meth:`fit_range`; the scale-factor part only on a record whose input
        varies (otherwise it is one with the bias part and stays at ``p``'s value)."""
        qs = self.fit_params(rec, kind)
        return tuple(q for q in qs if q.name != "sf_coef_per_c" or rec.varies("input"))

    def identifiable(self, p: Mapping[str, float], rec: Record) -> bool:
        """The lag is read from how the element's temperature falls behind the logged one after
        each change of the temperature's rate (a step, a turn, the start of a ramp from the
        settled state the recursion starts in): it is resolved when (i) that signature, lag × the
        largest change of the rate, reaches the logged temperature's resolution
        (:data:`TEMP_RESOLUTION_C`), and (ii) the response settles inside the record (two lags:
        86 %, so lag ≤ half the record) — a longer lag is a slow drift of the element on it."""
        if not rec.varies("temp"):
            return False
        lag = p.get("lag_s", math.inf)
        rate = temperature_rate(rec)
        swing = max(float(rate.max()), 0.0) - min(float(rate.min()), 0.0)  # the settled start is rate 0
        return lag * swing >= TEMP_RESOLUTION_C and lag <= 0.5 * rec.duration_s

    def drawable_range(self, q: Param, rec: Record, kind: str) -> tuple[float, float]:
        """The lag up to a quarter of the record (its response settles e^−4 inside it):
        :data:`LAG_DRAW_S` when the record holds that span from five sample intervals up; on a
        shorter record from half the temperature's sweep time (:func:`sweep_time`) up — a shorter
        lag shifts the element by less than half the swing at the fastest logged rate, and on a
        record of minutes that is mostly its look-alike, temperature_bias (whose snr counts only
        what lags in this range cannot absorb)."""
        if q.name != "lag_s":
            return q.low, q.high
        lo = max(q.low, 5 * rec.dt_s)
        hi = max(min(q.high, 0.25 * rec.duration_s), lo * 1.01)
        if lo <= LAG_DRAW_S[0] and LAG_DRAW_S[1] <= hi:
            return LAG_DRAW_S
        lo = min(max(lo, 0.5 * sweep_time(rec)), hi / 1.01)
        return lo, hi

    def draw_others(self, rng: np.random.Generator, rec: Record, kind: str) -> Params:
        """The lag log-uniform in :meth:`drawable_range`; the scale-factor part 0 (the draw sizes
        the bias part, the main parameter, by its snr — as temperature_bias draws its linear term)."""
        lo, hi = self.drawable_range(self.param("lag_s", kind), rec, kind)
        return {"sf_coef_per_c": 0.0, "lag_s": math.exp(rng.uniform(math.log(lo), math.log(hi)))}

    def reference_params(self, rec: Record, kind: str) -> Params:
        lo, hi = self.drawable_range(self.param("lag_s", kind), rec, kind)
        return {"coef_per_c": 0.0, "sf_coef_per_c": 0.0, "lag_s": math.sqrt(lo * hi)}

    # ---- fit starts -------------------------------------------------------------------
    def fit_starts(self, rec: Record, residual: np.ndarray, *, kind: str | None = None,
                   rows: np.ndarray | None = None, held_out: np.ndarray | None = None) -> list[Params]:
        """A grid of 17 lags log-spaced over :meth:`fit_range` (four per decade on a 1-Hz record of
        hours), the coefficients (the scale-factor one only when the input varies) by least
        squares on ``rows`` with the base regressors projected out; the :data:`N_STARTS` best."""
        kind = kind or guess_kind(rec)
        rows = np.ones(rec.n, bool) if rows is None else np.asarray(rows, bool)
        a = base_regressors(rec)[rows]
        r = project_out(np.asarray(residual, float)[rows], a)
        qs = {q.name: q for q in self.params_for(kind)}
        lo, hi = self.fit_range(qs["lag_s"], rec, kind)
        lo, hi = max(lo, qs["lag_s"].low), min(hi, qs["lag_s"].high)
        with_sf = rec.varies("input")
        u = rec.column("input")[rows] if with_sf else None
        cands = []
        for lag in np.geomspace(lo, max(hi, lo * 1.01), 17):
            d = element_temperature(rec, float(lag))[rows] - T_REF_C
            cols = [d] + ([d * u] if u is not None else [])
            m = np.column_stack([project_out(c, a) for c in cols])
            coef, *_ = np.linalg.lstsq(m, r, rcond=None)
            p = {"coef_per_c": float(np.clip(coef[0], qs["coef_per_c"].low, qs["coef_per_c"].high)),
                 "sf_coef_per_c": 0.0, "lag_s": float(lag)}
            if u is not None:
                p["sf_coef_per_c"] = float(np.clip(coef[1], qs["sf_coef_per_c"].low, qs["sf_coef_per_c"].high))
            fitted = m @ np.array([p["coef_per_c"]] + ([p["sf_coef_per_c"]] if u is not None else []))
            cands.append((float(np.sum((r - fitted) ** 2)), p))
        cands.sort(key=lambda c: c[0])
        return [c[1] for c in cands[:N_STARTS]]
