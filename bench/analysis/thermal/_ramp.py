"""Thermal ramp: bias over temperature, thermal hysteresis and temperature-rate sensitivity.

One static record taken while the chamber ramps up and down: the unit's output y(t) (its
bias plus the constant static input), and its own sensor's temperature T(t). Model, on
block means of ``block_s``::

    y = p(T_e) + h·z/2 + k·Ṫ + noise,      T_e = T lagged by τ:  τ·dT_e/dt = T − T_e

* p — the **bias-vs-temperature curve** (order 0 … 3 about ``reference_c``, BIC), at zero
  rate and mid-way between the branches, in the element's temperature T_e (the sensor's
  when τ = 0);
* z, the branch: the output of a **play (backlash) operator** of half width w on T_e,
  z = (T_e − m)/w in [−1, 1], whose memory m stays put while |T_e − m| < w and is dragged
  at distance w otherwise — so z = +1 well into an up branch, −1 well into a down branch,
  and after a reversal it crosses over linearly in 2w of travel (a unit's hysteresis takes a
  reversal of some degrees to switch, not an instant). w, the **switching half width**, is
  fitted (``hysteresis_width_c`` None: profiled over [``reversal_band_c``/4,
  ``hysteresis_width_max_c``], the lower end the noise immunity the dead band states) with
  its standard uncertainty; ``hysteresis_width_c = 0`` is the instant switch at each extremum
  of T (found with a ``reversal_band_c`` dead band, so sensor noise cannot flip it). h, the
  **thermal hysteresis**, is the up-minus-down offset at equal temperature and zero rate
  once the branch has switched fully. The play's memory at the start depends on the unit's
  history before the record (it is somewhere within w of T_e), so with w > 0 the first
  branch's first 2·w_bound of travel (w_bound: the fixed w, or ``hysteresis_width_max_c``)
  is left out of the fits: from there on the memory is known whatever it was (the element's
  lag τ·r behind the sensor eats into that margin);
* Ṫ — the sensor's rate in °C/min (the least-squares slope of its samples over ``rate_window_s``
  about each block's centre, by default the block: its mean rate, turns included); k, the
  **temperature-rate sensitivity** (a FOG's Shupe effect, an accelerometer's gradient
  sensitivity), in output units per °C/min;
* τ — the sensing element's lag behind the sensor: during a ramp it makes p(T) read
  p(T − τṪ), a rate term of size τ·p'(T)·Ṫ. ``lag_s`` fixes τ (0: the sensor reads the
  element), None fits it when the data can tell it from k — only through p's curvature,
  since for a linear p the lag *is* a rate term; otherwise τ = 0 and the rate term carries it.

**h and k are confounded** when the unit ramps up and down at one rate: on steady ramps
Ṫ = ±r is then ±r·s, so h·s/2 + k·Ṫ = (h/2 + k·r)·s, and with one up rate and a different
down rate Ṫ is an affine function of s whose constant the curve absorbs. They separate only
when the steady rate takes more values than the branch explains — ramps at two rates
(dwells help little: they sit at the extremes, where the curve's own shape absorbs them).
The check is made on the **steady** blocks only (the rate ``steady_window_s`` before and
after the block, and at the block, agree within ``steady_tolerance`` of the largest rate):
a unit accelerating out of a reversal or a soak changes Ṫ too, but there the model is least
sure (the branch's switch, the rate's smoothing), so those blocks must not be what separates
the terms. The fraction of the steady rate column outside the span of the curve and branch
columns there (1/√VIF) must reach ``min_separation``; otherwise ``hysteresis`` and
``rate_sensitivity`` are None with the reason. The rate term stays in the fitted model
either way (so its transients are not mistaken for drift), and their combination, which the
record does determine, is always reported: ``branch_offset`` = h + k·(r_up − r_down), the
up-minus-down difference at equal temperature at the record's ramp rates
``ramp_rates_c_per_min`` (the median rate of each direction's blocks, dwells left out).
The lag is checked the same way against the other columns.

Model-free beside it, the **branch difference curve**: separate polynomials (the curve's
order) of the sensor temperature for the up and the down branch on the steady ramp blocks
(the difference at the record's ramp rates, not through the turns), their difference over
the temperatures both branches covered.

The record (block means, rate, branches, steady blocks) is prepared by
:mod:`bench.analysis.thermal._ramp_record`.

Uncertainties: the residual of a long static record is coloured (bias instability, drift),
so the fit is a feasible GLS under an AR noise model (:mod:`bench.analysis.thermal._drift_gls`);
τ's and w's standard uncertainties come from the whitened Jacobian with their columns added
(linearised at the estimate), so the linear terms' covariance carries them too. Blocks
before the first branch is known (before the first reversal with w > 0) are left out of
every fit, and so is the first branch's first 2·w_bound of travel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize, signal

import bench.analysis.thermal._drift_gls as drift_gls
from bench.analysis._checks import check_int, check_real
from bench.analysis.thermal._drift_gls import NoiseModel
from bench.analysis.thermal._inputs import TEMPERATURE_LIMITS_C
from bench.analysis.thermal._play import WIDTH_GRID, WidthProfile, memory_known, play_output, width_profile
from bench.analysis.thermal._poly import MAX_ORDER, PolynomialCurve, polynomial_rows
from bench.analysis.thermal._ramp_record import (
    Blocks,
    RampSegment,
    branch_states,
    ramp_rates,
    ramp_segments,
    slope_at,
    steady_blocks,
)
from bench.values import Estimate

MIN_BLOCKS = 40
_GRID_POINTS = 41
_LAG_GRID = 10


@dataclass(frozen=True, eq=False)
class ThermalRampResult:
    """Bias curve, thermal hysteresis and temperature-rate sensitivity from a ramp record.

    Thermal ramp analysis (module docstring). Output units: those of ``output``;
    ``rate_sensitivity`` per °C/min; ``lag_s`` in s (std None when fixed by the caller).
    ``not_separable`` names each term the record could not separate and why. Block-level
    arrays: ``block_*``; ``block_used`` marks the blocks every fit used.

    Attributes
    ----------
    curve : PolynomialCurve
        Bias-vs-temperature curve p(T_e) about ``reference_c`` (output units per °C^j), at
        zero rate and mid-way between the branches.
    hysteresis : Estimate or None
        h, the up-minus-down offset at equal temperature and zero rate, output units; None
        when not separable from the rate term.
    rate_sensitivity : Estimate or None
        k, output units per °C/min; None when not separable.
    lag_s : Estimate
        τ, the element's lag behind the sensor, in s (std None when fixed by the caller or
        not separable).
    hysteresis_width_c : Estimate
        w, the play operator's half width in °C of the element's temperature: a reversal
        switches the branch fully over 2w of travel; std (None when fixed by the caller; 0 is
        the instant switch) = the longer side of the 95 % profile interval / 1.96.
    hysteresis_width_interval_c : tuple of float or None
        The 95 % profile-likelihood interval of w (Δχ² ≤ 3.84), °C; None when fixed.
    branch_offset : Estimate
        h + k·(r_up − r_down): the up-minus-down difference at equal temperature at the
        record's ramp rates, output units (always determined).
    ramp_rates_c_per_min : tuple of float
        ``(r_up, r_down)``: median rate of the up and the down blocks, dwells left out, °C/min.
    not_separable : dict of str to str
        Each term (``"hysteresis"``, ``"rate_sensitivity"``, ``"lag_s"``,
        ``"hysteresis_width_c"``) the record could not separate, with the reason.
    separation_rate : float
        Fraction of the steady rate column outside the span of the curve and branch columns
        (1/√VIF); compared with ``min_separation``.
    separation_lag : float or None
        The same for the lag's column; None when the lag was fixed.
    branch_difference_t_c : ndarray
        Temperature grid over the range both branches cover, in °C.
    branch_difference : ndarray
        Model-free up-minus-down difference of separate branch polynomials on that grid,
        output units.
    branch_difference_std : ndarray
        Its standard uncertainty, output units.
    branch_difference_mean : Estimate
        Its mean over the grid, output units.
    segments : tuple of RampSegment
        Each branch between reversals, with its direction and steady rate.
    order : int
        The curve's order (0 … 3).
    bic_by_order : dict of int to float
        BIC of every order tried.
    noise : NoiseModel
        The fitted AR noise model (white plus Gauss–Markov drift).
    noise_sigma : float
        The white noise's standard deviation, output units.
    dof : int
        Degrees of freedom of the final fit.
    block_s : float
        Averaging block, in s.
    block_t_s : ndarray
        Block mean times, in s.
    block_output : ndarray
        Block mean outputs, output units.
    block_temperature_c : ndarray
        Block mean sensor temperatures, in °C.
    block_rate_c_per_min : ndarray
        The sensor's rate at each block, in °C/min.
    block_branch : ndarray of int
        +1 up, −1 down, 0 before the first branch is known (the dead-band branches of T).
    block_play : ndarray
        z, the fitted play operator's output per block, in [−1, 1].
    block_used : ndarray of bool
        Blocks every fit used.
    block_residual : ndarray
        Output − fitted model per block, output units.
    """

    curve: PolynomialCurve
    hysteresis: Estimate | None
    rate_sensitivity: Estimate | None
    lag_s: Estimate
    hysteresis_width_c: Estimate
    hysteresis_width_interval_c: tuple[float, float] | None
    branch_offset: Estimate
    ramp_rates_c_per_min: tuple[float, float]
    not_separable: dict[str, str]
    separation_rate: float
    separation_lag: float | None
    branch_difference_t_c: np.ndarray
    branch_difference: np.ndarray
    branch_difference_std: np.ndarray
    branch_difference_mean: Estimate
    segments: tuple[RampSegment, ...]
    order: int
    bic_by_order: dict[int, float]
    noise: NoiseModel
    noise_sigma: float
    dof: int
    block_s: float
    block_t_s: np.ndarray
    block_output: np.ndarray
    block_temperature_c: np.ndarray
    block_rate_c_per_min: np.ndarray
    block_branch: np.ndarray
    block_play: np.ndarray
    block_used: np.ndarray
    block_residual: np.ndarray

    def to_dict(self) -> dict:
        def est(e):
            return None if e is None else e.to_dict()
        return {"curve": self.curve.to_dict(), "order": self.order, "hysteresis": est(self.hysteresis),
                "rate_sensitivity": est(self.rate_sensitivity), "lag_s": est(self.lag_s),
                "hysteresis_width_c": est(self.hysteresis_width_c),
                "hysteresis_width_interval_c": (None if self.hysteresis_width_interval_c is None
                                                else list(self.hysteresis_width_interval_c)),
                "branch_offset": est(self.branch_offset), "ramp_rates_c_per_min": list(self.ramp_rates_c_per_min),
                "not_separable": dict(self.not_separable),
                "separation_rate": self.separation_rate, "separation_lag": self.separation_lag,
                "branch_difference_t_c": self.branch_difference_t_c.tolist(),
                "branch_difference": self.branch_difference.tolist(),
                "branch_difference_std": self.branch_difference_std.tolist(),
                "branch_difference_mean": est(self.branch_difference_mean),
                "segments": [vars(s) for s in self.segments],
                "bic_by_order": {str(k): v for k, v in self.bic_by_order.items()},
                "noise": self.noise.to_dict(), "noise_sigma": self.noise_sigma, "dof": self.dof,
                "block_s": self.block_s}


def lag_filter(t: np.ndarray, temp: np.ndarray, lag_s: float) -> np.ndarray:
    """``temp`` through a first-order lag of ``lag_s`` (exact for a piecewise-linear input;
    starts soaked: T_e(t_0) = T(t_0))."""
    if lag_s <= 0.0:
        return temp.copy()
    dt = np.diff(t)
    e = np.exp(-dt / lag_s)
    x = (1.0 - e) * temp[:-1] + np.diff(temp) * (1.0 - lag_s * (1.0 - e) / dt)
    if np.allclose(dt, dt[0], rtol=1e-9):
        out, _ = signal.lfilter([1.0], [1.0, -e[0]], x, zi=[e[0] * temp[0]])
        return np.concatenate([[temp[0]], out])
    out = np.empty_like(temp)
    out[0] = temp[0]
    for i in range(1, temp.size):
        out[i] = e[i - 1] * out[i - 1] + x[i - 1]
    return out


# --------------------------------------------------------------------------- the fit


@dataclass(frozen=True, eq=False)
class _Design:
    """The model's columns on block means of sample-level terms: the element's temperature and
    the play run on the samples, so a switch inside a block counts for the part of it after."""

    t: np.ndarray  # samples
    temp: np.ndarray  # samples, the sensor
    blocks: Blocks
    rate: np.ndarray  # per block, °C/min
    state: np.ndarray  # per block: dead-band branch of T, +1, −1, 0
    used: np.ndarray
    reference_c: float
    with_rate: bool
    cache: dict = field(default_factory=dict)  # T_e per lag: the width's profile reuses it

    def element(self, lag_s: float) -> np.ndarray:
        key = float(lag_s)
        if key not in self.cache:
            if len(self.cache) > 64:
                self.cache.clear()
            self.cache[key] = lag_filter(self.t, self.temp, lag_s)
        return self.cache[key]

    def branch(self, lag_s: float, width_c: float) -> np.ndarray:
        """z per block: the block mean of the play's output on T_e (w > 0), or the dead-band
        branch of T (w = 0)."""
        if width_c <= 0.0:
            return self.state.astype(float)
        return self.blocks.mean(play_output(self.element(lag_s), width_c))

    def columns(self, order: int, lag_s: float, width_c: float) -> np.ndarray:
        te = self.element(lag_s)
        poly = self.blocks.mean(polynomial_rows(te - self.reference_c, order))
        z = self.state.astype(float) if width_c <= 0.0 else self.blocks.mean(play_output(te, width_c))
        cols = [poly, z[:, None] / 2.0]
        if self.with_rate:
            cols.append(self.rate[:, None])
        return np.hstack(cols)


def _profile(rss, lo: float, hi: float, with_zero: bool) -> float:
    """The minimiser of ``rss`` over [lo, hi]: a grid (0 first when ``with_zero``, then
    log-spaced), then a bounded search between the best grid point's neighbours."""
    grid = np.geomspace(lo, hi, _LAG_GRID - 1)
    if with_zero:
        grid = np.concatenate([[0.0], grid])
    values = [rss(g) for g in grid]
    i = int(np.argmin(values))
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    best = optimize.minimize_scalar(rss, bounds=(a, b), method="bounded", options={"xatol": 1e-4 * max(b, 1e-3)})
    return float(best.x) if best.fun <= values[i] else float(grid[i])


