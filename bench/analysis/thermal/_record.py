"""Thermal calibration from one continuous record, the element's lag behind the logged sensor fitted.

A chamber record — soaks and ramps, logged by a temperature sensor on the unit's case — with
the unit's output and, optionally, the input applied to it (a rate table's rate, a tilt's g).
The sensing element does not sit at the logged temperature: it lags it. Model, on block
means of ``block_s``::

    τ·dT_e/dt = T_log − T_e                      (the element starts soaked: T_e(t_0) = T_log(t_0))
    y = S(T_e)·x + b(T_e) [+ h·z/2] [+ k·Ṫ_log] + noise    S, b = Σ s_j, b_j (T − T_ref)^j

* x the applied input (None: a static unit, S·x folded into b); y the output.
* S, the **scale factor**, and b, the **bias in output units**, are polynomials of the
  element's estimated temperature, orders 0 … 3 each by BIC; in the compensation file's
  terms (output = SF(T)·(x + B(T))) SF = S and B = b/S, the bias in input units (its power
  series about T_ref, exact to the orders kept; the remainder is (s_1/s_0)^(n+1)·b_0·u^(n+1),
  ~10⁻⁹ of b_0 per °C for a 150 ppm/°C scale factor).
* τ, the **lag**, by profiling the whitened residual over τ (a grid from 0 to ``lag_max_s``,
  then a bounded search) — plain least squares against T_log reads the TC of a lagged curve,
  and on a ramp of rate r the element is τ·r behind the sensor. It is identified where the
  sensor's rate changes (a ramp starting or ending: the element catches up in ~τ): its column
  must stand ``min_separation`` (1/√VIF, as the ramp analysis) away from the others, or τ is
  fixed at 0 with the reason.
* h·z/2 (``hysteresis=True``): the thermal hysteresis as the ramp analysis models it, z a play
  operator of half width w on T_e (:mod:`bench.analysis.thermal._play`), w profiled.
* k·Ṫ_log (``rate_term=True``): a gradient or Shupe sensitivity. For a straight bias curve
  it is the same column as the lag on a steady ramp; only the transients tell them apart.
* noise: white plus a Gauss–Markov drift, (φ, ρ) by REML jointly with the regression, and
  the covariance integrated over their uncertainty (:mod:`bench.analysis.thermal._drift_gls`);
  τ's standard uncertainty comes from the whitened Jacobian with its column added, so the
  coefficients' covariance carries the lag's uncertainty too.

Reported at ``reference_c``: the bias TC dB/dT (input units per °C) and the scale factor TC
(dS/dT)/S (ppm/°C), each by the delta method from the coefficients' covariance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

import bench.analysis.thermal._drift_gls as drift_gls
from bench.analysis._checks import check_int, check_real
from bench.analysis.thermal._compensation import CompensationModel, QuantityCompensation
from bench.analysis.thermal._drift_gls import NoiseModel
from bench.analysis.thermal._inputs import TEMPERATURE_LIMITS_C
from bench.analysis.thermal._play import WIDTH_GRID, WidthProfile, memory_known, play_output, width_profile
from bench.analysis.thermal._poly import MAX_ORDER, PolynomialCurve, polynomial_rows
from bench.analysis.thermal._ramp import lag_filter
from bench.analysis.thermal._ramp_record import Blocks, branch_states, slope_at
from bench.analysis.thermal._soak import SoakCriterion
from bench.values import Estimate

MIN_BLOCKS = 40
# A temperature coefficient needs a span well beyond the chamber's uniformity (±0.5 °C for a
# good chamber, IEC 60068-3-5): 10× that, so the gradient misreads the slope by ≤ 10 %.
MIN_SPAN_C = 5.0
_LAG_GRID = 10
_PPM = 1e6
_COMPLEX_STEP = 1e-30
_START_WINDOW_S = 600.0
_REVERSAL_BAND_C = 0.5  # the ramp analysis's dead band: sensor noise cannot flip a branch


@dataclass(frozen=True, eq=False)
class ThermalRecordResult:
    """Bias and scale factor over the element's temperature, and the element's lag, from one record.

    Thermal record analysis (module docstring). Output units: those of ``output``; input
    units: those of ``applied`` (the output's without it).

    Attributes
    ----------
    bias_tc : Estimate
        dB/dT at ``reference_c``: the bias in input units per °C (output units per °C
        without ``applied``).
    scale_factor_tc_ppm_per_c : Estimate or None
        (dS/dT)/S at ``reference_c``, ppm/°C; None without ``applied``.
    lag_s : Estimate
        τ, the element's lag behind the logged sensor, in s (std None when fixed by the
        caller or not separable).
    bias_curve : PolynomialCurve
        B(T) = b/S about ``reference_c``, input units per °C^j (b itself without ``applied``).
    scale_factor_curve : PolynomialCurve or None
        S(T), output units per input unit per °C^j; None without ``applied``.
    output_bias_curve : PolynomialCurve
        b(T), the bias in output units as fitted.
    rate_sensitivity : Estimate or None
        k, output units per °C/min of the logged sensor (``rate_term=True`` only).
    bias_order, scale_factor_order : int
        Orders chosen (scale_factor_order 0 without ``applied``).
    bic_by_order : dict of str to float
        BIC of each ``"bias_order,scale_factor_order"`` tried.
    not_separable : dict of str to str
        Each term (``"lag_s"``, ``"hysteresis"``, ``"hysteresis_width_c"``) the record could not
        tell, with the reason.
    separation_lag : float or None
        The lag column's separation from the others (1/√VIF); None when fixed.
    warnings : tuple of str
        Conditions the fit assumes but the record does not show (a start that is not soaked).
    hysteresis : Estimate or None
        h, the up-minus-down offset once switched fully, output units (``hysteresis=True``
        only; not in the compensation file).
    hysteresis_width_c : Estimate or None
        w, the play's half width, °C; σ the longer side of the 95 % profile interval / 1.96.
    hysteresis_width_interval_c : tuple of float or None
        The 95 % profile-likelihood interval of w, °C.
    reference_c : float
        Reference temperature, °C.
    element_range_c : tuple of float
        ``(min, max)`` of the element's estimated temperature over the blocks used, °C.
    noise : NoiseModel
        The fitted noise model (white plus Gauss–Markov drift, per block).
    noise_sigma : float
        The white noise's standard deviation per block, output units.
    dof : int
        Degrees of freedom of the final fit.
    block_s : float
        Averaging block, s.
    block_t_s, block_output, block_temperature_c, block_element_c, block_applied, block_residual : ndarray
        Per block: mean time (s), output, logged temperature (°C), the element's estimate (°C),
        applied input (None without it) and output − model (output units).
    block_used : ndarray of bool
        Blocks the fit used.
    """

    bias_tc: Estimate
    scale_factor_tc_ppm_per_c: Estimate | None
    lag_s: Estimate
    bias_curve: PolynomialCurve
    scale_factor_curve: PolynomialCurve | None
    output_bias_curve: PolynomialCurve
    rate_sensitivity: Estimate | None
    bias_order: int
    scale_factor_order: int
    bic_by_order: dict[str, float]
    not_separable: dict[str, str]
    separation_lag: float | None
    warnings: tuple[str, ...]
    hysteresis: Estimate | None
    hysteresis_width_c: Estimate | None
    hysteresis_width_interval_c: tuple[float, float] | None
    reference_c: float
    element_range_c: tuple[float, float]
    noise: NoiseModel
    noise_sigma: float
    dof: int
    block_s: float
    block_t_s: np.ndarray
    block_output: np.ndarray
    block_temperature_c: np.ndarray
    block_element_c: np.ndarray
    block_applied: np.ndarray | None
    block_residual: np.ndarray
    block_used: np.ndarray

    def element_temperature(self, t_s, temperature_c) -> np.ndarray:
        """The element's temperature (°C) estimated from a logged record through the fitted lag
        (the record starting soaked): what the compensation's curves take."""
        t = np.asarray(t_s, dtype=float)
        temp = np.asarray(temperature_c, dtype=float)
        check_record(t, temp, None, None)
        return lag_filter(t, temp, self.lag_s.value)

    def compensation_model(self, *, unit_serial: str, unit_model: str, input_unit: str, output_unit: str,
                           valid_range_c: tuple[float, float] | None = None, created: str = "",
                           notes: str = "") -> CompensationModel:
        """The compensation file's model: ``k0`` (bias, B(T) in ``input_unit``) and, with an
        applied input, ``k1`` (scale factor S(T) in ``output_unit``/``input_unit``), both of the
        element's temperature (``temperature_source = "element"``) with ``element_lag_s`` = τ̂,
        ``valid_range_c`` by default the element's range over the record. Write it with
        :func:`~bench.analysis.thermal.compensation_to_toml`."""
        rng = self.element_range_c if valid_range_c is None else valid_range_c
        grid = np.linspace(rng[0], rng[1], 201) if rng[0] < rng[1] else np.array([rng[0]])
        used = self.block_used
        s0 = 1.0 if self.scale_factor_curve is None else float(self.scale_factor_curve.coefficients[0])
        resid = self.block_residual[used] / s0
        quantities = [_quantity("k0", "bias", input_unit, self.bias_curve, resid, grid, int(used.sum()))]
        if self.scale_factor_curve is not None:
            x = self.block_applied[used] if self.block_applied is not None else np.ones(int(used.sum()))
            big = np.abs(x) >= 0.5 * np.abs(x).max()
            sf_resid = self.block_residual[used][big] / x[big]
            quantities.insert(0, _quantity("k1", "scale_factor", f"{output_unit}/{input_unit}",
                                           self.scale_factor_curve, sf_resid, grid, int(used.sum())))
        lag_note = (f"element temperature = logged sensor through a first-order lag of {self.lag_s.value:.6g} s "
                    "(tau*dTe/dt = T_log - Te)")
        return CompensationModel(
            unit_serial=unit_serial, unit_model=unit_model, temperature_source="element",
            reference_c=self.reference_c, valid_range_c=rng, input_unit=input_unit,
            output_unit=output_unit, quantities=tuple(quantities), created=created,
            notes=(notes + "; " if notes else "") + lag_note, element_lag_s=float(self.lag_s.value))

    def to_dict(self) -> dict:
        def est(e):
            return None if e is None else e.to_dict()

        def arr(a):
            return None if a is None else a.tolist()
        return {"bias_tc": est(self.bias_tc), "scale_factor_tc_ppm_per_c": est(self.scale_factor_tc_ppm_per_c),
                "lag_s": est(self.lag_s), "bias_curve": self.bias_curve.to_dict(),
                "scale_factor_curve": None if self.scale_factor_curve is None else self.scale_factor_curve.to_dict(),
                "output_bias_curve": self.output_bias_curve.to_dict(),
                "rate_sensitivity": est(self.rate_sensitivity), "bias_order": self.bias_order,
                "scale_factor_order": self.scale_factor_order, "bic_by_order": dict(self.bic_by_order),
                "not_separable": dict(self.not_separable), "separation_lag": self.separation_lag,
                "warnings": list(self.warnings), "hysteresis": est(self.hysteresis),
                "hysteresis_width_c": est(self.hysteresis_width_c),
                "hysteresis_width_interval_c": (None if self.hysteresis_width_interval_c is None
                                                else list(self.hysteresis_width_interval_c)),
                "reference_c": self.reference_c,
                "element_range_c": list(self.element_range_c), "noise": self.noise.to_dict(),
                "noise_sigma": self.noise_sigma, "dof": self.dof, "block_s": self.block_s,
                "block_t_s": arr(self.block_t_s), "block_output": arr(self.block_output),
                "block_temperature_c": arr(self.block_temperature_c), "block_element_c": arr(self.block_element_c),
                "block_applied": arr(self.block_applied), "block_residual": arr(self.block_residual),
                "block_used": self.block_used.tolist()}


