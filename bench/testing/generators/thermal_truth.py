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


def simulate_ramp(unit: ThermalUnit, program: Program, dt_s: float, seed: int, substeps: int = 8) -> dict:
    """Integrate air, case, element (classic RK4, ``substeps`` per sample) and draw the output."""
    rng = np.random.default_rng(seed)
    n = int(program.knots_s[-1] // dt_s) + 1
    t = np.arange(n) * dt_s
    h = dt_s / substeps
    sp = program.at(np.arange(2 * n * substeps + 1) * (h / 2)).tolist()  # set point at every half step
    ta, tc, te = unit.tau_air_s, unit.tau_case_s, unit.tau_element_s
    air = case = el = float(sp[0])
    out = np.empty((n, 4))

    def deriv(s_p, a, c, e):
        return (s_p - a) / ta, (a - c) / tc, (0.0 if te == 0 else (c - e) / te)

    for i in range(n):
        if te == 0:
            el = case
        out[i] = air, case, el, 60.0 * (air - case) / tc
        for k in range(substeps):
            j = 2 * (i * substeps + k)
            a1, c1, e1 = deriv(sp[j], air, case, el)
            a2, c2, e2 = deriv(sp[j + 1], air + h / 2 * a1, case + h / 2 * c1, el + h / 2 * e1)
            a3, c3, e3 = deriv(sp[j + 1], air + h / 2 * a2, case + h / 2 * c2, el + h / 2 * e2)
            a4, c4, e4 = deriv(sp[j + 2], air + h * a3, case + h * c3, el + h * e3)
            air += h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
            case += h / 6 * (c1 + 2 * c2 + 2 * c3 + c4)
            el += h / 6 * (e1 + 2 * e2 + 2 * e3 + e4)
    air_c, case_c, element, rate_case = out.T
    branch = branch_state(element, unit.flip_c)
    drift = np.zeros(n)
    if unit.ar1_sd > 0:
        e = rng.normal(0.0, unit.ar1_sd, n)
        for i in range(1, n):
            drift[i] = unit.ar1_phi * drift[i - 1] + e[i]
    clean = poly(unit.bias_coef, element) + unit.hysteresis / 2 * branch + unit.rate_coef * rate_case
    output = clean + drift + rng.normal(0.0, unit.white_sd, n)
    sensor = case_c + rng.normal(0.0, unit.sensor_noise_c, n)
    return {"t": t, "air": air_c, "case": case_c, "element": element, "sensor": sensor,
            "rate_case": rate_case, "branch": branch, "clean": clean, "output": output}


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