def _fit_lag(design: _Design, y: np.ndarray, order: int, width: float, noise: NoiseModel, lag_max_s: float) -> float:
    """τ minimising the whitened residual (0 and log-spaced to lag_max_s, then bounded)."""
    return _profile(lambda lag: drift_gls.gls(design.columns(order, lag, width), y, design.used, noise).rss,
                    lag_max_s / 1000.0, lag_max_s, True)


def _lag_jacobian(design: _Design, order: int, lag: float, width: float, coef: np.ndarray) -> np.ndarray:
    """∂(model)/∂τ with the linear coefficients held (central difference; forward at 0)."""
    h = max(1e-3 * lag, 1e-3 * (design.t[1] - design.t[0]))
    lo, hi = max(lag - h, 0.0), lag + h
    return (design.columns(order, hi, width) @ coef - design.columns(order, lo, width) @ coef) / (hi - lo)


def _width_profile(design: _Design, y: np.ndarray, order: int, lag: float, noise: NoiseModel,
                   lo: float, hi: float, points: int = WIDTH_GRID) -> WidthProfile:
    return width_profile(lambda w: drift_gls.gls(design.columns(order, lag, w), y, design.used, noise), lo, hi,
                         points)


def analyze_thermal_ramp(t_s, output, temperature_c, *, order: int | None = None, reference_c: float = 25.0,
                         block_s: float = 60.0, rate_window_s: float | None = None, reversal_band_c: float = 0.5,
                         lag_s: float | None = None, lag_max_s: float = 7200.0,
                         hysteresis_width_c: float | None = None, hysteresis_width_max_c: float = 15.0,
                         min_separation: float = 0.1, steady_tolerance: float = 0.1,
                         steady_window_s: float = 600.0) -> ThermalRampResult:
    """Bias over temperature, hysteresis and rate sensitivity from a static record over a temperature ramp.

    Analyse a static record over an up-and-down temperature ramp (module docstring).

    ``t_s`` (s, increasing), ``output`` (any unit), ``temperature_c`` (the unit's sensor, °C)
    of one length. ``order`` fixes the curve's order (0 … 3; None: BIC). ``block_s`` (0, 3600]
    the averaging block; ``rate_window_s`` [block_s, record/4] the rate's window (None: block_s);
    ``reversal_band_c`` (0, 20] the dead band for reversals; ``lag_s`` the element's lag behind
    the sensor in s, [0, 1e5], or None to fit it within [0, ``lag_max_s``];
    ``hysteresis_width_c`` the play operator's half width in °C, [0, 50], or None to fit it within
    [``reversal_band_c``/4, ``hysteresis_width_max_c``];
    ``min_separation`` (0, 1), ``steady_tolerance`` (0, 1) and ``steady_window_s``
    [rate_window_s, record/4] the identifiability check. The model
    ``y = p(T_e) + h·z/2 + k·Ṫ + noise`` is fitted by feasible GLS under an AR noise model on
    block means; h and k separate only when the steady rate takes more values than the branch
    explains (ramps at two rates).

    Parameters
    ----------
    t_s : array_like, shape (N,)
        Sample times, in s, strictly increasing; N ≥ 40.
    output : array_like, shape (N,)
        The unit's static output (bias plus a constant input), any unit.
    temperature_c : array_like, shape (N,)
        The unit's own sensor temperature, in °C, within −100 … 200; it must reverse (up and
        down) by more than ``reversal_band_c``.
    order : int, optional
        The curve's order, 0 … 3; None chooses it by BIC.
    reference_c : float, default 25.0
        Reference temperature of the curve, in °C.
    block_s : float, default 60.0
        Averaging block, in s, in (0, 3600]; the record must give ≥ 40 blocks.
    rate_window_s : float, optional
        Window of the rate's least-squares slope about each block's centre, in s, in
        [block_s, record/4]; None: ``block_s`` (the block's mean rate).
    reversal_band_c : float, default 0.5
        Dead band for reversals, in °C, in (0, 20].
    lag_s : float, optional
        The element's lag behind the sensor, in s, in [0, 1e5]; None fits it within
        [0, ``lag_max_s``].
    lag_max_s : float, default 7200.0
        Largest lag fitted, in s, in (0, 1e5].
    hysteresis_width_c : float, optional
        The play operator's half width w, in °C, in [0, 50] (0: the branch switches at once at
        each extremum); None fits it within [``reversal_band_c``/4, ``hysteresis_width_max_c``].
    hysteresis_width_max_c : float, default 15.0
        Largest half width fitted, in °C, in (``reversal_band_c``/4, 50].
    min_separation : float, default 0.1
        Separation below which a term is not separable, in (0, 1].
    steady_tolerance : float, default 0.1
        Rate agreement that makes a block steady, as a fraction of the largest rate, in (0, 1].
    steady_window_s : float, default 600.0
        Distance before and after a block whose rates must agree, in s, in
        [rate_window_s, record/4].

    Returns
    -------
    ThermalRampResult
        The bias curve, hysteresis and rate sensitivity (or why not), their combination, the
        lag, the branch difference curve, the noise model and the block-level arrays.

    Raises
    ------
    ValueError
        If the arrays are not 1-D of one length, finite, with increasing times and ≥ 40
        samples, or the temperature is out of range; a setting is outside its range; the
        record gives fewer than 40 blocks, never reverses by more than ``reversal_band_c``, or
        leaves no up or no down branch to fit; or the branches share no temperature range.

    Examples
    --------
    A 5-h record: chamber air ramping 25 → 70 → −20 °C at 1 °C/min, then 70 and −20 at
    2 °C/min; the unit's case follows it with τ = 300 s. The unit: bias curve, 20 µg
    hysteresis (its branch flips once the case has turned back), 15 µg per °C/min and 2 µg
    of white noise.

    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from bench.analysis.thermal import analyze_thermal_ramp
    >>> t = np.arange(0.0, 18000.0, 10.0)
    >>> air = np.interp(t, [0, 2700, 8100, 10800, 13500, 18000], [25, 70, -20, 70, -20, 25])
    >>> a = np.exp(-10.0 / 300.0)
    >>> case = lfilter([1 - a], [1, -a], air, zi=[a * air[0]])[0]
    >>> rate = np.gradient(case, t) * 60.0  # °C/min
    >>> branch = np.sign(np.interp(t - 300.0, t, rate))
    >>> rng = np.random.default_rng(0)
    >>> y = (1e-3 + 10e-6 * (case - 25) + 3e-8 * (case - 25) ** 2 + 20e-6 / 2 * branch + 15e-6 * rate
    ...      + 2e-6 * rng.standard_normal(t.size))
    >>> r = analyze_thermal_ramp(t, y, case + 0.01 * rng.standard_normal(t.size), lag_s=0.0)
    >>> r.order, r.not_separable
    (2, {})
    >>> round(r.hysteresis.value * 1e6, 1), round(r.rate_sensitivity.value * 1e6, 1)  # µg, µg per °C/min
    (22.1, 14.1)
    >>> bool(abs(r.hysteresis.value - 20e-6) < 2 * r.hysteresis.std)
    True

    The branch switching 300 s after each turn, at 1–2 °C/min, reads as a play of half width
    about 2.3 °C (a switch over 4.6 °C of travel):

    >>> round(r.hysteresis_width_c.value, 1), [round(v, 1) for v in r.hysteresis_width_interval_c]
    (2.3, [2.2, 2.5])
    """
    t = np.asarray(t_s, dtype=float)
    y_raw = np.asarray(output, dtype=float)
    temp_raw = np.asarray(temperature_c, dtype=float)
    if t.ndim != 1 or t.shape != y_raw.shape or t.shape != temp_raw.shape:
        raise ValueError(f"t_s, output and temperature_c must be 1-D of one length, got shapes "
                         f"{t.shape}, {y_raw.shape}, {temp_raw.shape}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y_raw)) and np.all(np.isfinite(temp_raw))):
        raise ValueError("t_s, output and temperature_c must be finite")
    if t.size < MIN_BLOCKS or np.any(np.diff(t) <= 0):
        raise ValueError(f"t_s must be strictly increasing with ≥ {MIN_BLOCKS} samples, got {t.size}")
    lo_t, hi_t = TEMPERATURE_LIMITS_C
    if temp_raw.min() < lo_t or temp_raw.max() > hi_t:
        raise ValueError(f"temperature_c spans {temp_raw.min():g} … {temp_raw.max():g} °C: "
                         f"allowed [{lo_t:g}, {hi_t:g}]")
    span = float(t[-1] - t[0])
    block = check_real("block_s", block_s, 0.0, 3600.0, low_open=True)
    window = block if rate_window_s is None else check_real("rate_window_s", rate_window_s, block,
                                                             max(span / 4, block))
    band = check_real("reversal_band_c", reversal_band_c, 0.0, 20.0, low_open=True)
    ref = check_real("reference_c", reference_c, lo_t, hi_t)
    if order is not None:
        check_int("order", order, 0, MAX_ORDER)
    fixed_lag = None if lag_s is None else check_real("lag_s", lag_s, 0.0, 1e5)
    lag_max = check_real("lag_max_s", lag_max_s, 0.0, 1e5, low_open=True)
    fixed_width = None if hysteresis_width_c is None else check_real("hysteresis_width_c", hysteresis_width_c,
                                                                     0.0, 50.0)
    width_lo = band / 4  # the dead band's noise immunity: a narrower play would switch on noise
    width_max = check_real("hysteresis_width_max_c", hysteresis_width_max_c, width_lo, 50.0, low_open=True)
    min_sep = check_real("min_separation", min_separation, 0.0, 1.0, low_open=True)
    steady_tol = check_real("steady_tolerance", steady_tolerance, 0.0, 1.0, low_open=True)
    steady_w = check_real("steady_window_s", steady_window_s, window, max(span / 4, window))

    blocks = Blocks.of(t, block)
    tb, yb, temp = blocks.mean(t), blocks.mean(y_raw), blocks.mean(temp_raw)
    if tb.size < MIN_BLOCKS:
        raise ValueError(f"the record gives {tb.size} blocks of {block:g} s; at least {MIN_BLOCKS} are needed "
                         "(a shorter block_s or a longer record)")
    rate = 60.0 * slope_at(t, temp_raw, tb, window / 2)
    state, starts = branch_states(temp, band)
    directions = {int(d) for d in state if d != 0}
    if directions != {1, -1}:
        raise ValueError(f"the temperature never reverses by more than reversal_band_c = {band:g} °C "
                         f"(span {temp.min():.4g} … {temp.max():.4g} °C): an up-and-down ramp is needed")
    known = state != 0
    used = known.copy()
    w_bound = width_max if fixed_width is None else fixed_width
    if w_bound > 0:  # the play's memory before the record is unknown (for any w up to the bound)
        used &= memory_known(temp, state, starts, w_bound)
    if not (np.any(used & (state > 0)) and np.any(used & (state < 0))):
        raise ValueError(f"no up or no down branch remains once the first branch's first 2·{w_bound:g} °C are "
                         "left out (the play's memory is unknown before): a longer ramp, a smaller "
                         "hysteresis_width_max_c, or hysteresis_width_c = 0")
    steady_known = known & steady_blocks(tb, rate, steady_w, steady_tol * np.abs(rate[known]).max())
    steady = used & steady_known
    segments = ramp_segments(tb, temp, rate, state, starts, steady_known)

    half = state / 2.0
    base = np.column_stack([polynomial_rows(temp - ref, MAX_ORDER), half])
    sep_rate = drift_gls.separation(rate[steady], base[steady]) if np.any(steady) else 0.0
    not_separable: dict[str, str] = {}
    separable = sep_rate >= min_sep
    if not separable:
        rates = sorted({round(s.rate_c_per_min, 3) for s in segments if s.rate_c_per_min is not None})
        not_separable["hysteresis"] = not_separable["rate_sensitivity"] = (
            f"on the steady blocks the rate is {sep_rate:.3g} < {min_sep:g} away from a function of the branch "
            f"(steady rates {rates} °C/min): up/down ramps at one rate each cannot tell an offset that follows "
            "the branch from one that follows the rate; ramp at two rates")
    # The rate term stays in the model even when it is not separable on the steady blocks, so
    # that its transients are not taken for drift; only an exactly collinear record drops it.
    with_rate = drift_gls.separation(rate[used], base[used]) > 1e-6
    design = _Design(t, temp_raw, blocks, rate, state, used, ref, with_rate)

    # Noise model (REML, jointly with the largest model) and the play's width there, every order
    # under it, then the lag, then the width again at the chosen order and lag.
    start_lag = 0.0 if fixed_lag is None else fixed_lag
    width = width_lo if fixed_width is None else fixed_width
    noise = drift_gls.fit_noise(design.columns(MAX_ORDER, start_lag, width), yb, used)
    if fixed_width is None:
        width = _width_profile(design, yb, MAX_ORDER, start_lag, noise, width_lo, width_max, WIDTH_GRID // 4).width
        noise = drift_gls.fit_noise(design.columns(MAX_ORDER, start_lag, width), yb, used)
    orders = range(MAX_ORDER + 1) if order is None else [order]
    fits = {k: drift_gls.gls(design.columns(k, start_lag, width), yb, used, noise) for k in orders}
    bic = {k: f.bic() for k, f in fits.items()}
    chosen = min(bic, key=lambda k: bic[k])
    lag_value, sep_lag = start_lag, None
    if fixed_lag is None:
        g = _lag_jacobian(design, chosen, 0.0, width, fits[chosen].coefficients)
        x0 = design.columns(chosen, 0.0, width)
        sep_lag = drift_gls.separation(g[steady], x0[steady]) if np.any(g[steady]) else 0.0
        if sep_lag >= min_sep:
            lag_value = _fit_lag(design, yb, chosen, width, noise, lag_max)
            noise = drift_gls.fit_noise(design.columns(chosen, lag_value, width), yb, used)
        else:
            not_separable["lag_s"] = (
                f"the lag's column is {sep_lag:.3g} < {min_sep:g} away from the curve, branch and rate columns "
                "(a lag of the element behind the sensor acts as a rate term unless the curve bends): "
                "fixed at 0, the rate term carries it")
    profile = None
    if fixed_width is None:
        width = _width_profile(design, yb, chosen, lag_value, noise, width_lo, width_max, WIDTH_GRID // 4).width
        noise = drift_gls.fit_noise(design.columns(chosen, lag_value, width), yb, used)
        profile = _width_profile(design, yb, chosen, lag_value, noise, width_lo, width_max)
        width = profile.width
    x = design.columns(chosen, lag_value, width)
    nodes, weights = drift_gls.noise_quadrature(x, yb, used, noise)
    fit = drift_gls.gls_integrated(x, yb, used, noise, nodes, weights)
    extra = []
    if fixed_lag is None and "lag_s" not in not_separable:
        extra.append(("lag", _lag_jacobian(design, chosen, lag_value, width, fit.coefficients)))
    cov, stds = fit.covariance, {}
    if extra:
        # τ's and w's uncertainty from the whitened Jacobian with their columns added (linearised)
        jac = np.column_stack([x] + [g for _, g in extra])
        full = drift_gls.gls_integrated(jac, yb - x @ fit.coefficients, used, noise, nodes, weights)
        k = x.shape[1]
        stds = {name: math.sqrt(full.covariance[k + i, k + i]) for i, (name, _) in enumerate(extra)}
        cov = full.covariance[:k, :k]
    lag_std = stds.get("lag")
    width_std, width_interval = None, None
    if profile is not None:
        # w's doubt carried into the linear terms by the law of total variance over its profile
        spread = profile.betas - fit.coefficients
        cov = cov + (spread.T * profile.weights) @ spread
        width_interval = profile.interval
        width_std = float(max(width - width_interval[0], width_interval[1] - width) / 1.959963984540054)
        if profile.at_edge:
            not_separable["hysteresis_width_c"] = (
                f"the 95 % profile interval of the width, {width_interval[0]:.3g} … {width_interval[1]:.3g} °C, "
                f"reaches the end of the range fitted [{width_lo:g}, {width_max:g}] °C: the record bounds it on "
                "one side only (a small hysteresis, or a switch narrower than the noise can show)")
    n_poly = chosen + 1
    coef = fit.coefficients
    if len(orders) > 1:
        # The order's doubt carried into h and k (law of total variance over the orders, BIC
        # weights at the final τ and w): a curve too straight for a branch that covers part of
        # the range leaks into the branch term, which the selected order's covariance leaves out.
        others = {k: drift_gls.gls(design.columns(k, lag_value, width), yb, used, fit.noise) for k in orders}
        b = np.array([others[k].bic() for k in orders])
        wk = np.exp(-0.5 * (b - b.min()))
        tail = np.array([others[k].coefficients[k + 1:] for k in orders]) - coef[n_poly:]
        cov = cov.copy()
        cov[n_poly:, n_poly:] += (tail.T * (wk / wk.sum())) @ tail
    curve = PolynomialCurve(ref, coef[:n_poly].copy(), cov[:n_poly, :n_poly].copy())
    offset_row = np.zeros(coef.size)
    offset_row[n_poly] = 1.0
    hysteresis = rate_sens = None
    rates_up_down = ramp_rates(rate, state, used)
    if with_rate:
        offset_row[n_poly + 1] = rates_up_down[0] - rates_up_down[1]
    if separable:
        hysteresis = Estimate(float(coef[n_poly]), math.sqrt(cov[n_poly, n_poly]))
        rate_sens = Estimate(float(coef[n_poly + 1]), math.sqrt(cov[n_poly + 1, n_poly + 1]))
    branch_offset = Estimate(float(offset_row @ coef), math.sqrt(max(float(offset_row @ cov @ offset_row), 0.0)))
    # on steady ramp blocks: the difference at the record's ramp rates, not through the turns
    on_ramp = used & steady_known & (np.abs(rate) >= 0.1 * np.abs(rate[used]).max())
    grid, diff, diff_std, diff_mean = _branch_difference(tb, temp, yb, state, on_ramp, chosen, ref, noise)
    resid = yb - x @ coef
    return ThermalRampResult(
        curve=curve, hysteresis=hysteresis, rate_sensitivity=rate_sens,
        lag_s=Estimate(float(lag_value), lag_std), hysteresis_width_c=Estimate(float(width), width_std),
        hysteresis_width_interval_c=width_interval,
        branch_offset=branch_offset, ramp_rates_c_per_min=rates_up_down,
        not_separable=not_separable,
        separation_rate=float(sep_rate), separation_lag=sep_lag, branch_difference_t_c=grid,
        branch_difference=diff, branch_difference_std=diff_std, branch_difference_mean=diff_mean,
        segments=segments, order=chosen, bic_by_order=bic, noise=fit.noise, noise_sigma=fit.sigma,
        dof=fit.dof, block_s=block, block_t_s=tb, block_output=yb, block_temperature_c=temp,
        block_rate_c_per_min=rate, block_branch=state, block_play=design.branch(lag_value, width) if width > 0
        else state.astype(float), block_used=used, block_residual=resid)


def _branch_difference(tb, temp, yb, state, used, order, ref, noise):
    """Up and down branches as separate polynomials of the sensor temperature; their
    difference on a grid over the range both cover, with its standard uncertainty, and its
    mean over the grid."""
    up, dn = used & (state > 0), used & (state < 0)
    lo = max(temp[up].min(), temp[dn].min())
    hi = min(temp[up].max(), temp[dn].max())
    if not lo < hi:
        raise ValueError(f"the up and down branches share no temperature range (up {temp[up].min():.4g} … "
                         f"{temp[up].max():.4g} °C, down {temp[dn].min():.4g} … {temp[dn].max():.4g} °C)")
    rows = polynomial_rows(temp - ref, order)
    x = np.hstack([rows * (state > 0)[:, None], rows * (state < 0)[:, None]])
    fit = drift_gls.gls(x, yb, used, noise)
    grid = np.linspace(lo, hi, _GRID_POINTS)
    g = polynomial_rows(grid - ref, order)
    gd = np.hstack([g, -g])
    diff = gd @ fit.coefficients
    std = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", gd, fit.covariance, gd), 0.0, None))
    m = gd.mean(axis=0)
    mean = Estimate(float(m @ fit.coefficients), math.sqrt(max(float(m @ fit.covariance @ m), 0.0)))
    return grid, diff, std, mean
