"""An independent thermal physics: the generator the thermal analysis is graded on.

Written apart from ``bench.analysis.thermal_*`` (house rule 7): none of its code is imported
here, and the physics is integrated differently (RK4 on a fine step, not the analysis's
exact first-order filter).

* **Chamber**: the set point follows a program of knots (time, °C) linearly; the air follows
  the set point through a first-order lag ``tau_air_s``.
* **Unit, two nodes**: the case follows the air (``tau_case_s``), the sensing element follows
  the case (``tau_element_s``), so the element lags the air and a gradient exists in ramps.
  The unit's temperature sensor reads the **case**, with white noise.
* **Output** (a static unit: its bias): ``bias(T_element)`` (polynomial about 25 °C)
  + ``hysteresis/2 · branch`` + ``rate_coef · dT_case/dt`` (°C/min; the gradient across
  the unit drives it) + an AR(1) drift + white noise. ``branch`` is +1 after the element's
  temperature turned upward and −1 after it turned downward, flipping once the element has
  moved ``flip_c`` back from its extreme (a real hysteresis needs an excursion to switch).
* **Play hysteresis** (``hysteresis_width_c`` = w > 0): instead of the branch flip, a
  backlash of half width w on the element temperature — the memory m holds while
  |T_e − m| < w and is dragged along at w otherwise; the term is ``hysteresis/2 · (T_e − m)/w``
  (a reversal switches it fully over 2w of travel). The memory starts on the branch opposite
  to the first move (the unit arrived at its start from the other side).
* **Chamber record** (:func:`simulate_chamber_record`): soaks and ramps of the set point, the
  logged sensor on the case, the element lagging the case by ``tau_element_s``, a rate
  table stepping through rates all along, and the output
  ``SF(T_e)·(rate + bias(T_e))`` with SF(T) = sf0·(1 + 1e-6·Σ c_j (T − 25)^j) plus an AR(1)
  drift and white noise.
* **Sweep points**: at soaked set points the tumble/rate-table estimates are drawn directly:
  the element sits a small random gradient from the sensor (``temperature_std_c``), and each
  estimate carries its own noise.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

REF_C = 25.0


def poly(coef, temp_c) -> np.ndarray:
    """Σ coef[j]·(T − 25)^j, written out (not the analysis's polynomial_rows)."""
    u = np.asarray(temp_c, dtype=float) - REF_C
    out = np.zeros_like(u)
    for j, c in enumerate(coef):
        out = out + c * u**j
    return out


def poly_slope(coef, temp_c) -> np.ndarray:
    u = np.asarray(temp_c, dtype=float) - REF_C
    out = np.zeros_like(u)
    for j, c in enumerate(coef):
        if j:
            out = out + j * c * u ** (j - 1)
    return out


@dataclass(frozen=True)
class ThermalUnit:
    bias_coef: tuple[float, ...] = (1e-3, 10e-6, 2e-8, 0.0)
    hysteresis: float = 0.0
    rate_coef: float = 0.0  # output units per °C/min of the case
    tau_air_s: float = 120.0
    tau_case_s: float = 600.0
    tau_element_s: float = 0.0
    white_sd: float = 1e-6
    ar1_sd: float = 0.0  # innovation sd per sample of the AR(1) drift
    ar1_phi: float = 0.99
    sensor_noise_c: float = 0.01
    flip_c: float = 0.3
    hysteresis_width_c: float = 0.0  # > 0: a play operator of this half width instead of the flip


@dataclass
class Program:
    """Set-point knots: times (s) and temperatures (°C), linear between them."""

    knots_s: list[float] = field(default_factory=list)
    knots_c: list[float] = field(default_factory=list)

    def at(self, t):
        return np.interp(t, self.knots_s, self.knots_c)

    @staticmethod
    def cycles(start_c: float, low_c: float, high_c: float, rates_c_per_min, dwell_s: float = 0.0,
               soak_s: float = 3600.0) -> Program:
        """Soak at ``start_c``, then for each rate: up to high, dwell, down to low, dwell."""
        t, ks, kc = 0.0, [0.0], [start_c]
        t += soak_s
        ks.append(t)
        kc.append(start_c)
        cur = start_c
        for r in rates_c_per_min:
            for target in (high_c, low_c):
                t += abs(target - cur) / r * 60.0
                ks.append(t)
                kc.append(target)
                cur = target
                if dwell_s:
                    t += dwell_s
                    ks.append(t)
                    kc.append(target)
        return Program(ks, kc)


def integrate_nodes(program: Program, tau_air_s: float, tau_case_s: float, tau_element_s: float, dt_s: float,
                    substeps: int = 8) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Times and the air, case and element temperatures (classic RK4, ``substeps`` per sample),
    all starting soaked at the program's first set point."""
    n = int(program.knots_s[-1] // dt_s) + 1
    t = np.arange(n) * dt_s
    h = dt_s / substeps
    sp = program.at(np.arange(2 * n * substeps + 1) * (h / 2)).tolist()  # set point at every half step
    ta, tc, te = tau_air_s, tau_case_s, tau_element_s
    air = case = el = float(sp[0])
    out = np.empty((n, 3))

    def deriv(s_p, a, c, e):
        return (s_p - a) / ta, (a - c) / tc, (0.0 if te == 0 else (c - e) / te)

    for i in range(n):
        if te == 0:
            el = case
        out[i] = air, case, el
        for k in range(substeps):
            j = 2 * (i * substeps + k)
            a1, c1, e1 = deriv(sp[j], air, case, el)
            a2, c2, e2 = deriv(sp[j + 1], air + h / 2 * a1, case + h / 2 * c1, el + h / 2 * e1)
            a3, c3, e3 = deriv(sp[j + 1], air + h / 2 * a2, case + h / 2 * c2, el + h / 2 * e2)
            a4, c4, e4 = deriv(sp[j + 2], air + h * a3, case + h * c3, el + h * e3)
            air += h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
            case += h / 6 * (c1 + 2 * c2 + 2 * c3 + c4)
            el += h / 6 * (e1 + 2 * e2 + 2 * e3 + e4)
    return t, out[:, 0], out[:, 1], out[:, 2]


def _ar1(rng, sd: float, phi: float, n: int) -> np.ndarray:
    drift = np.zeros(n)
    if sd > 0:
        e = rng.normal(0.0, sd, n)
        for i in range(1, n):
            drift[i] = phi * drift[i - 1] + e[i]
    return drift


def simulate_ramp(unit: ThermalUnit, program: Program, dt_s: float, seed: int, substeps: int = 8) -> dict:
    """Integrate air, case, element (classic RK4, ``substeps`` per sample) and draw the output."""
    rng = np.random.default_rng(seed)
    t, air_c, case_c, element = integrate_nodes(program, unit.tau_air_s, unit.tau_case_s, unit.tau_element_s,
                                                dt_s, substeps)
    n = t.size
    rate_case = 60.0 * (air_c - case_c) / unit.tau_case_s
    if unit.hysteresis_width_c > 0:
        branch = play_output(element, unit.hysteresis_width_c)
    else:
        branch = branch_state(element, unit.flip_c)
    drift = _ar1(rng, unit.ar1_sd, unit.ar1_phi, n)
    clean = poly(unit.bias_coef, element) + unit.hysteresis / 2 * branch + unit.rate_coef * rate_case
    output = clean + drift + rng.normal(0.0, unit.white_sd, n)
    sensor = case_c + rng.normal(0.0, unit.sensor_noise_c, n)
    return {"t": t, "air": air_c, "case": case_c, "element": element, "sensor": sensor,
            "rate_case": rate_case, "branch": branch, "clean": clean, "output": output}


def play_output(temp: np.ndarray, width_c: float) -> np.ndarray:
    """(T − m)/w in [−1, 1] for a play (backlash) of half width w on ``temp``: the memory m
    stays while |T − m| < w and follows at distance w otherwise; it starts on the branch
    opposite to the first move (m = T_0 + w·sign of the first move)."""
    moved = np.flatnonzero(np.abs(temp - temp[0]) > 1e-9)
    first = 1.0 if moved.size == 0 else float(np.sign(temp[moved[0]] - temp[0]))
    m = float(temp[0]) + first * width_c
    out = np.empty(temp.size)
    for i, v in enumerate(temp.tolist()):
        if v - m > width_c:
            m = v - width_c
        elif m - v > width_c:
            m = v + width_c
        out[i] = (v - m) / width_c
    return out


def branch_state(temp: np.ndarray, flip_c: float) -> np.ndarray:
    """+1 once the temperature has risen ``flip_c`` above its last low, −1 once it has fallen
    ``flip_c`` below its last high; before the first move, the first move's sign."""
    out = np.zeros(temp.size)
    state, ext = 0.0, float(temp[0])
    for i, v in enumerate(temp.tolist()):
        if state == 0.0:
            if abs(v - ext) >= flip_c:
                state, ext = (1.0 if v > ext else -1.0), v
        elif state * (v - ext) > 0:
            ext = v
        elif state * (ext - v) >= flip_c:
            state, ext = -state, v
        out[i] = state
    moved = np.flatnonzero(out)
    if moved.size:
        out[: moved[0]] = out[moved[0]]
    return out


@dataclass(frozen=True)
class SweepPoints:
    temperature_c: np.ndarray  # the sensor's reading at each point
    element_c: np.ndarray  # the truth the quantity follows
    value: np.ndarray
    std: np.ndarray
    temperature_std_c: np.ndarray


def sweep_points(coef, temps_c, std, temperature_std_c, seed: int, offset: float = 0.0) -> SweepPoints:
    """Soaked points: element = sensor + N(0, temperature_std_c); value = poly(element) + offset
    + N(0, std) (``std`` one value or per point)."""
    rng = np.random.default_rng(seed)
    temps = np.asarray(temps_c, dtype=float) + rng.uniform(-0.3, 0.3, len(temps_c))  # set points are not hit exactly
    s = np.broadcast_to(np.asarray(std, dtype=float), temps.shape) * rng.uniform(0.7, 1.4, temps.size)
    ts = np.full(temps.size, float(temperature_std_c))
    element = temps + rng.normal(0.0, 1.0, temps.size) * ts
    value = poly(coef, element) + offset + rng.normal(0.0, 1.0, temps.size) * s
    return SweepPoints(temps, element, value, s, ts)


@dataclass(frozen=True)
class ChamberUnit:
    """A unit on a rate table in a chamber (input in °/s, or g for an accelerometer).

    Bias ``bias_coef`` (input units, Σ c_j (T − 25)^j of the element), scale factor
    ``sf0 · (1 + 1e-6 · Σ sf_ppm_coef[j] (T − 25)^(j+1))`` (so ``sf_ppm_coef[0]`` is the SF TC in
    ppm/°C), the logged sensor on the case (``tau_case_s`` behind the air), the element
    ``tau_element_s`` behind the case; white noise and an AR(1) drift on the output; a play
    hysteresis ``hysteresis/2 · z`` (input units, half width ``hysteresis_width_c``) on the
    element when both are non-zero."""

    bias_coef: tuple[float, ...] = (0.05, 2.0e-3)
    sf0: float = 1.0
    sf_ppm_coef: tuple[float, ...] = (150.0,)
    tau_air_s: float = 120.0
    tau_case_s: float = 600.0
    tau_element_s: float = 400.0
    white_sd: float = 5e-3
    ar1_sd: float = 0.0
    ar1_phi: float = 0.995
    sensor_noise_c: float = 0.02
    hysteresis: float = 0.0
    hysteresis_width_c: float = 0.0


def chamber_program(rng, low_c: float = -20.0, high_c: float = 60.0, duration_s: float = 5.75 * 3600) -> Program:
    """Soaks and ramps between ``low_c`` and ``high_c``: a soak at 25 °C, then set points drawn
    across the range (each at least a quarter of the span from the last), ramps of 0.5–2 °C/min,
    soaks of 15–40 min, until ``duration_s``."""
    t, ks, kc = 0.0, [0.0], [25.0]
    t += rng.uniform(900.0, 1800.0)
    ks.append(t)
    kc.append(25.0)
    cur, ends = 25.0, [low_c, high_c]
    while t < duration_s:
        target = float(rng.choice(ends)) if rng.uniform() < 0.5 else float(rng.uniform(low_c, high_c))
        if abs(target - cur) < (high_c - low_c) / 4:
            target = high_c if cur < (low_c + high_c) / 2 else low_c
        t += abs(target - cur) / rng.uniform(0.5, 2.0) * 60.0
        ks.append(t)
        kc.append(target)
        t += rng.uniform(900.0, 2400.0)
        ks.append(t)
        kc.append(target)
        cur = target
    end = float(np.interp(duration_s, ks, kc))  # the record ends at duration_s, mid-segment or not
    keep = [i for i, k in enumerate(ks) if k < duration_s]
    return Program([ks[i] for i in keep] + [duration_s], [kc[i] for i in keep] + [end])


def rate_table(t_s: np.ndarray, rates, dwell_s: float, offset_s: float = 0.0) -> np.ndarray:
    """A rate table stepping through ``rates`` (°/s), ``dwell_s`` each, cyclically, changing
    rate at 100 °/s² (a short linear ramp between levels)."""
    rates = np.asarray(rates, dtype=float)
    k = np.floor((t_s + offset_s) / dwell_s).astype(np.int64)
    level = rates[k % rates.size]
    prev = rates[(k - 1) % rates.size]
    into = (t_s + offset_s) - k * dwell_s
    ramp_s = np.abs(level - prev) / 100.0
    frac = np.where(ramp_s > 0, np.clip(into / np.where(ramp_s > 0, ramp_s, 1.0), 0.0, 1.0), 1.0)
    return prev + (level - prev) * frac


def simulate_chamber_record(unit: ChamberUnit, program: Program, applied_fn, dt_s: float, seed: int,
                            substeps: int = 4) -> dict:
    """Integrate the chamber and the unit (RK4), apply ``applied_fn(t)`` (the table's rate) and
    draw the output ``SF(T_e)·(rate + bias(T_e))`` + drift + white noise; the logged sensor
    reads the case with white noise."""
    rng = np.random.default_rng(seed)
    t, air, case, element = integrate_nodes(program, unit.tau_air_s, unit.tau_case_s, unit.tau_element_s,
                                            dt_s, substeps)
    applied = np.asarray(applied_fn(t), dtype=float)
    u = element - REF_C
    rel = np.zeros_like(u)
    for j, c in enumerate(unit.sf_ppm_coef):
        rel = rel + c * u ** (j + 1)
    sf = unit.sf0 * (1.0 + 1e-6 * rel)
    bias = poly(unit.bias_coef, element)
    if unit.hysteresis and unit.hysteresis_width_c > 0:
        bias = bias + unit.hysteresis / 2 * play_output(element, unit.hysteresis_width_c)
    clean = sf * (applied + bias)
    output = clean + _ar1(rng, unit.ar1_sd, unit.ar1_phi, t.size) + rng.normal(0.0, unit.white_sd, t.size)
    sensor = case + rng.normal(0.0, unit.sensor_noise_c, t.size)
    return {"t": t, "air": air, "case": case, "element": element, "sensor": sensor, "applied": applied,
            "scale_factor": sf, "clean": clean, "output": output}


def draw_chamber_case(rng) -> tuple[ChamberUnit, Program, tuple[float, ...], float]:
    """The chamber-record population: a gyro on a rate table in a chamber, −20 … +60 °C over 5.75 h.

    Bias TC ±(0.5 … 3)·10⁻³ °/s/°C with a curvature half the time, SF TC ±(50 … 300) ppm/°C,
    the logged sensor on the case (τ 300 … 900 s behind the air), the element 300 … 600 s behind
    the case; white noise 2 … 10·10⁻³ °/s per sample and an AR(1) drift up to 5 % of it
    (φ 0.99 … 0.999 per 2-s sample); the table stepping through 0, ±10, ±50, ±100 °/s (order
    drawn) with dwells of 60 … 180 s. Returns the unit, the chamber programme, the rates and
    the dwell."""
    tc = float(rng.choice([-1.0, 1.0]) * rng.uniform(0.5e-3, 3e-3))
    curvature = float(rng.normal(0.0, 1.0) * abs(tc) / 100 * (rng.uniform() < 0.5))
    sf_tc = float(rng.choice([-1.0, 1.0]) * rng.uniform(50.0, 300.0))
    white = float(rng.uniform(2e-3, 1e-2))
    unit = ChamberUnit(bias_coef=(float(rng.normal(0.0, 0.05)), tc, curvature), sf0=float(rng.uniform(0.9, 1.1)),
                       sf_ppm_coef=(sf_tc,), tau_case_s=float(rng.uniform(300.0, 900.0)),
                       tau_element_s=float(rng.uniform(300.0, 600.0)), white_sd=white,
                       ar1_sd=white * float(rng.uniform(0.0, 0.05)), ar1_phi=float(rng.uniform(0.99, 0.999)))
    rates = tuple(float(r) for r in rng.permutation([0.0, 10.0, -10.0, 50.0, -50.0, 100.0, -100.0]))
    dwell = float(rng.uniform(60.0, 180.0))
    return unit, chamber_program(rng), rates, dwell