def _quantity(name, role, unit, curve: PolynomialCurve, resid, grid, n_points) -> QuantityCompensation:
    resid = np.asarray(resid, dtype=float)
    return QuantityCompensation(
        name=name, role=role, unit=unit, coefficients=curve.coefficients, covariance=curve.covariance,
        residual_rms=float(np.sqrt(np.mean(resid**2))) if resid.size else 0.0,
        residual_max_abs=float(np.abs(resid).max()) if resid.size else 0.0,
        prediction_std_max=float(curve.std(grid).max()), n_points=n_points, order_selection="bic")


# --------------------------------------------------------------------------- the record


def check_record(t: np.ndarray, temp: np.ndarray, y: np.ndarray | None, x: np.ndarray | None) -> None:
    """Shapes, finiteness, monotonic time and the temperature range (ValueError naming the
    array, the first bad index and what is allowed)."""
    named = {"t_s": t, "temperature_c": temp, "output": y, "applied": x}
    for name, a in named.items():
        if a is None:
            continue
        if a.ndim != 1 or a.shape != t.shape:
            raise ValueError(f"{name} has shape {a.shape}: allowed 1-D of the length of t_s ({t.size})")
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise ValueError(f"{name}[{bad[0]}] = {float(a[bad[0]])!r}: allowed finite numbers only "
                             f"({bad.size} non-finite of {a.size})")
    back = np.flatnonzero(np.diff(t) <= 0)
    if back.size:
        i = int(back[0])
        raise ValueError(f"t_s[{i + 1}] = {float(t[i + 1])!r} s does not follow t_s[{i}] = {float(t[i])!r} s: "
                         "allowed strictly increasing times")
    lo, hi = TEMPERATURE_LIMITS_C
    out = np.flatnonzero((temp < lo) | (temp > hi))
    if out.size:
        raise ValueError(f"temperature_c[{out[0]}] = {float(temp[out[0]])!r} °C: allowed [{lo:g}, {hi:g}]")


@dataclass(frozen=True, eq=False)
class _Record:
    """Samples and their blocks; the design's columns per lag, cached."""

    t: np.ndarray
    temp: np.ndarray
    x: np.ndarray | None
    blocks: Blocks
    reference_c: float
    rate: np.ndarray | None  # °C/min of the logged sensor per kept block, or None
    cache: dict

    def block_mean(self, a: np.ndarray) -> np.ndarray:
        return self.blocks.mean(a)

    def element(self, lag: float) -> np.ndarray:
        key = ("element", float(lag))
        if key not in self.cache:
            self.cache[key] = lag_filter(self.t, self.temp, lag)
        return self.cache[key]

    def powers(self, lag: float) -> np.ndarray:
        """Block means of u^j and x·u^j, j = 0 … 3, u = T_e − T_ref (columns 0–3, 4–7)."""
        key = float(lag)
        if key not in self.cache:
            u = polynomial_rows(self.element(lag) - self.reference_c, MAX_ORDER)
            cols = u if self.x is None else np.hstack([u, u * self.x[:, None]])
            if len(self.cache) > 128:
                self.cache.clear()
            self.cache[key] = self.block_mean(cols)
        return self.cache[key]

    def columns(self, bias_order: int, sf_order: int, lag: float, width: float | None = None) -> np.ndarray:
        """[b_0 … b_nb | s_0 … s_ns (with x) | z/2 (a play of half width ``width``) | Ṫ (rate term)]."""
        p = self.powers(lag)
        cols = [p[:, :bias_order + 1]]
        if self.x is not None:
            cols.append(p[:, MAX_ORDER + 1:MAX_ORDER + 2 + sf_order])
        if width is not None:
            cols.append(self.block_mean(play_output(self.element(lag), width))[:, None] / 2.0)
        if self.rate is not None:
            cols.append(self.rate[:, None])
        return np.hstack(cols)


def _fit_lag(rec: _Record, y, used, nb, ns, width, noise: NoiseModel, lag_max: float) -> float:
    """τ minimising the whitened residual: a grid (0 and log-spaced to lag_max), then a bounded
    search between the best grid point's neighbours."""
    def rss(lag):
        try:
            return drift_gls.gls(rec.columns(nb, ns, lag, width), y, used, noise).rss
        except ValueError:  # a lag that makes the play's column constant: not a candidate
            return math.inf
    grid = np.concatenate([[0.0], np.geomspace(lag_max / 1000.0, lag_max, _LAG_GRID - 1)])
    values = [rss(g) for g in grid]
    i = int(np.argmin(values))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    best = optimize.minimize_scalar(rss, bounds=(lo, hi), method="bounded",
                                    options={"xatol": 1e-4 * max(hi, 1.0)})
    return float(best.x) if best.fun <= values[i] else float(grid[i])


def _lag_jacobian(rec: _Record, nb, ns, width, lag, coef) -> np.ndarray:
    """∂(model)/∂τ with the linear coefficients held (central difference; forward at 0)."""
    dt = float(np.median(np.diff(rec.t)))
    h = max(1e-3 * lag, 1e-2 * dt, 1e-3)
    lo, hi = max(lag - h, 0.0), lag + h
    return (rec.columns(nb, ns, hi, width) @ coef - rec.columns(nb, ns, lo, width) @ coef) / (hi - lo)


def _width(rec: _Record, y, used, nb, ns, lag, noise: NoiseModel, lo, hi, points) -> WidthProfile:
    return width_profile(lambda w: drift_gls.gls(rec.columns(nb, ns, lag, w), y, used, noise), lo, hi, points)


def _tcs(coef: np.ndarray, nb: int, ns: int, with_sf: bool) -> tuple[float, float]:
    """Bias TC (input units per °C) and SF TC (ppm/°C) at T_ref from one fit's coefficients."""
    b1 = coef[1] if nb >= 1 else 0.0
    if not with_sf:
        return float(b1), 0.0
    s0, s1 = coef[nb + 1], (coef[nb + 2] if ns >= 1 else 0.0)
    return float(b1 / s0 - coef[0] * s1 / s0**2), float(_PPM * s1 / s0)


def _series_ratio(b: np.ndarray, s: np.ndarray, order: int) -> np.ndarray:
    """Power-series coefficients of b(u)/s(u) to ``order`` (complex-safe)."""
    c = np.zeros(order + 1, dtype=np.result_type(b, s))
    for k in range(order + 1):
        acc = b[k] if k < b.size else 0.0
        for i in range(1, min(k, s.size - 1) + 1):
            acc = acc - s[i] * c[k - i]
        c[k] = acc / s[0]
    return c


def _ratio_curve(b, s, cov, ref, order) -> PolynomialCurve:
    """B = b/S as a polynomial curve, its covariance by the complex-step Jacobian."""
    theta = np.concatenate([b, s])
    nb = b.size
    value = _series_ratio(b, s, order)
    jac = np.empty((order + 1, theta.size))
    for i in range(theta.size):
        th = theta.astype(complex)
        th[i] += 1j * _COMPLEX_STEP
        jac[:, i] = _series_ratio(th[:nb], th[nb:], order).imag / _COMPLEX_STEP
    return PolynomialCurve(ref, value.real.astype(float), jac @ cov @ jac.T)


def analyze_thermal_record(t_s, output, temperature_c, applied=None, *, reference_c: float = 25.0,
                           block_s: float = 60.0, bias_order: int | None = None,
                           scale_factor_order: int | None = None, lag_s: float | None = None,
                           lag_max_s: float = 7200.0, rate_term: bool = False, rate_window_s: float | None = None,
                           hysteresis: bool = False, hysteresis_width_max_c: float = 15.0,
                           min_separation: float = 0.1) -> ThermalRecordResult:
    """Bias and scale factor over temperature, and the element's lag, from one chamber record.

    Fit a continuous record of soaks and/or ramps (module docstring): the element's
    temperature is the logged one through a fitted first-order lag τ, and the bias (and, with
    ``applied``, the scale factor) are polynomials of it, fitted by feasible GLS under a
    white-plus-drift noise model on block means. Temperature coefficients are read at
    ``reference_c``.

    Parameters
    ----------
    t_s : array_like, shape (N,)
        Sample times, in s, strictly increasing.
    output : array_like, shape (N,)
        The unit's output, any unit.
    temperature_c : array_like, shape (N,)
        The logged temperature (a sensor on the case, or the unit's own), in °C, within
        −100 … 200, spanning at least 5 °C. The record should start soaked (the element
        is taken to start at the logged temperature).
    applied : array_like, shape (N,), optional
        The input applied (rate table °/s, g …), taking two or more values; with it the
        scale factor and its temperature coefficient are fitted too. None: a static unit.
    reference_c : float, default 25.0
        Reference temperature of the curves and the TCs, in °C, −100 … 200.
    block_s : float, default 60.0
        Averaging block, s, in (0, 3600]; the record must give ≥ 40 blocks.
    bias_order, scale_factor_order : int, optional
        Fixed orders, 0 … 3; None chooses each by BIC.
    lag_s : float, optional
        Fixed lag, s, in [0, 1e5]; None fits it within [0, ``lag_max_s``].
    lag_max_s : float, default 7200.0
        Largest lag fitted, s, in (0, 1e5].
    rate_term : bool, default False
        Add k·Ṫ_log (a gradient or Shupe sensitivity) to the model.
    rate_window_s : float, optional
        Window of the logged temperature's least-squares slope about each block's centre (the
        rate term, and the soaked-start check), s, in [block_s, record/4]; None: ``block_s``.
    hysteresis : bool, default False
        Add the thermal hysteresis h·z/2, z a play operator of half width w on the element's
        temperature, w profiled within [0.125, ``hysteresis_width_max_c``] °C (as
        :func:`analyze_thermal_ramp`); the first branch's first 2·``hysteresis_width_max_c``
        of travel is then left out (the play's memory before the record is unknown).
    hysteresis_width_max_c : float, default 15.0
        Largest half width fitted, °C, in (0.125, 50].
    min_separation : float, default 0.1
        Separation (1/√VIF) the lag's column needs from the others, in (0, 1].

    Returns
    -------
    ThermalRecordResult
        Bias TC, scale factor TC (ppm/°C) and lag with standard uncertainties, the curves, the
        orders and their BIC, the noise model and block-level arrays;
        :meth:`~ThermalRecordResult.compensation_model` gives the compensation file.

    Raises
    ------
    ValueError
        If an array is not 1-D of the length of ``t_s`` or not finite (the message names the
        first bad index), times are not strictly increasing, a temperature is outside
        −100 … 200 °C or the logged span is under 5 °C, ``applied`` is constant, the record
        gives fewer than 40 blocks, a setting is outside its range, or the terms are not
        separable on the record.

    Examples
    --------
    A gyro on a rate table stepping 0, ±50, ±100 °/s every 90 s; the chamber soaks at 25 °C,
    ramps to 60, soaks, ramps to −20, soaks; the logged sensor leads the element by 400 s.
    True bias TC 2.0e-3 °/s/°C, SF TC 150 ppm/°C.

    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from bench.analysis.thermal import analyze_thermal_record
    >>> t = np.arange(0.0, 20000.0, 2.0)
    >>> logged = np.interp(t, [0, 1800, 4200, 7200, 12000, 20000], [25, 25, 60, 60, -20, -20])
    >>> a = np.exp(-2.0 / 400.0)
    >>> element = lfilter([1 - a], [1, -a], logged, zi=[a * logged[0]])[0]
    >>> rate = np.array([0.0, 50.0, -50.0, 100.0, -100.0])[(t // 90).astype(int) % 5]
    >>> sf = 1.0 + 150e-6 * (element - 25)
    >>> rng = np.random.default_rng(1)
    >>> y = sf * (rate + 0.05 + 2.0e-3 * (element - 25)) + 5e-3 * rng.standard_normal(t.size)
    >>> r = analyze_thermal_record(t, y, logged + 0.02 * rng.standard_normal(t.size), rate)
    >>> round(r.lag_s.value), bool(abs(r.lag_s.value - 400.0) < 2 * r.lag_s.std)
    (399, True)
    >>> round(r.bias_tc.value * 1e3, 3), round(r.scale_factor_tc_ppm_per_c.value, 1)  # °/s/°C ×1e3, ppm/°C
    (2.002, 150.0)
    >>> r.bias_order, r.scale_factor_order  # the bias in output units, S·B, bends with S
    (2, 1)

    The compensation file: curves of the element's temperature, the lag stated with them.

    >>> from bench.analysis.thermal import compensation_to_toml
    >>> model = r.compensation_model(unit_serial="G-0001", unit_model="FOG-1", input_unit="deg/s",
    ...                              output_unit="deg/s")
    >>> model.temperature_source, round(model.element_lag_s)
    ('element', 399)
    >>> "element_lag_s = " in compensation_to_toml(model)
    True
    """
    t = np.asarray(t_s, dtype=float)
    temp = np.asarray(temperature_c, dtype=float)
    y_raw = np.asarray(output, dtype=float)
    x = None if applied is None else np.asarray(applied, dtype=float)
    if t.ndim != 1:
        raise ValueError(f"t_s has shape {t.shape}: allowed 1-D")
    if t.size < MIN_BLOCKS:
        raise ValueError(f"t_s has {t.size} samples: at least {MIN_BLOCKS} are needed")
    check_record(t, temp, y_raw, x)
    span_c = float(temp.max() - temp.min())
    if span_c < MIN_SPAN_C:
        raise ValueError(f"temperature_c spans {span_c:.3g} °C ({temp.min():.4g} … {temp.max():.4g}): "
                         f"allowed ≥ {MIN_SPAN_C:g} °C to read a temperature coefficient")
    if x is not None and np.ptp(x) == 0.0:
        raise ValueError(f"applied is constant at {float(x[0])!r}: a scale factor needs two or more input levels "
                         "(pass applied=None to fit the bias only)")
    span = float(t[-1] - t[0])
    block = check_real("block_s", block_s, 0.0, 3600.0, low_open=True)
    ref = check_real("reference_c", reference_c, *TEMPERATURE_LIMITS_C)
    fixed_b = None if bias_order is None else check_int("bias_order", bias_order, 0, MAX_ORDER)
    fixed_s = None if scale_factor_order is None else check_int("scale_factor_order", scale_factor_order, 0,
                                                                  MAX_ORDER)
    fixed_lag = None if lag_s is None else check_real("lag_s", lag_s, 0.0, 1e5)
    lag_max = check_real("lag_max_s", lag_max_s, 0.0, 1e5, low_open=True)
    min_sep = check_real("min_separation", min_separation, 0.0, 1.0, low_open=True)
    window = block if rate_window_s is None else check_real("rate_window_s", rate_window_s, block,
                                                             max(span / 4, block))

    blocks = Blocks.of(t, block)
    if int(blocks.full.sum()) < MIN_BLOCKS:
        raise ValueError(f"the record gives {int(blocks.full.sum())} blocks of {block:g} s; at least {MIN_BLOCKS} "
                         "are needed (a shorter block_s or a longer record)")
    rec = _Record(t, temp, x, blocks, ref, None, {})
    tb, yb, tempb = rec.block_mean(t), rec.block_mean(y_raw), rec.block_mean(temp)
    xb = None if x is None else rec.block_mean(x)
    if xb is not None and np.ptp(xb) <= 1e-12 * max(np.abs(xb).max(), 1e-300):
        raise ValueError(f"applied averages to one level per {block:g} s block ({xb[0]:.6g}): a scale factor "
                         "needs input levels held for whole blocks (a longer dwell or a shorter block_s)")
    rate = 60.0 * slope_at(t, temp, tb, window / 2)
    if rate_term:
        rec = _Record(t, temp, x, blocks, ref, rate, {})
    used = np.ones(tb.size, dtype=bool)
    warnings = []
    not_separable: dict[str, str] = {}
    width: float | None = None
    width_lo = _REVERSAL_BAND_C / 4  # the dead band's noise immunity, as the ramp analysis
    width_max = check_real("hysteresis_width_max_c", hysteresis_width_max_c, width_lo, 50.0, low_open=True)
    if hysteresis:
        state, starts = branch_states(tempb, _REVERSAL_BAND_C)
        if {int(d) for d in state if d} != {1, -1}:
            not_separable["hysteresis"] = (f"the logged temperature never reverses by more than {_REVERSAL_BAND_C:g} "
                                           "°C: no branch to switch")
        else:
            used = memory_known(tempb, state, starts, width_max)
            if int(used.sum()) < MIN_BLOCKS:
                raise ValueError(f"{int(used.sum())} blocks remain once the first branch's first 2·{width_max:g} °C "
                                 f"are left out (the play's memory is unknown before); at least {MIN_BLOCKS} are "
                                 "needed: a longer record, a smaller hysteresis_width_max_c, or hysteresis=False")
            width = width_lo
    # Soaked at the start: the soak criterion's default rate (SoakCriterion, 0.05 °C/min) over
    # the first 10 min (or quarter of the record) of the logged temperature.
    head = min(_START_WINDOW_S, span / 4)
    start_rate = 60.0 * float(slope_at(t, temp, np.array([t[0] + head / 2]), head / 2)[0])
    if abs(start_rate) > SoakCriterion().max_rate_c_per_min:
        warnings.append(f"the record does not start soaked (logged rate {start_rate:.3g} °C/min over its first "
                        f"{head:g} s, allowed ≤ {SoakCriterion().max_rate_c_per_min:g}): the element is taken to "
                        "start at the logged temperature, so the first few lags are biased")

    nb_top = MAX_ORDER if fixed_b is None else fixed_b
    ns_top = (MAX_ORDER if fixed_s is None else fixed_s) if x is not None else 0
    # Noise and a first lag (and play width) under the largest model, the orders by BIC there,
    # then the lag again, then the width at the chosen orders and lag.
    lag0 = 0.0 if fixed_lag is None else fixed_lag
    noise = drift_gls.fit_noise(rec.columns(nb_top, ns_top, lag0, width), yb, used)
    if width is not None:
        width = _width(rec, yb, used, nb_top, ns_top, lag0, noise, width_lo, width_max, WIDTH_GRID // 4).width
        noise = drift_gls.fit_noise(rec.columns(nb_top, ns_top, lag0, width), yb, used)
    if fixed_lag is None:
        lag0 = _fit_lag(rec, yb, used, nb_top, ns_top, width, noise, lag_max)
        noise = drift_gls.fit_noise(rec.columns(nb_top, ns_top, lag0, width), yb, used)
    b_orders = range(MAX_ORDER + 1) if fixed_b is None else [fixed_b]
    s_orders = ([0] if x is None else range(MAX_ORDER + 1)) if fixed_s is None else [fixed_s]
    bic: dict[str, float] = {}
    for nb in b_orders:
        for ns in s_orders:
            bic[f"{nb},{ns}"] = drift_gls.gls(rec.columns(nb, ns, lag0, width), yb, used, noise).bic()
    nb, ns = (int(v) for v in min(bic, key=lambda k: bic[k]).split(","))
    lag_value, sep_lag = lag0, None
    if fixed_lag is None:
        fit0 = drift_gls.gls(rec.columns(nb, ns, lag0, width), yb, used, noise)
        g = _lag_jacobian(rec, nb, ns, width, lag0, fit0.coefficients)
        sep_lag = drift_gls.separation(g[used], rec.columns(nb, ns, lag0, width)[used]) if np.any(g) else 0.0
        if sep_lag >= min_sep:
            lag_value = _fit_lag(rec, yb, used, nb, ns, width, noise, lag_max)
            noise = drift_gls.fit_noise(rec.columns(nb, ns, lag_value, width), yb, used)
        else:
            lag_value = 0.0
            not_separable["lag_s"] = (
                f"the lag's column is {sep_lag:.3g} < {min_sep:g} away from the curves' columns (the logged "
                "temperature's rate hardly changes, or the curves are flat): fixed at 0")
    profile = None
    if width is not None:
        width = _width(rec, yb, used, nb, ns, lag_value, noise, width_lo, width_max, WIDTH_GRID // 4).width
        noise = drift_gls.fit_noise(rec.columns(nb, ns, lag_value, width), yb, used)
        profile = _width(rec, yb, used, nb, ns, lag_value, noise, width_lo, width_max, WIDTH_GRID)
        width = profile.width
    xd = rec.columns(nb, ns, lag_value, width)
    nodes, weights = drift_gls.noise_quadrature(xd, yb, used, noise)
    fit = drift_gls.gls_integrated(xd, yb, used, noise, nodes, weights)
    cov, lag_std = fit.covariance, None
    if fixed_lag is None and "lag_s" not in not_separable:
        jac = np.column_stack([xd, _lag_jacobian(rec, nb, ns, width, lag_value, fit.coefficients)])
        both = drift_gls.gls_integrated(jac, yb - xd @ fit.coefficients, used, noise, nodes, weights)
        lag_std = math.sqrt(both.covariance[-1, -1])
        cov = both.covariance[:-1, :-1]
    coef = fit.coefficients
    hyst = width_est = None
    if profile is not None and width is not None:
        # w's doubt carried into every coefficient by the law of total variance over its profile
        spread = profile.betas - coef
        cov = cov + (spread.T * profile.weights) @ spread
        ip = nb + 1 + (ns + 1 if x is not None else 0)
        hyst = Estimate(float(coef[ip]), math.sqrt(cov[ip, ip]))
        lo_w, hi_w = profile.interval
        width_est = Estimate(width, max(width - lo_w, hi_w - width) / 1.959963984540054)
        if profile.at_edge:
            not_separable["hysteresis_width_c"] = (
                f"the 95 % profile interval of the width, {lo_w:.3g} … {hi_w:.3g} °C, reaches the end of the range "
                f"fitted [{width_lo:g}, {width_max:g}] °C: the record bounds it on one side only")
    ib = slice(0, nb + 1)
    out_bias = PolynomialCurve(ref, coef[ib].copy(), cov[ib, ib].copy())
    rate_sens = None
    if rate_term:
        rate_sens = Estimate(float(coef[-1]), math.sqrt(cov[-1, -1]))
    sf_curve = sf_tc = None
    if x is None:
        bias_curve = out_bias
    else:
        js = slice(nb + 1, nb + 2 + ns)
        sf_curve = PolynomialCurve(ref, coef[js].copy(), cov[js, js].copy())
        s0 = float(coef[nb + 1])
        if s0 == 0.0:
            raise ValueError("the fitted scale factor is 0 at reference_c: the output does not follow applied")
        sf_tc = sf_curve.relative_slope_ppm_per_c(ref)
        keep = np.r_[np.arange(nb + 1), np.arange(nb + 1, nb + 2 + ns)]
        bias_curve = _ratio_curve(coef[ib], coef[js], cov[np.ix_(keep, keep)], ref, min(MAX_ORDER, nb + ns))
    bias_tc = bias_curve.slope_at(ref)
    if len(bic) > 1:
        # The orders' doubt carried into the TCs (law of total variance over the orders, BIC
        # weights at the final τ): a curve one order too straight tilts its slope at T_ref.
        spread_b = spread_s = 0.0
        scores = {}
        for key in bic:
            kb, ks = (int(v) for v in key.split(","))
            f = drift_gls.gls(rec.columns(kb, ks, lag_value, width), yb, used, fit.noise)
            scores[key] = (f.bic(), _tcs(f.coefficients, kb, ks, x is not None))
        b = np.array([v[0] for v in scores.values()])
        wk = np.exp(-0.5 * (b - b.min()))
        wk /= wk.sum()
        for w_i, (_, (tc_b, tc_s)) in zip(wk, scores.values()):
            spread_b += w_i * (tc_b - bias_tc.value) ** 2
            if sf_tc is not None:
                spread_s += w_i * (tc_s - sf_tc.value) ** 2
        bias_tc = Estimate(bias_tc.value, math.sqrt((bias_tc.std or 0.0) ** 2 + spread_b))
        if sf_tc is not None:
            sf_tc = Estimate(sf_tc.value, math.sqrt((sf_tc.std or 0.0) ** 2 + spread_s))
    te_b = rec.block_mean(rec.element(lag_value))
    return ThermalRecordResult(
        bias_tc=bias_tc, scale_factor_tc_ppm_per_c=sf_tc,
        lag_s=Estimate(float(lag_value), lag_std), bias_curve=bias_curve, scale_factor_curve=sf_curve,
        output_bias_curve=out_bias, rate_sensitivity=rate_sens, bias_order=nb, scale_factor_order=ns,
        bic_by_order=bic, not_separable=not_separable, separation_lag=sep_lag, warnings=tuple(warnings),
        hysteresis=hyst, hysteresis_width_c=width_est,
        hysteresis_width_interval_c=None if profile is None else profile.interval,
        reference_c=ref, element_range_c=(float(te_b[used].min()), float(te_b[used].max())),
        noise=fit.noise, noise_sigma=fit.sigma, dof=fit.dof, block_s=block, block_t_s=tb, block_output=yb,
        block_temperature_c=tempb, block_element_c=te_b, block_applied=xb, block_residual=yb - xd @ coef,
        block_used=used)
